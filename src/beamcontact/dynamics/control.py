"""Step control of the time integration, once for every loop: the controller's settings,
its state, the energy account, the tests an attempt must pass and the size of the next
step (docs/architecture.md, "One time step").

The functions marked jitable are plain Python that the host loop (dynamics/driver.py, the
JAX engine) calls as they are and the compiled loop of the native engine
(dynamics/native_loop.py) compiles into its own code: one controller, not two copies. They
read an attempt's report as the vectors of :mod:`~beamcontact.dynamics.report` and keep
the controller's state in one float64 vector (:func:`new_state`, the positions below).

* Local error (Zienkiewicz & Xie 1991) and the step after it: the elementary controller
  h (tol / e)^(1/3) with a safety factor (Hairer, Norsett & Wanner, Solving ODEs I,
  Sec. II.4), see :func:`next_step` and :func:`retry_step`.
* The tests of an attempt, in order (:func:`verdict`): Newton converged, no contact block
  missed, penetration within bounds, the conservative advancement respected, the local
  error within ``error_tol``, the energy created within ``energy_tol`` (with its floor),
  and a set change refined while that shrinks its jump. A failed test is a rejection of
  one of the :data:`KINDS`, with the step to retry with.
* The energy account (both signs): ``E_set_change`` sums the jumps of the contact energy
  when the frozen set changes between steps, ``E_dissipated`` what the integrator removed
  under one set, so that ``E_total + E_dissipated - E_set_change`` stays constant.
"""

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from beamcontact._native import jitable
from beamcontact.dynamics.report import (
    C_FLAGS,
    C_ITERATIONS,
    CONVERGED,
    DIAG0,
    DIAGNOSTICS,
    MISSING_BLOCK,
    V_APPROACH,
    V_EC_BEFORE,
    V_ERROR,
    V_FLOOR,
    V_GAP,
    V_H,
)

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
# a step that moved further than the candidate search foresaw is redone with the search
# margin doubled, up to this factor (then it is a rejection)
MOTION_FACTOR_MAX = 16.0

# the kinds of rejection (codes 1, 2, ...; 0: accepted), as summary.json counts them
KINDS = ("newton", "missing_block", "penetration", "advancement", "error", "energy",
         "set_change")
ACCEPTED = 0
NEWTON, MISSING, PENETRATION, ADVANCEMENT, ERROR, ENERGY, SET_CHANGE = range(1, len(KINDS) + 1)
# what the controller makes of an attempt (:func:`decide`)
ACCEPT, REJECT, STOP, REDO = range(4)

# the positions of the diagnostics (DIAGNOSTICS order), in the report after DIAG0 and in
# the controller's state after LAST
D_STRAIN, D_GRAVITY, D_EXT, D_CONTACT, D_KIN, D_PX, D_PY = range(len(DIAGNOSTICS))
# the controller's state (:func:`new_state`): the time reached, the step to try next, the
# search's motion factor, rejected attempts in a row and in all, the set-change jumps
# refined at this step (their number and the last |jump|), accepted steps, Newton
# iterations of all attempts, the energy account, the last attempt's energy test
# (created, jump, allowance), the last rejection's kind and step to retry; LAST: the
# diagnostics of the last accepted state; REJECTED: the rejected attempts by kind
(T, H_TRY, MOTION_FACTOR, CONSECUTIVE, CUTBACKS, N_SET_JUMPS, LAST_SET_JUMP, STEPS,
 ITERATIONS, E_DISSIPATED, E_SET_CHANGE, CREATED, JUMP, ALLOWANCE, KIND, RETRY,
 LAST) = range(17)
