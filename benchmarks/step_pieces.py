"""Device time of the pieces of one time-step attempt of the peer drop, in contact.

Runs the peer drop of benchmarks/peers (``--model`` ipip-points, ipip or cg) to
``--t`` seconds (into the first impact by default), reads the last state back from
results.h5 like a restart, and times each piece of one attempt jitted alone (best of 5,
BLAS on one thread as in ``beamcontact run``): the whole fused attempt, its Newton solve,
one assembly with and without contact, one dense LU solve, the diagnostics, the post-step
check, the advancement ratio, and for IPIP the candidate dispatch and the host selection
("zones") or the device selection that the fused attempt includes ("points").

    python benchmarks/step_pieces.py [--model cg] [--t 0.76] [--h 2e-5]

The run to --t is kept in --out (default results_step_pieces/) and reused.
"""

import argparse
import sys
import tomllib
from pathlib import Path

import numpy as np

import beamcontact

beamcontact.enable_x64()

import jax  # noqa: E402
import jax.numpy as jnp  # noqa: E402
from threadpoolctl import threadpool_limits  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent / "peers"))
from _shared import best_ms  # noqa: E402
from compare import MODELS, drop_case  # noqa: E402

from beamcontact.assembly.system import residual_tangent_with_contact  # noqa: E402
from beamcontact.contact.advance import approach_ratio  # noqa: E402
from beamcontact.contact.problem import freeze, missed_blocks  # noqa: E402
from beamcontact.contact.step_set import step_set  # noqa: E402
from beamcontact.dynamics.hht import hht_step  # noqa: E402
from beamcontact.dynamics.step import (  # noqa: E402
    _predicted_x,
    closest_pair_candidates,
    diagnostics,
    fused_attempt,
    positions,
)
from beamcontact.io.case import parse_case  # noqa: E402
from beamcontact.runner import _restart_state, run_case  # noqa: E402
from beamcontact.setup.start import prepare  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--model", default="ipip-points", choices=MODELS)
    ap.add_argument("--t", type=float, default=0.76, help="time of the state [s]")
    ap.add_argument("--h", type=float, default=2e-5, help="step of the attempt [s]")
    ap.add_argument("--out", type=Path, default=Path("results_step_pieces"))
    ap.add_argument("--case", type=Path, default=None,
                    help="time the state of this case file at --t instead of the peer drop")
    a = ap.parse_args()
    if a.case is None:
        case = parse_case(drop_case(a.model, t_end=a.t))
        out = a.out / f"{a.model}_{a.t:g}"
    else:
        raw = tomllib.loads(a.case.read_text())
        raw["analysis"]["t_end"] = a.t
        case = parse_case(raw)
        out = a.out / f"{a.case.stem}_{a.t:g}"
    if not (out / "results.h5").exists():
        run_case(case, case.to_toml(), out)
    prepared = prepare(case)
    model, contact = prepared.model, prepared.contact
    state, _ = _restart_state(case, out, model)
    h, search = np.float64(a.h), contact.search
    cap = contact.first_capacity(case.contact.capacity)
    rows = []
    with threadpool_limits(limits=1, user_api="blas"):
        cs_host = None
        if contact.law.closest_pairs:
            def candidates():
                return closest_pair_candidates(state, model, h, np.float64(1.0), search,
                                               capacity=cap)
            pairs, q, _, _, motion = jax.device_get(candidates())
            cs = contact.closest_pair_set(pairs, q, float(motion))
            if contact.law.pairing == "zones":  # chosen on the host and passed to the step
                cs_host = cs
                rows += [("IPIP candidate dispatch", best_ms(candidates)),
                         ("IPIP host selection",
                          best_ms(lambda: contact.closest_pair_set(pairs, q,
                                                                   float(motion))))]
            else:  # "points": chosen inside the fused step (the host rule gives the same set)
                select = jax.jit(step_set, static_argnames=("capacity",))
                x_pred = _predicted_x(state, model, h)
                rows.append(("IPIP points selection (part of the fused attempt)", best_ms(
                    lambda: select(x_pred, motion, search, capacity=cap))))
        else:
            cs = contact.frozen_set(positions(state.u, model), 0.01, cap)[0]
        real = int(np.sum(np.asarray(cs.pairs)[:, 0] < search.elements.n_elements))
        args = (state, model, h, np.float64(0.0), np.float64(1e-9), np.float64(1e-10),
                None, np.float64(1e-3), np.float64(1.0), search, cs_host)
        counts = fused_attempt(*args, max_iterations=25, capacity=cap)[2]
        rows.append((f"whole fused attempt ({int(counts[1])} Newton iterations)",
                     best_ms(lambda: fused_attempt(*args, max_iterations=25, capacity=cap))))
        fc = freeze(contact, cs)
        newton = jax.jit(hht_step, static_argnames=("max_iterations",))
        rows.append(("HHT Newton solve alone", best_ms(
            lambda: newton(state, model, h, 0.0, 1e-9, 1e-12, max_iterations=25,
                           contact=fc))))
        assemble = jax.jit(residual_tangent_with_contact)
        ls = state.load_state
        rows += [("one assembly without contact",
                  best_ms(lambda: assemble(state.u, model, 1.0, ls, None))),
                 ("one assembly with contact",
                  best_ms(lambda: assemble(state.u, model, 1.0, ls, fc)))]
        K = assemble(state.u, model, 1.0, ls, fc)[1]
        if model.sparse:
            from beamcontact.solvers import linear

            solve = jax.jit(linear.solve)
            rows.append((f"one sparse LU solve ({model.n_dof} dofs)",
                         best_ms(lambda: solve(K, state.u))))
        else:
            solve = jax.jit(jnp.linalg.solve)
            rows.append((f"one dense LU solve ({K.shape[0]} dofs)",
                         best_ms(lambda: solve(K, state.u))))
        rows.append(("diagnostics", best_ms(lambda: diagnostics(state, model, fc))))
        x0 = positions(state.u, model)
        check = jax.jit(missed_blocks, static_argnames=("capacity",))
        rows.append(("post-step check", best_ms(
            lambda: check(x0, search.elements, cs.pairs, search.reach,
                          search.law.interaction_distance(), capacity=cap))))
        ratio = jax.jit(approach_ratio)
        rows.append(("advancement ratio", best_ms(
            lambda: ratio(x0, (1e-6 * x0,), search.elements, cs.pairs,
                          search.law.advance_slack()))))
    print(f"peer drop, {a.model}, state at t = {a.t:g} s, h = {a.h:g} s, {real} candidate "
          f"blocks in the list")
    print("| piece | ms |\n|---|---|")
    for name, ms in rows:
        print(f"| {name} | {ms:.3f} |")


if __name__ == "__main__":
    main()
