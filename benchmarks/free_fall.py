"""Time the bundled free-fall benchmark (coarse-grained and IPIP contact), no file output.

Prints: simulated time, steps, Newton iterations, cut-backs, compile time, wall time after
compilation, per step and per iteration, and the share of one Newton iteration spent in
contact (assembly with and without the contact blocks, at the state just after impact).

    python benchmarks/free_fall.py [--t-end 2.0] [--models cg ipip] [--repeat 1]

Timings on a shared 2-core machine vary by +-10 %; --repeat runs each model again
(the compilation cache is not used, so every run compiles from scratch).
"""

import argparse
import time
import tomllib
from pathlib import Path

import beamcontact

beamcontact.enable_x64()

import jax  # noqa: E402
from threadpoolctl import threadpool_limits  # noqa: E402

from beamcontact.assembly.model import initial_load_state  # noqa: E402
from beamcontact.assembly.system import residual_tangent_with_contact  # noqa: E402
from beamcontact.contact.problem import freeze  # noqa: E402
from beamcontact.dynamics.driver import solve_dynamic  # noqa: E402
from beamcontact.io.case import parse_case  # noqa: E402
from beamcontact.setup.start import dynamic_start, prepare  # noqa: E402

REPO = Path(__file__).resolve().parents[1]


def _time(f, n=30):
    jax.block_until_ready(f())
    t0 = time.perf_counter()
    for _ in range(n):
        r = f()
    jax.block_until_ready(r)
    return (time.perf_counter() - t0) / n


def run(model_name: str, t_end: float) -> None:
    raw = tomllib.loads((REPO / f"examples/free_fall/case_{model_name}.toml").read_text())
    raw["analysis"]["t_end"] = t_end
    case = parse_case(raw)
    start = dynamic_start(prepare(case))
    model, contact, an = start.prepared.model, start.prepared.contact, case.analysis
    cap = contact.first_capacity(case.contact.capacity)
    kept = {}

    def keep(s):
        if "impact" not in kept and s.diagnostics["E_contact"] > 1e-6:
            kept["impact"] = s.state

    t0 = time.perf_counter()
    res = solve_dynamic(start.engine, start.state, an.t_end, start.prepared.length,
                        start.control, capacity=cap.blocks, on_step=keep)
    wall = time.perf_counter() - t0
    run_time = wall - res.compile_time
    share = float("nan")
    if "impact" in kept:
        u = kept["impact"].u
        x = model.x_ref + u.reshape(-1, 2)
        cs, _ = contact.grown_set(x, 0.0, cap)
        ls = initial_load_state(model)
        with_c = jax.jit(lambda u, cs: residual_tangent_with_contact(
            u, model, 1.0, ls, freeze(contact, cs)))
        without = jax.jit(lambda u: residual_tangent_with_contact(
            u, model, 1.0, ls, None))
        tc, tn = _time(lambda: with_c(u, cs)), _time(lambda: without(u))
        share = (tc - tn) / tc
    print(f"| {model_name:<4} | {t_end:4.1f} | {res.steps:6d} | {res.iterations:6d} | "
          f"{res.cutbacks:5d} | {res.compile_time:6.2f} | {run_time:7.2f} | "
          f"{1e3 * run_time / res.steps:6.2f} | {1e3 * run_time / max(res.iterations, 1):6.2f}"
          f" | {100 * share:5.1f} % | {res.status} |")


def main() -> None:
    # one BLAS thread, as `beamcontact run` uses (reproducible digits, no oversubscription)
    threadpool_limits(1, "blas")
    ap = argparse.ArgumentParser()
    ap.add_argument("--t-end", type=float, default=2.0)
    ap.add_argument("--models", nargs="+", default=["cg", "ipip"], choices=["cg", "ipip"])
    ap.add_argument("--repeat", type=int, default=1)
    args = ap.parse_args()
    print(f"JAX {jax.__version__} on {jax.devices()[0].platform}")
    print("| model | t_end [s] | steps | Newton it. | cut-backs | compile [s] | run [s] | "
          "per step [ms] | per iteration [ms] | contact share | status |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for name in args.models:
        for _ in range(args.repeat):
            jax.clear_caches()
            run(name, args.t_end)


if __name__ == "__main__":
    main()