REJECTED = LAST + len(DIAGNOSTICS)
CONTROL_SIZE = REJECTED + len(KINDS)


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
        max_cutbacks: successive rejected attempts at one step before the run stops.
    """

    dt: float
    dt_min: float
    error_tol: float = 0.0
    energy_tol: float = 0.0
    max_cutbacks: int = 40

    @classmethod
    def fixed(cls, dt: float, max_halvings: int = 12) -> "StepControl":
        """Fixed steps of dt, halved only when Newton fails (theory tests of HHT)."""
        return cls(dt, dt * 0.5 ** (max_halvings + 0.5), 0.0, 0.0, max_halvings)


class Limits(NamedTuple):
    """The settings of one solve as the loops read them (plain floats, for compiled code):
    ``tol`` the local error bound [m] (error_tol L), ``max_penetration`` inf without
    contact."""

    t_end: float
    dt: float
    dt_min: float
    tol: float
    energy_tol: float
    max_cutbacks: float
    max_penetration: float

    @classmethod
    def of(cls, control: StepControl, t_end: float, length: float,
           max_penetration: float | None) -> "Limits":
        """The limits of a solve to t_end with length scale L = ``length``."""
        return cls(float(t_end), float(control.dt), float(control.dt_min),
                   float(control.error_tol * length), float(control.energy_tol),
                   float(control.max_cutbacks),
                   np.inf if max_penetration is None else float(max_penetration))


@dataclass(frozen=True)
class EnergyAccount:
    """Cumulative energy removed by the integrator and changed by contact-set changes,
    and the energies of the last accepted state (the reference of the next step)."""

    E_dissipated: float = 0.0
    E_set_change: float = 0.0
    last: dict | None = None


def new_state(t: float, h_try: float, account: EnergyAccount) -> np.ndarray:
    """The controller's state at the start of a solve from time t (nothing counted yet)."""
    ctl = np.zeros(CONTROL_SIZE)
    ctl[T], ctl[H_TRY], ctl[MOTION_FACTOR] = t, h_try, 1.0
    ctl[E_DISSIPATED], ctl[E_SET_CHANGE] = account.E_dissipated, account.E_set_change
    ctl[LAST:LAST + len(DIAGNOSTICS)] = [account.last[k] for k in DIAGNOSTICS]
    return ctl


def rejections(ctl: np.ndarray) -> dict:
    """The rejected attempts by kind (the kinds that occurred)."""
    return {k: int(ctl[REJECTED + i]) for i, k in enumerate(KINDS) if ctl[REJECTED + i] > 0}


def total_energy(d: dict) -> float:
    """E_kin + E_strain + E_gravity + E_ext + E_contact."""
    return d["E_kin"] + d["E_strain"] + d["E_gravity"] + d["E_ext"] + d["E_contact"]


@jitable
def _total(v, o):
    """:func:`total_energy` of the diagnostics at v[o:]."""
    return v[o + D_KIN] + v[o + D_STRAIN] + v[o + D_GRAVITY] + v[o + D_EXT] + v[o + D_CONTACT]


@jitable
def _scale(v, o):
    """The energy a step's tolerance refers to: E_kin + E_strain + |E_contact| at v[o:]."""
    return v[o + D_KIN] + v[o + D_STRAIN] + abs(v[o + D_CONTACT])


@jitable
def energy_change(values, ctl, energy_tol):
    """(created, jump, allowance) of an attempt against the last accepted state: ``jump``
    the change of the contact energy when the frozen set changed (evaluated at the old
    state), ``created`` the change of the total energy under one set (what the integrator
    added, negative when it removed), ``allowance`` what the energy test admits:
    energy_tol times the energy scale plus the floor (the resolution of the converged
    solve and round-off); 0 without energy test."""
    scale = max(_scale(values, DIAG0), _scale(ctl, LAST))
    roundoff = 0.0
    for d in (D_KIN, D_STRAIN, D_GRAVITY, D_EXT, D_CONTACT):
        roundoff += abs(values[DIAG0 + d]) + abs(ctl[LAST + d])
    floor = values[V_FLOOR] + ENERGY_ROUNDOFF * roundoff
    jump = values[V_EC_BEFORE] - ctl[LAST + D_CONTACT]
    created = _total(values, DIAG0) - (_total(ctl, LAST) + jump)
    return created, jump, energy_tol * scale + floor if energy_tol > 0 else 0.0


@jitable
def next_step(h, error, tol, dt, after_rejection, iterations):
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


@jitable
def retry_step(h, error, tol):
    """The step to retry after a rejection for too large an error (always shorter)."""
    return h * min(max(SAFETY * (tol / error) ** (1.0 / 3.0), SHRINK_MIN), SAFETY)


