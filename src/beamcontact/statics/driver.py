"""Load stepping with Newton-Raphson and automatic cut-back.

The load factor lam runs from 0 to 1 in ``load_steps`` equal increments. A failed Newton
solve, or a solution whose smallest contact gap is below -max_penetration (the contact set
is frozen during an increment, so a large one can carry a point through a beam),
restores the last converged state and halves the increment, up to ``max_cutbacks``
times in a row; after a success the increment grows back (doubling) to the nominal one.
This is the time stepping's controller (dynamics/control.py: its state vector,
``count_rejection``, ``next_step``) with the load factor as time and no error
estimate. Every converged step is handed to ``on_step`` at once, so a later failure
loses nothing (nor does an interrupt that lands in a garbage-collection callback:
:func:`beamcontact.stop_signals.interrupts_kept`). The loop holds no JAX: an engine
(:class:`StaticEngine`; the JAX one is :class:`~beamcontact.statics.step.JaxStatics`)
makes the attempts.

Before the first step, a model whose supports leave some beam free to move rigidly is
checked for a singular tangent (statics/restraint.py): if neither supports nor contact
hold it, the analysis stops at once with status "failed" naming the beams, instead of
halving the load increment on NaN residuals.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Protocol

import numpy as np

from beamcontact._native import Stopwatch
from beamcontact.dynamics import control as ctl_
from beamcontact.dynamics.control import (
    CONSECUTIVE,
    CUTBACKS,
    NEWTON,
    PENETRATION,
    EnergyAccount,
    count_rejection,
    next_step,
)
from beamcontact.dynamics.report import Overflow
from beamcontact.stop_signals import interrupts_kept, raise_dropped

if TYPE_CHECKING:  # names for annotations only: the loop itself imports no JAX
    from beamcontact.contact.broadphase import SearchCapacity
    from beamcontact.contact.problem import ContactProblem
    from beamcontact.statics.step import LoadAttempt


class StaticEngine(Protocol):
    """What the load loop asks of an engine (docs/architecture.md, "Engines"; the JAX one
    is :class:`~beamcontact.statics.step.JaxStatics`)."""

    name: str
    contact: ContactProblem | None

    def initial(self):
        """The unloaded reference state."""

    def complete_set(self, state, margin: float, capacity: SearchCapacity):
        """The contact set at ``state``, capacities grown until complete: (set, capacities)."""

    def attempt(self, state, lam: float, margin: float,
                capacity: SearchCapacity | None) -> LoadAttempt | Overflow:
        """Newton at load factor lam from ``state``, the contact set frozen there."""

    def accept(self, state, attempt: LoadAttempt):
        """The state of an accepted attempt."""

    def values(self, state, lam: float, cs) -> dict:
        """Energies and the smallest gap of ``state`` under the contact set ``cs``."""

    def mechanism(self, state, cs, beam_names) -> str | None:
        """Why the tangent at ``state`` is singular (an unheld beam), or None."""

    def displacement(self, state) -> np.ndarray:
        """The displacement of ``state`` on the host."""


@dataclass(frozen=True)
class StaticStep:
    """One converged load step."""

    step: int
    load_factor: float
    u: np.ndarray
    iterations: int
    cutbacks: int
    energies: dict


@dataclass(frozen=True)
class StaticResult:
    """Outcome of a static analysis."""

    status: str  # "completed" | "failed"
    message: str
    steps: int
    iterations: int
    cutbacks: int
    load_factor: float
    u: np.ndarray
    wall_time: float
    compile_time: float  # Numba's compiles in the solve, the first attempt besides


def solve_static(engine: StaticEngine, load_steps: int, max_cutbacks: int = 12,
                 on_step: Callable[[StaticStep], None] | None = None,
                 capacity: int | SearchCapacity = 64,
                 beam_names: Sequence[str] | None = None) -> StaticResult:
    """Ramp the loads from 0 to 1 and return the last converged state.

    Args:
        engine: makes the attempts (:class:`StaticEngine`; it holds the model, the
            contact problem, whose candidate set is found at the start of every load step
            and frozen during Newton, and the Newton settings).
        load_steps: nominal number of equal load increments.
        max_cutbacks: successive halvings of the increment allowed before giving up.
        on_step: called with every converged step (write results there).
        capacity: initial length of the contact candidate list, or both capacities of
            the search (:class:`SearchCapacity`); they grow on overflow.
        beam_names: the beams' names in model order, for the message when the supports
            leave a beam free (None: beams are named by number and control points).
    """
    with interrupts_kept():  # none dropped in a garbage-collection callback
        return _ramp(engine, load_steps, max_cutbacks, on_step, capacity, beam_names)


def _ramp(engine: StaticEngine, load_steps: int, max_cutbacks: int,
          on_step: Callable[[StaticStep], None] | None, capacity: int | SearchCapacity,
          beam_names: Sequence[str] | None) -> StaticResult:
    """The load stepping of :func:`solve_static`."""
    contact = engine.contact
    loop = _LoadLoop(engine, engine.initial(), 1.0 / load_steps,
                     None if contact is None else contact.first_capacity(capacity),
                     0.0 if contact is None else 0.5 * contact.reach)
    loop.dlam = loop.nominal
    # the controller of time stepping with the load factor as time: steps of at most the
    # nominal increment, halved on failure, no error estimate, no smallest step
    if contact is not None:  # complete, since the singularity check needs every block
        loop.cs, loop.capacity = engine.complete_set(loop.state, loop.margin, loop.capacity)
    if on_step is not None:
        on_step(StaticStep(0, 0.0, engine.displacement(loop.state), 0, 0,
                           engine.values(loop.state, 0.0, loop.cs)))
    singular = engine.mechanism(loop.state, loop.cs, beam_names)
    if singular is not None:
        return loop.result("failed", singular)
    while loop.lam < 1.0 - 1e-12:
        dl = min(loop.dlam, 1.0 - loop.lam)
        res = _load_attempt(loop, dl)
        if res is None:  # the candidate list or the search margin grew: redo
            continue
        kind = _rejection(res, contact)
        if kind != ctl_.ACCEPTED:
            if count_rejection(loop.ctl, kind, 0.5 * dl, 0.0, 0.0, max_cutbacks):
                return loop.result("failed", _failure(loop, res, dl, kind))
            loop.dlam = 0.5 * dl
            continue
        loop.ctl[CONSECUTIVE] = 0.0
        loop.state, loop.lam, loop.steps = engine.accept(loop.state, res), loop.reached(dl), \
            loop.steps + 1
        if on_step is not None:
            values = engine.values(loop.state, loop.lam, loop.cs)
            on_step(StaticStep(loop.steps, loop.lam, engine.displacement(loop.state),
                               res.iterations, int(loop.ctl[CUTBACKS]), values))
        raise_dropped()
        # no error estimate in statics: the increment grows back after every converged step
        loop.dlam = next_step(loop.dlam, 0.0, 0.0, loop.nominal, False, 0)
    return loop.result("completed", f"reached load factor 1 in {loop.steps} steps")


@dataclass
class _LoadLoop:
    """The host state of the load stepping between attempts (local to solve_static)."""

    engine: StaticEngine
    state: object
    nominal: float
    capacity: SearchCapacity | None
    margin: float
    lam: float = 0.0
    dlam: float = 0.0
    cs: object = None
    steps: int = 0
    iterations: int = 0
    ctl: np.ndarray = field(default_factory=lambda: ctl_.new_state(0.0, 0.0, _NO_ENERGY))
    compile_time: float | None = None  # the first solve's seconds outside Numba's compiles
    start: Stopwatch = field(default_factory=Stopwatch)

    def reached(self, dl: float) -> float:
        """The load factor after an increment dl: exactly 1 at the last (increments of
        1 / load_steps sum to 1 only within round-off, so the full load would otherwise
        be applied as 0.9999999999999999)."""
        lam = self.lam + dl
        return 1.0 if lam > 1.0 - 1e-12 else lam

    def result(self, status: str, message: str) -> StaticResult:
        return StaticResult(status, message, self.steps, self.iterations,
                            int(self.ctl[CUTBACKS]), self.lam,
                            self.engine.displacement(self.state),
                            time.perf_counter() - self.start.wall,
                            self.start.compiles() + (self.compile_time or 0.0))


def _load_attempt(loop: _LoadLoop, dl: float) -> LoadAttempt | None:
    """Newton at load factor lam + dl from the last converged state with the contact set
    frozen there; None when the candidate list overflowed or the solution left the search
    margin (both grown in ``loop``; the attempt is redone)."""
    watch = Stopwatch()
    res = loop.engine.attempt(loop.state, loop.reached(dl), loop.margin, loop.capacity)
    if isinstance(res, Overflow):
        loop.capacity = loop.engine.contact.grown(loop.capacity, res.count, res.load)
        return None
    loop.cs = res.contact_set
    if res.missing:
        loop.margin *= 4.0  # the step moved further than the margin foresaw: redo it
        return None
    if loop.compile_time is None:
        loop.compile_time = watch.outside_compiles()  # one solve, and XLA compiling it
    loop.iterations += res.iterations
    return res


# the controller's energy account is unused in statics
_NO_ENERGY = EnergyAccount(0.0, 0.0, dict.fromkeys(ctl_.DIAGNOSTICS, 0.0))


def _rejection(res: LoadAttempt, contact: ContactProblem | None) -> int:
    """Why a load step is redone with half the increment (a kind of
    :data:`~beamcontact.dynamics.control.KINDS`): Newton did not converge, or the
    solution penetrates deeper than ``max_penetration`` (the contact set is frozen at the
    start of the step, so a point that was out of reach there can pass into, or through,
    another beam or its own within one increment); ACCEPTED: accepted."""
    if not res.converged:
        return NEWTON
    if contact is not None and res.gap < -contact.max_penetration:
        return PENETRATION
    return ctl_.ACCEPTED


def _failure(loop: _LoadLoop, res: LoadAttempt, dl: float, kind: int) -> str:
    """The message of load stepping stopped after ``max_cutbacks`` successive halvings."""
    why = "Newton did not converge" if kind == NEWTON else (
        f"the smallest gap {res.gap:.3g} m is below -max_penetration = "
        f"{-loop.engine.contact.max_penetration:.3g} m")
    return (f"{why} at load factor {loop.reached(dl):.6g} "
            f"({res.iterations} iterations, residual {res.residual_norm:.3e} "
            f"from {res.initial_residual_norm:.3e}) after "
            f"{int(loop.ctl[CONSECUTIVE]) - 1} successive halvings of the load increment "
            f"(now {dl:.3g}); the last converged load factor is {loop.lam:.6g}")
