"""Native (Numba) twin of the contact set of one time step (:mod:`beamcontact.contact.step_set`)
for models on the all-pairs broad phase (at most ``ALL_PAIRS_LIMIT`` = 64 elements).

The JAX functions stay the definition; these compute the same numbers (to round-off, the
selections exactly; tests/test_step_set_native.py):

* the broad phase: element boxes of the control points grown by a margin, every element
  pair (i < j) whose boxes overlap and that may touch
  (:func:`~beamcontact.contact.broadphase.all_pair_candidates`,
  :meth:`~beamcontact.contact.points.ContactElements.may_touch`), in the same sorted order;
* integrated laws (coarse-grained): the candidates culled to the blocks with a point pair
  closer than interaction + 2 motion (:func:`~beamcontact.contact.problem.near_candidates`);
* IPIP "points": the gaps of every point pair of the candidates and the closest-point
  weights of :func:`~beamcontact.contact.select.point_weights_on_device` (each point of
  either beam with its closest point on the other beam among all candidate blocks, 1/2
  from each side, ties within rtol sharing), blocks with a weight first
  (:func:`~beamcontact.contact.step_set._closest_points`);
* conservative advancement (:func:`~beamcontact.contact.advance.approach_ratio`), for the
  predictor's two displacement fields and for the actual displacement;
* the post-step check (:func:`~beamcontact.contact.problem.missed_blocks`, with
  :func:`~beamcontact.contact.broadphase.box_gap_lower_bound`);
* the arc-length weights W_ij = w1_i w2_j of a coarse-grained block
  (:func:`~beamcontact.contact.blocks.arc_length_weights`).

Where the JAX lists have a fixed capacity padded with the sentinel element E, these return
plain arrays of the real entries: element pairs are int64 (n_pairs, 2), sorted by
(e1, e2) with e1 < e2 as the JAX list, so nothing overflows and there is no count/load to
check (the number of box candidates is still returned where the JAX function returns it;
the fullest-cell load of the all-pairs path is always 0). Arithmetic follows the JAX
expressions operation by operation (the same sums in the same order); XLA contracts some
a * b + c into fused multiply-adds, Numba without fastmath does not, so the gaps agree to
the last bit or two (a few 1e-16), far inside the tie tolerance RTOL, and the comparisons
of the selections (d < limit, ties within rtol, nearest < q_active) fall the same way
unless a gap lies within round-off of such a threshold.

Self-contact (a beam allowed to touch itself) follows from the same formulas
(:meth:`ContactElements.may_touch`, ``point_mask``, the two-sided segment minima; tested
on a ring closing on itself) although the engine this serves has none; obstacles
(``obstacle_gaps``, ``obstacle_approach_ratio``) and the deviation test of ``after_step``
(|x_new - x_pred| > motion + 1e-6 reach) are not part of this module.

Importing this module imports neither JAX nor matplotlib.
"""

import math
from typing import NamedTuple

import numpy as np

from beamcontact._native import njit, njit_inline, njit_parallel, njit_uncounted, prange
from beamcontact.arrays_native import copy_2d
from beamcontact.contact.blocks_native import CHUNK, bounding_box, chunk_boxes, point_box_gap2
from beamcontact.dynamics.control import ADVANCE_ACCEPT, ADVANCE_FRACTION

# the tie rule of point_weights_on_device: two gaps are equal within RTOL max(1, |q|)
RTOL = 1e-9
# a margin on squared distances compared with a squared limit: s >= limit^2 (1 + 1e-12)
# in floating point means sqrt(s) >= limit after rounding (as blocks_native's reach)
_SQUARE_MARGIN = 1.0 + 1e-12
# the JAX element_boxes masks the padding control points with the largest float, not inf
_BIG = float(np.finfo(np.float64).max)


class NativeContactElements(NamedTuple):
    """:class:`~beamcontact.contact.points.ContactElements` as flat host arrays (E elements of
    all beams, n_s contact points per element, n_loc padded local control points, B beams).

    Attributes:
        conn: (E, n_loc) int64 global control points of each element (padding: 0).
        loc_valid: (E, n_loc) bool, the real local control points.
        R: (E, n_s, n_loc) basis rows of the contact points (padding columns 0).
        w: (E, n_s) reference arc-length weights of the points.
        s: (E, n_s) reference arc-length positions of the points along their beam.
        radius, beta: (E,) radius and density of each element's beam.
        beam: (E,) int64 beam of each element.
        allowed: (B, B) bool, which beams interact (the diagonal: self-contact).
        exclusion: the smallest arc-length distance of two interacting points of one beam.
        n_beams: B.
    """

    conn: np.ndarray
    loc_valid: np.ndarray
    R: np.ndarray
    w: np.ndarray
    s: np.ndarray
    radius: np.ndarray
    beta: np.ndarray
    beam: np.ndarray
    allowed: np.ndarray
    exclusion: float
    n_beams: int


def native_contact_elements(ce) -> NativeContactElements:
    """The flat host arrays of a :class:`~beamcontact.contact.points.ContactElements`
    (JAX or NumPy fields; C-contiguous copies, float64 / int64 / bool)."""

    # writable copies: NumPy views of JAX arrays are read-only, and Numba compiles a
    # kernel again for each combination of read-only arguments
    def f64(a):
        return np.array(a, dtype=np.float64, order="C", copy=True)

    def i64(a):
        return np.array(a, dtype=np.int64, order="C", copy=True)

    def flag(a):
        return np.array(a, dtype=np.bool_, order="C", copy=True)

    return NativeContactElements(
        conn=i64(ce.conn), loc_valid=flag(ce.loc_valid), R=f64(ce.R), w=f64(ce.w),
        s=f64(ce.s), radius=f64(ce.radius), beta=f64(ce.beta), beam=i64(ce.beam),
        allowed=flag(ce.allowed), exclusion=float(ce.exclusion), n_beams=int(ce.n_beams))


# A note on speed: a compiled call that takes the NamedTuple pays the reference counts of
# all its arrays (about 0.1 us here), so the loops unpack it once and call helpers that take
# plain arrays (inlined by LLVM, free); only the public functions take it.

# ------------------------------------------------------------------------- which pairs


@njit
def _may_touch(beam, allowed, s, exclusion, e1, e2):
    """:func:`may_touch` on the arrays of the elements."""
    b1, b2 = beam[e1], beam[e2]
    if not allowed[b1, b2]:
        return False
    if b1 != b2:
        return True
    last = s.shape[1] - 1
    spread = max(s[e2, last] - s[e1, 0], s[e1, last] - s[e2, 0])
    return e1 != e2 and spread >= exclusion


