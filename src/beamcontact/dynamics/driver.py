"""Adaptive time stepping with HHT-alpha through impacts: the time loop, whichever engine
makes the attempts (docs/architecture.md, "Engines").

An engine (:class:`Engine`; the JAX one is :class:`~beamcontact.dynamics.step.JaxEngine`)
makes one attempt at a step: predictor, contact candidates, conservative advancement (the
step is shortened before it is solved so that no point pair approaches further than a
fraction of its gap, :mod:`~beamcontact.contact.advance`), Newton on the HHT residual,
post-step checks and diagnostics, reported as Python numbers
(:mod:`~beamcontact.dynamics.report`). The step controller
(:mod:`~beamcontact.dynamics.control`) then accepts the step or redoes it shorter, in one
of two loops that call the same controller: the host loop here (:func:`solve_dynamic`,
which holds no JAX), where an engine makes one attempt per call, or the engine's own
compiled loop (the native engine, dynamics/native_loop.py), which makes many steps per
call and hands the accepted ones back to :func:`solve_dynamic` in order. The rules:

* **Local error** (Zienkiewicz & Xie 1991): with the acceleration linear over the step,
  the Newmark displacement differs from the exact cubic by
  ``e = h^2 |beta - 1/6| (a_{n+1} - a_n)``; its largest component must not exceed
  ``error_tol * L`` (L the longest beam). The next step is ``h (error_tol L / e)^(1/3)``
  times a safety factor 0.9, kept between 0.2 h and 2 h, never longer than ``dt`` (the
  first and the largest step) and not longer than h right after a rejection (no
  oscillation between rejected and accepted sizes). A step that the advancement bound
  shortened grows back towards the step attempted, as far as its own error allows.
  ``error_tol = 0`` gives fixed steps.
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
``on_step`` before, also when the run is interrupted (Ctrl-C) inside a compiled loop; an
interrupt that lands in a garbage-collection callback is not lost
(:func:`beamcontact.stop_signals.interrupts_kept`: raised after the next batch of
steps is handed over).
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Protocol

import numpy as np

from beamcontact._native import Stopwatch
from beamcontact.dynamics import control as ctl_
from beamcontact.dynamics.control import (
    ACCEPT,
    CUTBACKS,
    E_DISSIPATED,
    E_SET_CHANGE,
    H_TRY,
    ITERATIONS,
    KINDS,
    MOTION_FACTOR,
    REJECTED,
    STEPS,
    STOP,
    EnergyAccount,
    Limits,
    StepControl,
    T,
    decide,
    new_state,
    step_size,
    unfinished,
)
from beamcontact.dynamics.report import (
    C_COUNT,
    C_COUNT_AFTER,
    C_FLAGS,
    C_ITERATIONS,
    C_LOAD,
    C_LOAD_AFTER,
    CONVERGED,
    COUNTS,
    DIAG0,
    DIAGNOSTICS,
    V_ERROR,
    V_GAP,
    V_H,
    V_RESIDUAL,
    V_RESIDUAL0,
    VALUES,
    Attempt,
    Overflow,
)
from beamcontact.stop_signals import interrupt_of, interrupts_kept, raise_dropped

if TYPE_CHECKING:  # names for annotations only: the loop itself imports no JAX
    from beamcontact.contact.broadphase import SearchCapacity
    from beamcontact.contact.problem import ContactProblem

# what a loop hands over for its accepted steps, in order and as many at once as it has
# (one per attempt in the host loop, one call's worth in a compiled loop): the states
# after them (a sequence of the engine's states: a list, or a compiled loop's arrays as
# a sequence, with ``arrays()``), their reports (values (k, len(VALUES)), counts (k,
# len(COUNTS))) and the controller's states right after each was accepted (k, len(ctl))
Emit = Callable[[Sequence, np.ndarray, np.ndarray, np.ndarray], None]


class Engine(Protocol):
    """What the time loop asks of an engine (docs/architecture.md, "Engines").

    Attributes:
        name: "jax" or "native".
        contact: the contact problem (None: no contact): its capacities and their growth,
            and ``max_penetration``, are the loop's.
        fixed_capacity: whether the attempt's candidate lists hold only the capacity it
            is given (the JAX engine's arrays of fixed shape), so that a count beyond it
            is an overflow: the loop grows the capacity and redoes the attempt. The
            native engine's lists have no fixed length: its counts are never overflows.

    An engine that runs the loop itself (the native one) also has ``runs_loop`` True and
    ``advance(state, ctl, limits, emit) -> (state, stopping attempt or None, seconds of
    its first attempt)``: it makes the attempts, asks :func:`~beamcontact.dynamics.
    control.decide` about each, and emits every accepted step (:data:`Emit`), from
    ``state`` and the controller's state ``ctl`` until t_end or a stop; and it may have
    ``loop_compiling(state, done=0.0) -> bool``: True while that loop is not ready but
    ``attempt`` is, so that the driver's host loop makes the steps meanwhile
    (:func:`_compiled_loop`; ``done`` is the fraction of the run's time made).
    """

    name: str
    contact: ContactProblem | None
    fixed_capacity: bool

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
    # the Newton iterations of every attempt so far (rejected ones too, as the result's
    # ``iterations``) and the rejected attempts by kind (KINDS), both since step0
    iterations_total: int = 0
    rejected: tuple[int, ...] = ()


@dataclass(frozen=True)
class StepBatch:
    """Accepted steps as a loop hands them over (:data:`Emit`), in order, with the number
    of the steps before this solve (``step0``): what a writer takes many at a time, as
    arrays (the columns of :class:`DynamicStep`), and :meth:`steps` one by one."""

    states: Sequence
    values: np.ndarray
    counts: np.ndarray
    after: np.ndarray
    step0: int = 0

    def __len__(self) -> int:
        return self.after.shape[0]

    @property
    def step(self) -> np.ndarray:
        return self.step0 + self.after[:, STEPS].astype(np.int64)

    @property
    def t(self) -> np.ndarray:
        return self.after[:, T]

    @property
    def dt(self) -> np.ndarray:
        return self.values[:, V_H]

    @property
    def dt_next(self) -> np.ndarray:
        return self.after[:, H_TRY]

    @property
    def iterations(self) -> np.ndarray:
        return self.counts[:, C_ITERATIONS]

    @property
    def cutbacks(self) -> np.ndarray:
        return self.after[:, CUTBACKS].astype(np.int64)

    @property
    def iterations_total(self) -> np.ndarray:
        return self.after[:, ITERATIONS].astype(np.int64)

    @property
    def rejected(self) -> np.ndarray:
        """(k, len(KINDS)) the rejected attempts by kind since step0."""
        return self.after[:, REJECTED:REJECTED + len(KINDS)]

    def diagnostics(self) -> dict[str, np.ndarray]:
        """:attr:`DynamicStep.diagnostics` of every step, as columns (the same numbers)."""
        diag = {name: self.values[:, DIAG0 + i] for i, name in enumerate(DIAGNOSTICS)}
        return {**diag, "min_gap": self.values[:, V_GAP], "E_total": ctl_.total_energy(diag),
                "error": self.values[:, V_ERROR], "E_dissipated": self.after[:, E_DISSIPATED],
                "E_set_change": self.after[:, E_SET_CHANGE]}

    def state_arrays(self) -> tuple[np.ndarray, ...]:
        """(u, v, a, f_pot, load theta, load tangent) of the states, each (k, ...)."""
        if hasattr(self.states, "arrays"):
            return self.states.arrays()

        def stacked(get) -> np.ndarray:
            return np.stack([np.asarray(get(s)) for s in self.states])

        return (stacked(lambda s: s.u), stacked(lambda s: s.v), stacked(lambda s: s.a),
                stacked(lambda s: s.f_pot), stacked(lambda s: s.load_state.theta),
                stacked(lambda s: s.load_state.tangent))

    @classmethod
    def initial(cls, state, diagnostics: dict, dt_next: float) -> StepBatch:
        """The row of a run's initial state: step 0 at t = 0 with its ``diagnostics`` (the
        engine's :meth:`Engine.energies`), nothing dissipated, ``dt_next`` to try first."""
        values = np.zeros((1, len(VALUES)))
        for i, name in enumerate(DIAGNOSTICS):
            values[0, DIAG0 + i] = diagnostics[name]
        values[0, V_GAP] = diagnostics["min_gap"]
        after = np.zeros((1, ctl_.CONTROL_SIZE))
        after[0, H_TRY] = dt_next
        return cls([state], values, np.zeros((1, len(COUNTS)), np.int64), after)

    def steps(self) -> list[DynamicStep]:
        """The steps one by one (Python numbers but the states)."""
        columns = {k: col.tolist() for k, col in self.diagnostics().items()}
        step, t, dt, dt_next = (x.tolist() for x in (self.step, self.t, self.dt,
                                                      self.dt_next))
        iterations, cutbacks = self.iterations.tolist(), self.cutbacks.tolist()
        totals, rejected = self.iterations_total.tolist(), self.rejected.astype(int).tolist()
        return [DynamicStep(step[j], t[j], dt[j], dt_next[j], state, iterations[j],
                            cutbacks[j], {k: col[j] for k, col in columns.items()},
                            totals[j], tuple(rejected[j]))
                for j, state in enumerate(self.states)]


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
    compile_time: float  # Numba's compiles in the solve, the first attempt besides
    rejections: dict


def solve_dynamic(engine: Engine, state, t_end: float, length: float, control: StepControl,
                  *, dt_start: float | None = None, step0: int = 0,
                  on_step: Callable[[DynamicStep], None] | None = None,
                  on_steps: Callable[[list[DynamicStep]], None] | None = None,
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
        on_steps: called with the same steps as many at once as the loop makes them
            (a compiled loop's call), in order, before ``on_step`` sees them, as a
            :class:`StepBatch`: for a writer that takes many rows at a time.
        capacity: initial length of the contact candidate list, or both capacities of
            the search (:class:`SearchCapacity`); they grow on overflow.
        account: the energy account of the state (a restart); default zero sums and the
            energies of ``state`` under its initial contact set.
    """
    start = Stopwatch()
    contact = engine.contact
    first = None if contact is None else contact.first_capacity(capacity)
    limits = Limits.of(control, t_end, length,
                       None if contact is None else contact.max_penetration)
    ctl = new_state(engine.time(state), control.dt if dt_start is None else dt_start,
                    _initial_account(engine, state, first, account))

    def emit(states: Sequence, values: np.ndarray, counts: np.ndarray,
             after: np.ndarray) -> None:
        batch = StepBatch(states, values, counts, after, step0)
        if on_steps is not None:
            on_steps(batch)
        if on_step is not None:
            for s in batch.steps():
                on_step(s)
        if sys.exc_info()[1] is None:  # not over an error already on its way out
            raise_dropped()  # an interrupt dropped in a garbage-collection callback

    loop = _compiled_loop if getattr(engine, "runs_loop", False) else _host_loop
    with interrupts_kept():
        state, stopped, first_s = loop(engine, state, ctl, limits, emit, first)
    status, message = ("completed", f"reached t = {ctl[T]:.6g} s in "
                                    f"{step0 + int(ctl[STEPS])} steps") \
        if stopped is None else ("failed", _failure(stopped, ctl, limits))
    return DynamicResult(status, message, int(ctl[STEPS]), int(ctl[ITERATIONS]),
                         int(ctl[CUTBACKS]), float(ctl[T]), state, float(ctl[H_TRY]),
                         time.perf_counter() - start.wall, start.compiles() + (first_s or 0.0),
                         ctl_.rejections(ctl))


def _initial_account(engine: Engine, state, capacity: SearchCapacity | None,
                     account: EnergyAccount | None) -> EnergyAccount:
    """The energy account to start from: the given one, or zero sums and the energies of
    ``state`` under its initial contact set."""
    if account is not None and account.last is not None:
        return account
    return EnergyAccount(0.0 if account is None else account.E_dissipated,
                         0.0 if account is None else account.E_set_change,
                         engine.energies(state, capacity))


def _compiled_loop(engine: Engine, state, ctl: np.ndarray, limits: Limits, emit: Emit,
                   capacity: SearchCapacity | None) -> tuple[object, Attempt | None, float]:
    """The loop of an engine that runs it itself (``advance``). While another process
    compiles that loop into an empty cache (``engine.loop_compiling(state)``, the native
    engine's helper), the steps are made meanwhile by :func:`_host_loop` from the
    engine's own attempts, the same steps bit for bit (tests/test_native_loop.py);
    ``advance`` goes on from where they end. Returns as :func:`_host_loop`, with the
    seconds of the first attempts of both."""
    compiling = getattr(engine, "loop_compiling", None)
    stopped, first_s = None, 0.0
    if compiling is not None and compiling(state):
        start, t0 = state, float(ctl[T])

        def meanwhile() -> bool:
            return compiling(start, (ctl[T] - t0) / max(limits.t_end - t0, 1e-300))

        state, stopped, host_s = _host_loop(engine, state, ctl, limits, emit, capacity,
                                            meanwhile=meanwhile)
        first_s += host_s or 0.0
    if stopped is None and unfinished(ctl[T], limits):
        state, stopped, loop_s = engine.advance(state, ctl, limits, emit)
        first_s += loop_s or 0.0
    return state, stopped, first_s


# the host loop hands its accepted steps over at least this often [s], as the native
# engine's compiled loop returns to Python (native_step.CALL_SECONDS): written one by one,
# the outputs of a step cost 0.1-0.15 ms, as much as a native attempt made from Python
EMIT_SECONDS = 0.1


def _host_loop(engine: Engine, state, ctl: np.ndarray, limits: Limits, emit: Emit,
               capacity: SearchCapacity | None, meanwhile: Callable[[], bool] | None = None
               ) -> tuple[object, Attempt | None, float | None]:
    """The loop of an engine that makes one attempt per call: (the last accepted state,
    the attempt that stopped the run or None, seconds of the first attempt). The
    candidate capacities grow on overflow (the attempt is redone). With ``meanwhile``,
    it returns too once that says False (checked before each attempt). Accepted steps
    are emitted at least every EMIT_SECONDS, and all of them before it returns or raises
    (an interrupt loses none)."""
    contact = engine.contact
    first_s = None
    pending: list[tuple] = []  # (state, values, counts, control row) not yet emitted
    emitted = time.perf_counter()

    def hand_over() -> None:
        nonlocal emitted
        if pending:
            # an interrupt before emit leaves them pending (handed over by the finally
            # below); once emit has started they count as handed over, never twice
            states, values, counts, after = zip(*pending, strict=True)
            try:
                emit(list(states), np.stack(values), np.stack(counts), np.stack(after))
            finally:
                pending.clear()
        emitted = time.perf_counter()

    try:
        while unfinished(ctl[T], limits) and (meanwhile is None or meanwhile()):
            h = step_size(ctl[T], limits.t_end, ctl[H_TRY])
            watch = Stopwatch()
            try:
                attempt = engine.attempt(state, h, float(ctl[MOTION_FACTOR]), capacity)
            except SystemError as exc:  # an interrupt inside a compiled call
                raise interrupt_of(exc) from None
            if isinstance(attempt, Overflow):
                capacity = contact.grown(capacity, attempt.count, attempt.load)
                continue
            if first_s is None:
                first_s = watch.outside_compiles()  # one attempt, and XLA compiling it
            values, counts = attempt.values, attempt.counts
            ctl[ITERATIONS] += counts[C_ITERATIONS]
            if contact is not None and engine.fixed_capacity:
                # the candidates after a diverged Newton solve say nothing about the solution
                converged = bool(counts[C_FLAGS] & CONVERGED)
                count = max(counts[C_COUNT], counts[C_COUNT_AFTER] if converged else 0)
                load = max(counts[C_LOAD], counts[C_LOAD_AFTER] if converged else 0)
                if not capacity.fits(int(count), int(load)):  # overflow: reallocate, redo
                    capacity = contact.grown(capacity, int(count), int(load))
                    continue
            outcome = decide(ctl, values, counts, h, limits)
            if outcome == STOP:
                return state, attempt, first_s
            if outcome == ACCEPT:
                state = engine.at_time(attempt.state, float(ctl[T]))
                pending.append((state, np.array(values), np.array(counts), ctl.copy()))
            if time.perf_counter() - emitted >= EMIT_SECONDS:  # also amid rejections
                hand_over()
        return state, None, first_s
    finally:
        hand_over()


def _failure(stopped: Attempt, ctl: np.ndarray, limits: Limits) -> str:
    """The message of a run stopped at the attempt ``stopped``."""
    values, counts = stopped.values, stopped.counts
    t, h = float(ctl[T]), float(values[V_H])
    kind = int(ctl[ctl_.KIND])
    return (f"{ctl_.reason(kind, values, ctl, limits)} at t = {t + h:.6g} s (step "
            f"{h:.3g} s, {int(counts[C_ITERATIONS])} iterations, residual "
            f"{values[V_RESIDUAL]:.3e} from {values[V_RESIDUAL0]:.3e}); "
            f"{ctl_.stop_reason(ctl, limits)}; the last accepted time is {t:.6g} s")
