"""Step counts of the peer drop over an ensemble of drop heights: what a change to the
step control or the model does to the work, beyond the chaos of one history.

The peer drop's later contacts depend on the phase of the beams' vibration, and its
histories part after about 1.2 s under any perturbation (benchmarks/README.md, session
25). So do its step counts: the 2 s drop with the falling beam 0, 0.1, ..., 0.5 mm
higher takes 6289-7268 steps (IPIP points) and 8433-9206 (CG), peers.py's case (0 mm)
7268 and 9206 (session 38). A change that moves the steps of one run by less than that
moves them by chance; this script measures it over ``--members`` runs whose falling beam
starts ``k * --dy`` higher (k = 0 .. members - 1; k = 0 is peers.py's case), each a
``beamcontact run`` as a user types it (every default output written), and prints for
each model and each choice of ``--outliers`` (``beams.remove_outliers`` of the falling
beam) one row per member and their mean, smallest and largest: steps, attempts (steps
and rejected attempts), Newton iterations, rejections by kind, the step loop and the
steps alone (summary.json's ``solve_time_s`` without ``writing_time_s``).

    python benchmarks/drop_ensemble.py [--models ipip-points cg] [--outliers keep remove]
                                       [--members 6] [--dy 1e-4] [--t-end 2.0]

To compare two versions of the code, run it from each checkout (a run uses the
``beamcontact`` that ``python -m beamcontact.cli`` imports). About 3 s per member here
after one untimed run per case fills the compilation cache. Numbers and machine:
benchmarks/README.md.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path[:0] = [str(HERE), str(HERE / "peers")]
from compare import drop_case  # noqa: E402
from peers import beamcontact_run  # noqa: E402

# the columns of a row: (heading, key of the member's record)
COLUMNS = (("steps", "steps"), ("attempts", "attempts"), ("Newton it.", "iterations"),
           ("rejected: error", "error"), ("energy", "energy"), ("other", "other"),
           ("step loop [s]", "loop"), ("steps alone [s]", "stepping"))


def case_file(model: str, outliers: str, offset: float, t_end: float, folder: Path) -> Path:
    """The peer drop of peers.py (every default output) with the falling beam ``offset``
    metres higher."""
    import tomli_w

    case = drop_case(model, t_end=t_end)
    case["output"]["vtk_interval"] = t_end / 100  # the default cadence
    upper = case["beams"][1]
    upper["remove_outliers"] = outliers == "remove"
    for end in ("start", "end"):
        upper["line"][end][1] += offset
    path = folder / f"drop_{model}_{outliers}_{offset:g}.toml"
    path.write_text(tomli_w.dumps(case))
    return path


def member(case: Path, out: Path) -> dict:
    """One ``beamcontact run`` of ``case``: its counts and times."""
    run = beamcontact_run(case, out, case.stem)
    summary = json.loads((out / "summary.json").read_text())
    rejected = summary["rejections"]
    return {**run, "attempts": summary["steps"] + summary["cutbacks"],
            "error": rejected.get("error", 0), "energy": rejected.get("energy", 0),
            "other": summary["cutbacks"] - rejected.get("error", 0) - rejected.get("energy", 0)}


def table(title: str, rows: list[tuple[str, dict]]) -> str:
    """A markdown table of the members and their mean, smallest and largest."""
    lines = [f"\n{title}", "| member | " + " | ".join(h for h, _ in COLUMNS) + " |",
             "|---|" + "---|" * len(COLUMNS)]

    def cell(value: float) -> str:
        return f"{value:.2f}" if isinstance(value, float) else f"{value}"

    for name, r in rows:
        lines.append(f"| {name} | " + " | ".join(cell(r[k]) for _, k in COLUMNS) + " |")
    values = {k: np.array([r[k] for _, r in rows], dtype=float) for _, k in COLUMNS}
    for name, f in (("mean", np.mean), ("smallest", np.min), ("largest", np.max)):
        cells = []
        for _, k in COLUMNS:
            v = f(values[k])
            cells.append(f"{v:.2f}" if k in ("loop", "stepping") else f"{v:.0f}")
        lines.append(f"| **{name}** | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--models", nargs="+", default=["ipip-points", "cg"],
                    choices=["ipip", "ipip-points", "cg"])
    ap.add_argument("--outliers", nargs="+", default=["keep", "remove"],
                    choices=["keep", "remove"])
    ap.add_argument("--members", type=int, default=6, help="runs per model and choice")
    ap.add_argument("--dy", type=float, default=1e-4,
                    help="the falling beam starts k dy higher in member k [m]")
    ap.add_argument("--t-end", type=float, default=2.0, help="simulated time [s]")
    args = ap.parse_args()
    if args.members < 1 or args.dy <= 0.0 or args.t_end <= 0.0:
        ap.error("--members must be at least 1, --dy and --t-end positive")
    print(f"peer drop ensemble: {args.members} members, the falling beam k x {args.dy:g} m "
          f"higher, {args.t_end:g} s simulated", flush=True)
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        for model in args.models:
            for outliers in args.outliers:
                cases = [case_file(model, outliers, k * args.dy, args.t_end, folder)
                         for k in range(args.members)]
                member(cases[0], folder / f"warm_up_{cases[0].stem}")  # fills the compilation cache
                rows = [(f"+{k * args.dy * 1e3:.2f} mm", member(c, folder / c.stem))
                        for k, c in enumerate(cases)]
                label = "outliers kept" if outliers == "keep" else "remove_outliers"
                print(table(f"{model}, {label}", rows), flush=True)


if __name__ == "__main__":
    main()
