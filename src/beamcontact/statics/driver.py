"""Load stepping with Newton-Raphson and automatic cut-back.

The load factor lam runs from 0 to 1 in ``load_steps`` equal increments. A failed Newton
solve, or a solution whose smallest contact gap is below -max_penetration (the contact set
is frozen during an increment, so a large one can carry a point through a beam),
restores the last converged state and halves the increment, up to ``max_cutbacks``
times in a row; after a success the increment grows back (doubling) to the nominal one.
This is the time stepping's controller (dynamics/control.py: ``StepControl``,
``Attempts``, ``Rejection``, ``next_step``) with the load factor as time and no error
estimate. Every converged step is handed to ``on_step`` at once, so a later failure
loses nothing.

Before the first step, a model whose supports leave some beam free to move rigidly is
checked for a singular tangent (statics/restraint.py): if neither supports nor contact
hold it, the analysis stops at once with status "failed" naming the beams, instead of
halving the load increment on NaN residuals.
"""

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import jax
import jax.numpy as jnp
import numpy as np

from beamcontact.assembly.model import LoadState, Model, initial_load_state
from beamcontact.assembly.system import (
    apply_supports,
    contact_energy_of,
    energies,
    residual_tangent_with_contact,
    update_load_state,
)
from beamcontact.contact.blocks import FrozenContact
from beamcontact.contact.broadphase import SearchCapacity
from beamcontact.contact.problem import ContactProblem, freeze
from beamcontact.dynamics.control import Attempts, Rejection, StepControl, next_step
from beamcontact.solvers.linear import to_dense
from beamcontact.solvers.newton import NewtonOptions, newton
from beamcontact.statics.restraint import beam_modes, beam_ranges, singular_tangent_message


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
    compile_time: float


@jax.jit(static_argnames=("max_iterations",))
def load_step(u0, model: Model, lam, load_state: LoadState, tolerances, max_iterations,
              contact: FrozenContact | None = None):
    """One load step, the static counterpart of ``dynamics.hht.hht_step``: Newton from the
    converged displacement u0 to equilibrium at load factor lam (the loads' rotations
    ``load_state`` of u0, the contact set frozen), as one jitted call. The init of load
    stepping is ``assembly.model.initial_load_state``."""

    def residual_tangent(u):
        r, K = residual_tangent_with_contact(u, model, lam, load_state, contact)
        return (*apply_supports(r, K, model.free), None)

    return newton(residual_tangent, u0, max_iterations, tolerances)


@jax.jit
def _energies(u, model, lam, state, contact: FrozenContact | None = None):
    return {**energies(u, model, lam, state), "E_contact": contact_energy_of(u, model, contact)}


_update = jax.jit(update_load_state)
_tangent = jax.jit(residual_tangent_with_contact)


def mechanism_message(model: Model, contact: ContactProblem | None, cs, load_state,
                      beam_names: Sequence[str] | None = None) -> str | None:
    """The reason the static tangent at u = 0 is singular, or None (statics/restraint.py).

    The tangent is assembled (at load factor 0: loads never restrain) only when some beam
    has rigid modes its supports leave free, so supported models pay nothing.
    """
    x_ref, free = np.asarray(model.x_ref), np.asarray(model.free) > 0.5
    ranges = beam_ranges([np.asarray(b.conn) for b in model.beams])
    if not any(m.shape[1] for m in beam_modes(x_ref, free, ranges)):
        return None
    if beam_names is None or len(beam_names) != len(ranges):
        labels = [f"#{i + 1} (control points {a}-{b - 1})" for i, (a, b) in enumerate(ranges)]
    else:
        labels = [repr(name) for name in beam_names]
    _, K = _tangent(jnp.zeros(model.n_dof), model, jnp.asarray(0.0), load_state,
                    freeze(contact, cs))
    return singular_tangent_message(to_dense(K), free, x_ref, ranges, labels,
                                    contact=contact is not None)


def solve_static(model: Model, load_steps: int, options: NewtonOptions, length: float,
                 max_cutbacks: int = 12,
                 on_step: Callable[[StaticStep], None] | None = None,
                 contact: ContactProblem | None = None, capacity: int | SearchCapacity = 64,
                 beam_names: Sequence[str] | None = None) -> StaticResult:
    """Ramp the loads from 0 to 1 and return the last converged state.

    Args:
        model: the discrete model.
        load_steps: nominal number of equal load increments.
        options: Newton settings.
        length: length scale of the increment tolerance.
        max_cutbacks: successive halvings of the increment allowed before giving up.
        on_step: called with every converged step (write results there).
        contact: the contact problem (None: no contact). Its candidate set is found at the
            start of every load step and frozen during Newton.
        capacity: initial length of the contact candidate list, or both capacities of
            the search (:class:`SearchCapacity`); they grow on overflow.
        beam_names: the beams' names in model order, for the message when the supports
            leave a beam free (None: beams are named by number and control points).
    """
    loop = _LoadLoop(jnp.zeros(model.n_dof), initial_load_state(model), 1.0 / load_steps,
                     None if contact is None else contact.first_capacity(capacity),
                     0.0 if contact is None else 0.5 * contact.reach)
    loop.dlam = loop.nominal
    # the controller of time stepping with the load factor as time: steps of at most the
    # nominal increment, halved on failure, no error estimate, no smallest step
    control = StepControl(loop.nominal, 0.0, 0.0, 0.0, max_cutbacks)
    tol = jnp.array([options.rtol, 0.0, options.utol * length])  # no absolute residual test
    if contact is not None:  # complete, since the singularity check needs every block
        loop.cs, loop.capacity = contact.grown_set(loop.x(model), loop.margin, loop.capacity)
    if on_step is not None:
        on_step(StaticStep(0, 0.0, np.zeros(model.n_dof), 0, 0,
                           _step_values(loop.u, model, 0.0, loop.state, contact, loop.cs)))
    singular = mechanism_message(model, contact, loop.cs, loop.state, beam_names)
    if singular is not None:
        return loop.result("failed", singular)
    while loop.lam < 1.0 - 1e-12:
        dl = min(loop.dlam, 1.0 - loop.lam)
        res = _load_attempt(loop, model, dl, tol, options, contact)
        if res is None:  # the candidate list or the search margin grew: redo
            continue
        rejection = _rejection(res, loop.gap, contact, dl)
        if rejection is not None:
            if loop.attempts.reject(rejection, control):
                return loop.result("failed", _failure(loop, res, dl, rejection))
            loop.dlam = rejection.retry
            continue
        loop.attempts.accept()
        loop.u, loop.lam, loop.steps = res.u, loop.lam + dl, loop.steps + 1
        loop.state = _update(model, loop.u, loop.state)
        if on_step is not None:
            values = _step_values(loop.u, model, loop.lam, loop.state, contact, loop.cs)
            on_step(StaticStep(loop.steps, loop.lam, np.asarray(loop.u), int(res.iterations),
                               loop.attempts.cutbacks, values))
        # no error estimate in statics: the increment grows back after every converged step
        loop.dlam = next_step(loop.dlam, 0.0, control.error_tol, control.dt, False, 0)
    return loop.result("completed", f"reached load factor 1 in {loop.steps} steps")


