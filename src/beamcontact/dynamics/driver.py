"""Time stepping with HHT-alpha, automatic cut-back and recovery of the nominal step.

A failed Newton solve (iteration limit or a non-finite value) restarts the step from the
last accepted state with half the step, up to ``max_cutbacks`` successive halvings; each
accepted step doubles the step back towards the nominal ``dt``. The last step is shortened
to land on ``t_end``. Every accepted step goes to ``on_step`` at once.
"""

import time
from functools import partial
from collections.abc import Callable
from dataclasses import dataclass, replace

import jax
import jax.numpy as jnp
import numpy as np

from beamcontact.assembly.inertia import kinetic_energy_and_momentum
from beamcontact.assembly.model import Model
from beamcontact.assembly.system import contact_energy_of, energies
from beamcontact.contact.blocks import ContactSet
from beamcontact.contact.problem import (
    ContactProblem,
    candidate_gaps,
    cg_candidates,
    missed_blocks,
)
from beamcontact.dynamics.hht import DynState, hht_step
from beamcontact.solvers.newton import NewtonOptions


@dataclass(frozen=True)
class DynamicStep:
    """One accepted time step (host values)."""

    step: int
    t: float
    dt: float
    state: DynState
    iterations: int
    cutbacks: int
    diagnostics: dict


@dataclass(frozen=True)
class DynamicResult:
    """Outcome of a dynamic analysis; ``state`` and ``dt_next`` allow a restart."""

    status: str  # "completed" | "failed"
    message: str
    steps: int
    iterations: int
    cutbacks: int
    t: float
    state: DynState
    dt_next: float
    wall_time: float
    compile_time: float


@partial(jax.jit, static_argnames=("law",))
def diagnostics(state: DynState, model: Model, ce=None, cs=None, law: str = "none") -> dict:
    """Energies (contact included) and linear momentum of a state."""
    e = energies(state.u, model, 1.0, state.load_state)
    e_kin, p = kinetic_energy_and_momentum(state.u, state.v, model)
    e_con = contact_energy_of(state.u, model, ce, cs, law)
    return {**e, "E_contact": e_con, "E_kin": e_kin, "p_x": p[0], "p_y": p[1]}


def host_diagnostics(state: DynState, model: Model, contact: "ContactProblem | None" = None,
                     cs=None, gap: float | None = None) -> dict:
    """:func:`diagnostics` as Python floats, with E_total and min_gap."""
    if contact is None:
        d = {k: float(v) for k, v in diagnostics(state, model).items()}
        d["min_gap"] = float("nan")
    else:
        d = {k: float(v) for k, v in diagnostics(state, model, contact.elements, cs,
                                                  contact.law).items()}
        d["min_gap"] = gap if gap is not None else contact.min_gap(
            model.x_ref + state.u.reshape(-1, 2), cs)
    d["E_total"] = d["E_kin"] + d["E_strain"] + d["E_gravity"] + d["E_ext"] + d["E_contact"]
    return d


# the scalars of one attempt, returned as one float64 vector (one device-to-host copy per
# step instead of one per scalar)
DIAGNOSTICS = ("E_strain", "E_gravity", "E_ext", "E_contact", "E_kin", "p_x", "p_y")
REPORT = ("converged", "iterations", "residual_norm", "initial_residual_norm", "count",
          "missing", "count_after", "min_gap", "E_contact_before", *DIAGNOSTICS)


@partial(jax.jit, static_argnames=("max_iterations", "law", "capacity"))
def fused_step(state: DynState, model: Model, h, alpha, rtol, utol, motion_factor,
               ce=None, params=None, reach=0.0, interaction=0.0, cs=None, *,
               max_iterations: int, law: str = "none", capacity: int = 0):
    """One attempt at a step, fused into a single dispatch: predictor, broad phase and
    culling of the candidate blocks to those within ``interaction`` plus the motion
    (unless ``cs`` is given, as IPIP's host selection does), the HHT-alpha Newton solve,
    the post-step contact checks and the diagnostics.

    Returns (new state, report): report is a float64 vector of the scalars
    named in :data:`REPORT` (Newton status, candidate count, whether a pair was missed,
    the smallest gap, the diagnostics); contact entries are 0 (min_gap NaN) without
    contact.
    """
    report = dict.fromkeys(REPORT, jnp.zeros(()))
    report["min_gap"] = jnp.asarray(jnp.nan)
    if law != "none":
        if cs is None:
            pairs, count = cg_candidates(_predicted_x(state, model, h), ce, reach,
                                         interaction, motion_factor * _motion(state, h),
                                         capacity)
            cs = ContactSet(pairs, None, params)
            report["count"] = count
    new, res = hht_step(state, model, h, alpha, rtol, utol, max_iterations, ce, cs, law)
    report.update(converged=res.converged, iterations=res.iterations,
                  residual_norm=res.residual_norm,
                  initial_residual_norm=res.initial_residual_norm)
    if law != "none":
        x_new = _x(new.u, model)
        missing, count, gap = missed_blocks(x_new, ce, cs.pairs, reach, interaction, capacity)
        report.update(missing=missing, count_after=count, min_gap=gap)
    report.update(diagnostics(new, model, ce, cs, law))
    # the energy test compares both states under the same frozen set: a change of the set
    # between steps (IPIP re-selects its closest pairs) is a jump of the model, not an
    # integration error
    report["E_contact_before"] = contact_energy_of(state.u, model, ce, cs, law)
    return new, jnp.stack([jnp.asarray(report[k], jnp.float64) for k in REPORT])