@jitable
def _rejection(values, flags, h, max_penetration, tol, allowance, created):
    """(kind, step to retry) of an attempt that fails a test other than the set change,
    else (ACCEPTED, 0). Without contact max_penetration is inf and the contact tests
    cannot fail (no flag, a NaN gap, no approach)."""
    if not flags & CONVERGED:
        return NEWTON, 0.5 * h
    if flags & MISSING_BLOCK:
        return MISSING, 0.5 * h
    if values[V_GAP] < -max_penetration:
        return PENETRATION, 0.5 * h
    if values[V_APPROACH] > ADVANCE_ACCEPT:
        return ADVANCEMENT, h * ADVANCE_FRACTION / values[V_APPROACH]
    if tol > 0.0 and values[V_ERROR] > tol:
        return ERROR, retry_step(h, values[V_ERROR], tol)
    if allowance > 0.0 and not abs(created) <= allowance:
        return ENERGY, 0.5 * h
    return ACCEPTED, 0.0


@jitable
def verdict(values, flags, max_penetration, tol, allowance, created, jump, n_set_jumps,
            last_set_jump, dt_min):
    """(kind, step to retry) of an attempt: (ACCEPTED, 0) if it is accepted.

    A set change is refined while halving the step at least halves its jump (the jump
    came from choosing the set at a far predictor), at most SET_CHANGE_REFINEMENTS
    times and never below ``dt_min``; a jump that does not shrink is a change of the
    model itself (IPIP "zones" gains or loses a contact zone, a jump of the same size
    however short the step) and is accepted and accounted in E_set_change, never a
    reason to stop the run.
    """
    h = values[V_H]
    kind, retry = _rejection(values, flags, h, max_penetration, tol, allowance, created)
    if kind != ACCEPTED:
        return kind, retry
    shrinking = n_set_jumps == 0 or abs(jump) <= 0.5 * last_set_jump
    if (abs(jump) > allowance and allowance > 0.0 and shrinking
            and n_set_jumps < SET_CHANGE_REFINEMENTS and 0.5 * h >= dt_min):
        return SET_CHANGE, 0.5 * h
    return ACCEPTED, 0.0


@jitable
def count_rejection(ctl, kind, retry, jump, dt_min, max_cutbacks):
    """Count a rejected attempt of ``kind`` and set the step to retry; True when the run
    must stop: the step would be shorter than dt_min, or more than max_cutbacks attempts
    in a row were rejected."""
    if kind == SET_CHANGE:
        ctl[N_SET_JUMPS] += 1.0
        ctl[LAST_SET_JUMP] = abs(jump)
    else:
        ctl[N_SET_JUMPS] = 0.0
    ctl[CUTBACKS] += 1.0
    ctl[CONSECUTIVE] += 1.0
    ctl[REJECTED + kind - 1] += 1.0
    ctl[KIND], ctl[RETRY] = kind, retry
    if retry < dt_min or ctl[CONSECUTIVE] > max_cutbacks:
        return True
    ctl[H_TRY] = retry
    return False


@jitable
def accept_step(ctl, values, h, iterations, created, jump, limits):
    """Take an attempt at a step of (at most) h: advance the time (onto the grid of dt),
    the energy account and the step to try next."""
    h_used = values[V_H]
    after_rejection = ctl[CONSECUTIVE] > ctl[N_SET_JUMPS]
    ctl[CONSECUTIVE] = 0.0
    ctl[N_SET_JUMPS] = 0.0
    ctl[MOTION_FACTOR] = 1.0
    ctl[T] = on_grid(ctl[T] + h_used, limits.dt, limits.t_end)
    ctl[STEPS] += 1.0
    ctl[E_DISSIPATED] = ctl[E_DISSIPATED] - created
    ctl[E_SET_CHANGE] = ctl[E_SET_CHANGE] + jump
    for d in range(len(DIAGNOSTICS)):
        ctl[LAST + d] = values[DIAG0 + d]
    h_next = next_step(h_used, values[V_ERROR], limits.tol, limits.dt, after_rejection,
                       iterations)
    if h_used < h * (1.0 - 1e-12):
        # shortened by the advancement bound, not by the error: back towards the step
        # attempted, whatever came before it or its Newton iterations, but only as far
        # as the short step's own error allows
        h_next = max(h_next, min(h, next_step(h_used, values[V_ERROR], limits.tol,
                                              limits.dt, False, 0)))
    ctl[H_TRY] = h_next


