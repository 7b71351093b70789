"""Native (Numba) contact kernels of one element pair and of one element against one rigid
obstacle: energy, gradient and Hessian in the element's control points.

The JAX path (:mod:`beamcontact.contact.blocks`, :mod:`beamcontact.contact.obstacles`)
stays the definition; these kernels compute the same sums (tests/test_native_contact.py):
for a block with contact points p1_i = R1_i X1, p2_j = R2_j X2, r_ij = p1_i - p2_j and
s = r . r, the energy sum_ij W_ij f(s_ij) with f(s) = phi(sqrt(s)) the pair law (eq. 9
coarse-grained, eq. 3 IPIP penalty), the pair gradient 2 W f' r and Hessian
2 W f' I + 4 W f'' r r^T lifted to the control points by the basis rows.

Where the JAX path evaluates every point pair of a block, these skip the pairs that
contribute exactly nothing: weight 0 (IPIP pairs not selected, masked pairs) and
centre-line distance at or beyond the law's reach (the cutoff of eq. 9; R1 + R2 for the
penalty, which acts only on overlaps), a whole row at once when its point is beyond the
reach of the bounding box of the other element's points, and chunks of CHUNK points of
the other element by their boxes. Most pairs of a candidate block are beyond the cutoff,
which is where the speed comes from. The law is evaluated for all pairs within reach of
a block at once (:func:`pair_laws`: the coarse-grained law pass by pass, so that its
square roots and divisions run as SIMD instructions), then summed row by row in the
order of j, so that every sum is the one of a pair-by-pair loop, bit for bit.

The law is chosen by a small integer (LAW_CG, LAW_PENALTY) and its parameters travel as
plain floats: cached Numba code cannot close over a law object. Layout: for elements of
n1 and n2 control points, f has 2 (n1 + n2) entries and k is square of that size, in the
order of the JAX ``fold_block_forces``: (X1.ravel(), X2.ravel()), i.e. dof 2 k + a of
element 1 then 2 n1 + 2 l + b of element 2 (``f[:2 n1]`` and ``f[2 n1:]`` are the two
elements' rows).
"""

import math
from typing import NamedTuple

import numpy as np

from beamcontact._native import (
    njit,
    njit_inline,
    njit_parallel_uncounted,
    njit_uncounted,
    prange,
)
from beamcontact.contact.laws.coarse_grained_native import cg_obstacle, cg_pair_s_many
from beamcontact.contact.laws.penalty_native import penalty_obstacle, penalty_pair_s

LAW_CG = 0
LAW_PENALTY = 1

# a margin on the squared reach: fl(reach * reach) may round below reach^2, and a pair
# skipped must be one whose law is exactly zero (d >= reach after the sqrt)
_REACH_MARGIN = 1.0 + 1e-12

# the points of element 2 are tested against a row's point in chunks of this many, each by
# its box first: most pairs of a block are beyond the reach, and a chunk's box test skips
# all of its pairs at once
CHUNK = 8


@njit_inline
def pair_reach(law, R12, cutoff):
    """The centre-line distance at and beyond which a pair contributes nothing: the
    cutoff of eq. (9), R1 + R2 for the penalty (eq. 3 acts on overlaps only)."""
    return cutoff if law == LAW_CG else R12


@njit
def obstacle_law(law, q, R, amplitude, w, m, q_reg, cutoff):
    """(e, de/dq, d2e/dq2) of one contact point at gap q from an obstacle (eq. 9's
    section-to-half-space counterpart, or eq. 3 with weight 1)."""
    if law == LAW_CG:
        return cg_obstacle(q, R, amplitude, w, m, q_reg, cutoff)
    return penalty_obstacle(q, amplitude)


@njit_uncounted
def _points(R, X, out):
    """out[i] = R_i X: the contact points of an element, (n_s, 2)."""
    for i in range(R.shape[0]):
        x = 0.0
        y = 0.0
        for a in range(X.shape[0]):
            x += R[i, a] * X[a, 0]
            y += R[i, a] * X[a, 1]
        out[i, 0] = x
        out[i, 1] = y


