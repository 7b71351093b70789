"""Conservative advancement: how far the point pairs of a step approach each other.

Tunnelling (one beam passing through another within a step, so that neither end of the
step shows a contact) is excluded by bounding, for every point pair (i, j) of the
candidate blocks, the relative displacement towards each other along the step:

    approach_ij = max(0, -n_ij . (dr_ij)),   n_ij = r_ij / |r_ij| at the start of the step,

against the pair's gap at the start, q_ij = |r_ij| - R_i - R_j, plus a slack s (the
regularisation gap q_reg for the coarse-grained potential, whose force is continued
linearly below q_reg; the admitted penetration ``max_penetration`` for IPIP, whose force
acts only for q < 0):

    approach_ij <= c (q_ij + s)   for every pair with q_ij + s > s / 100.

Since |r(t)| >= n . r(t) = |r| - approach, a relative path that is a straight line keeps
its gap above (1 - c) q - c s: a pair outside contact can neither cross the other beam
nor penetrate deeper than c s in one step. Pairs already within s / 100 of that depth
are in contact and left to the contact law (bounding them would shrink the steps
geometrically without end, a Zeno sequence). Before the solve the bound is applied to the
predictor's motion split into its velocity and acceleration parts (each counted only when
it approaches, so that the bound scales at least linearly when the step shrinks); after
the solve, to the actual displacement of the step.
"""

from __future__ import annotations

from beamcontact._jax import jnp
from beamcontact.contact.blocks import _block_geometry, over_real_chunks, point_mask
from beamcontact.contact.points import ContactElements


def approach_ratio(x0, displacements, ce: ContactElements, pairs, slack):
    """Largest approach_ij / (q_ij + s) over the point pairs of the blocks ``pairs``.

    Args:
        x0: control points at the start of the step (n_cp, 2).
        displacements: control-point displacement fields (n_cp, 2); the approach is the
            sum of the approaching parts of each (one field: the actual motion; two:
            the predictor's h v and h^2 a / 2).
        pairs: candidate blocks (C, 2), padding rows >= E.
        slack: s, the distance added to the gap (see the module docstring).

    Returns 0 when no pair approaches; pairs with less room than s / 100 are left out
    (they are in contact: the contact law, not the advancement, governs them).
    """

    def largest(chunk):  # per block of the chunk
        (_, _, r1, _), (_, _, r2, _), r = _block_geometry(x0, ce, chunk)
        d = jnp.sqrt(jnp.sum(r * r, axis=-1))
        n = r / jnp.maximum(d, 1e-300)[..., None]
        approach = 0.0
        for field in displacements:
            dr = _block_geometry(field, ce, chunk)[2]
            approach = approach + jnp.maximum(-jnp.sum(n * dr, axis=-1), 0.0)
        room = d - (r1 + r2)[:, None, None] + slack
        real = point_mask(ce, chunk) & (room > 1e-2 * slack)
        return jnp.max(jnp.where(real, approach / jnp.where(real, room, 1.0), 0.0),
                       axis=(1, 2), initial=0.0)

    return jnp.max(over_real_chunks(largest, ce, pairs, 0.0), initial=0.0)
