"""Adaptive time stepping with HHT-alpha through impacts.

Every attempt at a step is one fused dispatch (:func:`fused_step`): predictor, contact
candidates, conservative advancement (the step is shortened before it is solved so that
no point pair approaches further than a fraction of its gap, :mod:`~beamcontact.contact.
advance`), Newton on the HHT residual, post-step checks and diagnostics. The host
(:func:`solve_dynamic`) then accepts the step or redoes it shorter:

* **Local error** (Zienkiewicz & Xie 1991): with the acceleration linear over the step,
  the Newmark displacement differs from the exact cubic by
  ``e = h^2 |beta - 1/6| (a_{n+1} - a_n)``; its largest component must not exceed
  ``error_tol * L`` (L the longest beam). The next step is ``h (error_tol L / e)^(1/3)``
  times a safety factor 0.9, kept between 0.2 h and 2 h, never longer than ``dt`` (the
  first and the largest step) and not longer than h right after a rejection (no
  oscillation between rejected and accepted sizes). ``error_tol = 0`` gives fixed steps.
* **No tunnelling**: after the solve, no point pair may have approached by more than
  ``ADVANCE_ACCEPT`` of its gap (plus the law's slack); else the step is redone shorter.
* **Energy account** (both signs): ``E_set_change`` sums the jumps of the contact energy
  when the frozen set changes between steps (IPIP re-selects its closest pairs; the
  coarse-grained set changes only beyond the cutoff), each evaluated at the same state;
  ``E_dissipated`` sums what the integrator removed in each step under one set:
  ``E_total(n) + E_set_change(n) - E_total(n+1)`` (HHT-alpha's numerical dissipation, and
  any energy error, with the opposite sign when a step creates energy). So
  ``E_total + E_dissipated - E_set_change`` stays at its initial value. A step that
  creates more than ``energy_tol`` of the energy scale, or whose set change jumps by more,
  is redone with half the step (a set change at most ``SET_CHANGE_REFINEMENTS`` times,
  then it is accepted and accounted: a new contact zone is a jump of the model itself).
  An absolute floor (the energy resolution of the converged solve and round-off) keeps
  round-off from rejecting steps.
* **Newton failure**, a contact block missed by the search, penetration beyond
  ``max_penetration``: redo with half the step (or a wider search).

A step that would have to be shorter than ``dt_min`` (or more than ``max_rejections``
attempts at one step) stops the run with a message; every accepted step has gone to
``on_step`` before.
"""

import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from functools import partial

import jax
import jax.numpy as jnp
import numpy as np

from beamcontact.assembly.inertia import kinetic_energy_and_momentum
from beamcontact.assembly.model import Model
from beamcontact.assembly.system import contact_energy_of, energies
from beamcontact.contact.advance import approach_ratio
from beamcontact.contact.blocks import ContactSet, FrozenContact
from beamcontact.contact.problem import (
    ContactProblem,
    ContactSearch,
    candidate_gaps,
    freeze,
    missed_blocks,
    near_candidates,
)
from beamcontact.dynamics.hht import DynState, hht_step
from beamcontact.solvers.newton import NewtonOptions

# step controller (Hairer, Norsett & Wanner, Solving ODEs I, Sec. II.4): safety factor and
# the bounds of the change of the step after an accepted or rejected step
SAFETY, GROW_MAX, SHRINK_MIN = 0.9, 2.0, 0.2
# conservative advancement: the predictor's approach is kept below ADVANCE_FRACTION of the
# gap before the solve; a solved step whose actual approach exceeds ADVANCE_ACCEPT is redone
ADVANCE_FRACTION, ADVANCE_ACCEPT = 0.5, 0.8
# a step that needed more Newton iterations is not followed by a longer one
GROW_ITERATIONS = 3
# halvings of a step allowed to shrink a jump of the contact energy at a set change
SET_CHANGE_REFINEMENTS = 4
# relative round-off of a total energy that is a sum of terms of either sign
ENERGY_ROUNDOFF = 1e-12


