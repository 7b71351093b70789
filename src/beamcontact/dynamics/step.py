"""One attempt at a time step, fused into one jitted dispatch, and the diagnostics of a
state (energies, momentum): the device side of dynamics/driver.py's loop.

The attempt (:func:`fused_step`): predictor, contact candidates, conservative advancement
(the step is shortened before it is solved so that no point pair approaches further than
a fraction of its gap, :mod:`~beamcontact.contact.advance`), Newton on the HHT residual
(:func:`~beamcontact.dynamics.hht.hht_step`), the local error estimate
(Zienkiewicz & Xie 1991), the post-step contact checks and the diagnostics.
"""

from functools import partial

import jax
import jax.numpy as jnp

from beamcontact._persistent import persistent_jit
from beamcontact.assembly.inertia import kinetic_energy_and_momentum
from beamcontact.assembly.model import Model
from beamcontact.assembly.system import contact_energy_of, energies
from beamcontact.contact.advance import approach_ratio
from beamcontact.contact.blocks import ContactSet, FrozenContact
from beamcontact.contact.broadphase import SearchCapacity
from beamcontact.contact.obstacles import obstacle_approach_ratio, obstacle_gaps
from beamcontact.contact.problem import (
    ContactProblem,
    ContactSearch,
    candidate_gaps,
    freeze,
    missed_blocks,
    near_candidates,
)
from beamcontact.contact.select import point_weights_on_device
from beamcontact.dynamics.control import ADVANCE_FRACTION, StepFlags, total_energy
from beamcontact.dynamics.hht import DynState, hht_step, predictor

# the diagnostics of a state
DIAGNOSTICS = ("E_strain", "E_gravity", "E_ext", "E_contact", "E_kin", "p_x", "p_y")
# the quantities of one attempt (float64) and its counts (integers, the status flags first)
VALUES = ("residual_norm", "initial_residual_norm", "h", "error", "approach", "min_gap",
          "E_contact_before", "energy_floor", *DIAGNOSTICS)
COUNTS = ("flags", "iterations", "count", "count_after", "load", "load_after")


@jax.jit
def diagnostics(state: DynState, model: Model, contact: FrozenContact | None = None) -> dict:
    """Energies (contact included) and linear momentum of a state."""
    e = energies(state.u, model, 1.0, state.load_state)
    e_kin, p = kinetic_energy_and_momentum(state.u, state.v, model)
    e_con = contact_energy_of(state.u, model, contact)
    return {**e, "E_contact": e_con, "E_kin": e_kin, "p_x": p[0], "p_y": p[1]}


