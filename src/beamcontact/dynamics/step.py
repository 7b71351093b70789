"""The JAX engine of the time loop: one attempt at a time step fused into one jitted
dispatch, and the diagnostics of a state (energies, momentum).

The attempt (:func:`fused_attempt`): predictor, the contact set of the step and the
conservative advancement (:mod:`~beamcontact.contact.step_set`: the step is shortened
before it is solved so that no point pair approaches further than a fraction of its
gap), Newton on the HHT residual (:func:`~beamcontact.dynamics.hht.hht_step`), the local
error estimate (Zienkiewicz & Xie 1991), the post-step contact checks and the
diagnostics. :class:`JaxEngine` is what the driver (dynamics/driver.py) calls.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from beamcontact._jax import jax, jnp, lazy_jit, on_device
from beamcontact._persistent import persistent_jit
from beamcontact._x64 import require_x64
from beamcontact.assembly.inertia import kinetic_energy_and_momentum
from beamcontact.assembly.model import Model
from beamcontact.assembly.system import contact_energy_of, energies
from beamcontact.contact.blocks import ContactSet, FrozenContact
from beamcontact.contact.broadphase import SearchCapacity
from beamcontact.contact.problem import ContactProblem, ContactSearch, candidate_gaps, freeze
from beamcontact.contact.step_set import advanced_step, after_step, chosen_in_step, step_set
from beamcontact.dynamics.hht import DynState, hht_step, predictor
from beamcontact.dynamics.report import (
    COUNTS,
    VALUES,
    Attempt,
    Overflow,
    StepFlags,
)
from beamcontact.solvers.newton import NewtonOptions


@lazy_jit
def diagnostics(state: DynState, model: Model, contact: FrozenContact | None = None) -> dict:
    """Energies (contact included) and linear momentum of a state."""
    e = energies(state.u, model, 1.0, state.load_state)
    e_kin, p = kinetic_energy_and_momentum(state.u, state.v, model)
    e_con = contact_energy_of(state.u, model, contact)
    return {**e, "E_contact": e_con, "E_kin": e_kin, "p_x": p[0], "p_y": p[1]}


@persistent_jit(static_argnames=("max_iterations", "capacity"))
def fused_attempt(state: DynState, model: Model, h, alpha, rtol, utol, etol, dt_ref,
                  motion_factor, search: ContactSearch | None = None,
                  cs: ContactSet | None = None, *,
                  max_iterations: int, capacity: SearchCapacity | None = None):
    """One attempt at a step of (at most) h, fused into a single dispatch.

    Predictor; the contact set at the predictor
    (:func:`~beamcontact.contact.step_set.step_set`), unless ``cs`` is given (IPIP
    "zones", chosen on the host); the conservative advancement
    (:func:`~beamcontact.contact.step_set.advanced_step`); the HHT-alpha Newton solve
    (increment tolerance ``utol`` scaled by (h/dt_ref)^2: the acceleration is a
    displacement difference over beta h^2; ``etol`` the bound of the error left in an
    iterate, None without that test); the local error estimate; the post-step
    contact checks (:func:`~beamcontact.contact.step_set.after_step`); diagnostics.

    Returns (new state, values, counts): values a float64 vector of the quantities named
    in :data:`~beamcontact.dynamics.report.VALUES` (``h`` is the step actually taken),
    counts an integer vector of :data:`~beamcontact.dynamics.report.COUNTS` (the first is
    the :class:`~beamcontact.dynamics.report.StepFlags`); contact entries are 0 (min_gap
    NaN) without contact. Two vectors, one device-to-host copy each, instead of one per
    scalar.
    """
    report = dict.fromkeys(VALUES + COUNTS, jnp.zeros((), jnp.int64))
    report.update(dict.fromkeys(VALUES, jnp.zeros(())))
    report["min_gap"] = jnp.asarray(jnp.nan)
    missing = jnp.asarray(False)
    motion = motion_factor * _motion(state, h)
    x_pred = _predicted_x(state, model, h)
    x0 = positions(state.u, model)
    h_used = h
    contact = None
    if search is not None:
        if cs is None:
            cs, report["count"], report["load"] = step_set(x_pred, motion, search, capacity)
        contact = FrozenContact(search.elements, cs, search.obstacles)
        h_used = advanced_step(state.v.reshape(-1, 2), state.a.reshape(-1, 2), x0, h, search,
                               cs)
    # no fixed floor: at short steps an increment test of a fixed size would accept
    # velocities wrong by gamma utol / (beta h); the residual test governs there, and the
    # increment test only stops Newton at the round-off of the positions
    utol_h = jnp.maximum(utol * jnp.minimum((h_used / dt_ref) ** 2, 1.0),
                         8.0 * jnp.finfo(x0.dtype).eps * jnp.max(jnp.abs(x0)))
    new, res = hht_step(state, model, h_used, alpha, rtol, utol_h, max_iterations, contact,
                        etol)
    beta = 0.25 * (1.0 - alpha) ** 2
    da = (new.a - state.a) * model.free
    # a tied end point is a control point of the curve like the others: its error counts
    da_max = jnp.maximum(jnp.max(jnp.abs(da)),
                         jnp.max(jnp.abs((new.a - state.a)[model.tied]), initial=0.0))
    report.update(iterations=res.iterations, residual_norm=res.residual_norm,
                  initial_residual_norm=res.initial_residual_norm, h=h_used,
                  error=h_used**2 * jnp.abs(beta - 1.0 / 6.0) * da_max)
    if search is not None:
        missing, after = after_step(positions(new.u, model), x0, x_pred, motion, search, cs,
                                    capacity)
        report.update(after)
    report.update(diagnostics(new, model, contact))
    # energies of the two states are compared under the same frozen set; the jump from
    # the previous step's set to this one is accounted separately (E_set_change)
    report["E_contact_before"] = contact_energy_of(state.u, model, contact)
    report["energy_floor"] = _energy_floor(state, new, model, report["E_kin"], utol_h, alpha,
                                           h_used)
    report["flags"] = (jnp.where(res.converged, int(StepFlags.CONVERGED), 0)
                       + jnp.where(missing, int(StepFlags.MISSING_BLOCK), 0))
    return (new, jnp.stack([jnp.asarray(report[k], jnp.float64) for k in VALUES]),
            jnp.stack([jnp.asarray(report[k], jnp.int64) for k in COUNTS]))


def _energy_floor(state: DynState, new: DynState, model: Model, e_kin_new, utol_h, alpha,
                  h):
    """What the converged solve can resolve of the energy: the forces times the increment
    tolerance, and the kinetic energy times the velocity that increment implies
    (gamma du / (beta h))."""
    beta = 0.25 * (1.0 - alpha) ** 2
    kinetic = jnp.maximum(e_kin_new, kinetic_energy_and_momentum(state.u, state.v, model)[0])
    return utol_h * (
        jnp.sum(jnp.abs(state.f_pot * model.free)) + jnp.sum(jnp.abs(new.f_pot * model.free))
        + (0.5 - alpha) / (beta * h) * jnp.sqrt(2.0 * kinetic * total_mass(model)))


def total_mass(model: Model):
    """Mass of all beams (rho A integrated over the reference arc length)."""
    return sum(jnp.sum(b.rho_area[:, None] * b.wq * jnp.sqrt(b.g_ref)) for b in model.beams)


def _motion(state: DynState, h):
    """Largest distance a control point may travel in a step of size h (x2 for safety)."""
    v, a = jnp.max(jnp.abs(state.v)), jnp.max(jnp.abs(state.a))
    return 2.0 * jnp.sqrt(2.0) * (v * h + 0.5 * a * h * h)


@lazy_jit
def _predicted_x(state: DynState, model: Model, h):
    return model.x_ref + predictor(state, h).reshape(-1, 2)


@lazy_jit
def positions(u, model: Model):
    """Control points (n_cp, 2) of the flat displacement u."""
    return model.x_ref + u.reshape(-1, 2)


@lazy_jit(static_argnames=("capacity",))
def closest_pair_candidates(state: DynState, model: Model, h, motion_factor,
                            search: ContactSearch, *, capacity: SearchCapacity):
    """Predictor, motion bound, candidate blocks and their point-pair gaps in one dispatch,
    for the host's closest-pair selection (IPIP): (pairs, gaps, count, load, motion)."""
    motion = motion_factor * _motion(state, h)
    return (*candidate_gaps(_predicted_x(state, model, h), search.elements,
                            search.reach + motion, capacity), motion)




