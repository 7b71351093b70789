"""IPIP: the closest integration-point pairs (paper Sec. 2.1), chosen once per step.

The "zones" rule runs on the host (NumPy, connected plateaus by scipy.ndimage); the
"points" rule runs on the host in statics and on the device in dynamics
(:func:`point_weights_on_device`, the same weights to the last bit, tested).

For each pair of beams, the discrete distance d(i, j) lives on the grid of their contact
points. Two rules choose the pairs that carry the penalty (``Penalty.pairing``):

* ``"zones"`` (the paper's): the local minima of d (no neighbour of the 8-neighbourhood
  is closer by more than a round-off tolerance) with a gap below ``q_active``: one pair
  per contact zone. Local minima that touch form a plateau (straight parallel beams give
  a valley of equal distances): the plateau is one zone and its middle pair is taken, or,
  for an even number of cells, the two middle pairs with weight 1/2 each, so that
  symmetric problems stay symmetric. Cells of a plateau are ordered lexicographically by
  (i, j). The number of zones jumps when a local minimum appears or vanishes, and with it
  the contact energy if the beams overlap there: this rule is not conservative.
* ``"points"``: every contact point of either beam with its closest point on the other
  beam, weight 1/2 from each side (no master and slave), a tie shared equally. Under
  self-contact, every point of a beam with its closest allowed point of the same beam. The
  contact energy sum_i 1/2 Pi(min_j d_ij) + sum_j 1/2 Pi(min_i d_ij) is a continuous
  function of the configuration (a closest partner changes only where two distances are
  equal), so set changes do not create energy; the contact is distributed along a line
  contact instead of a point force per zone (the traction the paper anticipates for
  nearly parallel beams), and the effective stiffness per length is about
  eps / (point spacing).
"""

import numpy as np


def closest_pair_weights(q: np.ndarray, pairs: np.ndarray, beam_of: np.ndarray,
                         local_element: np.ndarray, q_active: float, rtol: float = 1e-9,
                         pairing: str = "zones") -> np.ndarray:
    """Pair weights W (C, n_s, n_s) of the IPIP model from the block gaps q (C, n_s, n_s).

    Args:
        q: gaps of every point pair of every candidate block (inf for padding blocks).
        pairs: the blocks' global element indices (C, 2); padding rows are >= E.
        beam_of: beam of every global element.
        local_element: index within its beam of every global element.
        q_active: pairs with a larger gap are left out (they cannot touch in this step).
        rtol: relative tolerance of "equal distance" on plateaus and ties.
        pairing: "zones" or "points" (module docstring).
    """
    C, ns, _ = q.shape
    W = np.zeros_like(q)
    E = len(beam_of)
    real = np.where(pairs[:, 0] < E)[0]
    keys = {}
    for c in real:
        keys.setdefault((beam_of[pairs[c, 0]], beam_of[pairs[c, 1]]), []).append(c)
    rule = _zone_weights if pairing == "zones" else _point_weights
    for (b1, b2), blocks in keys.items():
        # the grid spans the candidate blocks only: every cell outside them is +inf, so
        # neither rule can choose it or be changed by it
        corners = np.array([(local_element[pairs[c, 0]] * ns, local_element[pairs[c, 1]] * ns)
                            for c in blocks])
        if b1 == b2 and pairing == "points":
            _own_point_weights(q, W, blocks, corners, rtol, q_active)
            continue
        corners -= corners.min(axis=0)
        grid = np.full(tuple(corners.max(axis=0) + ns), np.inf)
        for c, (i0, j0) in zip(blocks, corners, strict=True):
            grid[i0 : i0 + ns, j0 : j0 + ns] = q[c]
        tol = rtol * np.maximum(1.0, np.abs(np.where(np.isfinite(grid), grid, 0.0)))
        weights = rule(grid, tol, q_active)
        for c, (i0, j0) in zip(blocks, corners, strict=True):
            W[c] = weights[i0 : i0 + ns, j0 : j0 + ns]
    return W


def _own_point_weights(q, W, blocks, corners, rtol, q_active) -> None:
    """The "points" rule for the blocks of one beam with itself (self-contact), into W:
    every point with its closest point of the same beam (weight 1/2, ties shared).

    The blocks hold each pair of points once (first element before the second), so a
    point is a row of some blocks and a column of others; on the symmetric grid of
    the beam's points with itself each point is one row, the row rule chooses its
    partners, and the weight of a pair is what it got as (i, j) plus as (j, i). (On a
    grid of two beams, rows and columns are different points and both rules are
    applied.)"""
    ns = q.shape[1]
    start = corners.min()
    corners = corners - start
    n = corners.max() + ns
    grid = np.full((n, n), np.inf)
    for c, (i0, j0) in zip(blocks, corners, strict=True):
        grid[i0 : i0 + ns, j0 : j0 + ns] = q[c]
        grid[j0 : j0 + ns, i0 : i0 + ns] = q[c].T
    tol = rtol * np.maximum(1.0, np.abs(np.where(np.isfinite(grid), grid, 0.0)))
    nearest = np.min(grid, axis=1, keepdims=True)
    ties = (grid <= nearest + tol) & (nearest < q_active) & np.isfinite(grid)
    rows = np.where(ties, 0.5 / np.maximum(np.sum(ties, axis=1, keepdims=True), 1), 0.0)
    for c, (i0, j0) in zip(blocks, corners, strict=True):
        W[c] = rows[i0 : i0 + ns, j0 : j0 + ns] + rows[j0 : j0 + ns, i0 : i0 + ns].T