@njit
def _point_may_touch(beam, allowed, s, exclusion, e1, e2, i, j):
    """:func:`point_may_touch` on the arrays of the elements."""
    b1, b2 = beam[e1], beam[e2]
    if not allowed[b1, b2]:
        return False
    return b1 != b2 or abs(s[e1, i] - s[e2, j]) >= exclusion


@njit
def may_touch(ne, e1, e2):
    """Whether elements e1, e2 hold a pair of points that may interact
    (:meth:`ContactElements.may_touch`): their beams interact and, on one beam, they are
    different elements with two points at least ``exclusion`` apart along it."""
    return _may_touch(ne.beam, ne.allowed, ne.s, ne.exclusion, e1, e2)


@njit
def point_may_touch(ne, e1, e2, i, j):
    """Whether point i of element e1 and point j of element e2 may interact
    (:meth:`ContactElements.point_mask`; :func:`blocks.point_mask` of a real block)."""
    return _point_may_touch(ne.beam, ne.allowed, ne.s, ne.exclusion, e1, e2, i, j)


# ------------------------------------------------------------------------- broad phase


@njit
def _boxes(x, conn, loc_valid, margin):
    """:func:`element_boxes` on the arrays of the elements."""
    E, n_loc = conn.shape
    lo = np.empty((E, 2))
    hi = np.empty((E, 2))
    for e in range(E):
        for d in range(2):
            a, b = _BIG, -_BIG
            for k in range(n_loc):
                if loc_valid[e, k]:
                    v = x[conn[e, k], d]
                    a = min(a, v)
                    b = max(b, v)
            lo[e, d] = a - margin
            hi[e, d] = b + margin
    return lo, hi


@njit
def element_boxes(x, ne, margin):
    """Lower and upper corners (E, 2) each of every element's box of its (real) control
    points at x (n_cp, 2), grown by ``margin`` (:func:`broadphase.element_boxes`)."""
    return _boxes(x, ne.conn, ne.loc_valid, margin)


