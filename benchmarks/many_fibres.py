"""Scaling with the number of fibres (issue 13): piles of N = 10, 100, 1000 fibres.

    python benchmarks/many_fibres.py [--fibres 10 100 1000] [--model ipip cg]

Each pile comes from examples/fibre_pile/pile.py with four rows of fibres, so that the
container grows in width with N and every fibre keeps about as many neighbours. Each N
runs in its own process (for its peak memory): the fibres fall until the lowest row has
landed (``--settle``, about 5 ms after the first impacts at 0.127 s), then the time per
step is measured over a further ``--window`` of simulated time, starting from candidate
lists already twice as large as the settled pile needs, so that nothing recompiles
(the first attempt, which compiles, is left out). Printed per
N: dofs, steps and Newton iterations of the window, ms per step, the candidate element
pairs of the broad phase at the end (and the grid's fullest cell), the peak resident
memory of the process, and the ratio of the time per step to that of the smallest N
times N / N_smallest (1 = linear).
"""

import argparse
import json
import resource
import subprocess
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def one(n: int, model: str, settle: float, window: float) -> dict:
    """Run the pile of n fibres in this process; the figures of its window."""
    import beamcontact

    beamcontact.enable_x64()
    import jax.numpy as jnp

    sys.path.insert(0, str(REPO / "examples" / "fibre_pile"))
    from pile import pile_case

    from beamcontact.contact.broadphase import candidate_pairs
    from beamcontact.dynamics.driver import solve_dynamic
    from beamcontact.io.case import parse_case
    from beamcontact.setup.start import dynamic_start, prepare

    case = parse_case(pile_case(n, seed=1, model=model, rows=4, t_end=settle,
                                container="rods"))
    t0 = time.perf_counter()
    prepared = prepare(case)
    setup = time.perf_counter() - t0
    start = dynamic_start(prepared)
    model_, contact, engine = prepared.model, prepared.contact, start.engine
    _, cap = contact.grown_set(model_.x_ref, 0.0, case.contact.capacity)
    first = solve_dynamic(engine, start.state, settle, prepared.length, start.control,
                          capacity=cap.blocks)
    # candidate lists with room for what the window will need
    x = model_.x_ref + first.state.u.reshape(-1, 2)
    _, cap = contact.grown_set(x, 0.0, cap)
    cap = cap._replace(blocks=2 * cap.blocks, per_cell=2 * cap.per_cell)
    t1 = time.perf_counter()
    second = solve_dynamic(engine, first.state, settle + window, prepared.length,
                           start.control, dt_start=first.dt_next, capacity=cap)
    wall = time.perf_counter() - t1
    x = model_.x_ref + second.state.u.reshape(-1, 2)
    _, count, load = candidate_pairs(jnp.asarray(x), contact.elements,
                                     jnp.asarray(contact.reach), cap)
    loop = wall - second.compile_time
    return {"fibres": n, "model": model, "dofs": int(model_.n_dof),
            "elements": int(contact.elements.n_elements), "setup_s": setup,
            "settle_steps": first.steps, "settle_s": first.wall_time,
            "status": second.status, "steps": second.steps,
            "iterations": second.iterations, "compile_s": second.compile_time,
            "ms_per_step": 1e3 * loop / max(second.steps - 1, 1),
            "candidates": int(count), "fullest_cell": int(load),
            "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
            "t_end": second.t, "sparse": bool(model_.sparse)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--fibres", type=int, nargs="+", default=[10, 100, 1000])
    ap.add_argument("--model", nargs="+", default=["ipip"], choices=["ipip", "cg"])
    ap.add_argument("--settle", type=float, default=0.132)
    ap.add_argument("--window", type=float, default=0.003)
    ap.add_argument("--one", type=int, default=None, help=argparse.SUPPRESS)
    a = ap.parse_args()
    if a.one is not None:
        print(json.dumps(one(a.one, a.model[0], a.settle, a.window)))
        return
    import os

    print(f"machine: {os.cpu_count()} cores; python {sys.version.split()[0]}; "
          f"{time.strftime('%Y-%m-%d %H:%M')}", flush=True)
    for model in a.model:
        rows = []
        for n in a.fibres:
            proc = subprocess.run([sys.executable, __file__, "--one", str(n), "--model", model,
                                   "--settle", str(a.settle), "--window", str(a.window)],
                                  capture_output=True, text=True)
            if proc.returncode:
                print(f"N = {n} failed:\n{proc.stderr[-3000:]}", flush=True)
                continue
            rows.append(json.loads(proc.stdout.strip().splitlines()[-1]))
            print(json.dumps(rows[-1]), flush=True)
        if not rows:
            continue
        base = rows[0]
        print(f"\n{model}: window of {a.window} s after {a.settle} s")
        print("| fibres | dofs | steps | Newton it. | ms per step | ratio / linear | "
              "candidates | fullest cell | peak memory [MB] | settle [s] |")
        print("|---|---|---|---|---|---|---|---|---|---|")
        for r in rows:
            linear = (r["ms_per_step"] / base["ms_per_step"]) / (r["fibres"] / base["fibres"])
            print(f"| {r['fibres']} | {r['dofs']} | {r['steps']} | {r['iterations']} | "
                  f"{r['ms_per_step']:.1f} | {linear:.2f} | {r['candidates']} | "
                  f"{r['fullest_cell']} | {r['peak_rss_mb']:.0f} | {r['settle_s']:.1f} |")


if __name__ == "__main__":
    main()
