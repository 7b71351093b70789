"""Convergence of the free-fall benchmark with the step tolerances (issue 10, item 4).

Runs the coarse-grained benchmark (case_cg.toml) for each error tolerance, with
``energy_tol = 100 error_tol`` (the ratio of the defaults), each a quarter of the previous
by default, and prints a Markdown table: steps, rejected attempts, first impact time,
first amplitude of A and when, its change from the previous row, and the largest
difference of A's deflection from the finest run before the second collision
(t < 1.25 s) and over the whole run.

    python examples/free_fall/convergence.py [--t-end 2.0] [--tol 1e-5 2.5e-6 ...] [--out DIR]
"""

import argparse
import time
import tomllib
from pathlib import Path

import numpy as np

import beamcontact

HERE = Path(__file__).resolve().parent


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--t-end", type=float, default=2.0)
    ap.add_argument("--tol", type=float, nargs="+", default=[1e-5, 2.5e-6, 6.25e-7, 1.5625e-7])
    ap.add_argument("--out", type=Path, default=Path("results_convergence"))
    ap.add_argument("--segments", type=int, default=None,
                    help="contact.segments_per_element (default: the case file's)")
    args = ap.parse_args()
    beamcontact.enable_x64()
    from beamcontact.io.case import parse_case
    from beamcontact.io.results import read_history
    from beamcontact.runner import run_case

    rows = []
    for tol in args.tol:
        raw = tomllib.loads((HERE / "case_cg.toml").read_text())
        raw["analysis"]["t_end"] = args.t_end
        raw["solver"] = {"error_tol": tol, "energy_tol": 100.0 * tol}
        if args.segments is not None:
            raw["contact"]["segments_per_element"] = args.segments
        out = args.out / f"error_tol={tol:g}"
        t0 = time.perf_counter()
        s = run_case(parse_case(raw), "", out)
        h = read_history(out / "history.csv")
        amp = s["first_amplitude"].get("A", {"uy": float("nan"), "t": float("nan")})
        rows.append({"tol": tol, "steps": s["steps"], "rejected": s["cutbacks"],
                     "impact": s["first_impact_time"], "amp": amp["uy"], "amp_t": amp["t"],
                     "dE": s["energy"]["E_total_final"] - s["energy"]["E_total_initial"],
                     "wall": time.perf_counter() - t0, "t": h["t"], "A": h["A_uy"]})
        print(f"error_tol {tol:g}: {s['status']}, {s['steps']} steps, first amplitude "
              f"{amp['uy']:.4f} m at {amp['t']:.4f} s", flush=True)
    finest = rows[-1]
    grid = np.linspace(0.0, args.t_end, 8001)
    ref = np.interp(grid, finest["t"], finest["A"])
    early = grid < 1.25
    print()
    print("| error_tol | energy_tol | steps | rejected | first impact [s] | first amplitude "
          "of A [m] | at t [s] | change from the row above [mm] | max diff. from finest, "
          "t < 1.25 s [mm] | max diff. from finest, whole run [mm] | E_total change [J] "
          "| wall [s] |")
    print("|---" * 12 + "|")
    previous = None
    for r in rows:
        d = np.abs(np.interp(grid, r["t"], r["A"]) - ref)
        change = "" if previous is None else f"{1e3 * abs(r['amp'] - previous):.1f}"
        print(f"| {r['tol']:g} | {100 * r['tol']:g} | {r['steps']} | {r['rejected']} | "
              f"{r['impact']:.5f} | {r['amp']:.4f} | {r['amp_t']:.3f} | {change} | "
              f"{1e3 * d[early].max():.2f} | {1e3 * d.max():.1f} | {r['dE']:.1f} | "
              f"{r['wall']:.0f} |")
        previous = r["amp"]


if __name__ == "__main__":
    main()