@dataclass(frozen=True)
class StepControl:
    """Settings of the step controller.

    Attributes:
        dt: the first and the largest step [s].
        dt_min: a step that would have to be shorter stops the run [s].
        error_tol: bound of the local error estimate of one step, a fraction of the
            length scale L (0: fixed steps, shortened only on failure).
        energy_tol: fraction of the energy scale E_kin + E_strain + |E_contact| that one
            step may create, or a set change may jump (0: no energy test).
        max_rejections: successive rejected attempts at one step before the run stops.
    """

    dt: float
    dt_min: float
    error_tol: float = 0.0
    energy_tol: float = 0.0
    max_rejections: int = 40

    @classmethod
    def fixed(cls, dt: float, max_halvings: int = 12) -> "StepControl":
        """Fixed steps of dt, halved only when Newton fails (theory tests of HHT)."""
        return cls(dt, dt * 0.5 ** (max_halvings + 0.5), 0.0, 0.0, max_halvings)


@dataclass(frozen=True)
class EnergyAccount:
    """Cumulative energy removed by the integrator and changed by contact-set changes,
    and the energies of the last accepted state (the reference of the next step)."""

    E_dissipated: float = 0.0
    E_set_change: float = 0.0
    last: dict | None = None


@dataclass(frozen=True)
class DynamicStep:
    """One accepted time step (host values); ``dt_next`` the step the controller tries
    next, ``error`` the local error estimate [m]."""

    step: int
    t: float
    dt: float
    dt_next: float
    state: DynState
    iterations: int
    cutbacks: int
    diagnostics: dict


@dataclass(frozen=True)
class DynamicResult:
    """Outcome of a dynamic analysis; ``state`` and ``dt_next`` allow a restart;
    ``rejections`` counts the rejected attempts by kind (newton, missing_block,
    penetration, advancement, error, energy, set_change)."""

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
    rejections: dict


@jax.jit
def diagnostics(state: DynState, model: Model, contact: FrozenContact | None = None) -> dict:
    """Energies (contact included) and linear momentum of a state."""
    e = energies(state.u, model, 1.0, state.load_state)
    e_kin, p = kinetic_energy_and_momentum(state.u, state.v, model)
    e_con = contact_energy_of(state.u, model, contact)
    return {**e, "E_contact": e_con, "E_kin": e_kin, "p_x": p[0], "p_y": p[1]}


def host_diagnostics(state: DynState, model: Model, contact: "ContactProblem | None" = None,
                     cs=None) -> dict:
    """:func:`diagnostics` as Python floats, with E_total and min_gap."""
    if contact is None:
        d = {k: float(v) for k, v in diagnostics(state, model).items()}
        d["min_gap"] = float("nan")
    else:
        d = {k: float(v) for k, v in diagnostics(state, model, freeze(contact, cs)).items()}
        d["min_gap"] = contact.min_gap(model.x_ref + state.u.reshape(-1, 2), cs)
    d["E_total"] = total_energy(d)
    return d


def total_energy(d: dict) -> float:
    """E_kin + E_strain + E_gravity + E_ext + E_contact."""
    return d["E_kin"] + d["E_strain"] + d["E_gravity"] + d["E_ext"] + d["E_contact"]


def energy_scale(d: dict) -> float:
    """The energy a step's tolerance refers to: E_kin + E_strain + |E_contact|."""
    return d["E_kin"] + d["E_strain"] + abs(d["E_contact"])


# the scalars of one attempt, returned as one float64 vector (one device-to-host copy per
# step instead of one per scalar)
DIAGNOSTICS = ("E_strain", "E_gravity", "E_ext", "E_contact", "E_kin", "p_x", "p_y")
REPORT = ("converged", "iterations", "residual_norm", "initial_residual_norm", "h", "error",
          "approach", "count", "missing", "count_after", "min_gap", "E_contact_before",
          "energy_floor", *DIAGNOSTICS)