def host_diagnostics(state: DynState, model: Model, contact: ContactProblem | None = None,
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


@persistent_jit(static_argnames=("max_iterations", "capacity"))
def fused_step(state: DynState, model: Model, h, alpha, rtol, utol, dt_ref, motion_factor,
               search: ContactSearch | None = None, cs: ContactSet | None = None, *,
               max_iterations: int, capacity: SearchCapacity | None = None):
    """One attempt at a step of (at most) h, fused into a single dispatch.

    Predictor; candidate blocks within the law's interaction distance plus the motion,
    or for IPIP "points" the candidates with their closest-point weights
    (:func:`_closest_points`), unless ``cs`` is given (IPIP "zones", chosen on the
    host); the conservative
    advancement (:func:`_advanced_step`); the HHT-alpha Newton solve (increment tolerance
    ``utol`` scaled by (h/dt_ref)^2: the acceleration is a displacement difference over
    beta h^2); the local error estimate; the post-step contact checks; diagnostics.

    Returns (new state, values, counts): values a float64 vector of the quantities named
    in :data:`VALUES` (``h`` is the step actually taken), counts an integer vector of
    :data:`COUNTS` (the first is the :class:`~beamcontact.dynamics.control.StepFlags`);
    contact entries are 0 (min_gap NaN) without contact. Two vectors, one device-to-host
    copy each, instead of one per scalar.
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
        if cs is None and _device_pairing(search.law):
            cs, report["count"], report["load"] = _closest_points(x_pred, motion, search,
                                                                  capacity)
        elif cs is None:
            pairs, report["count"], report["load"] = near_candidates(
                x_pred, search.elements, search.reach, search.law.interaction_distance(),
                motion, capacity)
            cs = ContactSet(pairs, None, search.law)
        contact = FrozenContact(search.elements, cs, search.obstacles)
        h_used = _advanced_step(state, x0, h, search, cs)
    # no fixed floor: at short steps an increment test of a fixed size would accept
    # velocities wrong by gamma utol / (beta h); the residual test governs there, and the
    # increment test only stops Newton at the round-off of the positions
    utol_h = jnp.maximum(utol * jnp.minimum((h_used / dt_ref) ** 2, 1.0),
                         8.0 * jnp.finfo(x0.dtype).eps * jnp.max(jnp.abs(x0)))
    new, res = hht_step(state, model, h_used, alpha, rtol, utol_h, max_iterations, contact)
    beta = 0.25 * (1.0 - alpha) ** 2
    da = (new.a - state.a) * model.free
    report.update(iterations=res.iterations, residual_norm=res.residual_norm,
                  initial_residual_norm=res.initial_residual_norm, h=h_used,
                  error=h_used**2 * jnp.abs(beta - 1.0 / 6.0) * jnp.max(jnp.abs(da)))
    if search is not None:
        missing, after = _contact_after_step(new, model, x0, x_pred, motion, search, cs,
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


def _advanced_step(state: DynState, x0, h, search: ContactSearch, cs: ContactSet):
    """h, shortened so that the predictor's approach of every candidate point pair stays
    below ADVANCE_FRACTION of its gap plus the law's slack (conservative advancement)."""
    v, a = state.v.reshape(-1, 2), state.a.reshape(-1, 2)
    ratio = _approach(x0, (h * v, 0.5 * h * h * a), search, cs)
    return h * jnp.minimum(1.0, ADVANCE_FRACTION / jnp.maximum(ratio, 1e-300))


def _contact_after_step(new: DynState, model: Model, x0, x_pred, motion,
                        search: ContactSearch, cs: ContactSet, capacity: SearchCapacity):
    """The post-step contact checks: (missed a block?, {count_after, load_after, min_gap,
    approach}).

    A block is missed when the broad phase at the solution finds an interacting block the
    frozen set lacks, or when the step moved further from the predictor than the search
    margin (it may have passed blocks that were never candidates)."""
    ce, reach = search.elements, search.reach
    x_new = positions(new.u, model)
    missing, count, load, gap = missed_blocks(x_new, ce, cs.pairs, reach,
                                        search.law.interaction_distance(), capacity)
    deviation = jnp.max(jnp.linalg.norm(x_new - x_pred, axis=1))
    missing = missing | (deviation > motion + 1e-6 * reach)
    if search.obstacles is not None:
        gap = jnp.minimum(gap, jnp.min(obstacle_gaps(x_new, ce, search.obstacles)))
    return missing, {"count_after": count, "load_after": load, "min_gap": gap,
                     "approach": _approach(x0, (x_new - x0,), search, cs)}


def _approach(x0, displacements, search: ContactSearch, cs: ContactSet):
    """The largest approach ratio of the candidate point pairs and of the points against
    the obstacles (:mod:`~beamcontact.contact.advance`)."""
    slack = search.law.advance_slack()
    ratio = approach_ratio(x0, displacements, search.elements, cs.pairs, slack)
    if search.obstacles is None:
        return ratio
    return jnp.maximum(ratio, obstacle_approach_ratio(x0, displacements, search.elements,
                                                      search.obstacles, slack))


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


@jax.jit
def _predicted_x(state: DynState, model: Model, h):
    return model.x_ref + predictor(state, h).reshape(-1, 2)


@jax.jit
def positions(u, model: Model):
    """Control points (n_cp, 2) of the flat displacement u."""
    return model.x_ref + u.reshape(-1, 2)


def _device_pairing(law) -> bool:
    """Whether the law's closest pairs are chosen on the device (IPIP "points"), inside
    the fused step; "zones" are chosen on the host and passed in."""
    return law.closest_pairs and law.pairing == "points"


def _closest_points(x_pred, motion, search: ContactSearch, capacity: SearchCapacity):
    """IPIP with pairing = "points" at the predictor x_pred: candidates, gaps and the
    weights of :func:`~beamcontact.contact.select.point_weights_on_device`, blocks with a
    weight first (as the host's selection orders them); returns (set, count, load)."""
    pairs, q, count, load = candidate_gaps(x_pred, search.elements, search.reach + motion,
                                           capacity)
    W = point_weights_on_device(q, pairs, search.elements, 2.0 * motion)
    order = jnp.argsort(~jnp.any(W != 0.0, axis=(1, 2)), stable=True)
    return ContactSet(pairs[order], W[order], search.law), count, load


@partial(jax.jit, static_argnames=("capacity",))
def closest_pair_candidates(state: DynState, model: Model, h, motion_factor,
                            search: ContactSearch, *, capacity: SearchCapacity):
    """Predictor, motion bound, candidate blocks and their point-pair gaps in one dispatch,
    for the host's closest-pair selection (IPIP): (pairs, gaps, count, load, motion)."""
    motion = motion_factor * _motion(state, h)
    return (*candidate_gaps(_predicted_x(state, model, h), search.elements,
                            search.reach + motion, capacity), motion)