@njit_inline
def point_box_gap2(px, py, lo_x, lo_y, hi_x, hi_y):
    """Squared distance from (px, py) to a box: a lower bound of the squared distance to
    every point in it, in floating point too (rounding is monotone)."""
    dx = max(lo_x - px, 0.0, px - hi_x)
    dy = max(lo_y - py, 0.0, py - hi_y)
    return dx * dx + dy * dy


@njit_inline
def _add_diagonal_block(k, o, Ri, sxx, sxy, syy):
    """k[o + 2a + c, o + 2b + e] += Ri_a Ri_b S_ce, S = [[sxx, sxy], [sxy, syy]]."""
    n = Ri.shape[0]
    for a in range(n):
        ra = Ri[a]
        if ra == 0.0:  # padding entries of the basis rows carry nothing
            continue
        for b in range(n):
            c = ra * Ri[b]
            k[o + 2 * a, o + 2 * b] += c * sxx
            k[o + 2 * a, o + 2 * b + 1] += c * sxy
            k[o + 2 * a + 1, o + 2 * b] += c * sxy
            k[o + 2 * a + 1, o + 2 * b + 1] += c * syy


@njit_inline
def _add_coupling_row(k, o, Ri, R2, cols, h, count):
    """The coupling block of one point i of element 1: k[2a + c, o + 2b + e] -=
    Ri_a sum_j H_ij^ce R2_jb over its ``count`` interacting points j = cols[:count], whose
    pair Hessians (xx, xy, yy) are h[:count]."""
    for b in range(R2.shape[1]):
        # the sums over j in registers: accumulating into an array per pair costs more
        txx = txy = tyy = 0.0
        for jj in range(count):
            c = R2[cols[jj], b]
            txx += h[jj, 0] * c
            txy += h[jj, 1] * c
            tyy += h[jj, 2] * c
        for a in range(Ri.shape[0]):
            ra = Ri[a]
            k[2 * a, o + 2 * b] -= ra * txx
            k[2 * a, o + 2 * b + 1] -= ra * txy
            k[2 * a + 1, o + 2 * b] -= ra * txy
            k[2 * a + 1, o + 2 * b + 1] -= ra * tyy


@njit_uncounted
def bounding_box(p):
    """(lo_x, lo_y, hi_x, hi_y) of points p (n, 2)."""
    lo_x, lo_y, hi_x, hi_y = math.inf, math.inf, -math.inf, -math.inf
    for j in range(p.shape[0]):
        lo_x, hi_x = min(lo_x, p[j, 0]), max(hi_x, p[j, 0])
        lo_y, hi_y = min(lo_y, p[j, 1]), max(hi_y, p[j, 1])
    return lo_x, lo_y, hi_x, hi_y


@njit_uncounted
def chunk_boxes(p, out):
    """out[c] = the box (lo_x, lo_y, hi_x, hi_y) of points p[c CHUNK:(c + 1) CHUNK] (the
    last chunk may be short)."""
    for c in range(out.shape[0]):
        # four numbers, not out[c] = the tuple: that assignment compiles Numba's error
        # message for mismatched shapes (1.4 s with empty caches)
        lo_x, lo_y, hi_x, hi_y = bounding_box(p[c * CHUNK:min((c + 1) * CHUNK, p.shape[0])])
        out[c, 0], out[c, 1], out[c, 2], out[c, 3] = lo_x, lo_y, hi_x, hi_y


@njit_uncounted
def _row_within_reach(px, py, p2, boxes2, W, i, reach2, j_out, r_out, s_out, start):
    """The pairs of point i, (px, py), of element 1 with the points p2 of element 2 that
    the law may see: weight W[i, j] not 0 and squared distance below reach2, in the order
    of j, written from index ``start`` on (j, r = (px, py) - p2[j], s = r . r). Chunks of
    CHUNK points of p2 whose box (boxes2) is beyond the reach are skipped unseen. Returns
    the index after the last pair written. (W whole and the row's index: a row view
    passed to this call would count a reference twice per row.)"""
    c_out = start
    n2 = p2.shape[0]
    for c in range(boxes2.shape[0]):
        b = boxes2[c]
        if point_box_gap2(px, py, b[0], b[1], b[2], b[3]) >= reach2:
            continue
        for j in range(c * CHUNK, min((c + 1) * CHUNK, n2)):
            if W[i, j] == 0.0:
                continue
            rx, ry = px - p2[j, 0], py - p2[j, 1]
            sj = rx * rx + ry * ry
            if sj >= reach2:
                continue
            j_out[c_out] = j
            r_out[c_out, 0] = rx
            r_out[c_out, 1] = ry
            s_out[c_out] = sj
            c_out += 1
    return c_out


