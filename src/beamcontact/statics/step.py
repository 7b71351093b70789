"""The JAX engine of load stepping: one attempt at a load step (the contact set chosen at
the last converged state, Newton to equilibrium at the new load factor as one jitted
call, the contact checks at the solution), the energies of a state and the check of a
singular tangent (statics/restraint.py). :class:`JaxStatics` is what the load loop
(statics/driver.py) calls.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from beamcontact._jax import jax, jnp, lazy_jit, on_device, pytree
from beamcontact._x64 import require_x64
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
from beamcontact.dynamics.report import Overflow
from beamcontact.solvers.linear import to_dense
from beamcontact.solvers.newton import NewtonOptions, newton
from beamcontact.statics.restraint import beam_modes, beam_ranges, singular_tangent_message


@pytree
@dataclass(frozen=True)
class StaticState:
    """A converged state of load stepping: the displacement and the loads' rotations."""

    u: jax.Array
    load_state: LoadState


@dataclass(frozen=True)
class LoadAttempt:
    """One attempt at a load step: the solution (meaningful if converged), Newton's
    outcome, the contact set it was solved with (None without contact), the smallest
    gap at the solution (inf without contact or when not converged) and whether the
    solution left the search margin (a block may have been missed: redo wider)."""

    u: jax.Array
    converged: bool
    iterations: int
    residual_norm: float
    initial_residual_norm: float
    contact_set: object
    gap: float
    missing: bool


@lazy_jit(static_argnames=("max_iterations",))
def load_step(u0, model: Model, lam, load_state: LoadState, tolerances, max_iterations,
              contact: FrozenContact | None = None):
    """One load step, the static counterpart of ``dynamics.hht.hht_step``: Newton from the
    converged displacement u0 to equilibrium at load factor lam (the loads' rotations
    ``load_state`` of u0, the contact set frozen), as one jitted call."""

    def residual_tangent(u):
        r, K = residual_tangent_with_contact(u, model, lam, load_state, contact)
        return (*apply_supports(r, K, model.free), None)

    return newton(residual_tangent, u0, max_iterations, tolerances)


@lazy_jit
def _energies(u, model, lam, state, contact: FrozenContact | None = None):
    return {**energies(u, model, lam, state), "E_contact": contact_energy_of(u, model, contact)}


_update = lazy_jit(update_load_state)
_tangent = lazy_jit(residual_tangent_with_contact)


def mechanism_message(model: Model, contact: ContactProblem | None, cs, load_state,
                      beam_names=None) -> str | None:
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


class JaxStatics:
    """The JAX engine of load stepping (docs/architecture.md, "Engines")."""

    name = "jax"

    def __init__(self, model: Model, contact: ContactProblem | None, options: NewtonOptions,
                 length: float):
        require_x64()  # the model moves to the device here: never in float32
        self.model, self.options = on_device(model), options
        self.contact = None if contact is None else contact.on_device()
        # no absolute residual test in statics
        self._tol = jnp.array([options.rtol, 0.0, options.utol * length])

    def initial(self) -> StaticState:
        """The unloaded reference state."""
        return StaticState(jnp.zeros(self.model.n_dof),
                           on_device(initial_load_state(self.model)))

    def _x(self, u):
        return self.model.x_ref + u.reshape(-1, 2)

    def complete_set(self, state: StaticState, margin: float, capacity: SearchCapacity):
        """The contact set at ``state`` with the capacities grown until it is complete:
        (set, capacities)."""
        return self.contact.grown_set(self._x(state.u), margin, capacity)

    def attempt(self, state: StaticState, lam: float, margin: float,
                capacity: SearchCapacity | None) -> LoadAttempt | Overflow:
        """Newton at load factor lam from ``state`` with the contact set frozen there (its
        candidates grown by ``margin``), and the contact checks at the solution."""
        cs = None
        if self.contact is not None:
            cs, count, load = self.contact.frozen_set(self._x(state.u), margin, capacity)
            if not capacity.fits(count, load):
                return Overflow(count, load)
        res = load_step(state.u, self.model, jnp.asarray(lam), state.load_state, self._tol,
                        max_iterations=self.options.max_iterations,
                        contact=freeze(self.contact, cs))
        converged, gap, missing = bool(res.converged), float("inf"), False
        if converged and self.contact is not None:
            missing, gap = self.contact.check_step(self._x(res.u), cs, capacity)
        return LoadAttempt(res.u, converged, int(res.iterations), float(res.residual_norm),
                           float(res.initial_residual_norm), cs, gap, missing)

    def accept(self, state: StaticState, attempt: LoadAttempt) -> StaticState:
        """The state of an accepted attempt: its displacement, the loads' rotations
        continued to it."""
        return StaticState(attempt.u, _update(self.model, attempt.u, state.load_state))

    def values(self, state: StaticState, lam: float, cs) -> dict:
        """Energies (contact included) and the smallest gap (NaN without contact)."""
        u, model = state.u, self.model
        if self.contact is None:
            d = {k: float(v) for k, v in _energies(u, model, lam, state.load_state).items()}
            d["min_gap"] = float("nan")
            return d
        d = {k: float(v) for k, v in
             _energies(u, model, lam, state.load_state, freeze(self.contact, cs)).items()}
        d["min_gap"] = self.contact.min_gap(self._x(u), cs)
        return d

    def mechanism(self, state: StaticState, cs, beam_names) -> str | None:
        """Why the tangent at the reference state is singular, or None."""
        return mechanism_message(self.model, self.contact, cs, state.load_state, beam_names)

    @staticmethod
    def displacement(state: StaticState) -> np.ndarray:
        """The displacement of ``state`` on the host."""
        return np.asarray(state.u)
