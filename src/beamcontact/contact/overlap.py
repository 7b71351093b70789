"""Beams that interpenetrate in the initial configuration (checked once, on the host).

For every pair of points that may interact (:meth:`ContactElements.point_mask`: beams
allowed to touch; on one beam under self-contact, points far enough apart along it), the
surface gap q = |x_i - x_j| - R_i - R_j (the discrete gap of the contact models,
docs/theory.md) is evaluated at the reference control points; a pair of beams (or a
beam with itself) with q < 0 somewhere is reported with its smallest gap and where it
occurs.

The element pairs come from the broad phase (:func:`all_candidates`, boxes grown by the
largest radius): a contact point lies in the convex hull of its element's control points
(NURBS with positive weights), so q < 0 needs the two boxes to overlap. Only those
element pairs are evaluated point by point, in chunks so that memory stays bounded.
"""

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from beamcontact.contact.broadphase import all_candidates

# point pairs per chunk of the exact test
POINT_CHUNK = 1 << 22


@dataclass(frozen=True)
class Overlap:
    """The deepest interpenetration of two beams in the initial configuration.

    Attributes:
        beams: the two beams' names (in model order).
        gap: the smallest surface gap q = d - R1 - R2 (negative) [m].
        point: midpoint between the two contact points where it occurs (x, y) [m].
        fractions: where that is along each beam, as fractions of its reference length.
        elements: the elements (numbered from 0 along each beam) holding the two points.
        point_pairs: how many contact point pairs of the two beams have q < 0.
    """

    beams: tuple[str, str]
    gap: float
    point: tuple[float, float]
    fractions: tuple[float, float]
    elements: tuple[int, int]
    point_pairs: int

    @property
    def message(self) -> str:
        """One line for the user."""
        (a, b), (fa, fb) = self.beams, self.fractions
        if a == b:
            return (f"beam {a!r} interpenetrates itself in the initial configuration: gap "
                    f"{self.gap:.4g} m at ({self.point[0]:.4g}, {self.point[1]:.4g}) (at "
                    f"{fa:.3g} and {fb:.3g} of its length)")
        return (f"beams {a!r} and {b!r} interpenetrate in the initial configuration: gap "
                f"{self.gap:.4g} m at ({self.point[0]:.4g}, {self.point[1]:.4g}) ({a} at "
                f"{fa:.3g} of its length, {b} at {fb:.3g})")

    def __str__(self) -> str:
        return self.message


def describe(findings: Sequence[Overlap]) -> str | None:
    """The message of the deepest interpenetration and how many more pairs of beams
    interpenetrate, or None when there are none."""
    if not findings:
        return None
    worst = min(findings, key=lambda f: f.gap)
    more = len(findings) - 1
    return worst.message + (f" (and {more} more pair(s) of beams)" if more else "")


def initial_overlaps(x, ce, beam_names: Sequence[str]) -> list[Overlap]:
    """Every pair of beams whose contact points interpenetrate at control points x.

    Args:
        x: reference control points of the whole model, shape (n_cp, 2).
        ce: the contact elements (:class:`beamcontact.contact.points.ContactElements`).
        beam_names: names of the beams in model order (``ce.beam`` indexes them).

    Returns:
        One :class:`Overlap` per pair of beams with a negative gap, deepest first. Where
        the smallest gap is shared by several point pairs (parallel straight beams: a
        plateau), the middle one of them is reported, as the contact models do.
    """
    x = np.asarray(x, dtype=float)
    conn, radius = np.asarray(ce.conn), np.asarray(ce.radius, dtype=float)
    beam_of = np.asarray(ce.beam)
    points = np.einsum("esk,ekd->esd", np.asarray(ce.R, dtype=float), x[conn])  # (E, S, 2)
    pairs = all_candidates(x, ce, float(radius.max()))
    mask = ce.point_mask(pairs[:, 0], pairs[:, 1], np) if len(pairs) else None
    tol = 1e-9 * float(radius.max())  # equal gaps to round-off of the radii: a plateau
    hits = _negative_gaps(points, radius, pairs, mask, tol)
    if hits is None:
        return []
    position = _arc_fractions(np.asarray(ce.w, dtype=float), beam_of)
    first = _first_elements(beam_of)
    found = []
    e1, e2 = hits["e1"], hits["e2"]
    key = beam_of[e1] * len(beam_names) + beam_of[e2]
    for k in np.unique(key):
        sel = np.nonzero(key == k)[0]
        found.append(_finding(hits, sel, points, position, first, beam_of, beam_names, tol))
    return sorted(found, key=lambda f: f.gap)


