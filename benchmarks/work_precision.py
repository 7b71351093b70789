"""Work against precision of the peer drop's time integration, beamcontact and PyElastica.

beamcontact's adaptive HHT steps and PyElastica's fixed explicit steps, each against its
own converged run.

peers.py compares the two codes at one setting each: PyElastica at dt = 1e-4 s and
beamcontact at its default tolerances. Those are not the same accuracy. This script
measures, for each code alone, how far its midspan deflection A_uy lies from the same
code's run at a much finer time resolution (same mesh, same model: the time-integration
error alone), and what each setting costs:

* PyElastica (benchmarks/peers/drop_pyelastica.py, PositionVerlet, explicit and
  symplectic) at the steps ``--dts`` and its reference at ``--reference-dt``;
* ``beamcontact run`` (native engine, every default output written) for each of
  ``--models`` at the step tolerances ``--tolerances`` (``solver.error_tol``, with
  ``energy_tol = 100 error_tol`` as in examples/free_fall/convergence.py) and its
  reference at ``--reference-tol``.

The window ends at ``--t-end`` (1.2 s by default): the histories of any two runs of the
peer drop part after its second contact episode, about 1.25 s (benchmarks/README.md,
session 25), so the error of a setting means something only before it. The error is the
largest |A_uy - A_uy of the reference| up to 1.0 s (the first contact episode, 0.75-0.95
s, included) and up to ``--t-end``.

Prints one table per code: setting, steps, step loop (PyElastica's as its script prints
it, the energy sampling excluded; beamcontact's steps alone, ``solve_time_s -
writing_time_s`` of summary.json), whole process, and both errors; then, for each of
PyElastica's steps and each window, beamcontact's cheapest tolerance at least as
accurate and the ratio of their step loops: the speed at equal accuracy.

    pip install ".[peers]"
    python benchmarks/work_precision.py [--models ipip-points cg] [--t-end 1.2]

About 11 minutes here (PyElastica's reference, 96 000 steps, half of it). Numbers and
machine: benchmarks/README.md.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
PEERS = HERE / "peers"
sys.path[:0] = [str(HERE), str(PEERS)]
from compare import drop_case  # noqa: E402
from peers import beamcontact_run, pyelastica, warm_up_pyelastica  # noqa: E402

# the windows of the error [s]: through the first contact episode, and to t_end
FIRST_EPISODE_END = 1.0
# PyElastica's rows: every step, or every ROW_INTERVAL at most [s]
ROW_INTERVAL = 1e-4


def _errors(ref: Path, other: Path, ends: list[float]) -> list[float]:
    """Largest |A_uy - A_uy of ref| [m] from t = 0 to each of ``ends``, at the other run's
    own times (its steps, where it claims its accuracy) with the reference (rows every
    step, or every 1e-4 s at most) interpolated linearly onto them."""
    d_ref, d_other = (np.genfromtxt(p, delimiter=",", names=True) for p in (ref, other))
    out = []
    for end in ends:
        t = d_other["t"][d_other["t"] <= end + 1e-12]
        diff = d_other["A_uy"][:len(t)] - np.interp(t, d_ref["t"], d_ref["A_uy"])
        out.append(float(np.max(np.abs(diff))))
    return out


def _case_file(model: str, t_end: float, error_tol: float, folder: Path) -> Path:
    import tomli_w

    case = drop_case(model, t_end=t_end)
    case["output"]["vtk_interval"] = t_end / 100  # the default cadence
    case["solver"] = {"engine": "native", "error_tol": error_tol,
                      "energy_tol": 100.0 * error_tol}
    path = folder / f"drop_{model}_tol{error_tol:g}.toml"
    path.write_text(tomli_w.dumps(case))
    return path


def _beamcontact(model: str, tol: float, t_end: float, tmp: Path) -> dict:
    case = _case_file(model, t_end, tol, tmp)
    if not (tmp / f"warm_{model}").exists():  # fills the compilation cache, untimed
        beamcontact_run(case, tmp / f"warm_{model}", "warm-up")
    row = beamcontact_run(case, tmp / f"bc_{model}_{tol:g}", f"error_tol {tol:g}")
    return {"setting": f"error_tol = {tol:g}", "steps": row["steps"],
            "loop": row["stepping"], "process": row["process"], "csv": row["csv"]}


def _pyelastica(dt: float, t_end: float, tmp: Path) -> dict:
    """PyElastica's drop with a row every step, or every ROW_INTERVAL at most (its sampling
    is outside its step loop's time)."""
    row = pyelastica(dt, t_end, tmp / f"pe_{dt:g}.csv", 1.0e7,
                     max_rows=round(t_end / max(dt, ROW_INTERVAL)) + 1)
    return {"setting": f"dt = {dt:g} s", "steps": round(t_end / dt), "loop": row["time"],
            "process": row["process"], "csv": row["csv"]}


