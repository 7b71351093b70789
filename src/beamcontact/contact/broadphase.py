"""Broad phase: element bounding boxes on a uniform grid (cell lists), fixed capacities.

A NURBS element with positive weights lies in the convex hull of its control points, so
the box of its control points contains the element's axis; boxes grown by a margin m
overlap for every pair of axes closer than 2 m. The candidates are the element pairs
whose grown boxes overlap and that may interact (:meth:`ContactElements.may_touch`:
beams allowed to touch, neighbours along one beam excluded).

Search without a list of all element pairs (the cost is linear in the number of
elements for a bounded number of neighbours per element): the grid's cells are as wide
as the largest grown box, so a box overlaps only boxes whose lower corner lies in its
own cell or one of the eight around it. Every box is keyed by the cell of its lower
corner, the keys are sorted, and each box looks at the first ``per_cell`` boxes of each of
the nine cells (found by binary search in the sorted keys). The capacities are fixed (one
compile per shape): the list holds ``blocks`` candidates and each cell is read up to
``per_cell`` boxes; the true count and the fullest cell's load are returned, and a value
above its capacity is the overflow flag that makes the host grow it and redo the step.

The list is sorted by (e1, e2) with e1 < e2, whatever the order the grid visits the
pairs in, so a list is a function of the configuration only. Padding entries point at
the sentinel element index E.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from beamcontact._jax import jax, jnp
from beamcontact.contact.points import ContactElements

# cells per axis at most (boxes further out share the last one: still found, as the
# exact box test follows); keys cx * rows + cy stay far inside int64
MAX_CELLS = float(2**24)
# the nine cells around (and including) a box's own, as (dx, dy)
_NEIGHBOURS = np.array([(dx, dy) for dx in (-1, 0, 1) for dy in (-1, 0, 1)])


class SearchCapacity(NamedTuple):
    """The fixed sizes of the search (static: a change recompiles).

    Attributes:
        blocks: length of the candidate list.
        per_cell: boxes read from each grid cell.
    """

    blocks: int
    per_cell: int

    def grown(self, count: int, load: int, limit: int) -> SearchCapacity:
        """Room for ``count`` candidates and cells of ``load`` boxes (each a power of two
        with 25 % to spare; the list at most ``limit``, the number of pairs that may
        interact)."""
        blocks = grown_capacity(count, limit) if count > self.blocks else self.blocks
        per_cell = grown_capacity(load) if load > self.per_cell else self.per_cell
        return SearchCapacity(blocks, per_cell)

    def fits(self, count: int, load: int) -> bool:
        """Whether a search that found ``count`` candidates with cells of at most ``load``
        boxes was complete."""
        return count <= self.blocks and load <= self.per_cell


def grown_capacity(count: int, limit: int | None = None) -> int:
    """A power of two with room for 1.25 times ``count``, at most ``limit``."""
    power = int(2 ** np.ceil(np.log2(1.25 * max(count, 1))))
    return power if limit is None else max(1, min(power, limit))


def element_boxes(x, ce: ContactElements, margin, xp=None):
    """Lower and upper corners of each element's grown box, shape (E, 2) each (``xp``:
    the array module, jax.numpy unless NumPy is given for a host check)."""
    xp = jnp if xp is None else xp
    cps = x[ce.conn]  # (E, n_loc, 2)
    big = xp.finfo(x.dtype).max
    lo = xp.min(xp.where(ce.loc_valid[..., None], cps, big), axis=1)
    hi = xp.max(xp.where(ce.loc_valid[..., None], cps, -big), axis=1)
    return lo - margin, hi + margin


def _cells(lo, hi):
    """Integer cell (E, 2) of every box's lower corner on a grid as wide as the widest
    box, and the number of rows that keeps the keys cx * rows + cy of the cells around
    any box distinct from every occupied cell's."""
    # a little wider than the widest box, so that round-off in the cell index never puts
    # two touching boxes two cells apart
    width = (1.0 + 1e-6) * jnp.max(hi - lo)
    width = jnp.where((width > 0.0) & jnp.isfinite(width), width, 1.0)
    rel = (lo - jnp.min(lo, axis=0)) / width
    # a float that is not finite or does not fit has no defined integer value (the
    # configuration of a diverged Newton iterate): every such box goes to cell 0 (the
    # host discards that search), and no index leaves the key range
    rel = jnp.where(jnp.isfinite(rel), jnp.clip(rel, 0.0, MAX_CELLS), 0.0)
    cell = jnp.floor(rel).astype(jnp.int64)
    # a row above the highest box and one below the lowest (cy = -1 wraps to the unused
    # row rows - 1 of the column before) are never occupied
    return cell, jnp.max(cell[:, 1]) + 3