@partial(jax.jit, static_argnames=("max_iterations", "capacity"))
def fused_step(state: DynState, model: Model, h, alpha, rtol, utol, dt_ref, motion_factor,
               search: ContactSearch | None = None, cs: ContactSet | None = None, *,
               max_iterations: int, capacity: int = 0):
    """One attempt at a step of (at most) h, fused into a single dispatch.

    Predictor; broad phase and culling of the candidate blocks to those within the law's
    interaction distance plus the motion (unless ``cs`` is given, as the host's
    closest-pair selection does); the step shortened so that the predictor's approach of
    every candidate point pair stays below ADVANCE_FRACTION of its gap plus the law's
    advancement slack; the HHT-alpha Newton solve
    (increment tolerance ``utol`` scaled by (h/dt_ref)^2: the acceleration is a
    displacement difference over beta h^2); the local error estimate; the post-step
    contact checks (the actual approach, a missed block, the smallest gap); diagnostics.

    Returns (new state, report): report is a float64 vector of the scalars named in
    :data:`REPORT` (``h`` is the step actually taken); contact entries are 0 (min_gap
    NaN) without contact.
    """
    report = dict.fromkeys(REPORT, jnp.zeros(()))
    report["min_gap"] = jnp.asarray(jnp.nan)
    motion = motion_factor * _motion(state, h)
    x_pred = _predicted_x(state, model, h)
    x0 = _x(state.u, model)
    h_used = h
    contact = None
    if search is not None:
        ce, reach = search.elements, search.reach
        interaction, slack = search.law.interaction_distance(), search.law.advance_slack()
        if cs is None:
            pairs, count = near_candidates(x_pred, ce, reach, interaction, motion, capacity)
            cs = ContactSet(pairs, None, search.law)
            report["count"] = count
        contact = FrozenContact(ce, cs)
        v, a = state.v.reshape(-1, 2), state.a.reshape(-1, 2)
        ratio = approach_ratio(x0, (h * v, 0.5 * h * h * a), ce, cs.pairs, slack)
        h_used = h * jnp.minimum(1.0, ADVANCE_FRACTION / jnp.maximum(ratio, 1e-300))
    # no fixed floor: at short steps an increment test of a fixed size would accept
    # velocities wrong by gamma utol / (beta h); the residual test governs there, and the
    # increment test only stops Newton at the round-off of the positions
    utol_h = jnp.maximum(utol * jnp.minimum((h_used / dt_ref) ** 2, 1.0),
                         8.0 * jnp.finfo(x0.dtype).eps * jnp.max(jnp.abs(x0)))
    new, res = hht_step(state, model, h_used, alpha, rtol, utol_h, max_iterations, contact)
    beta = 0.25 * (1.0 - alpha) ** 2
    da = (new.a - state.a) * model.free
    report.update(converged=res.converged, iterations=res.iterations,
                  residual_norm=res.residual_norm,
                  initial_residual_norm=res.initial_residual_norm, h=h_used,
                  error=h_used**2 * jnp.abs(beta - 1.0 / 6.0) * jnp.max(jnp.abs(da)))
    if search is not None:
        x_new = _x(new.u, model)
        missing, count, gap = missed_blocks(x_new, ce, cs.pairs, reach, interaction, capacity)
        # a step that moved further from the predictor than the search margin may have
        # passed blocks that were never candidates
        deviation = jnp.max(jnp.linalg.norm(x_new - x_pred, axis=1))
        report.update(missing=missing | (deviation > motion + 1e-6 * reach), count_after=count,
                      min_gap=gap,
                      approach=approach_ratio(x0, (x_new - x0,), ce, cs.pairs, slack))
    report.update(diagnostics(new, model, contact))
    # energies of the two states are compared under the same frozen set; the jump from
    # the previous step's set to this one is accounted separately (E_set_change)
    report["E_contact_before"] = contact_energy_of(state.u, model, contact)
    # what the converged solve can resolve: the forces times the increment tolerance, and
    # the kinetic energy times the velocity that increment implies (gamma du / (beta h))
    kinetic = jnp.maximum(report["E_kin"],
                          kinetic_energy_and_momentum(state.u, state.v, model)[0])
    report["energy_floor"] = utol_h * (
        jnp.sum(jnp.abs(state.f_pot * model.free)) + jnp.sum(jnp.abs(new.f_pot * model.free))
        + (0.5 - alpha) / (beta * h_used) * jnp.sqrt(2.0 * kinetic * total_mass(model)))
    return new, jnp.stack([jnp.asarray(report[k], jnp.float64) for k in REPORT])


