"""Adaptive time stepping with HHT-alpha through impacts: the time loop, whichever engine
makes the attempts (docs/architecture.md, "Engines").

An engine (:class:`Engine`; the JAX one is :class:`~beamcontact.dynamics.step.JaxEngine`)
makes one attempt at a step: predictor, contact candidates, conservative advancement (the
step is shortened before it is solved so that no point pair approaches further than a
fraction of its gap, :mod:`~beamcontact.contact.advance`), Newton on the HHT residual,
post-step checks and diagnostics, reported as Python numbers
(:mod:`~beamcontact.dynamics.report`). The host loop here (:func:`solve_dynamic`), which
holds no JAX, then accepts the step or redoes it shorter
(:mod:`~beamcontact.dynamics.control`):

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

A step that would have to be shorter than ``dt_min`` (or more than ``max_cutbacks``
attempts at one step) stops the run with a message; every accepted step has gone to
``on_step`` before.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Protocol

from beamcontact.dynamics.control import (
    GROW_MAX,
    Attempts,
    EnergyAccount,
    Rejection,
    StepControl,
    energy_change,
    next_step,
    on_grid,
    step_size,
    total_energy,
    verdict,
)
from beamcontact.dynamics.report import DIAGNOSTICS, Attempt, Overflow, StepFlags

if TYPE_CHECKING:  # names for annotations only: the loop itself imports no JAX
    from beamcontact.contact.broadphase import SearchCapacity
    from beamcontact.contact.problem import ContactProblem


class Engine(Protocol):
    """What the time loop asks of an engine (docs/architecture.md, "Engines").

    Attributes:
        name: "jax" or "native".
        contact: the contact problem (None: no contact): its capacities and their growth,
            and ``max_penetration``, are the loop's.
    """

    name: str
    contact: ContactProblem | None

    def attempt(self, state, h: float, motion_factor: float,
                capacity: SearchCapacity | None) -> Attempt | Overflow:
        """One attempt at a step of at most h from ``state`` (report: the step taken)."""

    def energies(self, state, capacity: SearchCapacity | None) -> dict:
        """The diagnostics of ``state`` under the contact set at its configuration."""

    def at_time(self, state, t: float):
        """``state`` with its time set to t."""

    def time(self, state) -> float:
        """The time of ``state``."""


@dataclass(frozen=True)
class DynamicStep:
    """One accepted time step (host values); ``dt_next`` the step the controller tries
    next, ``error`` the local error estimate [m]."""

    step: int
    t: float
    dt: float
    dt_next: float
    state: object  # the engine's state (a DynState of arrays)
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
    state: object
    dt_next: float
    wall_time: float
    compile_time: float
    rejections: dict


@dataclass
class _Loop:
    """The host state of the time loop between attempts (local to one solve_dynamic)."""

    engine: Engine
    state: object
    account: EnergyAccount
    h_try: float
    capacity: SearchCapacity | None
    start: float = field(default_factory=time.perf_counter)
    steps: int = 0
    iterations: int = 0
    attempts: Attempts = field(default_factory=Attempts)
    set_jumps: list = field(default_factory=list)  # |jump| of the set changes refined
    motion_factor: float = 1.0
    compile_time: float | None = None

    @property
    def t(self) -> float:
        return self.engine.time(self.state)

    def result(self, status: str, message: str) -> DynamicResult:
        return DynamicResult(status, message, self.steps, self.iterations,
                             self.attempts.cutbacks, self.t, self.state, self.h_try,
                             time.perf_counter() - self.start, self.compile_time or 0.0,
                             self.attempts.by_kind)


def solve_dynamic(engine: Engine, state, t_end: float, length: float, control: StepControl,
                  *, dt_start: float | None = None, step0: int = 0,
                  on_step: Callable[[DynamicStep], None] | None = None,
                  capacity: int | SearchCapacity = 64,
                  account: EnergyAccount | None = None) -> DynamicResult:
    """Integrate from ``state`` to ``t_end`` with adaptive steps (module docstring).

    Args:
        engine: makes the attempts (:class:`Engine`; it holds the model, the contact
            problem, alpha and the Newton settings).
        state: initial (or restart) state, the engine's.
        t_end: final time.
        length: the length scale L of the tolerances.
        control: step-controller settings.
        dt_start: the step to try first (default control.dt; a restart passes the
            interrupted run's next step).
        step0: number of the last accepted step (restart).
        on_step: called with every accepted step; its diagnostics hold the energies,
            momentum, min_gap, the local error ``error`` [m] and the cumulative
            ``E_dissipated`` and ``E_set_change``.
        capacity: initial length of the contact candidate list, or both capacities of
            the search (:class:`SearchCapacity`); they grow on overflow.
        account: the energy account of the state (a restart); default zero sums and the
            energies of ``state`` under its initial contact set.
    """
    contact = engine.contact
    first = None if contact is None else contact.first_capacity(capacity)
    loop = _Loop(engine, state, _initial_account(engine, state, first, account),
                 control.dt if dt_start is None else dt_start, first)
    tol = control.error_tol * length
    while t_end - loop.t > 1e-12 * max(control.dt, t_end):
        h = step_size(loop.t, t_end, loop.h_try)
        attempt = _attempt(loop, h, contact)
        if attempt is None:  # the candidate list or the search margin grew: redo
            continue
        new, report, flags = attempt.state, attempt.report, attempt.flags
        diag = {k: report[k] for k in DIAGNOSTICS}
        created, jump, allowance = energy_change(diag, loop.account.last,
                                                 report["E_contact_before"],
                                                 report["energy_floor"], control.energy_tol)
        rejection = verdict(report, flags, report["h"],
                            None if contact is None else contact.max_penetration, tol,
                            allowance, created, jump, loop.set_jumps, control.dt_min)
        if rejection is not None:
            if _reject(loop, rejection, jump, control):
                return loop.result("failed", _failure(loop, rejection, report, control))
            continue
        _accept(loop, new, report, diag, created, jump, h, tol, control.dt, t_end)
        if on_step is not None:
            on_step(DynamicStep(step0 + loop.steps, loop.t, report["h"], loop.h_try,
                                loop.state, report["iterations"], loop.attempts.cutbacks,
                                {**diag, "min_gap": report["min_gap"],
                                 "E_total": total_energy(diag), "error": report["error"],
                                 "E_dissipated": loop.account.E_dissipated,
                                 "E_set_change": loop.account.E_set_change}))
    return loop.result("completed", f"reached t = {loop.t:.6g} s in {loop.steps} steps")


def _initial_account(engine: Engine, state, capacity: SearchCapacity | None,
                     account: EnergyAccount | None) -> EnergyAccount:
    """The energy account to start from: the given one, or zero sums and the energies of
    ``state`` under its initial contact set."""
    if account is not None and account.last is not None:
        return account
    return EnergyAccount(0.0 if account is None else account.E_dissipated,
                         0.0 if account is None else account.E_set_change,
                         engine.energies(state, capacity))


def _attempt(loop: _Loop, h: float, contact: ContactProblem | None) -> Attempt | None:
    """One attempt at a step of (at most) h, or None when the candidate list overflowed
    or the solution left the search margin (both grown in ``loop``; the attempt is
    redone)."""
    t0 = time.perf_counter()
    attempt = loop.engine.attempt(loop.state, h, loop.motion_factor, loop.capacity)
    if isinstance(attempt, Overflow):
        loop.capacity = contact.grown(loop.capacity, attempt.count, attempt.load)
        return None
    report, flags = attempt.report, attempt.flags
    if loop.compile_time is None:
        loop.compile_time = time.perf_counter() - t0
    loop.iterations += report["iterations"]
    if contact is not None:
        # the candidates after a diverged Newton solve say nothing about the solution
        converged = StepFlags.CONVERGED in flags
        count = max(report["count"], report["count_after"] if converged else 0)
        load = max(report["load"], report["load_after"] if converged else 0)
        if not loop.capacity.fits(count, load):  # overflow: reallocate and redo
            loop.capacity = contact.grown(loop.capacity, count, load)
            return None
        if converged and StepFlags.MISSING_BLOCK in flags and loop.motion_factor < 16:
            loop.motion_factor *= 2.0  # the step moved further than foreseen: redo it
            return None
    return attempt


def _reject(loop: _Loop, rejection: Rejection, jump: float, control: StepControl) -> bool:
    """Count a rejected attempt and set the step to retry; True when the run must stop
    (the step would be shorter than dt_min, or too many successive rejections)."""
    if rejection.kind == "set_change":
        loop.set_jumps.append(abs(jump))
    else:
        loop.set_jumps.clear()
    if loop.attempts.reject(rejection, control):
        return True
    loop.h_try = rejection.retry
    return False


def _failure(loop: _Loop, rejection: Rejection, report: dict, control: StepControl) -> str:
    """The message of a run stopped at ``rejection`` (``report``: the last attempt)."""
    return (f"{rejection.reason} at t = {loop.t + report['h']:.6g} s (step "
            f"{report['h']:.3g} s, {report['iterations']} iterations, residual "
            f"{report['residual_norm']:.3e} from {report['initial_residual_norm']:.3e}); "
            f"{loop.attempts.stop_reason(rejection, control)}; the last accepted time is "
            f"{loop.t:.6g} s")


def _accept(loop: _Loop, new, report: dict, diag: dict, created: float,
            jump: float, h: float, tol: float, dt: float, t_end: float) -> None:
    """Take the attempt: advance the time, the energy account and the step to try next."""
    h_used = report["h"]
    after_rejection = loop.attempts.consecutive > len(loop.set_jumps)
    loop.attempts.accept()
    loop.set_jumps.clear()
    loop.motion_factor = 1.0
    t = on_grid(loop.t + h_used, dt, t_end)
    loop.state = loop.engine.at_time(new, t)
    loop.steps += 1
    loop.account = EnergyAccount(loop.account.E_dissipated - created,
                                 loop.account.E_set_change + jump, diag)
    loop.h_try = next_step(h_used, report["error"], tol, dt, after_rejection,
                           report["iterations"])
    if h_used < h * (1.0 - 1e-12):  # shortened by the advancement bound, not the error
        loop.h_try = max(loop.h_try, min(h, GROW_MAX * h_used))