def candidate_pairs(x, ce: ContactElements, margin, capacity: SearchCapacity):
    """Candidate element pairs (blocks, 2) at control points x, boxes grown by ``margin``.

    Returns (pairs, count, load): the list sorted by (e1, e2), e1 < e2, padded with the
    sentinel; the true number of candidates; the number of boxes in the fullest cell (0
    for a small model). Complete when ``capacity.fits(count, load)``. Models of at most
    :data:`ALL_PAIRS_LIMIT` elements test all element pairs (:func:`all_pair_candidates`),
    larger ones search the grid (:func:`grid_candidates`); both give the same list.
    """
    if ce.n_elements <= ALL_PAIRS_LIMIT:
        return all_pair_candidates(x, ce, margin, capacity)
    return grid_candidates(x, ce, margin, capacity)


# up to this many elements all E (E - 1) / 2 box tests cost less than the grid's sorts
# and binary searches (the peer drop, 26 elements: 0.5 ms per step less)
ALL_PAIRS_LIMIT = 64


def all_pair_candidates(x, ce: ContactElements, margin, capacity: SearchCapacity):
    """:func:`candidate_pairs` by the box test of every element pair (i < j, in (i, j)
    order, so the compacted list is sorted); the load is 0 (no cells)."""
    E = ce.n_elements
    if E < 2:  # no pair at all
        return (jnp.broadcast_to(ce.sentinel, (capacity.blocks, 2)), jnp.zeros((), int),
                jnp.zeros((), int))
    lo, hi = element_boxes(x, ce, margin)
    i, j = (jnp.asarray(a) for a in np.triu_indices(E, k=1))
    hit = jnp.all((lo[i] <= hi[j]) & (lo[j] <= hi[i]), axis=-1) & ce.may_touch(i, j)
    count = jnp.sum(hit)
    (idx,) = jnp.nonzero(hit, size=capacity.blocks, fill_value=0)
    real = jnp.arange(capacity.blocks) < count
    pairs = jnp.stack([jnp.where(real, i[idx], E), jnp.where(real, j[idx], E)], axis=1)
    return pairs, count, jnp.zeros((), count.dtype)