class JaxEngine:
    """The JAX engine of the time loop (docs/architecture.md, "Engines"): one attempt is
    one fused dispatch (:func:`fused_attempt`); IPIP "zones" are chosen on the host before
    it (:meth:`ContactProblem.closest_pair_set`).

    The driver (dynamics/driver.py) calls :meth:`attempt`, :meth:`energies` and
    :meth:`at_time`; it sees the state only as an opaque value and the report as Python
    numbers.
    """

    name = "jax"
    fixed_capacity = True

    def __init__(self, model: Model, contact: ContactProblem | None, alpha: float,
                 options: NewtonOptions, length: float, dt_ref: float):
        require_x64()  # the model moves to the device here: never in float32
        self.model, self.options = on_device(model), options
        self.contact = None if contact is None else contact.on_device()
        # host scalars as NumPy float64: strongly typed like the arrays they replace, and
        # passed to the jitted step without eager device operations
        # without the error test (fixed steps) no etol at all: Newton then solves once per
        # iteration (solvers/newton.py)
        self._scalars = (np.float64(alpha), np.float64(options.rtol),
                         np.float64(options.utol * length),
                         np.float64(options.etol * length) if options.etol > 0 else None,
                         np.float64(dt_ref))
        self._search = None if contact is None else self.contact.search

    def attempt(self, state: DynState, h: float, motion_factor: float,
                capacity: SearchCapacity | None) -> Attempt | Overflow:
        """One attempt at a step of (at most) h from ``state``, or the :class:`Overflow`
        of the host's "zones" selection."""
        cs = None
        if self.contact is not None and not chosen_in_step(self.contact.law):
            cs = self._zone_set(state, h, motion_factor, capacity)
            if isinstance(cs, Overflow):
                return cs
        new, values, counts = fused_attempt(
            state, self.model, np.float64(h), *self._scalars, np.float64(motion_factor),
            self._search, cs, max_iterations=self.options.max_iterations, capacity=capacity)
        values, counts = jax.device_get((values, counts))
        return Attempt(new, np.asarray(values, np.float64), np.asarray(counts, np.int64))

    def _zone_set(self, state: DynState, h: float, motion_factor: float,
                  capacity: SearchCapacity) -> ContactSet | Overflow:
        """The IPIP "zones" set of an attempt, chosen on the host."""
        pairs, q, count, load, motion = jax.device_get(closest_pair_candidates(
            state, self.model, np.float64(h), np.float64(motion_factor), self._search,
            capacity=capacity))
        if not capacity.fits(int(count), int(load)):
            return Overflow(int(count), int(load))
        return self.contact.closest_pair_set(pairs, q, float(motion))

    def energies(self, state: DynState, capacity: SearchCapacity | None) -> dict:
        """The diagnostics (:data:`~beamcontact.dynamics.report.DIAGNOSTICS`) of ``state``
        under the contact set at its configuration (the energy account's start, and the
        first row of a run), with the smallest surface gap (NaN without contact)."""
        if self.contact is None:
            return {**{k: float(v) for k, v in diagnostics(state, self.model).items()},
                    "min_gap": float("nan")}
        x = positions(state.u, self.model)
        cs = self.contact.grown_set(x, 0.0, capacity)[0]
        return {**{k: float(v) for k, v in
                   diagnostics(state, self.model, freeze(self.contact, cs)).items()},
                "min_gap": self.contact.min_gap(x, cs)}

    def at_time(self, state: DynState, t: float) -> DynState:
        """``state`` with its time set to t (the driver snaps times onto its grid)."""
        return replace(state, t=jnp.asarray(t))

    @staticmethod
    def time(state: DynState) -> float:
        """The time of ``state``."""
        return float(state.t)
