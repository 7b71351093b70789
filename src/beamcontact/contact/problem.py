"""The contact problem on the host: the law, the contact points, and the per-step frozen set.

Each step (or load step) the candidate blocks are found by the broad phase on the
predicted configuration, with boxes grown by the law's search reach (coarse-grained:
half the cutoff; IPIP: the largest radius) plus the motion expected in the step; an
integrated law then keeps only the blocks with a point pair closer than its interaction
distance plus twice the motion (:func:`near_blocks`); for a closest-pair law (IPIP) the
closest pairs are selected on the host.
The set is frozen during the Newton loop so the tangent stays consistent; after the step
the driver checks that no interacting block was missed (:func:`missed_blocks`; else the
step is redone with a larger motion margin) and that the capacities were enough (else
they grow and the step is redone).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from beamcontact._jax import jnp, lazy_jit, on_device, pytree
from beamcontact.contact.blocks import (
    CHUNK,
    ContactSet,
    FrozenContact,
    block_distances,
    block_gaps,
    near_blocks,
)
from beamcontact.contact.broadphase import (
    SearchCapacity,
    box_gap_lower_bound,
    candidate_pairs,
    pair_key,
)
from beamcontact.contact.laws import ContactLaw
from beamcontact.contact.obstacles import Obstacles, obstacle_gaps
from beamcontact.contact.points import ContactElements
from beamcontact.contact.select import closest_pair_weights


@pytree
@dataclass(frozen=True)
class ContactSearch:
    """What a jitted step needs to find and check its own contact set: the contact points,
    the law (its interaction distance and advancement slack) and the box growth
    ``reach`` of the broad phase."""

    elements: ContactElements
    law: ContactLaw
    reach: float
    obstacles: Obstacles | None = None


@dataclass(frozen=True, eq=False)
class ContactProblem:
    """Contact settings and element data (host side).

    Attributes:
        law: the contact law (:mod:`beamcontact.contact.laws`).
        elements: contact points of every element.
        reach: boxes grow by this (plus motion) in the broad phase (the law's
            ``search_reach`` for the largest radius).
        max_penetration: a step whose smallest gap is below -max_penetration is redone
            with a smaller time step.
        beam_of, local_element: numbering used by the closest-pair selection.
        obstacles: the rigid obstacles every beam touches (None: none;
            :mod:`beamcontact.contact.obstacles`).
    """

    law: ContactLaw
    elements: ContactElements
    reach: float
    max_penetration: float
    beam_of: np.ndarray
    local_element: np.ndarray
    obstacles: Obstacles | None = None

    @property
    def interaction(self) -> float:
        """Centre-line distance beyond which a point pair contributes nothing (inf: every
        box candidate is kept)."""
        return float(self.law.interaction_distance())

    def on_device(self) -> ContactProblem:
        """This problem with its contact points and obstacles as JAX arrays on the
        default device (:func:`beamcontact._jax.on_device`; the JAX engine's copy)."""
        return replace(self, elements=on_device(self.elements),
                       obstacles=None if self.obstacles is None else on_device(self.obstacles))

    @property
    def search(self) -> ContactSearch:
        """The device-side data of the search (:class:`ContactSearch`)."""
        return ContactSearch(self.elements, self.law, self.reach, self.obstacles)

    def frozen_set(self, x_pred, motion: float,
                   capacity: SearchCapacity) -> tuple[ContactSet, int, int]:
        """Candidate blocks (and closest-pair weights) for a step; returns (set, count,
        load), complete when ``capacity.fits(count, load)``."""
        if not self.law.closest_pairs:
            pairs, count, load = _near_set(x_pred, self.elements, jnp.asarray(self.reach),
                                           jnp.asarray(self.interaction), jnp.asarray(motion),
                                           capacity=capacity)
            return ContactSet(pairs, None, self.law), int(count), int(load)
        pairs, q, count, load = _candidate_gaps(x_pred, self.elements,
                                                jnp.asarray(self.reach + motion), capacity)
        return self.closest_pair_set(pairs, q, motion), int(count), int(load)

    def closest_pair_set(self, pairs, q, motion: float) -> ContactSet:
        """The IPIP set from the candidate blocks and their gaps: the closest pairs chosen
        on the host (:func:`closest_pair_weights`), blocks with a chosen pair first so
        that the kernels skip the rest chunk by chunk."""
        pairs, q = np.asarray(pairs), np.asarray(q)
        W = closest_pair_weights(q, pairs, self.beam_of, self.local_element,
                                 q_active=2.0 * motion, pairing=self.law.pairing)
        order = np.argsort(~W.any(axis=(1, 2)), kind="stable")
        return ContactSet(pairs[order], W[order], self.law)

    @property
    def all_pairs(self) -> int:
        """The largest useful list length: the number of element pairs that may
        interact, rounded up to whole chunks of the block kernel."""
        n = self.elements.element_pair_count()
        return max(-(-n // CHUNK) * CHUNK, CHUNK)

    def first_capacity(self, blocks: int | SearchCapacity) -> SearchCapacity:
        """The capacities to start a run with: ``blocks`` candidates (at most
        :attr:`all_pairs`) and 16 boxes per cell, or the given capacities (the list
        shortened to at most :attr:`all_pairs`)."""
        if isinstance(blocks, SearchCapacity):
            return blocks._replace(blocks=min(blocks.blocks, self.all_pairs))
        return SearchCapacity(min(blocks, self.all_pairs), 16)

    def grown(self, capacity: SearchCapacity, count: int, load: int) -> SearchCapacity:
        """Capacities with room for ``count`` candidates and cells of ``load`` boxes."""
        return capacity.grown(count, load, self.all_pairs)

    def grown_set(self, x, motion: float,
                  capacity: SearchCapacity | int) -> tuple[ContactSet, SearchCapacity]:
        """:meth:`frozen_set` with the capacities grown until the search is complete (an
        int: the list length to start from, see :meth:`first_capacity`)."""
        capacity = self.first_capacity(capacity)
        while True:
            cs, count, load = self.frozen_set(x, motion, capacity)
            if capacity.fits(count, load):
                return cs, capacity
            capacity = self.grown(capacity, count, load)

    def check_step(self, x, cs: ContactSet, capacity: SearchCapacity) -> tuple[bool, float]:
        """After a step: (did the broad phase at x find an interacting block the frozen set
        lacks, or overflow; smallest surface gap, see :func:`missed_blocks`)."""
        missing, count, load, gap = _after_step(x, self.elements, cs.pairs,
                                                jnp.asarray(self.reach),
                                                jnp.asarray(self.interaction), capacity)
        missing = bool(missing) or not capacity.fits(int(count), int(load))
        return missing, min(float(gap), self._obstacle_gap(x))

    def _obstacle_gap(self, x) -> float:
        """Smallest gap of a contact point to an obstacle (inf without obstacles)."""
        if self.obstacles is None:
            return np.inf
        return float(_smallest_obstacle_gap(x, self.elements, self.obstacles))

    def min_gap(self, x, cs: ContactSet) -> float:
        """Smallest surface gap at x (see :func:`missed_blocks`), the capacities grown
        until the search is complete."""
        capacity = self.first_capacity(cs.pairs.shape[0])
        while True:
            _, count, load, gap = _after_step(x, self.elements, cs.pairs,
                                              jnp.asarray(self.reach),
                                              jnp.asarray(self.interaction), capacity)
            if capacity.fits(int(count), int(load)):
                return min(float(gap), self._obstacle_gap(x))
            capacity = self.grown(capacity, int(count), int(load))


def near_candidates(x, ce, reach, interaction, motion, capacity: SearchCapacity):
    """Blocks of an integrated law to freeze at the predicted x: the box candidates (grown
    by reach + motion) culled to those with a point pair closer than
    interaction + 2 motion; returns (pairs, number of box candidates, fullest cell)."""
    pairs, count, load = candidate_pairs(x, ce, reach + motion, capacity)
    return near_blocks(x, ce, pairs, interaction + 2.0 * motion), count, load


_near_set = lazy_jit(near_candidates, static_argnames=("capacity",))


def candidate_gaps(x, ce, margin, capacity: SearchCapacity):
    """IPIP candidates at x: (pairs, the gaps of all their point pairs, count, load)."""
    pairs, count, load = candidate_pairs(x, ce, margin, capacity)
    return pairs, block_gaps(x, ce, pairs), count, load


_candidate_gaps = lazy_jit(candidate_gaps, static_argnames=("capacity",))


def missed_blocks(x, ce, frozen_pairs, reach, interaction, capacity: SearchCapacity):
    """Checks after a step at x: (an interacting block is not in ``frozen_pairs``, number
    of box candidates, fullest cell, smallest surface gap).

    Candidates: blocks whose boxes grown by ``reach`` overlap; interacting: a candidate
    with a point pair closer than ``interaction`` (inf: every candidate). The gap is the
    smallest over the point pairs of the candidates (all pairs within 2 reach), or, when
    there are none, a lower bound from the boxes (:func:`box_gap_lower_bound`, then larger
    than 2 reach - R1 - R2).
    """
    pairs, count, load = candidate_pairs(x, ce, reach, capacity)
    E = ce.n_elements
    key = lambda p: pair_key(p[:, 0], p[:, 1], E)  # noqa: E731
    d = block_distances(x, ce, pairs)
    near = jnp.min(d, axis=(1, 2)) < interaction
    frozen = jnp.sort(key(frozen_pairs))  # membership by binary search: linear, not C^2
    at = jnp.searchsorted(frozen, key(pairs), method="sort")
    at = jnp.minimum(at, frozen.shape[0] - 1)
    found = (frozen[at] == key(pairs)) | (pairs[:, 0] >= E) | ~near
    gap = jnp.min(block_gaps(x, ce, pairs, d))
    gap = jnp.where(jnp.isfinite(gap), gap, box_gap_lower_bound(x, ce, reach))
    return ~jnp.all(found), count, load, gap


_after_step = lazy_jit(missed_blocks, static_argnames=("capacity",))


@lazy_jit
def _smallest_obstacle_gap(x, ce, obstacles):
    return jnp.min(obstacle_gaps(x, ce, obstacles))


def freeze(contact: ContactProblem | None, cs: ContactSet | None) -> FrozenContact | None:
    """The contact of one step for the assembly (None without contact)."""
    return None if contact is None else FrozenContact(contact.elements, cs, contact.obstacles)
