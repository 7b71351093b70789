"""Where the steps of a dynamic run go: free flight and contact, steps, rejected attempts,
Newton iterations and the step sizes of each (issue 22, "Fewer steps, too").

Reads the output folder of ``beamcontact run`` (history.csv and summary.json). A step is
"in contact" when its contact energy is not zero (the coarse-grained potential acts within
its cutoff, IPIP on overlap), else "free"; the rejected attempts are charged to the step
that followed them (the history's cumulative ``cutbacks``), by kind only in total
(summary.json's ``rejections``).

    python benchmarks/step_budget.py RUN_DIR [RUN_DIR ...]
"""

import argparse
import json
from pathlib import Path

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


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("runs", nargs="+", type=Path, help="output folders of beamcontact run")
    for run in ap.parse_args().runs:
        budget(run)


if __name__ == "__main__":
    main()