def grid_candidates(x, ce: ContactElements, margin, capacity: SearchCapacity):
    """:func:`candidate_pairs` by the uniform grid (module docstring)."""
    E = ce.n_elements
    lo, hi = element_boxes(x, ce, margin)
    cell, rows = _cells(lo, hi)
    key = cell[:, 0] * rows + cell[:, 1]
    order = jnp.argsort(key, stable=True)
    keys = key[order]
    around = ((cell[:, None, 0] + _NEIGHBOURS[:, 0]) * rows
              + cell[:, None, 1] + _NEIGHBOURS[:, 1])  # (E, 9)
    first = jnp.searchsorted(keys, around, method="sort")
    slot = first[..., None] + jnp.arange(capacity.per_cell)
    inside = jnp.minimum(slot, E - 1)
    j = order[inside]  # (E, 9, per_cell)
    i = jnp.arange(E)[:, None, None]
    hit = (slot < E) & (keys[inside] == around[..., None]) & (j > i)
    hit &= jnp.all((lo[i] <= hi[j]) & (lo[j] <= hi[i]), axis=-1)
    hit &= ce.may_touch(jnp.broadcast_to(i, j.shape), j)
    # each box's own cell (neighbour 4, offset (0, 0)) starts at first[:, 4]
    load = jnp.max(jnp.searchsorted(keys, key, side="right", method="sort") - first[:, 4])
    count = jnp.sum(hit)
    (idx,) = jnp.nonzero(hit.ravel(), size=capacity.blocks, fill_value=0)
    first = jnp.broadcast_to(i, j.shape).ravel()[idx]
    found = jnp.where(jnp.arange(capacity.blocks) < count,
                      pair_key(first, j.ravel()[idx], E), pair_key(E, E, E))
    found = jnp.sort(found)
    return jnp.stack([found // (E + 1), found % (E + 1)], axis=1), count, load


def pair_key(e1, e2, n_elements: int):
    """e1 (E + 1) + e2: one integer per element pair (the sentinel E included) that
    orders pairs by (e1, e2)."""
    return e1 * (n_elements + 1) + e2


def all_candidates(x, ce: ContactElements, margin: float) -> np.ndarray:
    """Every candidate pair (P, 2) at x on the host, sorted by (e1, e2), for one-off
    checks such as the initial overlaps, in NumPy (no JAX program): up to
    :data:`ALL_PAIRS_LIMIT` elements the tests of :func:`all_pair_candidates`, above it
    the same boxes on a grid (:func:`host_grid_pairs`); both give the list of the box
    test of every pair."""
    x = np.asarray(x, dtype=np.float64)
    E = ce.n_elements
    lo, hi = element_boxes(x, ce, margin, xp=np)
    if E <= ALL_PAIRS_LIMIT:
        i, j = np.triu_indices(E, k=1)
    else:
        beam = np.asarray(ce.beam)
        i, j = host_grid_pairs(lo, hi, beam, np.diag(np.asarray(ce.allowed)))
    hit = np.all((lo[i] <= hi[j]) & (lo[j] <= hi[i]), axis=-1) & ce.may_touch(i, j, np)
    return np.stack([i[hit], j[hit]], axis=1).astype(np.int64)


def host_grid_pairs(lo, hi, beam, own) -> tuple[np.ndarray, np.ndarray]:
    """The pairs (i, j), i < j, sorted, of boxes whose lower corners lie in neighbouring
    cells (or the same) of a grid as wide as the widest box: a superset of the pairs of
    boxes that overlap, as :func:`grid_candidates` finds them, in NumPy; pairs on one
    beam only where ``own[beam]`` (self-contact). The cost grows with the number of
    boxes and of close pairs, not with E^2 (a check of 20 000 elements was a JAX program
    compiled again for every growth of its capacities); a cell's boxes are ordered by
    beam, so that the many neighbours on a box's own beam are skipped as a range
    rather than listed and dropped."""
    E = len(lo)
    width = (1.0 + 1e-6) * float(np.max(hi - lo)) if E else 1.0
    if not (width > 0.0 and np.isfinite(width)) or not np.all(np.isfinite(lo)):
        return np.triu_indices(E, k=1)  # nothing to grid on: every pair
    cell = np.floor((lo - lo.min(axis=0)) / width).astype(np.int64)
    rows = int(cell[:, 1].max()) + 3  # a free row above and below: keys stay distinct
    n_beams = int(beam.max()) + 1
    key = cell[:, 0] * rows + cell[:, 1]
    order = np.argsort(key * n_beams + beam, kind="stable")
    keys = (key * n_beams + beam)[order]
    firsts, seconds = [], []

    def add(i, start, stop):
        count = stop - start
        total = int(count.sum())
        if total:
            within = np.arange(total) - np.repeat(np.cumsum(count) - count, count)
            i, j = np.repeat(i, count), order[np.repeat(start, count) + within]
            firsts.append(i[j > i])
            seconds.append(j[j > i])

    boxes = np.arange(E)
    for dx in (-1, 0, 1):
        for dy in (-1, 0, 1):
            near = (key + dx * rows + dy) * n_beams
            start, stop = (np.searchsorted(keys, near + b) for b in (0, n_beams))
            own_start, own_stop = (np.searchsorted(keys, near + beam + b) for b in (0, 1))
            add(boxes, start, own_start)  # the other beams, before this box's own
            add(boxes, own_stop, stop)  # and after it
            mine = own[beam]
            add(boxes[mine], own_start[mine], own_stop[mine])
    if not firsts:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    i, j = np.concatenate(firsts), np.concatenate(seconds)
    sort = np.lexsort((j, i))
    return i[sort], j[sort]


# above this many elements the lower bound of the gap compares the boxes of whole beams
# instead of elements (an E x E table of box distances, computed every step, would not
# scale)
ELEMENT_BOUND_LIMIT = 512


def box_gap_lower_bound(x, ce: ContactElements, reach):
    """A lower bound of the surface gap of every pair of points that may interact, for
    a configuration whose search with boxes grown by ``reach`` found no candidate.

    No candidate means every pair that may interact is more than 2 reach apart, so
    the gap exceeds 2 reach - 2 R_max. Tighter, from the boxes: with at most
    ELEMENT_BOUND_LIMIT elements the smallest distance of two element boxes that may
    interact, less both radii; with more, that of two different beams' boxes.
    """
    lo, hi = element_boxes(x, ce, 0.0)
    E = ce.n_elements
    if E <= ELEMENT_BOUND_LIMIT:
        e = jnp.arange(E)
        near = jnp.where(ce.may_touch(e[:, None], e[None, :]),
                         _box_distances(lo, hi) - ce.radius[:, None] - ce.radius[None, :],
                         jnp.inf)
    else:
        B = ce.n_beams
        lo = jax.ops.segment_min(lo, ce.beam, B)
        hi = jax.ops.segment_max(hi, ce.beam, B)
        radius = jax.ops.segment_max(ce.radius, ce.beam, B)
        near = jnp.where(ce.allowed & ~jnp.eye(B, dtype=bool),
                         _box_distances(lo, hi) - radius[:, None] - radius[None, :], jnp.inf)
    return jnp.maximum(jnp.min(near), 2.0 * reach - 2.0 * jnp.max(ce.radius))


def _box_distances(lo, hi):
    """Euclidean distances (n, n) between n axis-aligned boxes (0 where they overlap)."""
    sep = jnp.maximum(jnp.maximum(lo[:, None] - hi[None, :], lo[None, :] - hi[:, None]), 0.0)
    return jnp.sqrt(jnp.sum(sep**2, axis=-1))
