"""One HHT-alpha step of one pinned beam, dense against sparse tangent, by beam size.

Times ``hht_step`` (jitted; Newton with two iterations from a perturbed state: three
assemblies, two solves) of a 10 m pinned quartic C^3 beam with N elements, for
``solver.linear_solver = "dense"`` and ``"sparse"`` (best of 5 means, BLAS on one thread
as in ``beamcontact run``), and checks that both give the same step. The crossover sets
``AUTO_SPARSE_DOFS`` in beamcontact/solvers/linear.py.

    python benchmarks/linear_solver.py [--elements 10 25 50 100 200 400 800]
"""

import argparse
import dataclasses

import numpy as np
from _shared import best_ms, pinned_beam_case

import beamcontact

beamcontact.enable_x64()

import jax  # noqa: E402
import jax.numpy as jnp  # noqa: E402
from threadpoolctl import threadpool_limits  # noqa: E402

from beamcontact.assembly.model import initial_load_state  # noqa: E402
from beamcontact.dynamics.hht import hht_step, initial_state  # noqa: E402
from beamcontact.io.case import parse_case  # noqa: E402
from beamcontact.setup.model import build_model  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--elements", type=int, nargs="+", default=[10, 25, 50, 100, 200, 400, 800])
    a = ap.parse_args()
    step = jax.jit(hht_step, static_argnames=("max_iterations",))
    print("| elements | dofs | dense [ms] | sparse [ms] | dense / sparse | Newton it. | "
          "max |u_dense - u_sparse| [m] |")
    print("|---|---|---|---|---|---|---|")
    with threadpool_limits(limits=1, user_api="blas"):
        for n in a.elements:
            model, _ = build_model(parse_case(pinned_beam_case(n)))
            ls = initial_load_state(model)
            # a state away from equilibrium, so that Newton iterates
            n_dof = model.n_dof
            s0 = initial_state(jnp.zeros(n_dof), 0.1 * model.free, model, ls)
            times, results = {}, {}
            for kind in ("dense", "sparse"):
                m = dataclasses.replace(model, sparse=kind == "sparse")

                def call(m=m, s0=s0):
                    return step(s0, m, 1e-3, -0.1, 1e-9, 1e-13, max_iterations=25)

                times[kind] = best_ms(call, 5 if n_dof > 3000 and kind == "dense" else 20)
                results[kind] = call()
            (d, rd), (s, _) = results["dense"], results["sparse"]
            dev = float(jnp.max(jnp.abs(d.u - s.u)))
            print(f"| {n} | {n_dof} | {times['dense']:.3f} | {times['sparse']:.3f} | "
                  f"{times['dense'] / times['sparse']:.2f} | {int(rd.iterations)} | {dev:.1e} |")


if __name__ == "__main__":
    np.set_printoptions(precision=3)
    main()
