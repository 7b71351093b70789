"""Time the HHT-alpha time stepping of a dynamic case (no file output).

Prints one table row per case: dofs, steps, Newton iterations, compile time, wall time
after compilation, time per step and per Newton iteration.

    python benchmarks/dynamic_step.py [CASE.toml ...]

Without arguments it times examples/pinned_beam_vibration at three mesh sizes.
"""

import sys
import time
import tomllib
from pathlib import Path

import beamcontact

beamcontact.enable_x64()

import jax  # noqa: E402

from beamcontact.dynamics.control import StepControl  # noqa: E402
from beamcontact.dynamics.driver import solve_dynamic  # noqa: E402
from beamcontact.io.case import parse_case  # noqa: E402
from beamcontact.setup.start import dynamic_start, prepare  # noqa: E402

REPO = Path(__file__).resolve().parents[1]


def time_case(raw: dict, label: str) -> None:
    case = parse_case(raw)
    start = dynamic_start(prepare(case))
    model, an = start.prepared.model, case.analysis
    t0 = time.perf_counter()
    # fixed steps: the benchmark times the step, not the controller
    res = solve_dynamic(start.engine, start.state, an.t_end, start.prepared.length,
                        StepControl.fixed(an.dt))
    wall = time.perf_counter() - t0
    run = wall - res.compile_time
    print(f"| {label:<28} | {model.n_dof:5d} | {res.steps:6d} | {res.iterations:6d} | "
          f"{res.compile_time:7.2f} | {run:7.2f} | {1e3 * run / res.steps:8.3f} | "
          f"{1e3 * run / max(res.iterations, 1):8.3f} |")


def main() -> None:
    print(f"JAX {jax.__version__} on {jax.devices()[0].platform}")
    print("| case | dofs | steps | Newton it. | compile [s] | run [s] | per step [ms] "
          "| per iteration [ms] |")
    print("|---|---|---|---|---|---|---|---|")
    paths = [Path(p) for p in sys.argv[1:]]
    if paths:
        for p in paths:
            time_case(tomllib.loads(p.read_text()), p.stem)
        return
    base = tomllib.loads((REPO / "examples/pinned_beam_vibration/case.toml").read_text())
    for elements in (10, 40, 160):
        base["beams"][0]["elements"] = elements
        time_case(base, f"pinned vibration, {elements} el.")


if __name__ == "__main__":
    main()
