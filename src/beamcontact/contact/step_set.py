"""The contact set of one time step inside the compiled attempt: choose it at the
predictor, bound the step by it, check the solution against it (docs/theory.md, "Time
stepping"). The host's counterparts for load stepping and for the IPIP "zones" rule are
in :mod:`beamcontact.contact.problem`; both call the same search and block functions.

* :func:`step_set`: the candidate blocks at the predicted configuration, culled to those
  within the law's interaction distance (integrated laws), or with the closest-point
  weights of IPIP "points" (:func:`~beamcontact.contact.select.point_weights_on_device`);
* :func:`advanced_step`: the step shortened so that no candidate point pair approaches
  further than ADVANCE_FRACTION of its gap (conservative advancement,
  :mod:`~beamcontact.contact.advance`);
* :func:`after_step`: the post-step checks: a missed block, the counts of the search at
  the solution, the smallest gap and the actual approach.
"""

from __future__ import annotations

from beamcontact._jax import jnp
from beamcontact.contact.advance import approach_ratio
from beamcontact.contact.blocks import ContactSet
from beamcontact.contact.broadphase import SearchCapacity
from beamcontact.contact.obstacles import obstacle_approach_ratio, obstacle_gaps
from beamcontact.contact.problem import (
    ContactSearch,
    candidate_gaps,
    missed_blocks,
    near_candidates,
)
from beamcontact.contact.select import point_weights_on_device
from beamcontact.dynamics.control import ADVANCE_FRACTION  # the controller's rule, no JAX


def chosen_in_step(law) -> bool:
    """Whether the law's set is chosen inside the compiled attempt: integrated laws and
    IPIP "points"; IPIP "zones" are chosen on the host and passed in."""
    return not (law.closest_pairs and law.pairing == "zones")


def step_set(x_pred, motion, search: ContactSearch, capacity: SearchCapacity):
    """The frozen set of a step at the predictor x_pred (a law chosen in the step, see
    :func:`chosen_in_step`): (set, number of box candidates, fullest cell)."""
    if search.law.closest_pairs:
        return _closest_points(x_pred, motion, search, capacity)
    pairs, count, load = near_candidates(x_pred, search.elements, search.reach,
                                         search.law.interaction_distance(), motion, capacity)
    return ContactSet(pairs, None, search.law), count, load


def _closest_points(x_pred, motion, search: ContactSearch, capacity: SearchCapacity):
    """IPIP with pairing = "points" at the predictor x_pred: candidates, gaps and the
    weights of :func:`~beamcontact.contact.select.point_weights_on_device`, blocks with a
    weight first (as the host's selection orders them); returns (set, count, load)."""
    pairs, q, count, load = candidate_gaps(x_pred, search.elements, search.reach + motion,
                                           capacity)
    W = point_weights_on_device(q, pairs, search.elements, 2.0 * motion)
    order = jnp.argsort(~jnp.any(W != 0.0, axis=(1, 2)), stable=True)
    return ContactSet(pairs[order], W[order], search.law), count, load


def advanced_step(v, a, x0, h, search: ContactSearch, cs: ContactSet):
    """h, shortened so that the predictor's approach of every candidate point pair stays
    below ADVANCE_FRACTION of its gap plus the law's slack (conservative advancement);
    v, a the control-point velocities and accelerations (n_cp, 2)."""
    ratio = approach(x0, (h * v, 0.5 * h * h * a), search, cs)
    return h * jnp.minimum(1.0, ADVANCE_FRACTION / jnp.maximum(ratio, 1e-300))


def after_step(x_new, x0, x_pred, motion, search: ContactSearch, cs: ContactSet,
               capacity: SearchCapacity):
    """The post-step contact checks at the solution x_new: (missed a block?,
    {count_after, load_after, min_gap, approach}).

    A block is missed when the broad phase at the solution finds an interacting block the
    frozen set lacks, or when the step moved further from the predictor than the search
    margin (it may have passed blocks that were never candidates)."""
    ce, reach = search.elements, search.reach
    missing, count, load, gap = missed_blocks(x_new, ce, cs.pairs, reach,
                                              search.law.interaction_distance(), capacity)
    deviation = jnp.max(jnp.linalg.norm(x_new - x_pred, axis=1))
    missing = missing | (deviation > motion + 1e-6 * reach)
    if search.obstacles is not None:
        gap = jnp.minimum(gap, jnp.min(obstacle_gaps(x_new, ce, search.obstacles)))
    return missing, {"count_after": count, "load_after": load, "min_gap": gap,
                     "approach": approach(x0, (x_new - x0,), search, cs)}


def approach(x0, displacements, search: ContactSearch, cs: ContactSet):
    """The largest approach ratio of the candidate point pairs and of the points against
    the obstacles (:mod:`~beamcontact.contact.advance`)."""
    slack = search.law.advance_slack()
    ratio = approach_ratio(x0, displacements, search.elements, cs.pairs, slack)
    if search.obstacles is None:
        return ratio
    return jnp.maximum(ratio, obstacle_approach_ratio(x0, displacements, search.elements,
                                                      search.obstacles, slack))