def total_mass(model: Model):
    """Mass of all beams (rho A integrated over the reference arc length)."""
    return sum(jnp.sum(b.rho_area[:, None] * b.wq * jnp.sqrt(b.g_ref)) for b in model.beams)


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
def closest_pair_candidates(state: DynState, model: Model, h, motion_factor,
                            search: ContactSearch, *, capacity: int):
    """Predictor, motion bound, candidate blocks and their point-pair gaps in one dispatch,
    for the host's closest-pair selection (IPIP): (pairs, gaps, count, motion)."""
    motion = motion_factor * _motion(state, h)
    return (*candidate_gaps(_predicted_x(state, model, h), search.elements,
                            search.reach + motion, capacity), motion)


def next_step(h: float, error: float, tol: float, dt: float, after_rejection: bool,
              iterations: int) -> float:
    """The step after an accepted step h with local error ``error`` (tolerance ``tol``,
    same units): h (tol/error)^(1/3) times SAFETY, between SHRINK_MIN h and GROW_MAX h, at
    most dt. It does not grow right after a rejection, nor after a step that needed more
    than GROW_ITERATIONS Newton iterations (a strongly nonlinear phase, an impact, where a
    longer step would make Newton diverge). Without error control (tol = 0) the step
    doubles back towards dt under the same two conditions."""
    cap = 1.0 if after_rejection or iterations > GROW_ITERATIONS else GROW_MAX
    if tol <= 0.0:
        return min(cap * h, dt)
    grow = GROW_MAX if error <= 0.0 else SAFETY * (tol / error) ** (1.0 / 3.0)
    return min(h * min(max(grow, SHRINK_MIN), cap), dt)


def retry_step(h: float, error: float, tol: float) -> float:
    """The step to retry after a rejection for too large an error (always shorter)."""
    return h * min(max(SAFETY * (tol / error) ** (1.0 / 3.0), SHRINK_MIN), SAFETY)