@njit
def candidate_pairs(x, ne, margin):
    """Candidate element pairs (P, 2) int64 at control points x (n_cp, 2), boxes grown by
    ``margin``: the pairs (i, j), i < j, whose grown boxes overlap and that may touch,
    sorted by (i, j) (:func:`broadphase.all_pair_candidates`: its first ``count`` rows;
    P is its count, its load is 0).

    The test of every pair costs E (E - 1) / 2 box comparisons: the JAX twin takes this
    path up to ALL_PAIRS_LIMIT = 64 elements (its grid path gives the same list above)."""
    beam, allowed, s, exclusion = ne.beam, ne.allowed, ne.s, ne.exclusion
    E = ne.conn.shape[0]
    lo, hi = _boxes(x, ne.conn, ne.loc_valid, margin)
    out = np.empty((max(E * (E - 1) // 2, 0), 2), dtype=np.int64)
    n = 0
    for i in range(E):
        for j in range(i + 1, E):
            if (lo[i, 0] <= hi[j, 0] and lo[j, 0] <= hi[i, 0] and lo[i, 1] <= hi[j, 1]
                    and lo[j, 1] <= hi[i, 1] and _may_touch(beam, allowed, s, exclusion, i, j)):
                out[n, 0] = i
                out[n, 1] = j
                n += 1
    return out[:n].copy()


@njit
def box_gap_lower_bound(x, ne, reach):
    """A lower bound of the surface gap of every pair of points that may interact, for a
    configuration whose search with boxes grown by ``reach`` found no candidate
    (:func:`broadphase.box_gap_lower_bound`, its path of at most ELEMENT_BOUND_LIMIT
    elements): the smallest distance of two element boxes that may touch less both radii,
    and at least 2 reach - 2 R_max."""
    beam, allowed, s, exclusion, radius = ne.beam, ne.allowed, ne.s, ne.exclusion, ne.radius
    E = ne.conn.shape[0]
    lo, hi = _boxes(x, ne.conn, ne.loc_valid, 0.0)
    near = math.inf
    for a in range(E):
        for b in range(E):
            if not _may_touch(beam, allowed, s, exclusion, a, b):
                continue
            sx = max(max(lo[a, 0] - hi[b, 0], lo[b, 0] - hi[a, 0]), 0.0)
            sy = max(max(lo[a, 1] - hi[b, 1], lo[b, 1] - hi[a, 1]), 0.0)
            # (a, b) and (b, a) both: the radii are subtracted in either order there
            near = min(near, math.sqrt(sx * sx + sy * sy) - radius[a] - radius[b])
    r_max = -math.inf
    for e in range(E):
        r_max = max(r_max, radius[e])
    return max(near, 2.0 * reach - 2.0 * r_max)


# ------------------------------------------------------------------------ point pairs


@njit
def _points_into(field, conn, R, e, out):
    """out[i] = R_i field[conn_e]: the contact points of element e (n_s, 2), summed over
    the local control points in order (the einsum of :func:`blocks._block_geometry`)."""
    for i in range(R.shape[1]):
        px = 0.0
        py = 0.0
        for k in range(conn.shape[1]):
            c = conn[e, k]
            px += R[e, i, k] * field[c, 0]
            py += R[e, i, k] * field[c, 1]
        out[i, 0] = px
        out[i, 1] = py


@njit
def _pair_points(field, conn, R, pairs):
    """The contact points (E, n_s, 2) of the elements that occur in ``pairs`` (the others,
    and padding indices >= E, are left out) under the control-point field (n_cp, 2)."""
    E, ns = conn.shape[0], R.shape[1]
    P = np.empty((E, ns, 2))
    done = np.zeros(E, dtype=np.bool_)
    for c in range(pairs.shape[0]):
        for side in range(2):
            e = pairs[c, side]
            if e < E and not done[e]:
                _points_into(field, conn, R, e, P[e])
                done[e] = True
    return P


@njit
def _point_boxes(P, pairs, E):
    """(E, 4) boxes (lo_x, lo_y, hi_x, hi_y) of the contact points P of the elements that
    occur in ``pairs`` (the others are left as they are)."""
    box = np.empty((E, 4))
    for c in range(pairs.shape[0]):
        for side in range(2):
            e = pairs[c, side]
            if e < E:
                box[e, 0], box[e, 1], box[e, 2], box[e, 3] = bounding_box(P[e])
    return box


@njit
def _box_distance(a, b):
    """The distance of two boxes (lo_x, lo_y, hi_x, hi_y) (a point is a box), computed
    as a point pair's sqrt(rx^2 + ry^2): every operation rounds monotonically, so it is
    at most the distance computed for any point of one box and any of the other."""
    return _corner_distance(a[0], a[1], a[2], a[3], b)


@njit
def _corner_distance(lo_x, lo_y, hi_x, hi_y, b):
    """:func:`_box_distance` of the box (lo_x, lo_y, hi_x, hi_y) and the box b."""
    dx = max(lo_x - b[2], b[0] - hi_x, 0.0)
    dy = max(lo_y - b[3], b[1] - hi_y, 0.0)
    return math.sqrt(dx * dx + dy * dy)


# blocks beyond this many are visited in their own order (an insertion sort costs the
# square of their number)
_SORTED_BLOCKS = 64


@njit
def _ascending(keys):
    """The order (int64) of ``keys`` ascending: an insertion sort, for the few blocks of
    a step (np.argsort compiles a quicksort of seconds); with more than _SORTED_BLOCKS
    keys, their own order (a visiting order only: the bounds hold in any)."""
    order = np.arange(keys.shape[0])
    if keys.shape[0] > _SORTED_BLOCKS:
        return order
    for c in range(keys.shape[0]):
        k = c
        while k > 0 and keys[order[k - 1]] > keys[c]:
            order[k] = order[k - 1]
            k -= 1
        order[k] = c
    return order


# the bounds that let a loop skip point pairs are lowered by this relative margin, so that
# a skipped pair is one whose computed value could not have counted
_BOUND_MARGIN = 1e-9


@njit
def block_distances(x, ne, pairs):
    """Centre-line distances (P, n_s, n_s) of all point pairs of the blocks ``pairs``
    (real pairs only) at x, +inf for the pairs that may not interact
    (:func:`blocks.block_distances`)."""
    beam, allowed, s, exclusion = ne.beam, ne.allowed, ne.s, ne.exclusion
    ns = ne.R.shape[1]
    P = _pair_points(x, ne.conn, ne.R, pairs)
    # the coordinates apart, so that the loop over j reads contiguous memory
    px = np.ascontiguousarray(P[:, :, 0])
    py = np.ascontiguousarray(P[:, :, 1])
    d = np.empty((pairs.shape[0], ns, ns))
    for c in range(pairs.shape[0]):
        e1, e2 = pairs[c, 0], pairs[c, 1]
        # two beams: every pair may interact, a loop without a branch (vectorised)
        whole = allowed[beam[e1], beam[e2]] and beam[e1] != beam[e2]
        for i in range(ns):
            x1, y1 = px[e1, i], py[e1, i]
            for j in range(ns):
                rx = x1 - px[e2, j]
                ry = y1 - py[e2, j]
                d[c, i, j] = math.sqrt(rx * rx + ry * ry)
            if not whole:
                for j in range(ns):
                    if not _point_may_touch(beam, allowed, s, exclusion, e1, e2, i, j):
                        d[c, i, j] = math.inf
    return d


@njit
def _gaps_from(d, radius, pairs):
    """q = d - (R1 + R2) of every point pair (:func:`blocks.block_gaps` given d)."""
    q = np.empty_like(d)
    for c in range(pairs.shape[0]):
        r12 = radius[pairs[c, 0]] + radius[pairs[c, 1]]
        for i in range(d.shape[1]):
            for j in range(d.shape[2]):
                q[c, i, j] = d[c, i, j] - r12
    return q


@njit
def block_gaps(x, ne, pairs):
    """Surface gaps q = d - R1 - R2 (P, n_s, n_s) of all point pairs of the blocks
    ``pairs`` at x (+inf for the pairs that may not interact; :func:`blocks.block_gaps`)."""
    return _gaps_from(block_distances(x, ne, pairs), ne.radius, pairs)


@njit
def arc_length_weights(ne, e1, e2):
    """W (n_s, n_s) of the block (e1, e2) of an integrated law: w1_i w2_j for the point
    pairs that may interact, 0 for the rest (:func:`blocks.arc_length_weights`)."""
    beam, allowed, s, exclusion, w = ne.beam, ne.allowed, ne.s, ne.exclusion, ne.w
    ns = w.shape[1]
    W = np.empty((ns, ns))
    # two beams that interact: every pair may touch, no test per pair
    whole = allowed[beam[e1], beam[e2]] and beam[e1] != beam[e2]
    for i in range(ns):
        for j in range(ns):
            ok = whole or _point_may_touch(beam, allowed, s, exclusion, e1, e2, i, j)
            W[i, j] = w[e1, i] * w[e2, j] if ok else 0.0
    return W


# ---------------------------------------------------------------- integrated laws (CG)


@njit
def near_blocks(x, ne, pairs, limit):
    """The blocks of ``pairs`` with a point pair closer than ``limit`` (centre-line
    distance at x), in their original order (:func:`blocks.near_blocks`: its real rows).
    A block whose point boxes are ``limit`` apart is dropped unseen, and the search of a
    block stops at its first close pair; the blocks are searched on the cores."""
    E = ne.conn.shape[0]
    P = _pair_points(x, ne.conn, ne.R, pairs)
    box = _point_boxes(P, pairs, E)
    keep = _near_flags(P, box, pairs, limit, ne.beam, ne.allowed, ne.s, ne.exclusion)
    return pairs[keep].copy()


@njit_parallel
def _near_flags(P, box, pairs, limit, beam, allowed, s, exclusion):
    """Whether each block of ``pairs`` has a point pair of P closer than ``limit``."""
    ns = P.shape[1]
    keep = np.zeros(pairs.shape[0], dtype=np.bool_)
    # a squared distance at or above this has d >= limit after rounding: no square root
    # for such a pair, and a row whose point is that far from the other element's box is
    # skipped whole
    far2 = limit * limit * _SQUARE_MARGIN
    for c in prange(pairs.shape[0]):
        e1, e2 = pairs[c, 0], pairs[c, 1]
        if _box_distance(box[e1], box[e2]) >= limit:
            continue
        whole = allowed[beam[e1], beam[e2]] and beam[e1] != beam[e2]
        b = box[e2]
        found = False
        for i in range(ns):
            px, py = P[e1, i, 0], P[e1, i, 1]
            if point_box_gap2(px, py, b[0], b[1], b[2], b[3]) >= far2:
                continue
            for j in range(ns):
                rx = px - P[e2, j, 0]
                ry = py - P[e2, j, 1]
                sq = rx * rx + ry * ry
                # the JAX twin's min(d) < limit, d = inf for pairs that may not interact
                if (sq < far2 and math.sqrt(sq) < limit
                        and (whole or _point_may_touch(beam, allowed, s, exclusion, e1, e2,
                                                       i, j))):
                    found = True
                    break
            if found:
                break
        keep[c] = found
    return keep


@njit
def near_candidates(x, ne, reach, interaction, motion):
    """The blocks of an integrated law to freeze at the predictor x: box candidates grown
    by reach + motion culled to those with a point pair closer than
    interaction + 2 motion (:func:`problem.near_candidates`, the integrated branch of
    :func:`step_set.step_set`). Returns (pairs (P, 2), number of box candidates)."""
    pairs = candidate_pairs(x, ne, reach + motion)
    return near_blocks(x, ne, pairs, interaction + 2.0 * motion), pairs.shape[0]


# ------------------------------------------------------------------------ IPIP "points"


@njit
def point_weights(q, pairs, ne, q_active, rtol=RTOL):
    """The "points" weights W (P, n_s, n_s) of the blocks ``pairs`` (real pairs only) from
    their gaps q (:func:`select.point_weights_on_device`, the same arithmetic).

    A point is keyed by (its element, its index, the other beam): its nearest gap is the
    minimum over every candidate block it belongs to, on either side of the block (a point
    of one beam under self-contact is the first element of some blocks and the second of
    others). A cell is a tie of a point when q <= nearest + rtol max(1, |q|) and
    nearest < q_active; the point's 1/2 is shared by its ties over all its blocks."""
    C, ns = q.shape[0], q.shape[1]
    B = ne.n_beams
    beam = ne.beam
    n_seg = ne.conn.shape[0] * ns * B
    nearest = np.full(n_seg, np.inf)
    # per block: the segments of its columns and their running minima / tie counts (the
    # rows' in registers: the block's row i is one point, its column j another)
    seg2 = np.empty(ns, dtype=np.int64)
    col = np.empty(ns)
    col_count = np.empty(ns, dtype=np.int64)
    for c in range(C):
        e1, e2 = pairs[c, 0], pairs[c, 1]
        b1, b2 = beam[e1], beam[e2]
        col[:] = np.inf
        for i in range(ns):
            row = np.inf
            for j in range(ns):
                v = q[c, i, j]
                row = min(row, v)
                col[j] = min(col[j], v)
            s1 = (e1 * ns + i) * B + b2
            nearest[s1] = min(nearest[s1], row)
        for j in range(ns):
            s2 = (e2 * ns + j) * B + b1
            nearest[s2] = min(nearest[s2], col[j])
    # the ties of both sides: bit 0 as a row of its block (point i of e1), bit 1 as a column
    ties = np.zeros((C, ns, ns), dtype=np.int8)
    count = np.zeros(n_seg, dtype=np.int64)
    for c in range(C):
        e1, e2 = pairs[c, 0], pairs[c, 1]
        b1, b2 = beam[e1], beam[e2]
        for j in range(ns):
            seg2[j] = (e2 * ns + j) * B + b1
            col[j] = nearest[seg2[j]]
            col_count[j] = 0
        for i in range(ns):
            s1 = (e1 * ns + i) * B + b2
            n1 = nearest[s1]
            active1 = n1 < q_active
            row_count = 0
            for j in range(ns):
                v = q[c, i, j]
                if not np.isfinite(v):
                    continue
                tol = rtol * max(1.0, abs(v))
                t = 0
                if active1 and v <= n1 + tol:
                    t |= 1
                    row_count += 1
                if col[j] < q_active and v <= col[j] + tol:
                    t |= 2
                    col_count[j] += 1
                ties[c, i, j] = t
            count[s1] += row_count
        for j in range(ns):
            count[seg2[j]] += col_count[j]
    W = np.zeros((C, ns, ns))
    share = np.empty(ns)
    for c in range(C):
        e1, e2 = pairs[c, 0], pairs[c, 1]
        b1, b2 = beam[e1], beam[e2]
        for j in range(ns):
            share[j] = 0.5 / max(count[(e2 * ns + j) * B + b1], 1)
        for i in range(ns):
            row_share = 0.5 / max(count[(e1 * ns + i) * B + b2], 1)
            for j in range(ns):
                t = ties[c, i, j]
                if t == 0:
                    continue
                # 0 + row share + column share, as the JAX sum (exact in any order)
                w = 0.0
                if t & 1:
                    w += row_share
                if t & 2:
                    w += share[j]
                W[c, i, j] = w
    return W


# ------------------------------------------------------------------------- IPIP "zones"


@njit
def zone_weights(q, pairs, beam, local, q_active, rtol=RTOL):
    """The "zones" weights W (P, n_s, n_s) of the blocks ``pairs`` (real pairs only) from
    their gaps q (:func:`select.closest_pair_weights` with pairing "zones", the same
    arithmetic and so the same weights): per pair of beams, the grid of the candidate
    blocks' gaps (``local`` the index of each element within its beam), its local minima
    below q_active (no 8-neighbour closer by more than rtol max(1, |q|)), the plateaus of
    touching minima (8-connected) and the middle cell of each in lexicographic (i, j)
    order, or the two middle ones with 1/2 each."""
    C, ns = q.shape[0], q.shape[1]
    W = np.zeros_like(q)
    done = np.zeros(C, dtype=np.bool_)
    members = np.empty(C, dtype=np.int64)
    for first in range(C):
        if done[first]:
            continue
        b1, b2 = beam[pairs[first, 0]], beam[pairs[first, 1]]
        m = 0
        i_min = j_min = 1 << 62
        for c in range(first, C):
            if not done[c] and beam[pairs[c, 0]] == b1 and beam[pairs[c, 1]] == b2:
                done[c] = True
                members[m] = c
                m += 1
                i_min = min(i_min, local[pairs[c, 0]] * ns)
                j_min = min(j_min, local[pairs[c, 1]] * ns)
        n1 = n2 = 0
        for k in range(m):
            c = members[k]
            n1 = max(n1, local[pairs[c, 0]] * ns - i_min + ns)
            n2 = max(n2, local[pairs[c, 1]] * ns - j_min + ns)
        grid = np.full((n1, n2), np.inf)
        for k in range(m):
            c = members[k]
            i0, j0 = local[pairs[c, 0]] * ns - i_min, local[pairs[c, 1]] * ns - j_min
            copy_2d(grid[i0:i0 + ns, j0:j0 + ns], q[c])
        weights = _plateau_middles(grid, q_active, rtol)
        for k in range(m):
            c = members[k]
            i0, j0 = local[pairs[c, 0]] * ns - i_min, local[pairs[c, 1]] * ns - j_min
            copy_2d(W[c], weights[i0:i0 + ns, j0:j0 + ns])
    return W


@njit
def _plateau_middles(grid, q_active, rtol):
    """:func:`select._zone_weights` on one grid: the middle of every plateau of local
    minima."""
    n1, n2 = grid.shape
    is_min = np.zeros((n1, n2), dtype=np.bool_)
    for i in range(n1):
        for j in range(n2):
            v = grid[i, j]
            if not (np.isfinite(v) and v < q_active):
                continue
            tol = rtol * max(1.0, abs(v))
            ok = True
            for di in range(-1, 2):
                for dj in range(-1, 2):
                    a, b = i + di, j + dj
                    if (di or dj) and 0 <= a < n1 and 0 <= b < n2 and not v <= grid[a, b] + tol:
                        ok = False
            is_min[i, j] = ok
    # the plateaus: 8-connected components, labelled by a flood fill
    labels = np.zeros((n1, n2), dtype=np.int64)
    size = np.zeros(n1 * n2 + 1, dtype=np.int64)
    stack = np.empty((n1 * n2, 2), dtype=np.int64)
    n_labels = 0
    for i in range(n1):
        for j in range(n2):
            if not is_min[i, j] or labels[i, j]:
                continue
            n_labels += 1
            labels[i, j] = n_labels
            stack[0, 0], stack[0, 1] = i, j
            top = 1
            while top:
                top -= 1
                a0, b0 = stack[top, 0], stack[top, 1]
                size[n_labels] += 1
                for di in range(-1, 2):
                    for dj in range(-1, 2):
                        a, b = a0 + di, b0 + dj
                        if 0 <= a < n1 and 0 <= b < n2 and is_min[a, b] and not labels[a, b]:
                            labels[a, b] = n_labels
                            stack[top, 0], stack[top, 1] = a, b
                            top += 1
    # the middle cell(s) of each plateau in row-major (lexicographic) order
    weights = np.zeros((n1, n2))
    seen = np.zeros(n_labels + 1, dtype=np.int64)
    for i in range(n1):
        for j in range(n2):
            lab = labels[i, j]
            if lab == 0:
                continue
            k, r = size[lab], seen[lab]
            if k % 2 == 1 and r == k // 2:
                weights[i, j] += 1.0
            elif k % 2 == 0 and (r == k // 2 - 1 or r == k // 2):
                weights[i, j] += 0.5
            seen[lab] = r + 1
    return weights


@njit
def weighted_first(pairs, W):
    """The blocks with a nonzero weight first, each group in its original order (the
    stable argsort of :func:`step_set._closest_points`): (pairs, W) reordered."""
    C, ns = W.shape[0], W.shape[1]
    weighted = np.zeros(C, dtype=np.bool_)
    for c in range(C):
        for i in range(ns):
            for j in range(ns):
                if W[c, i, j] != 0.0:
                    weighted[c] = True
    order = np.empty(C, dtype=np.int64)
    n = 0
    for c in range(C):
        if weighted[c]:
            order[n] = c
            n += 1
    for c in range(C):
        if not weighted[c]:
            order[n] = c
            n += 1
    return pairs[order], W[order]


@njit
def closest_points(x_pred, ne, reach, motion, rtol=RTOL):
    """The IPIP "points" set of a step at the predictor x_pred
    (:func:`step_set._closest_points`): box candidates grown by reach + motion, the gaps
    of their point pairs, the weights of :func:`point_weights` with q_active = 2 motion,
    blocks with a weight first. Returns (pairs (P, 2), W (P, n_s, n_s), number of box
    candidates P)."""
    pairs = candidate_pairs(x_pred, ne, reach + motion)
    q = block_gaps(x_pred, ne, pairs)
    W = point_weights(q, pairs, ne, 2.0 * motion, rtol)
    pairs, W = weighted_first(pairs, W)
    return pairs, W, pairs.shape[0]


# ------------------------------------------------------------- conservative advancement


@njit
def approach_ratio(x0, fields, ne, pairs, slack, at_least=0.0):
    """Largest approach_ij / (q_ij + s) over the point pairs of the blocks ``pairs``
    (:func:`advance.approach_ratio`), or ``at_least`` if that is larger.

    Args:
        x0: control points at the start of the step (n_cp, 2).
        fields: control-point displacement fields (n_fields, n_cp, 2); the approach of a
            pair is the sum over the fields of max(0, -n . dr) (one field: the actual
            motion; two: the predictor's h v and h^2 a / 2).
        slack: s, the distance added to the gap.
        at_least: a ratio below which the caller needs no value (the threshold of its
            test): blocks, rows, chunks of CHUNK points of the other element and pairs
            that cannot exceed it are skipped unseen.

    0 when no pair approaches; pairs with room q + s <= s / 100 are left out (in contact).
    Rows at or beyond E (the JAX padding) are skipped, so a JAX list may be passed as is.
    """
    beam, allowed, s, exclusion, radius = ne.beam, ne.allowed, ne.s, ne.exclusion, ne.radius
    conn, R = ne.conn, ne.R
    E, ns, F = conn.shape[0], R.shape[1], fields.shape[0]
    # the coordinates apart, so that the loop over j reads contiguous memory
    X = _pair_points(x0, conn, R, pairs)
    xx, xy = np.ascontiguousarray(X[:, :, 0]), np.ascontiguousarray(X[:, :, 1])
    dxs, dys = np.empty((F, E, ns)), np.empty((F, E, ns))
    for f in range(F):
        D = _pair_points(fields[f], conn, R, pairs)
        copy_2d(dxs[f], D[:, :, 0])
        copy_2d(dys[f], D[:, :, 1])
    # bounds: the room of a pair is at least the distance of the point boxes less R1 + R2
    # plus s, its approach at most the sum over the fields of the two points' motions;
    # the same for chunks of CHUNK points of an element (their boxes and largest motion)
    box = _point_boxes(X, pairs, E)
    chunk_box = _chunk_boxes(X, pairs, E)
    chunk_motion = np.zeros((E, chunk_box.shape[1]))
    motion = np.zeros((E, ns))
    motion_max = np.zeros(E)
    done = np.zeros(E, dtype=np.bool_)
    for c in range(pairs.shape[0]):
        for side in range(2):
            e = pairs[c, side]
            if e < E and not done[e]:
                _element_motion(e, dxs, dys, motion, motion_max, chunk_motion)
                done[e] = True
    floor = 1e-2 * slack
    # the blocks in the order of their bound, largest first: a block whose bound is below
    # the ratio found is skipped unseen
    bound = np.zeros(pairs.shape[0])
    for c in range(pairs.shape[0]):
        e1, e2 = pairs[c, 0], pairs[c, 1]
        if e1 < E and e2 < E:
            room = _room_bound(box[e1], box[e2], radius[e1] + radius[e2], slack)
            bound[c] = (math.inf if room <= floor
                        else (motion_max[e1] + motion_max[e2]) / room)
    ratio = at_least
    for c in _ascending(-bound):
        e1, e2 = pairs[c, 0], pairs[c, 1]
        if e1 >= E or e2 >= E:
            continue
        if bound[c] <= ratio:
            continue  # no pair of this block can exceed the ratio found
        ratio = _block_ratio(ratio, e1, e2, xx, xy, dxs, dys, box, motion, motion_max,
                             chunk_box, chunk_motion, radius[e1] + radius[e2], slack, floor,
                             beam, allowed, s, exclusion)
    return ratio


@njit_uncounted
def _element_motion(e, dxs, dys, motion, motion_max, chunk_motion):
    """The motion bounds of :func:`approach_ratio` for element e: of each of its points
    (the sum over the fields of its length, raised by _BOUND_MARGIN), the largest, and
    the largest of each chunk of CHUNK points."""
    ns = dxs.shape[2]
    for i in range(ns):
        m = 0.0
        for f in range(dxs.shape[0]):
            m += math.sqrt(dxs[f, e, i] ** 2 + dys[f, e, i] ** 2)
        motion[e, i] = m * (1.0 + _BOUND_MARGIN)
        motion_max[e] = max(motion_max[e], motion[e, i])
        chunk_motion[e, i // CHUNK] = max(chunk_motion[e, i // CHUNK], motion[e, i])


@njit_uncounted
def _block_ratio(ratio, e1, e2, xx, xy, dxs, dys, box, motion, motion_max, chunk_box,
                 chunk_motion, r12, slack, floor, beam, allowed, s, exclusion):
    """The largest of ``ratio`` and approach / room over the point pairs of the block
    (e1, e2) (:func:`approach_ratio`'s loop): a row of element e1 is skipped whole when
    its room to the box of element e2 and the motions bound its pairs' ratios by the
    ratio found, and likewise each chunk of element e2's points within a row."""
    ns = xx.shape[1]
    # two beams: every pair may interact, no test per pair
    whole = allowed[beam[e1], beam[e2]] and beam[e1] != beam[e2]
    for i in range(ns):
        px, py = xx[e1, i], xy[e1, i]
        room_i = (_point_box_distance(px, py, box[e2, 0], box[e2, 1], box[e2, 2], box[e2, 3])
                  * (1.0 - _BOUND_MARGIN) - r12 + slack)
        if room_i > floor and (motion[e1, i] + motion_max[e2]) <= ratio * room_i:
            continue  # no pair of this row can exceed the ratio found
        for k in range(chunk_box.shape[1]):
            room_k = (_point_box_distance(px, py, chunk_box[e2, k, 0], chunk_box[e2, k, 1],
                                          chunk_box[e2, k, 2], chunk_box[e2, k, 3])
                      * (1.0 - _BOUND_MARGIN) - r12 + slack)
            if room_k > floor and (motion[e1, i] + chunk_motion[e2, k]) <= ratio * room_k:
                continue  # nor of this chunk
            ratio = _chunk_ratio(ratio, i, k * CHUNK, min((k + 1) * CHUNK, ns), e1, e2,
                                 whole, xx, xy, dxs, dys, r12, slack, floor, beam, allowed,
                                 s, exclusion)
    return ratio


@njit_inline
def _point_box_distance(px, py, lo_x, lo_y, hi_x, hi_y):
    """The distance of the point (px, py) to a box, at most the distance computed for
    any point pair with a point in the box (every operation rounds monotonically)."""
    dx = max(px - hi_x, lo_x - px, 0.0)
    dy = max(py - hi_y, lo_y - py, 0.0)
    return math.sqrt(dx * dx + dy * dy)


@njit_uncounted
def _chunk_ratio(ratio, i, first, last, e1, e2, whole, xx, xy, dxs, dys, r12, slack, floor,
                 beam, allowed, s, exclusion):
    """The largest of ``ratio`` and approach / room over the pairs of point i of element
    e1 with the points first..last-1 of element e2 (:func:`approach_ratio`'s pair
    arithmetic)."""
    F = dxs.shape[0]
    for j in range(first, last):
        if not (whole or _point_may_touch(beam, allowed, s, exclusion, e1, e2, i, j)):
            continue
        rx = xx[e1, i] - xx[e2, j]
        ry = xy[e1, i] - xy[e2, j]
        d = math.sqrt(rx * rx + ry * ry)
        room = d - r12 + slack
        # pairs with room <= s / 100 are in contact: left to the law
        if not room > floor:
            continue
        # the approach along n = r / max(d, 1e-300) times max(d, 1e-300): the divisions
        # only for a pair that may raise the ratio
        dd = max(d, 1e-300)
        scaled = 0.0
        for f in range(F):
            dx = dxs[f, e1, i] - dxs[f, e2, j]
            dy = dys[f, e1, i] - dys[f, e2, j]
            scaled += max(-(rx * dx + ry * dy), 0.0)
        if scaled > ratio * room * dd * (1.0 - _BOUND_MARGIN):
            # as the JAX twin: n by two divisions, the approach over the room
            nx, ny = rx / dd, ry / dd
            approach = 0.0
            for f in range(F):
                dx = dxs[f, e1, i] - dxs[f, e2, j]
                dy = dys[f, e1, i] - dys[f, e2, j]
                approach += max(-(nx * dx + ny * dy), 0.0)
            ratio = max(ratio, approach / room)
    return ratio


@njit
def _room_bound(a, b, r12, slack):
    """A lower bound of the room d - R1 - R2 + s of the point pairs of two boxes."""
    return _box_distance(a, b) * (1.0 - _BOUND_MARGIN) - r12 + slack


@njit
def predictor_approach_ratio(x0, v, a, h, ne, pairs, slack, at_least=0.0):
    """:func:`approach_ratio` of the predictor's motion split into h v and h^2 a / 2 (the
    ratio of :func:`step_set.advanced_step`); v, a the control-point velocities and
    accelerations (n_cp, 2)."""
    fields = np.empty((2, x0.shape[0], 2))
    c = 0.5 * h * h  # the JAX twin's 0.5 * h * h * a, scalars first
    for p in range(x0.shape[0]):
        for d in range(2):
            fields[0, p, d] = h * v[p, d]
            fields[1, p, d] = c * a[p, d]
    return approach_ratio(x0, fields, ne, pairs, slack, at_least)


@njit
def step_approach_ratio(x0, x_new, ne, pairs, slack, at_least=0.0):
    """:func:`approach_ratio` of the actual displacement x_new - x0 of a step (the
    ``approach`` of :func:`step_set.after_step`)."""
    fields = np.empty((1, x0.shape[0], 2))
    for p in range(x0.shape[0]):
        for d in range(2):
            fields[0, p, d] = x_new[p, d] - x0[p, d]
    return approach_ratio(x0, fields, ne, pairs, slack, at_least)


# ------------------------------------------------------------------- post-step check


@njit
def missed_blocks(x, ne, frozen_pairs, reach, interaction):
    """The checks after a step at x (:func:`problem.missed_blocks`): (an interacting block
    is not in ``frozen_pairs``, number of box candidates, smallest surface gap).

    Candidates: element pairs whose boxes grown by ``reach`` overlap; interacting: a
    candidate with a point pair closer than ``interaction`` (inf: every candidate). The
    gap is the smallest over the candidates' point pairs, or, with none (or none finite),
    :func:`box_gap_lower_bound`. Rows of ``frozen_pairs`` at or beyond E (the JAX
    padding) are ignored; its order does not matter."""
    E = ne.conn.shape[0]
    beam, allowed, s, exclusion = ne.beam, ne.allowed, ne.s, ne.exclusion
    frozen = np.zeros((E, E), dtype=np.bool_)
    for c in range(frozen_pairs.shape[0]):
        e1, e2 = frozen_pairs[c, 0], frozen_pairs[c, 1]
        if e1 < E and e2 < E:
            frozen[e1, e2] = True
    pairs = candidate_pairs(x, ne, reach)
    P = _pair_points(x, ne.conn, ne.R, pairs)
    box = _point_boxes(P, pairs, E)
    chunk_box = _chunk_boxes(P, pairs, E)
    radius = ne.radius
    # a block is skipped unseen when its point boxes are further apart than the gap found
    # and, if not frozen, than the interaction distance: the nearest block first, alone,
    # then the others on the cores, each from the gap of that one
    near = np.empty(pairs.shape[0])
    first = -1
    for c in range(pairs.shape[0]):
        near[c] = _box_distance(box[pairs[c, 0]], box[pairs[c, 1]]) * (1.0 - _BOUND_MARGIN)
        if first < 0 or near[c] < near[first]:
            first = c
    missing = False
    gap = math.inf
    if first >= 0:
        missing, gap = _block_missed(first, False, math.inf, pairs, P, box, chunk_box, near,
                                     frozen, radius, interaction, beam, allowed, s,
                                     exclusion)
        flags, gaps = _blocks_missed(first, missing, gap, pairs, P, box, chunk_box, near,
                                     frozen, radius, interaction, beam, allowed, s,
                                     exclusion)
        for c in range(pairs.shape[0]):
            missing = missing or flags[c]
            gap = min(gap, gaps[c])
    if not np.isfinite(gap):
        gap = box_gap_lower_bound(x, ne, reach)
    return missing, pairs.shape[0], gap


@njit_parallel
def _blocks_missed(first, missing, gap, pairs, P, box, chunk_box, near, frozen, radius,
                   interaction, beam, allowed, s, exclusion):
    """:func:`_block_missed` of every block but ``first``, on the cores, each from the
    ``missing`` and ``gap`` of that one: (missed flags, gaps)."""
    flags = np.zeros(pairs.shape[0], dtype=np.bool_)
    gaps = np.full(pairs.shape[0], math.inf)
    for c in prange(pairs.shape[0]):
        if c != first:
            # prange counts in uint64: the index as the serial call passes it, so that
            # the kernel is compiled once
            flags[c], gaps[c] = _block_missed(np.int64(c), missing, gap, pairs, P, box,
                                              chunk_box, near, frozen, radius, interaction,
                                              beam, allowed, s, exclusion)
    return flags, gaps


@njit
def _chunk_boxes(P, pairs, E):
    """(E, n_chunks, 4) boxes (lo_x, lo_y, hi_x, hi_y) of the chunks of CHUNK contact
    points (the last may be short) of the elements that occur in ``pairs``
    (:func:`~beamcontact.contact.blocks_native.chunk_boxes`; the others are left as they
    are)."""
    out = np.empty((E, (P.shape[1] + CHUNK - 1) // CHUNK, 4))
    for c in range(pairs.shape[0]):
        for side in range(2):
            e = pairs[c, side]
            if e < E:
                chunk_boxes(P[e], out[e])
    return out


@njit
def _block_missed(c, missing, gap, pairs, P, box, chunk_box, near, frozen, radius,
                  interaction, beam, allowed, s, exclusion):
    """(an interacting block c missing from ``frozen``, the smallest gap of its point pairs
    or ``gap``), given a block already ``missing`` and a ``gap`` already found (the
    arithmetic of :func:`missed_blocks`)."""
    e1, e2 = pairs[c, 0], pairs[c, 1]
    r12 = radius[e1] + radius[e2]
    check = not (missing or frozen[e1, e2])
    if near[c] - r12 >= gap and not (check and near[c] < interaction):
        return False, gap
    nearest = math.sqrt(_nearest2(e1, e2, P, box, chunk_box, beam, allowed, s, exclusion))
    gap = min(gap, nearest - r12)
    return check and nearest < interaction, gap


@njit_uncounted
def _nearest2(e1, e2, P, box, chunk_box, beam, allowed, s, exclusion):
    """The smallest squared distance of the point pairs of elements e1, e2 that may
    interact (inf: none). The smallest squared distance first, one square root after: the
    square root and d - r12 are monotone in floating point too, so the nearest d and the
    smallest gap are the numbers that a root per pair would give. A row of e1, and a
    chunk of CHUNK points of e2 within a row, whose box is no nearer than the nearest
    pair found is skipped unseen (point_box_gap2 is a lower bound in floating point)."""
    ns = P.shape[1]
    whole = allowed[beam[e1], beam[e2]] and beam[e1] != beam[e2]
    nearest2 = math.inf
    for i in range(ns):
        px, py = P[e1, i, 0], P[e1, i, 1]
        if point_box_gap2(px, py, box[e2, 0], box[e2, 1], box[e2, 2],
                          box[e2, 3]) >= nearest2:
            continue
        for k in range(chunk_box.shape[1]):
            if point_box_gap2(px, py, chunk_box[e2, k, 0], chunk_box[e2, k, 1],
                              chunk_box[e2, k, 2], chunk_box[e2, k, 3]) >= nearest2:
                continue
            for j in range(k * CHUNK, min((k + 1) * CHUNK, ns)):
                rx = px - P[e2, j, 0]
                ry = py - P[e2, j, 1]
                sq = rx * rx + ry * ry
                if sq < nearest2 and (whole or _point_may_touch(beam, allowed, s,
                                                                exclusion, e1, e2, i, j)):
                    nearest2 = sq
    return nearest2


# ---------------------------------------------------------------- the set of one step


class NativeLaw(NamedTuple):
    """A contact law as the compiled step reads it (plain numbers, no law object).

    Attributes:
        code: blocks_native.LAW_CG or LAW_PENALTY.
        points, zones: IPIP with pairing "points" (the closest-point weights) or "zones"
            (the middle of each plateau of local minima); neither: an integrated law
            (the arc-length weights).
        reach, interaction, slack: the broad phase's reach, the distance within which
            a block interacts (inf: every candidate) and the law's advancement slack.
        m, q_reg, cutoff: the coarse-grained parameters (0 for the penalty).
        amplitude, r12: (E, E) the law's amplitude and R1 + R2 of every element pair.
        local: (E,) int64 the index of each element within its beam (the zones' grid).
    """

    code: int
    points: bool
    zones: bool
    reach: float
    interaction: float
    slack: float
    m: float
    q_reg: float
    cutoff: float
    amplitude: np.ndarray
    r12: np.ndarray
    local: np.ndarray


@njit
def frozen_blocks(ne, law, pairs, W):
    """The frozen set of the blocks ``pairs`` with weights W, as the compiled attempt and
    its contact kernel take it: (conn, R, pairs, W, R1 + R2, amplitudes, law code, m,
    q_reg, cutoff)."""
    r12 = np.empty(pairs.shape[0])
    amplitudes = np.empty(pairs.shape[0])
    for p in range(pairs.shape[0]):
        r12[p] = law.r12[pairs[p, 0], pairs[p, 1]]
        amplitudes[p] = law.amplitude[pairs[p, 0], pairs[p, 1]]
    return (ne.conn, ne.R, pairs, W, r12, amplitudes, law.code, law.m, law.q_reg, law.cutoff)


@njit
def frozen_set_at(x, motion, ne, law):
    """The blocks and weights to freeze at configuration x for a motion of at most
    ``motion`` (the twin of :func:`step_set.step_set`, and of
    :meth:`problem.ContactProblem.frozen_set` in statics): (pairs, W, number of box
    candidates). IPIP: the candidate blocks and the weights of the law's pairing at the
    activation gap 2 motion, the blocks with a weight first; an integrated law: the
    blocks within its interaction distance, the arc-length weights."""
    if law.points or law.zones:
        pairs = candidate_pairs(x, ne, law.reach + motion)
        count = pairs.shape[0]
        q = block_gaps(x, ne, pairs)
        if law.points:
            W = point_weights(q, pairs, ne, 2.0 * motion)
        else:
            W = zone_weights(q, pairs, ne.beam, law.local, 2.0 * motion)
        pairs, W = weighted_first(pairs, W)
        return pairs, W, count
    pairs, count = near_candidates(x, ne, law.reach, law.interaction, motion)
    ns = ne.R.shape[1]
    W = np.empty((pairs.shape[0], ns, ns))
    for p in range(pairs.shape[0]):
        copy_2d(W[p], arc_length_weights(ne, pairs[p, 0], pairs[p, 1]))
    return pairs, W, count


@njit
def step_set_at(x0, x_pred, v, a, h, motion, ne, law):
    """The contact set of a step h chosen at its predictor x_pred
    (:func:`frozen_set_at`) and the step after the conservative advancement
    (:func:`step_set.advanced_step`): (pairs, W, number of box candidates, h used). x0:
    the control points at the start, v, a their velocities and accelerations (n_cp, 2),
    ``motion`` the bound of the predictor's motion."""
    pairs, W, count = frozen_set_at(x_pred, motion, ne, law)
    # a ratio up to ADVANCE_FRACTION leaves the step as it is: no need to know it
    ratio = predictor_approach_ratio(x0, v, a, h, ne, pairs, law.slack, ADVANCE_FRACTION)
    return pairs, W, count, h * min(1.0, ADVANCE_FRACTION / max(ratio, 1e-300))


@njit
def after_step(x0, x_new, x_pred, motion, ne, law, pairs):
    """The checks after a step from x0 to x_new under the frozen blocks ``pairs``
    (:func:`step_set.after_step`): (a block was missed or the solution left the
    predictor's motion bound, number of box candidates at x_new, smallest surface gap,
    the largest approach ratio of the step, or ADVANCE_ACCEPT if it is not larger: the
    controller's test needs no more)."""
    missing, count, gap = missed_blocks(x_new, ne, pairs, law.reach, law.interaction)
    worst = 0.0
    for p in range(x_new.shape[0]):
        dx, dy = x_new[p, 0] - x_pred[p, 0], x_new[p, 1] - x_pred[p, 1]
        worst = max(worst, math.sqrt(dx * dx + dy * dy))
    missing = missing or worst > motion + 1e-6 * law.reach
    # the controller tests approach > ADVANCE_ACCEPT: a smaller value is not needed
    return missing, count, gap, step_approach_ratio(x0, x_new, ne, pairs, law.slack,
                                                    ADVANCE_ACCEPT)