def _zone_weights(grid: np.ndarray, tol: np.ndarray, q_active: float) -> np.ndarray:
    """Weights on the grid of the "zones" rule: the middle of every plateau of local
    minima."""
    n1, n2 = grid.shape
    padded = np.pad(grid, 1, constant_values=np.inf)
    is_min = np.isfinite(grid) & (grid < q_active)
    for di in (-1, 0, 1):
        for dj in (-1, 0, 1):
            if di or dj:
                is_min &= grid <= padded[1 + di : n1 + 1 + di, 1 + dj : n2 + 1 + dj] + tol
    from scipy import ndimage  # its import costs 0.1 s; the native engine has its own

    labels, count = ndimage.label(is_min, structure=np.ones((3, 3)))
    weights = np.zeros_like(grid)
    for lab in range(1, count + 1):
        cells = np.argwhere(labels == lab)  # lexicographic (i, j) order
        k = len(cells)
        if k % 2:
            weights[tuple(cells[k // 2])] += 1.0
        else:
            weights[tuple(cells[k // 2 - 1])] += 0.5
            weights[tuple(cells[k // 2])] += 0.5
    return weights


def _point_weights(grid: np.ndarray, tol: np.ndarray, q_active: float) -> np.ndarray:
    """Weights on the grid of the "points" rule: each row's and each column's closest
    cells, 1/2 per side shared equally among ties."""
    weights = np.zeros_like(grid)
    for axis in (1, 0):
        nearest = np.min(grid, axis=axis, keepdims=True)
        ties = (grid <= nearest + tol) & (nearest < q_active) & np.isfinite(grid)
        share = 0.5 / np.maximum(np.sum(ties, axis=axis, keepdims=True), 1)
        weights += np.where(ties, share, 0.0)
    return weights


def point_weights_on_device(q, pairs, ce, q_active, rtol: float = 1e-9):
    """The "points" rule (:func:`_point_weights`) on the device, for the blocks' gaps q
    (C, n_s, n_s): the same weights, without the host round trip.

    The host rule works on one grid per pair of beams; here a point's closest partner on
    another beam is a segment minimum over the point's global index times the number of
    beams plus the other beam. A point of one beam under self-contact occurs on both
    sides of its blocks (as the first element of some and the second of others): the
    minimum and the tie count are taken over both sides. Equality, tie counts and shares
    use the host's arithmetic.
    """
    from beamcontact._jax import jax, jnp

    C, ns, _ = q.shape
    E = ce.n_elements
    real = pairs[:, 0] < E
    e1, e2 = jnp.minimum(pairs[:, 0], E - 1), jnp.minimum(pairs[:, 1], E - 1)
    q = jnp.where(real[:, None, None], q, jnp.inf)
    tol = rtol * jnp.maximum(1.0, jnp.abs(jnp.where(jnp.isfinite(q), q, 0.0)))
    local = jnp.arange(ns)
    n_seg = E * ns * ce.n_beams
    sides = [((own[:, None] * ns + local) * ce.n_beams + ce.beam[other][:, None], axis)
             for own, other, axis in ((e1, e2, 2), (e2, e1, 1))]  # (segment (C, ns), axis)
    nearest = jnp.minimum(*[jax.ops.segment_min(jnp.min(q, axis=axis).ravel(), seg.ravel(),
                                                n_seg) for seg, axis in sides])
    ties = [(q <= jnp.expand_dims(nearest[seg], axis) + tol)
            & (jnp.expand_dims(nearest[seg], axis) < q_active) & jnp.isfinite(q)
            for seg, axis in sides]
    count = sum(jax.ops.segment_sum(jnp.sum(t, axis=axis).ravel(), seg.ravel(), n_seg)
                for t, (seg, axis) in zip(ties, sides, strict=True))
    weights = jnp.zeros_like(q)
    for t, (seg, axis) in zip(ties, sides, strict=True):
        share = 0.5 / jnp.maximum(jnp.expand_dims(count[seg], axis), 1)
        weights = weights + jnp.where(t, share, 0.0)
    return weights