def solve_dynamic(model: Model, state: DynState, t_end: float, alpha: float,
                  options: NewtonOptions, length: float, control: StepControl, *,
                  dt_start: float | None = None, step0: int = 0,
                  on_step: Callable[[DynamicStep], None] | None = None,
                  contact: ContactProblem | None = None, capacity: int = 64,
                  account: EnergyAccount | None = None) -> DynamicResult:
    """Integrate from ``state`` to ``t_end`` with adaptive steps (module docstring).

    Args:
        model: the discrete model.
        state: initial (or restart) state.
        t_end: final time.
        alpha: HHT parameter in [-1/3, 0].
        options: Newton settings.
        length: the length scale L of the tolerances.
        control: step-controller settings.
        dt_start: the step to try first (default control.dt; a restart passes the
            interrupted run's next step).
        step0: number of the last accepted step (restart).
        on_step: called with every accepted step; its diagnostics hold the energies,
            momentum, min_gap, the local error ``error`` [m] and the cumulative
            ``E_dissipated`` and ``E_set_change``.
        contact: the contact problem (None: no contact).
        capacity: initial length of the contact candidate list (grows on overflow).
        account: the energy account of the state (a restart); default zero sums and the
            energies of ``state`` under its initial contact set.
    """
    start = time.perf_counter()
    dt = control.dt
    # host scalars as NumPy float64: strongly typed like the arrays they replace, and
    # passed to the jitted step without eager device operations
    rtol = np.float64(options.rtol)
    utol = np.float64(options.utol * length)
    alpha_arr = np.float64(alpha)
    tol = control.error_tol * length
    t = float(state.t)
    h_try = dt if dt_start is None else dt_start
    steps = iterations = cutbacks = consecutive = 0
    set_jumps: list[float] = []  # |jump| of the attempts at this step refined for a set change
    compile_time = 0.0
    first = True
    search = None if contact is None else contact.search
    if contact is not None:
        capacity = min(capacity, contact.all_pairs)
    if account is None or account.last is None:
        cs0 = None if contact is None else contact.grown_set(_x(state.u, model), 0.0,
                                                             capacity)[0]
        last = {k: float(v) for k, v in diagnostics(state, model,
                                                    freeze(contact, cs0)).items()}
        account = EnergyAccount(0.0 if account is None else account.E_dissipated,
                                0.0 if account is None else account.E_set_change, last)
    e_dissipated, e_set_change, last = account.E_dissipated, account.E_set_change, account.last
    motion_factor = 1.0
    rejections: dict[str, int] = {}
    while t_end - t > 1e-12 * max(dt, t_end):
        h = _step_size(t, t_end, h_try)
        cs = None
        if contact is not None and contact.law.closest_pairs:  # chosen on the host
            pairs, q, count, motion = jax.device_get(closest_pair_candidates(
                state, model, np.float64(h), np.float64(motion_factor), search,
                capacity=capacity))
            if count > capacity:
                capacity = contact.capacity_for(int(count))
                continue
            cs = contact.closest_pair_set(pairs, q, float(motion))
        t0 = time.perf_counter()
        new, packed = fused_step(
            state, model, np.float64(h), alpha_arr, rtol, utol, np.float64(dt),
            np.float64(motion_factor), search, cs, max_iterations=options.max_iterations,
            capacity=capacity)
        report = dict(zip(REPORT, np.asarray(packed).tolist(), strict=True))
        if first:
            compile_time = time.perf_counter() - t0
            first = False
        n_iter = int(report["iterations"])
        iterations += n_iter
        h_used = report["h"]
        if contact is not None:
            # the candidates after a diverged Newton solve say nothing about the solution
            count = max(int(report["count"]),
                        int(report["count_after"]) if report["converged"] else 0)
            if count > capacity:  # overflow: reallocate and redo
                capacity = contact.capacity_for(count)
                continue
            if report["converged"] and report["missing"] != 0.0 and motion_factor < 16:
                motion_factor *= 2.0  # the step moved further than foreseen: redo it
                continue
        diag = {k: report[k] for k in DIAGNOSTICS}
        scale = max(energy_scale(diag), energy_scale(last))
        floor = report["energy_floor"] + ENERGY_ROUNDOFF * sum(
            abs(diag[k]) + abs(last[k])
            for k in ("E_kin", "E_strain", "E_gravity", "E_ext", "E_contact"))
        jump = report["E_contact_before"] - last["E_contact"]
        created = total_energy(diag) - (total_energy(last) + jump)
        allowance = control.energy_tol * scale + floor if control.energy_tol > 0 else 0.0
        verdict = _verdict(report, h_used, contact, tol, allowance, created, jump, set_jumps)
        if verdict is not None:
            kind, reason, h_retry = verdict
            cutbacks += 1
            consecutive += 1
            if kind == "set_change":
                set_jumps.append(abs(jump))
            else:
                set_jumps.clear()
            rejections[kind] = rejections.get(kind, 0) + 1
            if h_retry < control.dt_min or consecutive > control.max_rejections:
                why = (f"the step would have to be shorter than dt_min = {control.dt_min:.3g} s"
                       if h_retry < control.dt_min else
                       f"{consecutive} successive attempts were rejected")
                return DynamicResult(
                    "failed",
                    f"{reason} at t = {t + h_used:.6g} s (step {h_used:.3g} s, {n_iter} "
                    f"iterations, residual {report['residual_norm']:.3e} from "
                    f"{report['initial_residual_norm']:.3e}); {why}; the last accepted time "
                    f"is {t:.6g} s",
                    steps, iterations, cutbacks, t, state, h_try,
                    time.perf_counter() - start, compile_time, rejections)
            h_try = h_retry
            continue
        after_rejection = consecutive > len(set_jumps)
        consecutive = 0
        set_jumps.clear()
        motion_factor = 1.0
        t = _on_grid(t + h_used, dt, t_end)
        state = replace(new, t=jnp.asarray(t))
        steps += 1
        e_dissipated -= created
        e_set_change += jump
        last = diag
        h_try = next_step(h_used, report["error"], tol, dt, after_rejection, n_iter)
        if h_used < h * (1.0 - 1e-12):  # shortened by the advancement bound, not the error
            h_try = max(h_try, min(h, GROW_MAX * h_used))
        if on_step is not None:
            on_step(DynamicStep(step0 + steps, t, h_used, h_try, state, n_iter, cutbacks,
                                {**diag, "min_gap": report["min_gap"],
                                 "E_total": total_energy(diag), "error": report["error"],
                                 "E_dissipated": e_dissipated, "E_set_change": e_set_change}))
    return DynamicResult("completed", f"reached t = {t:.6g} s in {steps} steps", steps,
                         iterations, cutbacks, t, state, h_try, time.perf_counter() - start,
                         compile_time, rejections)