def _negative_gaps(points, radius, pairs, mask, tol) -> dict | None:
    """For every element pair with a negative gap: its smallest gap, the indices of the
    two points (the middle of the point pairs within tol of it), and the number of point
    pairs with q < 0 (only the point pairs of ``mask``, (P, n_s, n_s), count)."""
    n_s = points.shape[1]
    rows = max(1, POINT_CHUNK // (n_s * n_s))
    parts = []
    for start in range(0, len(pairs), rows):
        i, j = pairs[start:start + rows].T
        d = np.linalg.norm(points[i][:, :, None, :] - points[j][:, None, :, :], axis=-1)
        q = np.where(mask[start:start + rows], d - (radius[i] + radius[j])[:, None, None],
                     np.inf)
        flat = q.reshape(len(i), -1)
        q_min = flat.min(axis=1)
        level = np.cumsum(flat <= (q_min + tol)[:, None], axis=1)
        best = np.argmax(level >= ((level[:, -1] + 1) // 2)[:, None], axis=1)
        neg = q_min < 0.0
        if np.any(neg):
            parts.append({"e1": i[neg], "e2": j[neg], "q": q_min[neg],
                          "s1": best[neg] // n_s, "s2": best[neg] % n_s,
                          "count": np.sum(flat[neg] < 0.0, axis=1)})
    if not parts:
        return None
    return {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}


def _arc_fractions(w, beam_of):
    """Fraction of its beam's reference length at every contact point (E, S): the arc
    length of the segments before it plus half its own, over the beam's length (the
    points are at the middle of equal-parameter segments whose arc lengths are w)."""
    before = np.cumsum(w.ravel()).reshape(w.shape) - 0.5 * w
    totals = np.bincount(beam_of, weights=w.sum(axis=1))
    start = np.concatenate([[0.0], np.cumsum(totals)])[beam_of]
    return (before - start[:, None]) / totals[beam_of][:, None]


def _first_elements(beam_of):
    """Global index of the first element of each beam."""
    first = np.full(beam_of.max() + 1, len(beam_of))
    np.minimum.at(first, beam_of, np.arange(len(beam_of)))
    return first


def _finding(hits, sel, points, position, first, beam_of, names, tol) -> Overlap:
    """The Overlap of one pair of beams from the element pairs ``sel`` of ``hits``."""
    q = hits["q"][sel]
    q_min = q.min()
    plateau = sel[q <= q_min + tol]  # of equal gaps: take its middle element pair
    order = np.lexsort((hits["e2"][plateau], hits["e1"][plateau]))
    h = plateau[order[len(order) // 2]]
    e1, e2, s1, s2 = hits["e1"][h], hits["e2"][h], hits["s1"][h], hits["s2"][h]
    mid = 0.5 * (points[e1, s1] + points[e2, s2])
    b1, b2 = beam_of[e1], beam_of[e2]
    return Overlap(beams=(names[b1], names[b2]), gap=float(q_min),
                   point=(float(mid[0]), float(mid[1])),
                   fractions=(float(position[e1, s1]), float(position[e2, s2])),
                   elements=(int(e1 - first[b1]), int(e2 - first[b2])),
                   point_pairs=int(hits["count"][sel].sum()))


def obstacle_overlaps(x, ce, obstacles, beam_names: Sequence[str],
                      obstacle_names: Sequence[str]) -> list[tuple[float, str]]:
    """Every beam whose contact points penetrate an obstacle at control points x: (the
    smallest gap q = s - R, a message naming both and the place), deepest first
    (:mod:`beamcontact.contact.obstacles`)."""
    from beamcontact.contact.obstacles import obstacle_gaps

    x = np.asarray(x, dtype=float)
    q = np.asarray(obstacle_gaps(x, ce, obstacles))  # (E, S, O)
    points = np.einsum("esk,ekd->esd", np.asarray(ce.R, dtype=float), x[np.asarray(ce.conn)])
    beam_of = np.asarray(ce.beam)
    position = _arc_fractions(np.asarray(ce.w, dtype=float), beam_of)
    found = []
    for b, name in enumerate(beam_names):
        for o, obstacle in enumerate(obstacle_names):
            qb = np.where((beam_of == b)[:, None], q[:, :, o], np.inf)
            e, s = np.unravel_index(np.argmin(qb), qb.shape)
            if qb[e, s] < 0.0:
                p = points[e, s]
                found.append((float(qb[e, s]),
                              f"beam {name!r} penetrates obstacle {obstacle!r} in the initial "
                              f"configuration: gap {qb[e, s]:.4g} m at ({p[0]:.4g}, "
                              f"{p[1]:.4g}) (at {position[e, s]:.3g} of its length)"))
    return sorted(found)
