"""Generate the fibre-pile case: N elastic fibres of random length and orientation
(seeded) dropped into a container: three rigid walls (``[[obstacles]]``), or steel rods
clamped at both ends (``--container rods``).

    python examples/fibre_pile/pile.py --fibres 200 --model cg > case_cg.toml

The fibres start on a grid of square cells above the container's floor, one fibre per
cell, centred in it and shorter than the cell, so that no two fibres (and no fibre and
the container) overlap at t = 0; the container is as wide as the grid.
benchmarks/many_fibres.py builds its cases with :func:`pile_case`.
"""

import argparse
import math
import sys

import numpy as np

# fibres: length between LENGTH_MIN and LENGTH_MAX [m], circular section of RADIUS [m]
LENGTH_MIN, LENGTH_MAX, RADIUS = 0.06, 0.14, 0.004
E_FIBRE, DENSITY = 2.0e7, 1000.0
CELL = 0.16  # one fibre per CELL x CELL square [m]
WALL_RADIUS = 0.008  # the container: steel rods clamped at both ends
FLOOR_CELLS = 4  # cells spanned by each rod of the floor


def pile_case(n_fibres: int, seed: int = 1, model: str = "cg", rows: int = 10,
              t_end: float = 1.0, dt: float = 2.0e-3, container: str = "walls") -> dict:
    """The case (a dict for :func:`beamcontact.io.case.parse_case`) of ``n_fibres``
    fibres on a grid of ``rows`` rows of cells in a container as wide as the grid: with
    the rows fixed, more fibres make a wider pile of the same height, in which every
    fibre has about as many neighbours (benchmarks/many_fibres.py). ``container``:
    "walls", a floor and two side walls as rigid obstacles, or "rods", clamped steel
    rods (beams) in the same places."""
    if container not in ("walls", "rods"):
        raise ValueError(f'container must be "walls" or "rods", got {container!r}')
    rng = np.random.default_rng(seed)
    columns = max(2, math.ceil(n_fibres / rows))
    rows = math.ceil(n_fibres / columns)
    width = columns * CELL
    gap = 2 * (RADIUS + WALL_RADIUS)  # clear of the container at t = 0
    beams = []
    for k in range(n_fibres):
        row, col = divmod(k, columns)
        centre = np.array([(col + 0.5) * CELL, gap + (row + 0.5) * CELL])
        length = rng.uniform(LENGTH_MIN, LENGTH_MAX)
        angle = rng.uniform(0.0, math.pi)
        half = 0.5 * length * np.array([math.cos(angle), math.sin(angle)])
        beams.append({"name": f"fibre{k}", "line": {"start": (centre - half).tolist(),
                                                "end": (centre + half).tolist()},
                      "degree": 3, "elements": 2,
                      "section": {"shape": "circle", "radius": RADIUS},
                      "material": {"E": E_FIBRE, "density": DENSITY}})
    height = gap + rows * CELL + CELL
    contact = {"model": model, "segments_per_element": 6, "capacity": 4 * n_fibres + 64}
    if model == "cg":
        # steric repulsion (m = 12): two parallel fibres push each other with about
        # 5 N/m (the weight of ten fibres above) at a gap of R/5; the cutoff, at a gap
        # of 2.5 R, leaves less than 1e-6 of that
        contact.update(exponent=12, k=3.0e-24, cutoff=4.5 * RADIUS)
    else:
        # a line penalty of about 1e5 N/m per 8 mm spacing: 5 N/m presses 0.4 um in
        contact.update(penalty=1.0e5, pairing="points")
    case = {"title": f"{n_fibres} fibres dropped into a container ({model})",
            "analysis": {"kind": "dynamic", "t_end": t_end, "dt": dt, "alpha": -0.1,
                         "gravity": [0.0, -9.81]},
            "beams": beams, "contact": contact}
    if container == "walls":
        case["obstacles"] = [
            {"name": "floor", "wall": {"point": [0.0, 0.0], "normal": [0.0, 1.0]}},
            {"name": "left", "wall": {"point": [-gap, 0.0], "normal": [1.0, 0.0]}},
            {"name": "right", "wall": {"point": [width + gap, 0.0], "normal": [-1.0, 0.0]}}]
        # the error bound is a fraction of the longest beam: 20 um per step (R / 200)
        case["solver"] = {"error_tol": 2.0e-5 / LENGTH_MAX}
        case["output"] = {"points": [{"name": "first", "beam": "fibre0", "at": 0.5}]}
        return case
    clamped = [{"at": "start", "type": "clamped"}, {"at": "end", "type": "clamped"}]
    wall = {"degree": 3, "section": {"shape": "circle", "radius": WALL_RADIUS},
            "material": {"E": 2.0e11, "density": 7850.0}, "supports": clamped,
            "gravity": False}
    # the floor: steel rods of FLOOR_CELLS cells each, clamped at both ends (short spans
    # barely sag under the pile), a little more than one rod diameter apart
    edges = np.linspace(-gap, width + gap, math.ceil(columns / FLOOR_CELLS) + 1)
    for k, (a, b) in enumerate(zip(edges[:-1], edges[1:], strict=True)):
        beams.append({"name": f"floor{k}", "line": {"start": [a + 1.1 * WALL_RADIUS, 0.0],
                                                    "end": [b - 1.1 * WALL_RADIUS, 0.0]},
                      "elements": 2 * FLOOR_CELLS, **wall})
    side = max(2, round(height / CELL))
    beams += [
        {"name": "left", "line": {"start": [-gap, gap], "end": [-gap, height]},
         "elements": side, **wall},
        {"name": "right", "line": {"start": [width + gap, gap], "end": [width + gap, height]},
         "elements": side, **wall},
    ]
    # the error bound is a fraction of the longest beam (a wall): 20 um per step (R / 200)
    case["solver"] = {"error_tol": 2.0e-5 / max(height - gap, edges[1] - edges[0])}
    case["output"] = {"points": [{"name": "floor_mid", "beam": "floor0", "at": 0.5}]}
    return case


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--fibres", type=int, default=200)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--model", choices=["cg", "ipip"], default="cg")
    ap.add_argument("--rows", type=int, default=10)
    ap.add_argument("--t-end", type=float, default=1.0)
    ap.add_argument("--container", choices=["walls", "rods"], default="walls")
    args = ap.parse_args(argv)
    from beamcontact.io.case import parse_case

    case = parse_case(pile_case(args.fibres, args.seed, args.model, args.rows,
                                t_end=args.t_end, container=args.container))
    sys.stdout.write(case.to_toml())


if __name__ == "__main__":
    main()
