"""Where the steps of a dynamic run go: free flight and contact, steps, rejected attempts,
Newton iterations and the step sizes of each (issue 22, "Fewer steps, too"); and what
sets the steps: the dof whose acceleration changed most in each accepted step.

Reads the output folder of ``beamcontact run`` (history.csv, summary.json, results.h5). A
step is "in contact" when its contact energy is not zero (the coarse-grained potential
acts within its cutoff, IPIP on overlap), else "free"; the rejected attempts are charged
to the step that followed them (the history's cumulative ``cutbacks``), by kind only in
total (summary.json's ``rejections``).

The local error estimate of a step (Zienkiewicz & Xie 1991) is h^2 |beta - 1/6| times
the largest |a_{n+1} - a_n| over the dofs, so the dof of that largest change is the one the
step controller follows. The second table counts, in the time windows between the
``--split`` times, which beam and direction it belongs to, and which control points of its
beam (numbered from 0 at its start) it is most often (results.h5 holds every accepted
state).

    python benchmarks/step_budget.py RUN_DIR [RUN_DIR ...] [--split 0.75 1.2]
"""

import argparse
import collections
import json
from pathlib import Path

import h5py
import numpy as np


def budget(run: Path) -> None:
    h = np.genfromtxt(run / "history.csv", delimiter=",", names=True)
    summary = json.loads((run / "summary.json").read_text())
    t, dt, it = h["t"][1:], h["dt"][1:], h["newton_iters"][1:]
    rejected = np.diff(h["cutbacks"])
    contact = h["E_contact"][1:] != 0.0
    print(f"\n{run}: {summary['title']}")
    print(f"{summary['steps']} steps to t = {summary['t_final']:.4g} s, "
          f"{summary['newton_iterations']} Newton iterations, rejected attempts by kind "
          f"{summary['rejections']}, step loop {summary['solve_time_s']:.2f} s")
    print("| phase | simulated [s] | steps | share of steps | rejected | Newton it. per step | "
          "mean step [ms] | smallest step [ms] |")
    print("|---|---|---|---|---|---|---|---|")
    for name, mask in (("free", ~contact), ("in contact", contact)):
        n = int(mask.sum())
        if n == 0:
            continue
        print(f"| {name} | {dt[mask].sum():.3f} | {n} | {n / len(t):.0%} | "
              f"{int(rejected[mask].sum())} | {it[mask].mean():.2f} | "
              f"{1e3 * dt[mask].mean():.3f} | {1e3 * dt[mask].min():.4f} |")


def error_dofs(run: Path, splits: list[float]) -> None:
    """The table of the dofs that set the local error estimate (module docstring)."""
    with h5py.File(run / "results.h5", "r") as f:
        t, dt, a = f["states/parameter"][:], f["states/dt"][:], f["states/a"][:]
        beams = [(name, int(g.attrs["offset"]), g["reference_points"].shape[0])
                 for name, g in f["model"].items()]
    dof = np.argmax(np.abs(np.diff(a, axis=0)), axis=1)
    cp, direction = dof // 2, np.where(dof % 2 == 0, "x", "y")
    beam, local = np.empty(len(cp), dtype=object), np.zeros(len(cp), dtype=int)
    for name, offset, n in beams:
        mine = (cp >= offset) & (cp < offset + n)
        beam[mine] = name
        local[mine] = cp[mine] - offset
    start, t, dt = t[0], t[1:], dt[1:]
    last = {name: n - 1 for name, _, n in beams}
    print("\nthe dof of the largest |a_{n+1} - a_n| (what the error estimate follows)")
    print("| window [s] | steps | median step [ms] | beam and direction (steps) | "
          "control points most often (steps) |")
    print("|---|---|---|---|---|")
    edges = [start] + sorted(splits) + [t[-1]]
    for lo, hi in zip(edges[:-1], edges[1:], strict=True):
        w = (t > lo) & (t <= hi)
        if not w.any():
            continue
        counts = collections.Counter(zip(beam[w], direction[w], strict=True))
        most = ", ".join(f"{b} {d} {n}" for (b, d), n in counts.most_common())
        points = collections.Counter(zip(beam[w], local[w], strict=True)).most_common(4)
        often = ", ".join(f"{b} {k} of 0-{last[b]} ({n})" for (b, k), n in points)
        print(f"| {lo:.3g}-{hi:.3g} | {int(w.sum())} | {1e3 * np.median(dt[w]):.3f} | "
              f"{most} | {often} |")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("runs", nargs="+", type=Path, help="output folders of beamcontact run")
    ap.add_argument("--split", nargs="*", type=float, default=[],
                    help="times [s] that split the run into the windows of the second table")
    args = ap.parse_args()
    for run in args.runs:
        budget(run)
        error_dofs(run, args.split)


if __name__ == "__main__":
    main()