@njit_uncounted
def pair_laws(law, s, count, R12, amplitude, m, q_reg, cutoff, f, f1, f2, d, inv, base):
    """(f, df/ds, d2f/ds2) of the pair law ``law`` (eq. 9 or 3) at each squared distance
    s[:count], into f, f1, f2 (the coarse-grained law pass by pass,
    :func:`~beamcontact.contact.laws.coarse_grained_native.cg_pair_s_many`, bitwise the
    numbers of ``cg_pair_s``, with d, inv, base its work arrays)."""
    if law == LAW_CG:
        cg_pair_s_many(s, count, R12, amplitude, m, q_reg, cutoff, f, f1, f2, d, inv, base)
        return
    for c in range(count):
        f[c], f1[c], f2[c] = penalty_pair_s(s[c], R12, amplitude)


@njit_inline
def _row_sums(Wi, js, r, phi, d1, d2, first, last, sums2, cols, h):
    """The pairs first..last-1 of one point of element 1 (:func:`_row_within_reach`)
    with their law values (phi, d1, d2): adds each pair's gradient and Hessian (gx, gy,
    hxx, hxy, hyy) to sums2[j] and records the j in cols and their Hessians in h.
    Returns (energy, the sums of (gx, gy, hxx, hxy, hyy) over the pairs)."""
    energy = gx1 = gy1 = hxx1 = hxy1 = hyy1 = 0.0
    for c in range(first, last):
        j = js[c]
        w = Wi[j]
        rx, ry = r[c, 0], r[c, 1]
        energy += w * phi[c]
        A, B = 2.0 * w * d1[c], 4.0 * w * d2[c]  # pair gradient A r, Hessian A I + B r r^T
        gx, gy = A * rx, A * ry
        hxx, hxy, hyy = A + B * rx * rx, B * rx * ry, A + B * ry * ry
        gx1 += gx
        gy1 += gy
        hxx1 += hxx
        hxy1 += hxy
        hyy1 += hyy
        sums2[j, 0] += gx
        sums2[j, 1] += gy
        sums2[j, 2] += hxx
        sums2[j, 3] += hxy
        sums2[j, 4] += hyy
        cc = c - first
        cols[cc] = j
        h[cc, 0] = hxx
        h[cc, 1] = hxy
        h[cc, 2] = hyy
    return energy, gx1, gy1, hxx1, hxy1, hyy1


@njit_uncounted
def _pairs_within_reach(law, X1, X2, R1, R2, W, R12, amplitude, m, q_reg, cutoff, p1, p2,
                        boxes2, rows, js, r, pair):
    """The point pairs of a block that its law sees and the law's values there, into the
    work arrays (:class:`BlockScratch`): row i's pairs are rows[i]..rows[i + 1] - 1, in
    the order of j, with their j in js, r in r, s in pair[0] and the law's (phi,
    dphi/ds, d2phi/ds2) in pair[1:4] (arguments as :func:`block_into`)."""
    ns1 = R1.shape[0]
    _points(R1, X1, p1)
    _points(R2, X2, p2)
    lo_x, lo_y, hi_x, hi_y = bounding_box(p2)
    chunk_boxes(p2, boxes2)
    reach = pair_reach(law, R12, cutoff)
    reach2 = reach * reach * _REACH_MARGIN
    sq = pair[0]
    count = 0
    for i in range(ns1):
        rows[i] = count
        px, py = p1[i, 0], p1[i, 1]
        if point_box_gap2(px, py, lo_x, lo_y, hi_x, hi_y) < reach2:  # else beyond reach
            count = _row_within_reach(px, py, p2, boxes2, W, i, reach2, js, r, sq, count)
    rows[ns1] = count
    pair_laws(law, sq, count, R12, amplitude, m, q_reg, cutoff, pair[1], pair[2], pair[3],
              pair[4], pair[5], pair[6])


