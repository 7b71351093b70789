"""Broad phase: element bounding boxes from control points, fixed-capacity candidates.

A NURBS element with positive weights lies in the convex hull of its control points, so
the box of its control points contains the element's axis; boxes grown by a margin m
overlap for every pair of axes closer than 2 m. Element pairs of different beams whose
grown boxes overlap are the candidates. The list has a fixed capacity (one compile per
shape); ``count`` larger than the capacity is the overflow flag that makes the host
reallocate and redo the step.
Padding entries point at the sentinel element index E.
"""

import jax.numpy as jnp

from beamcontact.contact.points import ContactElements


def element_boxes(x, ce: ContactElements, margin):
    """Lower and upper corners of each element's grown box, shape (E, 2) each."""
    cps = x[ce.conn]  # (E, n_loc, 2)
    big = jnp.finfo(x.dtype).max
    lo = jnp.min(jnp.where(ce.loc_valid[..., None], cps, big), axis=1)
    hi = jnp.max(jnp.where(ce.loc_valid[..., None], cps, -big), axis=1)
    return lo - margin, hi + margin


def candidate_pairs(x, ce: ContactElements, margin, capacity: int):
    """Candidate element pairs (capacity, 2) and their true number (overflow if > capacity).

    Args:
        x: control points (n_cp, 2).
        ce: contact element data.
        margin: each box grows by this much, so pairs closer than 2 margin are captured.
        capacity: length of the candidate list.
    """
    lo, hi = element_boxes(x, ce, margin)
    i, j = ce.pairs[:-1, 0], ce.pairs[:-1, 1]
    overlap = jnp.all((lo[i] <= hi[j]) & (lo[j] <= hi[i]), axis=1)
    (idx,) = jnp.nonzero(overlap, size=capacity, fill_value=ce.pairs.shape[0] - 1)
    return ce.pairs[idx], jnp.sum(overlap)


def box_gap_lower_bound(x, ce: ContactElements):
    """A lower bound of the surface gap between different beams from the element boxes."""
    lo, hi = element_boxes(x, ce, 0.0)
    i, j = ce.pairs[:-1, 0], ce.pairs[:-1, 1]
    sep = jnp.maximum(jnp.maximum(lo[i] - hi[j], lo[j] - hi[i]), 0.0)
    return jnp.min(jnp.sqrt(jnp.sum(sep**2, axis=1)) - ce.radius[i] - ce.radius[j])
