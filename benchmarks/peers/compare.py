"""beamcontact against the peer codes on the drop of benchmarks/peers/README.md.

Runs the drop (a free 4 m beam falling from a surface gap of 2.76 m onto a pinned 10 m
beam, E = 1e7 Pa, R = 0.1 m, rho = 1000 kg/m^3, gravity on the falling beam only) with
both contact models of beamcontact (IPIP with the paper's pairing rule, "zones", and with
the conservative "points" rule), HHT alpha = 0 (the trapezoidal rule: no numerical
damping, like the peers' integrators), and compares the midspan deflection of the lower
beam over 0 < t < 1.2 s with the peers' results in benchmarks/peers/results/*.csv
(made by drop_pyelastica.py and drop_exudyn.py). Prints a table of the largest
deviations and writes the overlay figure.

    python benchmarks/peers/compare.py [--out DIR] [--figure PNG]
"""

import argparse
import time
from pathlib import Path

import numpy as np

import beamcontact

HERE = Path(__file__).resolve().parent
PEERS = {"PyElastica": HERE / "results" / "pyelastica.csv",
         "Exudyn": HERE / "results" / "exudyn.csv"}


MODELS = ("cg", "ipip", "ipip-points")


def drop_case(model: str, t_end: float = 1.2, segments: int = 20,
              penalty: float = 1.0e6, E: float = 1.0e7) -> dict:
    """The peer drop as a beamcontact case (the bundled benchmark's discretisation and
    contact parameters, with the peers' geometry and material). ``model``: one of
    MODELS; "ipip" is the paper's pairing rule ("zones"), "ipip-points" the
    conservative one (contact.pairing = "points")."""
    material = {"E": E, "density": 1000.0}
    section = {"shape": "circle", "radius": 0.1}
    contact = {"model": model.split("-")[0], "segments_per_element": segments}
    if model == "cg":
        contact.update(exponent=12, k=5.0e-25, densities=[1.0, 1.0], cutoff=0.3)
    else:
        contact.update(penalty=penalty, pairing="points" if model == "ipip-points" else "zones")
    return {
        "title": f"Peer drop: 4 m beam onto a pinned 10 m beam ({model})",
        "analysis": {"kind": "dynamic", "t_end": t_end, "dt": 1.0e-3, "alpha": 0.0,
                     "gravity": [0.0, -9.81]},
        "beams": [
            {"name": "lower", "line": {"start": [0.0, 0.0], "end": [10.0, 0.0]},
             "degree": 4, "elements": 20, "continuity": 1, "section": section,
             "material": material, "gravity": False,
             "supports": [{"at": "start", "type": "pinned"}, {"at": "end", "type": "pinned"}]},
            {"name": "upper", "line": {"start": [3.0, 2.96], "end": [7.0, 2.96]},
             "degree": 4, "elements": 8, "continuity": 1, "section": section,
             "material": material, "gravity": True},
        ],
        "contact": contact,
        "output": {"points": [{"name": "A", "beam": "lower", "at": 0.5}],
                   "vtk_interval": 0.02},
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("results_peer_drop"))
    parser.add_argument("--figure", type=Path,
                        default=HERE.parents[1] / "examples" / "free_fall" / "peer_drop.png")
    parser.add_argument("--t-end", type=float, default=1.2)
    args = parser.parse_args()
    beamcontact.enable_x64()
    from beamcontact.io.case import parse_case
    from beamcontact.io.results import read_history
    from beamcontact.runner import run_case

    curves = {}
    for name, path in PEERS.items():
        data = np.genfromtxt(path, delimiter=",", names=True)
        curves[name] = (data["t"], data["A_uy"])
    for model in MODELS:
        t0 = time.perf_counter()
        summary = run_case(parse_case(drop_case(model, args.t_end)), "", args.out / model)
        h = read_history(args.out / model / "history.csv")
        curves[f"beamcontact {model.upper()}"] = (h["t"], h["A_uy"])
        print(f"beamcontact {model}: {summary['status']}, {summary['steps']} steps, "
              f"{time.perf_counter() - t0:.1f} s, energy {summary['energy']}")
    grid = np.linspace(0.0, args.t_end, 2401)
    on_grid = {k: np.interp(grid, t, a) for k, (t, a) in curves.items()}
    names = list(on_grid)
    print(f"largest |difference| of A_uy over 0 < t < {args.t_end} s [m]")
    print("| | " + " | ".join(names) + " |")
    print("|---" * (len(names) + 1) + "|")
    for a in names:
        row = [f"{np.max(np.abs(on_grid[a] - on_grid[b])):.3f}" for b in names]
        print(f"| {a} | " + " | ".join(row) + " |")
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4))
    for k, (t, a) in curves.items():
        ax.plot(t, a, label=k, lw=1.2, ls="--" if "beamcontact" not in k else "-")
    ax.set_xlim(0.0, args.t_end)
    ax.set_xlabel("t [s]")
    ax.set_ylabel("midspan deflection of the lower beam u_y [m]")
    ax.set_title("Peer drop: beamcontact (HHT alpha = 0) against PyElastica and Exudyn")
    ax.grid(alpha=0.3)
    ax.legend()
    fig.tight_layout()
    args.figure.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(args.figure, dpi=120)
    print(f"wrote {args.figure}")


if __name__ == "__main__":
    main()