def _motion(state: DynState, h):
    """Largest distance a control point may travel in a step of size h (x2 for safety)."""
    v, a = jnp.max(jnp.abs(state.v)), jnp.max(jnp.abs(state.a))
    return 2.0 * jnp.sqrt(2.0) * (v * h + 0.5 * a * h * h)


@jax.jit
def _predicted_x(state: DynState, model: Model, h):
    return model.x_ref + (state.u + h * state.v + 0.5 * h * h * state.a).reshape(-1, 2)


@jax.jit
def _x(u, model: Model):
    return model.x_ref + u.reshape(-1, 2)


@partial(jax.jit, static_argnames=("capacity",))
def ipip_candidates(state: DynState, model: Model, h, motion_factor, ce, reach, *,
                    capacity: int):
    """Predictor, motion bound, candidate blocks and their point-pair gaps in one dispatch,
    for IPIP's host selection: (pairs, gaps, count, motion)."""
    motion = motion_factor * _motion(state, h)
    return (*candidate_gaps(_predicted_x(state, model, h), ce, reach + motion, capacity),
            motion)


def solve_dynamic(model: Model, state: DynState, t_end: float, dt: float, alpha: float,
                  options: NewtonOptions, length: float, max_cutbacks: int = 12, *,
                  dt_start: float | None = None, step0: int = 0,
                  on_step: Callable[[DynamicStep], None] | None = None,
                  contact: ContactProblem | None = None,
                  capacity: int = 64, energy_tol: float = 1e-2) -> DynamicResult:
    """Integrate from ``state`` to ``t_end``.

    Args:
        model: the discrete model.
        state: initial (or restart) state.
        t_end: final time; dt: nominal step; alpha: HHT parameter in [-1/3, 0].
        options: Newton settings; length: scale of the increment tolerance.
        max_cutbacks: successive halvings allowed before giving up.
        dt_start: the step to try first (a restart passes the interrupted run's).
        step0: number of the last accepted step (restart).
        on_step: called with every accepted step.
        contact: the contact problem (None: no contact).
        capacity: initial length of the contact candidate list (grows on overflow).
        energy_tol: a converged step whose total energy grows by more than energy_tol
            times (E_kin + E_strain + E_contact) is rejected and retried with half the
            step. All forces are conservative and HHT-alpha (alpha <= 0) only dissipates,
            so a gain is an integration error: typically a step that crossed the steep
            part of a contact potential at once. 0 or less switches the check off.
    """
    start = time.perf_counter()
    # host scalars as NumPy float64: strongly typed like the arrays they replace, and
    # passed to the jitted step without eager device operations
    rtol = np.float64(options.rtol)
    utol = np.float64(options.utol * length)
    alpha_arr = np.float64(alpha)
    t = float(state.t)
    dt_cur = dt if dt_start is None else dt_start
    steps = iterations = cutbacks = consecutive = 0
    compile_time = 0.0
    first = True
    law = "none" if contact is None else contact.law
    ce = None if contact is None else contact.elements
    params = None if contact is None else contact.params
    reach = 0.0 if contact is None else contact.reach
    interaction = 0.0 if contact is None else contact.interaction
    if contact is not None:
        capacity = min(capacity, contact.all_pairs)
    cs0 = None if contact is None else contact.grown_set(_x(state.u, model), 0.0, capacity)[0]
    e_prev = _energy_totals({k: float(v) for k, v in
                             diagnostics(state, model, ce, cs0, law).items()})
    motion_factor = 1.0
    while t_end - t > 1e-12 * max(dt, t_end):
        h = _step_size(t, t_end, dt_cur)
        cs = None
        if law == "ipip":  # the closest pairs are chosen on the host
            pairs, q, count, motion = jax.device_get(ipip_candidates(
                state, model, np.float64(h), np.float64(motion_factor), ce, reach,
                capacity=capacity))
            if count > capacity:
                capacity = contact.capacity_for(int(count))
                continue
            cs = contact.ipip_set(pairs, q, float(motion))
        t0 = time.perf_counter()
        # the acceleration is 1/(beta h^2) times a displacement difference: the increment
        # test tightens like h^2 for cut steps, down to a round-off floor of the positions
        utol_h = np.maximum(utol * min(1.0, (h / dt) ** 2), 1e-13 * length)
        new, packed = fused_step(
            state, model, np.float64(h), alpha_arr, rtol, utol_h, np.float64(motion_factor),
            ce, params, reach, interaction, cs, max_iterations=options.max_iterations, law=law,
            capacity=capacity)
        report = dict(zip(REPORT, np.asarray(packed).tolist(), strict=True))
        converged = report["converged"] != 0.0
        n_iter = int(report["iterations"])
        if first:
            compile_time = time.perf_counter() - t0
            first = False
        iterations += n_iter
        reason = "Newton did not converge"
        gap = report["min_gap"]
        if contact is not None:
            # the candidates after a diverged Newton solve say nothing about the solution
            count = max(int(report["count"]), int(report["count_after"]) if converged else 0)
            if count > capacity:  # overflow: reallocate and redo
                capacity = contact.capacity_for(count)
                continue
            if converged and report["missing"] != 0.0:
                if motion_factor < 16:
                    motion_factor *= 2.0  # the step moved further than foreseen: redo it
                    continue
                converged = False  # never accept a step that missed a force: cut it
                reason = ("the step moved further than the candidate search foresaw "
                          "(a contact block was missing)")
            if converged and gap < -contact.max_penetration:
                converged = False
                reason = f"penetration {-gap:.3g} m exceeded max_penetration"
        diag = {k: report[k] for k in DIAGNOSTICS}
        e_new = _energy_totals(diag)
        e_before = e_prev[0] - e_prev[2] + report["E_contact_before"]
        if converged and energy_tol > 0 and (
                e_new[0] - e_before > energy_tol * max(e_new[1], e_prev[1], 1e-300)):
            converged = False
            reason = (f"the total energy grew by {e_new[0] - e_before:.3g} J in one step "
                      f"(more than energy_tol = {energy_tol:g} of {max(e_new[1], e_prev[1]):.3g} J)")
        if not converged:
            cutbacks += 1
            consecutive += 1
            if consecutive > max_cutbacks:
                return DynamicResult(
                    "failed",
                    f"{reason} at t = {t + h:.6g} s ({n_iter} "
                    f"iterations, residual {report['residual_norm']:.3e} from "
                    f"{report['initial_residual_norm']:.3e}) after {consecutive - 1} "
                    f"successive halvings of the time step (now {h:.3g} s); the last "
                    f"accepted time is {t:.6g} s",
                    steps, iterations, cutbacks, t, state, dt_cur,
                    time.perf_counter() - start, compile_time)
            dt_cur = 0.5 * h
            continue
        consecutive = 0
        motion_factor = 1.0
        t = _on_grid(t + h, dt, t_end)
        state = replace(new, t=jnp.asarray(t))
        steps += 1
        e_prev = e_new
        if on_step is not None:
            diag["min_gap"] = gap
            diag["E_total"] = e_new[0]
            on_step(DynamicStep(step0 + steps, t, h, state, n_iter, cutbacks,
                                diag))
        dt_cur = next_step_size(h, dt, n_iter)
    return DynamicResult("completed", f"reached t = {t:.6g} s in {steps} steps", steps,
                         iterations, cutbacks, t, state, dt_cur, time.perf_counter() - start,
                         compile_time)


