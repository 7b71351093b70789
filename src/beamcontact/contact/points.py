"""Contact integration points (paper Sec. 2.1, Fig. 2) and the element data of contact.

Each element is split into ``segments_per_element`` segments of equal parameter length,
with one point at the middle of each and the segment's reference arc length as weight.
All elements of all beams are numbered globally; basis rows are padded to the largest
number of local control points (padding rows of R are zero).
"""

from dataclasses import dataclass, field

import jax
import jax.numpy as jnp
import numpy as np

from beamcontact._x64 import as_float
from beamcontact.spline import nurbs_basis_derivatives


@jax.tree_util.register_dataclass
@dataclass(frozen=True)
class ContactElements:
    """Per global element: shapes conn, loc_valid (E, n_loc); R (E, n_s, n_loc);
    w (E, n_s); radius, beta (E,); beam (E,) beam index; pairs (P + 1, 2) all element
    pairs of different beams, the last row a sentinel (E, E); n_beams (static) the
    number of beams."""

    conn: jax.Array
    loc_valid: jax.Array
    R: jax.Array
    w: jax.Array
    radius: jax.Array
    beta: jax.Array
    beam: jax.Array
    pairs: jax.Array
    n_beams: int = field(metadata=dict(static=True))

    @property
    def n_elements(self) -> int:
        """Number of elements of all beams."""
        return self.conn.shape[0]


def contact_elements(disc, segments: int, betas, beam_pairs=None) -> ContactElements:
    """Contact points of every element of every beam (host-side, once).

    Args:
        beam_pairs: pairs of beam indices that interact (None: every two different beams);
            only their element pairs enter ``pairs``, the broad phase's universe.
    """
    n_loc = max(b.curve.degree + 1 for b in disc.beams)
    conn, valid, Rs, ws, radius, beta, beam_of = [], [], [], [], [], [], []
    x, gw = np.polynomial.legendre.leggauss(8)
    for b_idx, info in enumerate(disc.beams):
        curve, mesh = info.curve, info.mesh
        p = curve.degree
        for e, (a, b) in enumerate(zip(mesh.breaks[:-1], mesh.breaks[1:], strict=True)):
            edges = np.linspace(a, b, segments + 1)
            u0, u1 = edges[:-1, None], edges[1:, None]
            R = np.zeros((segments, n_loc))
            _, d = nurbs_basis_derivatives(curve.knots, p, curve.weights, 0.5 * (u0 + u1)[:, 0])
            R[:, : p + 1] = d[:, 0]
            uq = 0.5 * (u1 - u0) * x + 0.5 * (u0 + u1)  # (segments, Gauss points)
            speed = np.linalg.norm(curve.evaluate(uq.ravel(), 1)[1], axis=1).reshape(uq.shape)
            # one dot product per segment, as the weights have always been summed
            w = np.array([row @ gw for row in 0.5 * (u1 - u0) * speed])
            c = np.zeros(n_loc, dtype=np.int64)
            c[: p + 1] = mesh.conn[e] + info.offset
            conn.append(c)
            valid.append(np.arange(n_loc) < p + 1)
            Rs.append(R)
            ws.append(w)
            radius.append(info.section.half_depth)
            beta.append(betas[b_idx])
            beam_of.append(b_idx)
    beam_of = np.array(beam_of)
    n = len(beam_of)
    i, j = np.triu_indices(n, k=1)
    n_beams = len(disc.beams)
    allowed = ~np.eye(n_beams, dtype=bool)
    if beam_pairs is not None:
        allowed[:] = False
        for b1, b2 in beam_pairs:
            allowed[b1, b2] = allowed[b2, b1] = b1 != b2
    cross = allowed[beam_of[i], beam_of[j]]
    pairs = np.vstack([np.column_stack([i[cross], j[cross]]), [[n, n]]]).astype(np.int64)
    return ContactElements(conn=jnp.asarray(np.array(conn)), loc_valid=jnp.asarray(valid),
                           R=as_float(Rs), w=as_float(ws), radius=as_float(radius),
                           beta=as_float(beta), beam=jnp.asarray(beam_of),
                           pairs=jnp.asarray(pairs), n_beams=n_beams)