def _verdict(report: dict, h: float, contact, tol: float, energy_allowance: float,
             created: float, jump: float, set_jumps: list[float]):
    """None if the attempt is accepted, else (kind, reason, the step to retry with); the
    kinds are counted in :attr:`DynamicResult.rejections`.

    A set change is refined while halving the step at least halves its jump (the jump
    came from choosing the set at a far predictor), at most SET_CHANGE_REFINEMENTS
    times; a jump that does not shrink is a change of the model itself (IPIP gains or
    loses a contact zone) and is accepted and accounted in E_set_change.
    """
    rejected = _rejection(report, h, contact, tol, energy_allowance, created)
    if rejected is not None:
        return rejected
    shrinking = not set_jumps or abs(jump) <= 0.5 * set_jumps[-1]
    if (abs(jump) > energy_allowance > 0.0 and shrinking
            and len(set_jumps) < SET_CHANGE_REFINEMENTS):
        return ("set_change", f"the contact energy jumped by {jump:.3g} J when the contact "
                f"set changed (allowed {energy_allowance:.3g} J)", 0.5 * h)
    return None


def _rejection(report: dict, h: float, contact, tol: float, energy_allowance: float,
               created: float):
    """(kind, reason, step to retry with) for an attempt that fails a test other than the
    set change, else None."""
    if report["converged"] == 0.0:
        return "newton", "Newton did not converge", 0.5 * h
    if contact is not None:
        if report["missing"] != 0.0:
            return ("missing_block", "the step moved further than the candidate search "
                    "foresaw (a contact block was missing)", 0.5 * h)
        if report["min_gap"] < -contact.max_penetration:
            return ("penetration", f"penetration {-report['min_gap']:.3g} m exceeded "
                    f"max_penetration = {contact.max_penetration:.3g} m", 0.5 * h)
        if report["approach"] > ADVANCE_ACCEPT:
            return ("advancement", f"a contact point approached by {report['approach']:.3g} "
                    f"of its gap in one step (tunnelling guard)",
                    h * ADVANCE_FRACTION / report["approach"])
    if tol > 0.0 and report["error"] > tol:
        return ("error", f"local error {report['error']:.3g} m above error_tol "
                f"({tol:.3g} m)", retry_step(h, report["error"], tol))
    if energy_allowance > 0.0 and not abs(created) <= energy_allowance:
        return ("energy", f"the total energy {'grew' if created > 0 else 'fell'} by "
                f"{abs(created):.3g} J in one step (allowed {energy_allowance:.3g} J)", 0.5 * h)
    return None


def _step_size(t: float, t_end: float, h_try: float) -> float:
    """The next step: h_try, shortened to land on t_end without leaving a sliver."""
    remaining = t_end - t
    if abs(remaining - h_try) <= 1e-9 * h_try:
        return h_try  # exactly nominal, so a restart repeats the same arithmetic
    h = min(h_try, remaining)
    return remaining if remaining - h < 1e-6 * h else h


def _on_grid(t: float, dt: float, t_end: float) -> float:
    """Snap a time within round-off of a multiple of the largest step (or of t_end) onto
    it, so that fixed-step times do not drift and a restarted run repeats an uninterrupted
    one."""
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
