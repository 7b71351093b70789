"""The contact problem on the host: model choice, parameters, and the per-step frozen set.

Each step (or load step) the candidate blocks are found by the broad phase on the
predicted configuration, with boxes grown by the interaction reach (coarse-grained:
half the cutoff; IPIP: the largest radius) plus the motion expected in the step; for
IPIP the closest pairs are selected too. The set is frozen during the Newton loop so the
tangent stays consistent; after the step the driver checks that no interacting pair was
missed (else the step is redone with a larger motion margin) and that the capacity was
enough (else it grows and the step is redone).
"""

from dataclasses import dataclass

import jax
import jax.numpy as jnp
import numpy as np

from beamcontact.contact.blocks import CHUNK, ContactSet, block_gaps, block_weights_cg
from beamcontact.contact.broadphase import box_gap_lower_bound, candidate_pairs
from beamcontact.contact.points import ContactElements, contact_elements
from beamcontact.contact.select import closest_pair_weights


@dataclass(frozen=True, eq=False)
class ContactProblem:
    """Contact settings and element data (host side).

    Attributes:
        law: "cg" or "ipip".
        elements: contact points of every element.
        params: (penalty, k, m, q_reg, cutoff) as a float64 array.
        reach: boxes grow by this (plus motion) in the broad phase.
        max_penetration: a step whose smallest gap is below -max_penetration is redone
            with a smaller time step.
        beam_of, local_element, n_elements: numbering used by the IPIP selection.
    """

    law: str
    elements: ContactElements
    params: jnp.ndarray
    reach: float
    max_penetration: float
    beam_of: np.ndarray
    local_element: np.ndarray
    n_elements: np.ndarray

    def frozen_set(self, x_pred, motion: float, capacity: int) -> tuple[ContactSet, int]:
        """Candidate blocks (and IPIP pair weights) for a step; returns (set, count)."""
        margin = jnp.asarray(self.reach + motion)
        if self.law == "cg":
            pairs, W, count = _cg_set(x_pred, self.elements, margin, capacity)
            return ContactSet(pairs, W, self.params), int(count)
        pairs, q, count = _candidate_gaps(x_pred, self.elements, margin, capacity)
        W = closest_pair_weights(np.asarray(q), np.asarray(pairs), self.beam_of,
                                 self.local_element, self.n_elements, q_active=2.0 * motion)
        return ContactSet(pairs, jnp.asarray(W), self.params), int(count)

    @property
    def all_pairs(self) -> int:
        """The largest useful capacity: the number of all element pairs of different beams,
        rounded up to whole chunks of the block kernel."""
        n = int(self.elements.pairs.shape[0]) - 1
        return -(-n // CHUNK) * CHUNK

    def capacity_for(self, count: int) -> int:
        """Candidate-list length for ``count`` candidates (see :func:`grown_capacity`)."""
        return grown_capacity(count, self.all_pairs)

    def grown_set(self, x, motion: float, capacity: int) -> tuple[ContactSet, int]:
        """:meth:`frozen_set` with the capacity grown until the candidates fit."""
        capacity = min(capacity, self.all_pairs)
        while True:
            cs, count = self.frozen_set(x, motion, capacity)
            if count <= capacity:
                return cs, capacity
            capacity = self.capacity_for(count)

    def check_step(self, x, cs: ContactSet, capacity: int) -> tuple[bool, float]:
        """After a step: (did the broad phase at x find a block the frozen set lacks,
        smallest gap over the frozen blocks, or a box bound when there are none)."""
        missing, gap, bound = _after_step(x, self.elements, cs.pairs,
                                          jnp.asarray(self.reach), capacity)
        gap = float(gap)
        return bool(missing), gap if np.isfinite(gap) else float(bound)

    def min_gap(self, x, cs: ContactSet) -> float:
        """Smallest surface gap over the frozen blocks (a box bound when there are none)."""
        return self.check_step(x, cs, cs.pairs.shape[0])[1]


def grown_capacity(count: int, limit: int | None = None) -> int:
    """A power of two with room for 1.25 times ``count`` candidates, at most ``limit`` (the
    number of all element pairs: a longer list could never fill)."""
    power = int(2 ** np.ceil(np.log2(1.25 * max(count, 1))))
    return power if limit is None else max(1, min(power, limit))


@jax.jit(static_argnames=("capacity",))
def _cg_set(x, ce, margin, capacity):
    pairs, count = candidate_pairs(x, ce, margin, capacity)
    return pairs, block_weights_cg(ce, pairs), count


@jax.jit(static_argnames=("capacity",))
def _candidate_gaps(x, ce, margin, capacity):
    pairs, count = candidate_pairs(x, ce, margin, capacity)
    return pairs, block_gaps(x, ce, pairs), count


@jax.jit(static_argnames=("capacity",))
def _after_step(x, ce, frozen_pairs, reach, capacity):
    """(some candidate at x is not frozen, smallest frozen gap, box bound of the gap)."""
    pairs, count = candidate_pairs(x, ce, reach, capacity)
    E = ce.n_elements
    key = lambda p: p[:, 0] * (E + 1) + p[:, 1]  # noqa: E731
    found = jnp.isin(key(pairs), key(frozen_pairs)) | (pairs[:, 0] >= E)
    missing = (count > capacity) | ~jnp.all(found)
    gap = jnp.min(block_gaps(x, ce, frozen_pairs))
    return missing, gap, box_gap_lower_bound(x, ce)


def build_contact(case, disc) -> ContactProblem | None:
    """The contact problem of a validated case (None for contact.model = "none")."""
    c = case.contact
    if c.model == "none" or len(disc.beams) < 2:
        return None
    betas = c.densities if len(c.densities) == len(disc.beams) else [c.densities[0]] * len(
        disc.beams)
    ce = contact_elements(disc, c.segments_per_element, betas)
    radii = [b.section.half_depth for b in disc.beams]
    q_reg = c.q_reg if c.q_reg is not None else 1e-3 * min(radii)
    params = jnp.asarray(np.array([c.penalty, c.k, c.exponent, q_reg, c.cutoff], float))
    reach = 0.5 * c.cutoff if c.model == "cg" else max(radii)
    beam_of = np.asarray(ce.beam)
    local, n_el = np.zeros_like(beam_of), np.zeros(len(disc.beams), dtype=np.int64)
    for e, b in enumerate(beam_of):
        local[e] = n_el[b]
        n_el[b] += 1
    max_pen = c.max_penetration if c.max_penetration is not None else min(radii)
    return ContactProblem(c.model, ce, params, reach, max_pen, beam_of, local, n_el)
