"""Contact integration points (paper Sec. 2.1, Fig. 2) and the element data of contact.

Each element is split into ``segments_per_element`` segments of equal parameter length,
with one point at the middle of each and the segment's reference arc length as weight.
All elements of all beams are numbered globally; basis rows are padded to the largest
number of local control points (padding rows of R are zero).

Which points may interact: points of two beams whose entry of ``allowed`` is true (every
two different beams, or the listed pairs); points of one beam (self-contact, where the
beam's diagonal entry is true) only if their reference arc-length distance along the
beam is at least ``exclusion`` (:func:`self_exclusion`), so that neighbours along the
axis, which are always closer than R1 + R2, never count as a contact. No list of element
pairs is kept: the broad phase (:mod:`beamcontact.contact.broadphase`) applies the rule to
the boxes it finds.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from beamcontact._jax import jax, jnp, model_array, pytree
from beamcontact._x64 import as_float
from beamcontact.beam.free_ends import fold_rows
from beamcontact.spline import nurbs_basis_derivatives


@pytree
@dataclass(frozen=True)
class ContactElements:
    """Per global element: shapes conn, loc_valid (E, n_loc); R (E, n_s, n_loc);
    w (E, n_s) segment arc lengths; s (E, n_s) the points' reference arc-length
    positions along their beam; radius, beta (E,); beam (E,) beam index; allowed
    (B, B) which beams interact (the diagonal: self-contact); exclusion (scalar) the
    smallest arc-length distance of two interacting points of one beam; n_beams (static)
    the number of beams B."""

    conn: jax.Array
    loc_valid: jax.Array
    R: jax.Array
    w: jax.Array
    s: jax.Array
    radius: jax.Array
    beta: jax.Array
    beam: jax.Array
    allowed: jax.Array
    exclusion: jax.Array
    n_beams: int = field(metadata=dict(static=True))

    @property
    def n_elements(self) -> int:
        """Number of elements of all beams."""
        return self.conn.shape[0]

    @property
    def sentinel(self) -> jax.Array:
        """The padding entry (E, E) of candidate lists."""
        return jnp.array([self.n_elements, self.n_elements])

    def may_touch(self, e1, e2, xp=None):
        """Whether elements e1 and e2 (global indices, any broadcastable shapes, < E) hold
        a pair of points that may interact: their beams interact and, on one beam, they
        are different elements with two points at least ``exclusion`` apart along it
        (``xp``: the array module, jax.numpy unless NumPy is given)."""
        xp = jnp if xp is None else xp
        b1, b2 = self.beam[e1], self.beam[e2]
        ns = self.s.shape[1]
        spread = xp.maximum(self.s[e2, ns - 1] - self.s[e1, 0], self.s[e1, ns - 1] - self.s[e2, 0])
        own = (e1 != e2) & (spread >= self.exclusion)
        return self.allowed[b1, b2] & ((b1 != b2) | own)

    def point_mask(self, e1, e2, xp=None):
        """(..., n_s, n_s) whether each point pair of elements e1, e2 (< E) may interact:
        :meth:`may_touch` refined point by point on one beam (``xp`` as there)."""
        xp = jnp if xp is None else xp
        far = xp.abs(self.s[e1][..., :, None] - self.s[e2][..., None, :]) >= self.exclusion
        same = (self.beam[e1] == self.beam[e2])[..., None, None]
        return self.allowed[self.beam[e1], self.beam[e2]][..., None, None] & (~same | far)

    def element_pair_count(self) -> int:
        """An upper bound of the number of element pairs that may interact (host)."""
        counts = np.bincount(np.asarray(self.beam), minlength=self.n_beams).astype(np.int64)
        allowed = np.asarray(self.allowed)
        cross = np.triu(allowed, k=1) * np.outer(counts, counts)
        own = np.diag(allowed) * counts * (counts - 1) // 2
        return int(cross.sum() + own.sum())


def self_exclusion(radius_max: float, interaction: float) -> float:
    """The arc-length distance below which two points of one beam never interact: four
    times the largest radius, and at least the law's interaction distance (finite for the
    coarse-grained cutoff).

    On a straight beam two points s apart are s apart in space, so with s >= 4 R their gap
    is at least 2 R; on a beam bent to a radius of curvature rho >= R the chord of an arc
    of 4 R is 2 rho sin(2 R / rho) > 2 R as well: the excluded neighbours are exactly the
    pairs that would otherwise touch without any fold. A point pair of a fold (the two
    legs of a hairpin, a rolled end resting on the beam) is much further apart along the
    beam and interacts.
    """
    reach = interaction if np.isfinite(interaction) else 0.0
    return float(max(4.0 * radius_max, reach))


def contact_elements(disc, segments: int, betas, beam_pairs=None, self_contact: bool = False,
                     exclusion: float = np.inf) -> ContactElements:
    """Contact points of every element of every beam (host-side, once).

    Args:
        beam_pairs: pairs of beam indices that interact (None: every two different beams).
        self_contact: every beam also interacts with itself (points at least
            ``exclusion`` apart along it).
        exclusion: see :func:`self_exclusion`.
    """
    n_loc = max(b.curve.degree + 1 for b in disc.beams)
    conn, valid, Rs, ws, ss, radius, beta, beam_of = [], [], [], [], [], [], [], []
    x, gw = np.polynomial.legendre.leggauss(8)
    for b_idx, info in enumerate(disc.beams):
        # every element of the beam at once: the same numbers, point by point, as an
        # element at a time (a loop over 10 000 elements cost seconds)
        curve, mesh = info.curve, info.mesh
        p, n_el = curve.degree, mesh.n_elements
        edges = np.linspace(mesh.breaks[:-1], mesh.breaks[1:], segments + 1, axis=1)
        u0, u1 = edges[:, :-1, None], edges[:, 1:, None]  # (n_el, segments, 1)
        R = np.zeros((n_el, segments, n_loc))
        _, d = nurbs_basis_derivatives(curve.knots, p, curve.weights,
                                       (0.5 * (u0 + u1))[..., 0].ravel())
        R[:, :, : p + 1] = d[:, 0].reshape(n_el, segments, p + 1)
        uq = 0.5 * (u1 - u0) * x + 0.5 * (u0 + u1)  # (n_el, segments, Gauss points)
        speed = np.linalg.norm(curve.evaluate(uq.ravel(), 1)[1], axis=1).reshape(uq.shape)
        # Gauss-Legendre per segment, summed in the order of the points (a BLAS dot
        # product per segment was a Python loop over millions of segments)
        scaled = 0.5 * (u1 - u0) * speed
        w = np.zeros((n_el, segments))
        for q in range(len(gw)):
            w += scaled[..., q] * gw[q]
        # arc length before each element, summed element by element; the middles
        before = np.concatenate([[0.0], np.cumsum(w.sum(axis=1))[:-1]])
        ss.append(before[:, None] + np.cumsum(w, axis=1) - 0.5 * w)
        c = np.zeros((n_el, n_loc), dtype=np.int64)
        c[:, : p + 1] = mesh.conn + info.offset
        conn.append(c)
        valid.append(np.broadcast_to(np.arange(n_loc) < p + 1, (n_el, n_loc)))
        # the contact forces act in the constrained space of the mesh (beam/free_ends.py)
        Rs.append(fold_rows(c, R, mesh.free_ends, info.offset))
        ws.append(w)
        radius.append(np.full(n_el, info.section.half_depth))
        beta.append(np.full(n_el, betas[b_idx], dtype=float))
        beam_of.append(np.full(n_el, b_idx))
    conn, valid, Rs, ws, ss = (np.concatenate(v) for v in (conn, valid, Rs, ws, ss))
    radius, beta, beam_of = (np.concatenate(v) for v in (radius, beta, beam_of))
    n_beams = len(disc.beams)
    allowed = ~np.eye(n_beams, dtype=bool)
    if beam_pairs is not None:
        allowed[:] = False
        for b1, b2 in beam_pairs:
            allowed[b1, b2] = allowed[b2, b1] = True
    if self_contact:
        np.fill_diagonal(allowed, True)
    return ContactElements(conn=model_array(conn), loc_valid=model_array(valid),
                           R=as_float(Rs), w=as_float(ws), s=as_float(ss),
                           radius=as_float(radius), beta=as_float(beta),
                           beam=model_array(beam_of), allowed=model_array(allowed),
                           exclusion=as_float(exclusion), n_beams=n_beams)