GROW_ITERATIONS = 3


def next_step_size(h: float, dt: float, iterations: int) -> float:
    """The step after an accepted step h: doubled (up to the nominal dt) when Newton needed
    at most GROW_ITERATIONS iterations, else kept, so that after a cut-back the step does
    not grow back into a strongly nonlinear phase (an impact) where Newton would diverge."""
    return min(2.0 * h, dt) if iterations <= GROW_ITERATIONS else h


def _energy_totals(d: dict) -> tuple[float, float, float]:
    """(total energy, scale E_kin + E_strain + |E_contact|, E_contact)."""
    total = d["E_kin"] + d["E_strain"] + d["E_gravity"] + d["E_ext"] + d["E_contact"]
    return total, d["E_kin"] + d["E_strain"] + abs(d["E_contact"]), d["E_contact"]


def _step_size(t: float, t_end: float, dt_cur: float) -> float:
    """The next step: dt_cur, shortened to land on t_end without leaving a sliver."""
    remaining = t_end - t
    if abs(remaining - dt_cur) <= 1e-9 * dt_cur:
        return dt_cur  # exactly nominal, so a restart repeats the same arithmetic
    h = min(dt_cur, remaining)
    return remaining if remaining - h < 1e-6 * h else h


def _on_grid(t: float, dt: float, t_end: float) -> float:
    """Snap a time within round-off of a multiple of the nominal step (or of t_end) onto it,
    so that times do not drift and a restarted run is identical to an uninterrupted one."""
    k = round(t / dt)
    if abs(t - k * dt) <= 1e-9 * dt:
        return k * dt
    return t_end if abs(t - t_end) <= 1e-9 * dt else t


def uniform_velocities(disc, velocities) -> np.ndarray:
    """Global control-point velocities from one uniform velocity per beam (flat)."""
    v = np.zeros((disc.n_cp, 2))
    for info, vel in zip(disc.beams, velocities, strict=True):
        v[info.offset : info.offset + info.n_cp] = vel
    return v.ravel()