@jitable
def decide(ctl, values, counts, h, limits):
    """What to make of an attempt at a step of (at most) h whose Newton iterations are
    counted: REDO it with a wider search (the step moved further than the search
    foresaw), REJECT it (the step to retry is in ctl[H_TRY]), STOP the run, or ACCEPT
    it (ctl advanced). The energy test's numbers stay in ctl (CREATED, JUMP, ALLOWANCE)."""
    flags = counts[C_FLAGS]
    if flags & CONVERGED and flags & MISSING_BLOCK and ctl[MOTION_FACTOR] < MOTION_FACTOR_MAX:
        ctl[MOTION_FACTOR] *= 2.0
        return REDO
    created, jump, allowance = energy_change(values, ctl, limits.energy_tol)
    ctl[CREATED], ctl[JUMP], ctl[ALLOWANCE] = created, jump, allowance
    kind, retry = verdict(values, flags, limits.max_penetration, limits.tol, allowance,
                          created, jump, ctl[N_SET_JUMPS], ctl[LAST_SET_JUMP], limits.dt_min)
    if kind != ACCEPTED:
        if count_rejection(ctl, kind, retry, jump, limits.dt_min, limits.max_cutbacks):
            return STOP
        return REJECT
    accept_step(ctl, values, h, counts[C_ITERATIONS], created, jump, limits)
    return ACCEPT


@jitable
def step_size(t, t_end, h_try):
    """The next step: h_try, shortened to land on t_end without leaving a sliver."""
    remaining = t_end - t
    if abs(remaining - h_try) <= 1e-9 * h_try:
        return h_try  # exactly nominal, so a restart repeats the same arithmetic
    h = min(h_try, remaining)
    return remaining if remaining - h < 1e-6 * h else h


@jitable
def unfinished(t, limits):
    """Whether a solve at time t has not reached t_end yet."""
    return limits.t_end - t > 1e-12 * max(limits.dt, limits.t_end)


@jitable
def on_grid(t, dt, t_end):
    """Snap a time within round-off of a multiple of the largest step (or of t_end) onto
    it, so that fixed-step times do not drift and a restarted run repeats an uninterrupted
    one."""
    k = round(t / dt)
    if abs(t - k * dt) <= 1e-9 * dt:
        return k * dt
    return t_end if abs(t - t_end) <= 1e-9 * dt else t


def reason(kind: int, values: np.ndarray, ctl: np.ndarray, limits: Limits) -> str:
    """Why an attempt was rejected (``kind``; its report ``values``, the controller's
    state after :func:`decide`)."""
    v = {k: float(values[i]) for i, k in ((V_GAP, "gap"), (V_APPROACH, "approach"),
                                          (V_ERROR, "error"))}
    created, jump, allowance = (float(ctl[i]) for i in (CREATED, JUMP, ALLOWANCE))
    return {
        NEWTON: "Newton did not converge",
        MISSING: "the step moved further than the candidate search foresaw (a contact "
                 "block was missing)",
        PENETRATION: f"penetration {-v['gap']:.3g} m exceeded max_penetration = "
                     f"{limits.max_penetration:.3g} m",
        ADVANCEMENT: f"a contact point approached by {v['approach']:.3g} of its gap in one "
                     f"step (tunnelling guard)",
        ERROR: f"local error {v['error']:.3g} m above error_tol ({limits.tol:.3g} m)",
        ENERGY: f"the total energy {'grew' if created > 0 else 'fell'} by {abs(created):.3g} "
                f"J in one step (allowed {allowance:.3g} J)",
        SET_CHANGE: f"the contact energy jumped by {jump:.3g} J when the contact set "
                    f"changed (allowed {allowance:.3g} J)",
    }[kind]


def stop_reason(ctl: np.ndarray, limits: Limits) -> str:
    """Why the run stops after :func:`count_rejection` said so."""
    if ctl[RETRY] < limits.dt_min:
        return f"the step would have to be shorter than dt_min = {limits.dt_min:.3g} s"
    return f"{int(ctl[CONSECUTIVE])} successive attempts were rejected"