def _windows(t_end: float) -> list[float]:
    """The ends of the error's windows [s]: the first contact episode's and t_end."""
    return sorted({min(FIRST_EPISODE_END, t_end), t_end})


def _table(title: str, rows: list[dict], ref: dict, t_end: float, loop: str) -> None:
    """One code's settings, their cost (``loop``: what its time column is) and errors."""
    ends = _windows(t_end)
    print(f"\n{title} (reference: {ref['setting']}, {ref['steps']} steps, {loop} "
          f"{ref['loop']:.2f} s)")
    print(f"| setting | steps | {loop} [s] | process [s] | "
          + " | ".join(f"max error of A_uy to {end:g} s [mm]" for end in ends) + " |")
    print("|---|---|---|---|" + "---|" * len(ends))
    for r in rows:
        r["errors"] = _errors(ref["csv"], r["csv"], ends)
        print(f"| {r['setting']} | {r['steps']} | {r['loop']:.2f} | {r['process']:.2f} | "
              + " | ".join(f"{1e3 * e:.3f}" for e in r["errors"]) + " |")
    sys.stdout.flush()


def _equal_accuracy(peer: list[dict], ours: dict[str, list[dict]], ends: list[float]) -> None:
    print("\nequal accuracy: for each PyElastica step and window, beamcontact's cheapest "
          "tolerance with an error at most PyElastica's")
    print("| to [s] | PyElastica | its error [mm] | its step loop [s] | model | beamcontact | "
          "error [mm] | steps alone [s] | PyElastica / beamcontact |")
    print("|---|---|---|---|---|---|---|---|---|")
    for w, end in enumerate(ends):
        for p in peer:
            for model, rows in ours.items():
                head = (f"| {end:g} | {p['setting']} | {1e3 * p['errors'][w]:.3f} | "
                        f"{p['loop']:.2f} | {model} |")
                good = [r for r in rows if r["errors"][w] <= p["errors"][w]]
                if not good:
                    print(f"{head} none as accurate | | | |")
                    continue
                r = min(good, key=lambda r: r["loop"])
                print(f"{head} {r['setting']} | {1e3 * r['errors'][w]:.3f} | "
                      f"{r['loop']:.2f} | {p['loop'] / r['loop']:.1f}x |")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--models", nargs="+", default=["ipip-points", "cg"],
                    choices=["cg", "ipip", "ipip-points"], help="beamcontact contact models")
    ap.add_argument("--t-end", type=float, default=1.2, help="simulated time [s]")
    ap.add_argument("--tolerances", type=float, nargs="+",
                    default=[1.6e-4, 4e-5, 1e-5, 2.5e-6, 6.25e-7, 1.5625e-7],
                    help="beamcontact's solver.error_tol (energy_tol = 100 times it)")
    ap.add_argument("--reference-tol", type=float, default=9.765625e-9,
                    help="beamcontact's reference run")
    ap.add_argument("--dts", type=float, nargs="+", default=[2e-4, 1e-4, 5e-5, 2.5e-5],
                    help="PyElastica's steps [s] (2.05e-4 s is its largest stable one)")
    ap.add_argument("--reference-dt", type=float, default=1.25e-5,
                    help="PyElastica's reference run [s]")
    args = ap.parse_args()
    print(f"machine: {os.cpu_count()} cores; python {sys.version.split()[0]}; "
          f"{time.strftime('%Y-%m-%d %H:%M')}", flush=True)
    with tempfile.TemporaryDirectory() as name:
        tmp = Path(name)
        ours = {}
        for model in args.models:
            ref = _beamcontact(model, args.reference_tol, args.t_end, tmp)
            rows = [_beamcontact(model, tol, args.t_end, tmp) for tol in args.tolerances]
            _table(f"beamcontact, {model}, native engine", rows, ref, args.t_end, "steps alone")
            ours[model] = rows
        warm_up_pyelastica(tmp)
        ref = _pyelastica(args.reference_dt, args.t_end, tmp)
        peer = [_pyelastica(dt, args.t_end, tmp) for dt in args.dts]
        _table("PyElastica, PositionVerlet", peer, ref, args.t_end, "step loop")
        _equal_accuracy(peer, ours, _windows(args.t_end))


if __name__ == "__main__":
    main()