@dataclass
class _LoadLoop:
    """The host state of the load stepping between attempts (local to solve_static)."""

    u: jax.Array
    state: LoadState
    nominal: float
    capacity: SearchCapacity | None
    margin: float
    gap: float = float("inf")  # smallest gap of the last converged attempt
    lam: float = 0.0
    dlam: float = 0.0
    cs: object = None
    steps: int = 0
    iterations: int = 0
    attempts: Attempts = field(default_factory=Attempts)
    compile_time: float | None = None
    start: float = field(default_factory=time.perf_counter)

    def x(self, model: Model):
        return model.x_ref + self.u.reshape(-1, 2)

    def result(self, status: str, message: str) -> "StaticResult":
        return StaticResult(status, message, self.steps, self.iterations,
                            self.attempts.cutbacks,
                            self.lam, np.asarray(self.u), time.perf_counter() - self.start,
                            self.compile_time or 0.0)


def _load_attempt(loop: _LoadLoop, model: Model, dl: float, tol, options: NewtonOptions,
                  contact: ContactProblem | None):
    """Newton at load factor lam + dl from the last converged state with the contact set
    frozen there; None when the candidate list overflowed or the solution left the search
    margin (both grown in ``loop``; the attempt is redone)."""
    if contact is not None:
        loop.cs, count, load = contact.frozen_set(loop.x(model), loop.margin, loop.capacity)
        if not loop.capacity.fits(count, load):
            loop.capacity = contact.grown(loop.capacity, count, load)
            return None
    t0 = time.perf_counter()
    res = load_step(loop.u, model, jnp.asarray(loop.lam + dl), loop.state, tol,
                      max_iterations=options.max_iterations, contact=freeze(contact, loop.cs))
    if bool(res.converged) and contact is not None:
        x_new = model.x_ref + res.u.reshape(-1, 2)
        missing, loop.gap = contact.check_step(x_new, loop.cs, loop.capacity)
        if missing:
            loop.margin *= 4.0  # the step moved further than the margin foresaw: redo it
            return None
    if loop.compile_time is None:
        loop.compile_time = time.perf_counter() - t0  # first call: compile + one solve
    loop.iterations += int(res.iterations)
    return res


def _rejection(res, gap: float, contact: ContactProblem | None,
               dl: float) -> Rejection | None:
    """Why a load step is redone with half the increment: Newton did not converge, or
    the solution penetrates deeper than ``max_penetration`` (the contact set is frozen
    at the start of the step, so a point that was out of reach there can pass into, or
    through, another beam or its own within one increment); None: accepted."""
    if not bool(res.converged):
        return Rejection("newton", "Newton did not converge", 0.5 * dl)
    if contact is not None and gap < -contact.max_penetration:
        return Rejection("penetration", f"the smallest gap {gap:.3g} m is below "
                         f"-max_penetration = {-contact.max_penetration:.3g} m", 0.5 * dl)
    return None


def _failure(loop: _LoadLoop, res, dl: float, rejection: Rejection) -> str:
    """The message of load stepping stopped after ``max_cutbacks`` successive halvings."""
    return (f"{rejection.reason} at load factor {loop.lam + dl:.6g} "
            f"({int(res.iterations)} iterations, residual {float(res.residual_norm):.3e} "
            f"from {float(res.initial_residual_norm):.3e}) after "
            f"{loop.attempts.consecutive - 1} successive halvings of the load increment (now "
            f"{dl:.3g}); the last converged load factor is {loop.lam:.6g}")


def _step_values(u, model, lam, state, contact, cs) -> dict:
    if contact is None:
        d = {k: float(v) for k, v in _energies(u, model, lam, state).items()}
        d["min_gap"] = float("nan")
        return d
    d = {k: float(v) for k, v in _energies(u, model, lam, state, freeze(contact, cs)).items()}
    d["min_gap"] = contact.min_gap(model.x_ref + u.reshape(-1, 2), cs)
    return d
