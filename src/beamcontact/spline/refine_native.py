"""Boehm's knot insertion (P&T A5.1, CurveKnotIns) of many knots in ascending order,
compiled, in time linear in the number of control points: the twin of
:func:`beamcontact.spline.refine.insert_homogeneous` applied knot after knot, with the
same arithmetic (tests/test_spline_geometry.py holds them equal bit for bit).

Inserted one at a time into arrays, every insertion copies all control points behind
it: 10 000 elements cost seconds a beam. Here the current arrays live in gap buffers of
their final size: a prefix at the front and the suffix not yet reached at the back, so
an insertion moves only the points it changes. An insertion at u changes control points
from span(u) - p on, and every later knot is larger, so what lies before is final.

Rows are copied element by element (:func:`~beamcontact.arrays_native.copy_1d`), never
as ``a[i] = b[j]``: such an
assignment makes Numba compile its error message for mismatched shapes (string
formatting of the shapes), 2 s of this module's 3 s of compilation with empty caches
(docs/engines.md, "Compilation").
"""

import numpy as np

from beamcontact._native import njit
from beamcontact.arrays_native import copy_1d


@njit
def _get(buf, m, shift, i):
    """Element i of the logical array held as buf[:m] (prefix) and buf[m + shift:]."""
    return buf[i] if i < m else buf[i + shift]


@njit
def _index(m, shift, i):
    """The row of buf holding row i of the logical array buf[:m] + buf[m + shift:]."""
    return i if i < m else i + shift


@njit
def _move_boundary(buf, m, shift, target):
    """The gap buffer's prefix moved to end at ``target``; returns the new m (buf of
    rows, (n, d))."""
    while m < target:
        copy_1d(buf[m], buf[m + shift])
        m += 1
    while m > target:
        m -= 1
        copy_1d(buf[m + shift], buf[m])
    return m


@njit
def insert_sorted_into(degree, knots, pw, values, counts, knots_out, pw_out):
    """Insert values[j] counts[j] times, j in ascending order of values, into the curve
    (knots, pw) of ``degree``: the result into knots_out and pw_out (their final sizes).
    Returns -1, or the index j of the first insertion that would exceed multiplicity
    ``degree`` (outputs then unfinished)."""
    p = degree
    n_k, n_p = knots.shape[0], pw.shape[0]
    total_k, total_p = knots_out.shape[0], pw_out.shape[0]
    # gap buffers: the logical array is buf[:m] followed by buf[m + shift:]
    kn = knots_out.reshape(-1, 1)  # rows of one knot, for _move_boundary
    for i in range(n_k):
        knots_out[total_k - n_k + i] = knots[i]
    for i in range(n_p):
        copy_1d(pw_out[total_p - n_p + i], pw[i])
    mk, shift_k = 0, total_k - n_k
    mp, shift_p = 0, total_p - n_p
    dim = pw.shape[1]
    r = np.empty((p + 1, dim))
    for j in range(values.shape[0]):
        u, times = values[j], counts[j]
        nk = total_k - shift_k  # the current number of knots
        # A2.1 on the current knots
        n = nk - p - 2
        if u >= _get(knots_out, mk, shift_k, n + 1):
            k = n
        elif u <= _get(knots_out, mk, shift_k, p):
            k = p
        else:
            lo, hi = 0, nk  # the first index with knot > u, minus 1
            while lo < hi:
                mid = (lo + hi) // 2
                if _get(knots_out, mk, shift_k, mid) > u:
                    hi = mid
                else:
                    lo = mid + 1
            k = lo - 1
        # multiplicity of u: the run of knots within 1e-14 of it, around k (sorted)
        s = 0
        i = k
        while i >= 0 and abs(_get(knots_out, mk, shift_k, i) - u) <= 1e-14:
            s += 1
            i -= 1
        i = k + 1
        while i < nk and abs(_get(knots_out, mk, shift_k, i) - u) <= 1e-14:
            s += 1
            i += 1
        if times + s > p:
            return j
        # the points that change: P[k-p .. k-s]; those before stay, those after shift
        mp = _move_boundary(pw_out, mp, shift_p, k - s)
        for i in range(p - s + 1):
            copy_1d(r[i], pw_out[_index(mp, shift_p, k - p + i)])
        for jj in range(1, times + 1):
            L = k - p + jj
            for i in range(p - jj - s + 1):
                alpha = ((u - _get(knots_out, mk, shift_k, L + i))
                         / (_get(knots_out, mk, shift_k, i + k + 1)
                            - _get(knots_out, mk, shift_k, L + i)))
                for d in range(dim):
                    r[i, d] = alpha * r[i + 1, d] + (1.0 - alpha) * r[i, d]
            copy_1d(pw_out[L], r[0])
            copy_1d(pw_out[k + times - jj - s], r[p - jj - s])
        L = k - p + times
        for i in range(L + 1, k - s):
            copy_1d(pw_out[i], r[i - L])
        # the prefix now ends after Q[k - s + times - 1]; the suffix (P[k-s:]) stays put
        mp = k - s + times
        shift_p -= times
        mk = _move_boundary(kn, mk, shift_k, k + 1)
        for i in range(times):
            knots_out[mk + i] = u
        mk += times
        shift_k -= times
    return -1