class BlockScratch(NamedTuple):
    """The work arrays of the block kernels, one row per run of blocks
    (:func:`block_scratch`):
    made once per call of :func:`blocks_into` and :func:`blocks_energy`, not per block
    (a coarse-grained block allocated 19 arrays; the peer drop made 5.5 million
    allocations, 4 % of its step loop). Per block: X1, X2 the control points (n1, 2),
    (n2, 2); p1, p2 the contact points (n_s1, 2), (n_s2, 2); boxes2 the chunk boxes of
    p2; rows (n_s1 + 1,), js (n_s1 n_s2,), r (n_s1 n_s2, 2) and pair (7, n_s1 n_s2): the
    pairs within reach (s, phi, dphi/ds, d2phi/ds2 and the law's three work rows);
    sums2 (n_s2, 5), active2, cols (n_s2,) and h (n_s2, 3): the sums per point of
    element 2."""
    X1: np.ndarray
    X2: np.ndarray
    p1: np.ndarray
    p2: np.ndarray
    boxes2: np.ndarray
    rows: np.ndarray
    js: np.ndarray
    r: np.ndarray
    pair: np.ndarray
    sums2: np.ndarray
    active2: np.ndarray
    cols: np.ndarray
    h: np.ndarray


@njit
def block_scratch(runs, n1, n2, ns1, ns2):
    """:class:`BlockScratch` of ``runs`` rows (one per run of blocks) for blocks of
    elements with n1 and n2 control points and ns1 and ns2 contact points."""
    cap = ns1 * ns2
    return BlockScratch(
        np.empty((runs, n1, 2)), np.empty((runs, n2, 2)), np.empty((runs, ns1, 2)),
        np.empty((runs, ns2, 2)), np.empty((runs, (ns2 + CHUNK - 1) // CHUNK, 4)),
        np.empty((runs, ns1 + 1), dtype=np.int64), np.empty((runs, cap), dtype=np.int64),
        np.empty((runs, cap, 2)), np.empty((runs, 7, cap)), np.empty((runs, ns2, 5)),
        np.empty((runs, ns2), dtype=np.bool_), np.empty((runs, ns2), dtype=np.int64),
        np.empty((runs, ns2, 3)))


@njit
def block_energy(law, X1, X2, R1, R2, W, R12, amplitude, m, q_reg, cutoff):
    """The energy of one element pair alone (arguments as :func:`block_into`): the same
    sums, bit for bit, without the gradient and Hessian."""
    ws = block_scratch(1, X1.shape[0], X2.shape[0], R1.shape[0], R2.shape[0])
    return _block_energy(law, X1, X2, R1, R2, W, R12, amplitude, m, q_reg, cutoff, ws.p1[0],
                         ws.p2[0], ws.boxes2[0], ws.rows[0], ws.js[0], ws.r[0], ws.pair[0])


@njit_uncounted
def _block_energy(law, X1, X2, R1, R2, W, R12, amplitude, m, q_reg, cutoff, p1, p2, boxes2,
                  rows, js, r, pair):
    """:func:`block_energy` with its work arrays (:class:`BlockScratch`)."""
    _pairs_within_reach(law, X1, X2, R1, R2, W, R12, amplitude, m, q_reg, cutoff, p1, p2,
                        boxes2, rows, js, r, pair)
    phi = pair[1]
    energy = 0.0
    for i in range(R1.shape[0]):
        first, last = rows[i], rows[i + 1]
        if last == first:
            continue
        e = 0.0
        for c in range(first, last):
            e += W[i, js[c]] * phi[c]
        energy += e
    return energy


@njit
def block_into(law, X1, X2, R1, R2, W, R12, amplitude, m, q_reg, cutoff, f, k, tangent=True):
    """Energy of one element pair; its gradient into f (2 (n1 + n2),) and Hessian into k
    (square), both overwritten, in the layout of the module docstring (``tangent`` False:
    k is left alone, the energy and gradient are the same numbers).

    Arguments, in call order:
        law: LAW_CG (eq. 9) or LAW_PENALTY (eq. 3).
        X1, X2: control points of the two elements, (n1, 2) and (n2, 2).
        R1, R2: basis rows of their contact points, (n_s1, n1) and (n_s2, n2).
        W: weights of the point pairs (n_s1, n_s2): w1_i w2_j for the coarse-grained law,
            the selection weights for IPIP; pairs of weight 0 are skipped.
        R12: R1 + R2 of the two beams.
        amplitude: the law's amplitude of the pair of beams (``law.amplitude``).
        m, q_reg, cutoff: the coarse-grained exponent, regularisation gap and cutoff
            (unused by the penalty).

    In three passes: the pairs within the law's reach, row by row; the law at all of
    them at once; the sums and lifts row by row, each row's pairs in the order of j.
    """
    ws = block_scratch(1, X1.shape[0], X2.shape[0], R1.shape[0], R2.shape[0])
    return _block_into(law, X1, X2, R1, R2, W, R12, amplitude, m, q_reg, cutoff, f, k,
                       tangent, ws.p1[0], ws.p2[0], ws.boxes2[0], ws.rows[0], ws.js[0],
                       ws.r[0], ws.pair[0], ws.sums2[0], ws.active2[0], ws.cols[0], ws.h[0])


@njit_uncounted
def _block_into(law, X1, X2, R1, R2, W, R12, amplitude, m, q_reg, cutoff, f, k, tangent, p1,
                p2, boxes2, rows, js, r, pair, sums2, active2, cols, h):
    """:func:`block_into` with its work arrays (:class:`BlockScratch`), plain arrays: a
    call that takes the NamedTuple counts a reference of each of its arrays."""
    o = 2 * X1.shape[0]
    ns1 = R1.shape[0]
    f[:] = 0.0
    if tangent:
        k[:, :] = 0.0
    _pairs_within_reach(law, X1, X2, R1, R2, W, R12, amplitude, m, q_reg, cutoff, p1, p2,
                        boxes2, rows, js, r, pair)
    phi, d1, d2 = pair[1], pair[2], pair[3]
    # per point j of element 2: the sums over i of (gx, gy, hxx, hxy, hyy)
    sums2[:, :] = 0.0
    active2[:] = False
    energy = 0.0
    for i in range(ns1):
        first, last = rows[i], rows[i + 1]
        if last == first:
            continue
        e, gx, gy, hxx, hxy, hyy = _row_sums(W[i], js, r, phi, d1, d2, first, last, sums2,
                                             cols, h)
        energy += e
        for jj in range(last - first):
            active2[cols[jj]] = True
        for a in range(X1.shape[0]):
            f[2 * a] += R1[i, a] * gx
            f[2 * a + 1] += R1[i, a] * gy
        if tangent:
            _add_diagonal_block(k, 0, R1[i], hxx, hxy, hyy)
            _add_coupling_row(k, o, R1[i], R2, cols, h, last - first)
    _add_second_element(f, k, o, R2, sums2, active2, tangent)
    if tangent:
        for a in range(o):  # the lower coupling block is the transpose of the upper one
            for b in range(o, k.shape[0]):
                k[b, a] = k[a, b]
    return energy


@njit_inline
def _add_second_element(f, k, o, R2, sums2, active2, tangent):
    """Element 2's gradient -sum_j R2_j g_j and (``tangent``) diagonal block
    sum_j R2_j R2_j^T H_j, from the per-point sums (gx, gy, hxx, hxy, hyy) over the pairs
    of its ``active2`` points."""
    for j in range(R2.shape[0]):
        if not active2[j]:
            continue
        for b in range(R2.shape[1]):
            f[o + 2 * b] -= R2[j, b] * sums2[j, 0]
            f[o + 2 * b + 1] -= R2[j, b] * sums2[j, 1]
        if tangent:
            _add_diagonal_block(k, o, R2[j], sums2[j, 2], sums2[j, 3], sums2[j, 4])


@njit_inline
def _block_points(x, conn, pairs, p, X1, X2):
    """X1, X2 = the control points (n_loc, 2) of the elements of block p, rows conn[e] of
    x; returns the two elements."""
    e1, e2 = pairs[p, 0], pairs[p, 1]
    for a in range(conn.shape[1]):
        X1[a, 0], X1[a, 1] = x[conn[e1, a], 0], x[conn[e1, a], 1]
        X2[a, 0], X2[a, 1] = x[conn[e2, a], 0], x[conn[e2, a], 1]
    return e1, e2


@njit_inline
def _run(t, runs, n_pairs):
    """The blocks (first, last + 1) of run t of ``runs`` contiguous runs of n_pairs."""
    return t * n_pairs // runs, (t + 1) * n_pairs // runs


# blocks_into and blocks_energy share the blocks out in at most this many contiguous runs,
# each with its row of work arrays, the runs on the cores: the thread count cannot size
# them (compiled code that asks Numba for it cannot be cached to disk), and more runs
# than threads keep the cores balanced
BLOCK_RUNS = 16


@njit
def blocks_scratch(conn, R, n_pairs):
    """:func:`block_scratch` for :func:`blocks_into` and :func:`blocks_energy` of
    ``n_pairs`` blocks of elements with connectivity conn and basis rows R: a row per run
    of blocks (``BLOCK_RUNS``), at least one."""
    n, ns = conn.shape[1], R.shape[1]
    return block_scratch(max(1, min(BLOCK_RUNS, n_pairs)), n, n, ns, ns)


@njit_parallel_uncounted
def blocks_into(x, conn, R, pairs, W, R12, amplitudes, law, m, q_reg, cutoff, F, K, energies,
                tangent, ws):
    """Every element pair of a frozen set at once, on the cores: block p = pairs[p] of
    elements with control points conn[e] at x (n_cp, 2) and basis rows R[e], weights
    W[p], R12[p] and amplitudes[p] (:func:`block_into`) into F[p] (its gradient), K[p]
    (its Hessian) and energies[p]. Each block is computed whole by one thread, exactly
    as alone, so the caller's sums in block order do not depend on the threads
    (``tangent`` False: K is left alone). ``ws``: :func:`blocks_scratch`, a row per run
    of blocks (a run whole on one thread); this loop allocates nothing and counts no
    references (the caller holds every array)."""
    runs = ws.X1.shape[0]
    for t in prange(runs):
        X1, X2 = ws.X1[t], ws.X2[t]
        for p in range(*_run(t, runs, pairs.shape[0])):
            e1, e2 = _block_points(x, conn, pairs, p, X1, X2)
            energies[p] = _block_into(
                law, X1, X2, R[e1], R[e2], W[p], R12[p], amplitudes[p], m, q_reg, cutoff, F[p],
                K[p], tangent, ws.p1[t], ws.p2[t], ws.boxes2[t], ws.rows[t], ws.js[t],
                ws.r[t], ws.pair[t], ws.sums2[t], ws.active2[t], ws.cols[t], ws.h[t])


@njit_parallel_uncounted
def blocks_energy(x, conn, R, pairs, W, R12, amplitudes, law, m, q_reg, cutoff, energies, ws):
    """The energy of every element pair of a frozen set (:func:`block_energy`) into
    energies[p], on the cores, each block whole on one thread (as :func:`blocks_into`)."""
    runs = ws.X1.shape[0]
    for t in prange(runs):
        X1, X2 = ws.X1[t], ws.X2[t]
        for p in range(*_run(t, runs, pairs.shape[0])):
            e1, e2 = _block_points(x, conn, pairs, p, X1, X2)
            energies[p] = _block_energy(law, X1, X2, R[e1], R[e2], W[p], R12[p], amplitudes[p],
                                        m, q_reg, cutoff, ws.p1[t], ws.p2[t], ws.boxes2[t],
                                        ws.rows[t], ws.js[t], ws.r[t], ws.pair[t])


@njit
def block_forces(law, X1, X2, R1, R2, W, R12, amplitude, m, q_reg, cutoff):
    """(energy, gradient, Hessian) of one element pair, freshly allocated (see
    :func:`block_into`)."""
    size = 2 * (X1.shape[0] + X2.shape[0])
    f = np.empty(size)
    k = np.empty((size, size))
    energy = block_into(law, X1, X2, R1, R2, W, R12, amplitude, m, q_reg, cutoff, f, k)
    return energy, f, k


@njit
def signed_distance(px, py, circle, point, normal, radius):
    """(s, ds/dx, ds/dy, d2s/dx2, d2s/dxdy, d2s/dy2) of the obstacle's signed distance at
    p: n . (p - p0) for a wall, |p - c| - r for a circle
    (:func:`beamcontact.contact.obstacles.signed_distance`)."""
    rx, ry = px - point[0], py - point[1]
    if not circle:
        return rx * normal[0] + ry * normal[1], normal[0], normal[1], 0.0, 0.0, 0.0
    r2 = rx * rx + ry * ry
    if not r2 > 1e-300:
        # obstacles.signed_distance's floor (a point at the centre is deep inside anyway):
        # constant below it, so JAX AD gives no derivatives there, nor does this
        return math.sqrt(1e-300) - radius, 0.0, 0.0, 0.0, 0.0, 0.0
    r = math.sqrt(r2)
    ux, uy = rx / r, ry / r
    return r - radius, ux, uy, (1.0 - ux * ux) / r, -ux * uy / r, (1.0 - uy * uy) / r


@njit
def obstacle_into(law, X, R, w, radius, circle, point, normal, obstacle_radius, amplitude, m,
                  q_reg, cutoff, f, k):
    """Energy of one element against one rigid obstacle; its gradient into f (2 n,) and
    Hessian into k (2 n, 2 n), both overwritten, in the order of X.ravel().

    Arguments, in call order:
        law: LAW_CG or LAW_PENALTY.
        X: control points (n, 2); R: basis rows of the contact points (n_s, n);
            w: their arc-length weights (n_s,); radius: the beam's radius R.
        circle, point, normal, obstacle_radius: the obstacle (``Obstacles`` fields: a
            wall's point and unit normal, or a circle's centre and radius).
        amplitude: ``law.obstacle_amplitude`` of the beam and obstacle.
        m, q_reg, cutoff: the coarse-grained parameters (unused by the penalty).
    """
    n = X.shape[0]
    f[:] = 0.0
    k[:, :] = 0.0
    energy = 0.0
    for i in range(R.shape[0]):
        px = py = 0.0
        for a in range(n):
            px += R[i, a] * X[a, 0]
            py += R[i, a] * X[a, 1]
        sd, nx, ny, sxx, sxy, syy = signed_distance(px, py, circle, point, normal,
                                                    obstacle_radius)
        e, d1, d2 = obstacle_law(law, sd - radius, radius, amplitude, w[i], m, q_reg, cutoff)
        if e == 0.0 and d1 == 0.0 and d2 == 0.0:
            continue  # beyond the law's reach
        energy += e
        # chain rule through s(p): H = e'' grad s grad s^T + e' Hess s
        for a in range(n):
            f[2 * a] += R[i, a] * d1 * nx
            f[2 * a + 1] += R[i, a] * d1 * ny
        _add_diagonal_block(k, 0, R[i], d2 * nx * nx + d1 * sxx, d2 * nx * ny + d1 * sxy,
                            d2 * ny * ny + d1 * syy)
    return energy


@njit
def obstacle_forces(law, X, R, w, radius, circle, point, normal, obstacle_radius, amplitude,
                    m, q_reg, cutoff):
    """(energy, gradient, Hessian) of one element against one obstacle, freshly allocated
    (see :func:`obstacle_into`)."""
    f = np.empty(2 * X.shape[0])
    k = np.empty((2 * X.shape[0], 2 * X.shape[0]))
    energy = obstacle_into(law, X, R, w, radius, circle, point, normal, obstacle_radius,
                           amplitude, m, q_reg, cutoff, f, k)
    return energy, f, k
