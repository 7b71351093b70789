"""The B-spline and NURBS basis point by point, compiled: P&T A2.1 (FindSpan) and A2.3
(DersBasisFuns), the rational basis by the quotient rule (paper eq. 40, P&T eq. 4.2), and
curve points as sums of the p + 1 non-zero functions (L. Piegl & W. Tiller, *The NURBS
Book*, 2nd ed., Springer 1997). :mod:`beamcontact.spline.basis` and
:class:`~beamcontact.spline.curve.NurbsCurve` call these; their tests are
tests/test_spline_basis.py.

Compiled because the discretisation of long beams evaluates the basis millions of times
(arc-length parameters, contact segment weights): as NumPy over arrays of points, A2.3 is
hundreds of small array operations per call, and 20 beams of 10 000 elements took minutes.
"""

import numpy as np

from beamcontact._native import njit, njit_parallel, prange
from beamcontact.arrays_native import count_not_above


@njit
def span_of(knots, degree, u):
    """Knot span index i with knots[i] <= u < knots[i+1] (P&T A2.1); u = knots[-1] and
    anything beyond belongs to the last non-empty span, anything at or below knots[p] to
    the first."""
    n = knots.shape[0] - degree - 2  # index of the last control point
    if u >= knots[n + 1]:
        return n
    if u <= knots[degree]:
        return degree
    return count_not_above(knots, u) - 1


@njit
def _ders_at(knots, p, span, u, nders, ndu, left, right, a, out):
    """A2.3 at one parameter: out[k, j] = the k-th derivative of N_{span-p+j}, k <= nders
    (rows above nders untouched); ndu (p+1, p+1), left, right (p+1,), a (2, p+1) scratch."""
    ndu[0, 0] = 1.0
    for j in range(1, p + 1):
        left[j] = u - knots[span + 1 - j]
        right[j] = knots[span + j] - u
        saved = 0.0
        for r in range(j):
            ndu[j, r] = right[r + 1] + left[j - r]
            temp = ndu[r, j - 1] / ndu[j, r]
            ndu[r, j] = saved + right[r + 1] * temp
            saved = left[j - r] * temp
        ndu[j, j] = saved
    for j in range(p + 1):
        out[0, j] = ndu[j, p]
    for r in range(p + 1):
        s1, s2 = 0, 1
        a[0, 0] = 1.0
        for k in range(1, nders + 1):
            d = 0.0
            rk, pk = r - k, p - k
            if r >= k:
                a[s2, 0] = a[s1, 0] / ndu[pk + 1, rk]
                d = a[s2, 0] * ndu[rk, pk]
            j1 = 1 if rk >= -1 else -rk
            j2 = k - 1 if r - 1 <= pk else p - r
            for j in range(j1, j2 + 1):
                a[s2, j] = (a[s1, j] - a[s1, j - 1]) / ndu[pk + 1, rk + j]
                d = d + a[s2, j] * ndu[rk + j, pk]
            if r <= pk:
                a[s2, k] = -a[s1, k - 1] / ndu[pk + 1, r]
                d = d + a[s2, k] * ndu[r, pk]
            out[k, r] = d
            s1, s2 = s2, s1
    factor = float(p)
    for k in range(1, nders + 1):
        for j in range(p + 1):
            out[k, j] *= factor
        factor *= p - k


@njit
def ders_basis_into(knots, p, spans, u, nders, out):
    """A2.3 at every u[i] in its span spans[i]: out (m, nders+1, p+1) as
    :func:`~beamcontact.spline.basis.basis_derivatives` returns it."""
    ndu = np.zeros((p + 1, p + 1))
    left, right, a = np.zeros(p + 1), np.zeros(p + 1), np.zeros((2, p + 1))
    for i in range(u.shape[0]):
        _ders_at(knots, p, spans[i], u[i], nders, ndu, left, right, a, out[i])


@njit
def _rational_at(knots, p, weights, u, ndu, left, right, a, N, out, second):
    """The rational basis R, dR/du, d2R/du2 at u into out (3, p+1) (zero second
    derivatives for p = 1; not computed, out[2] left alone, without ``second``); returns
    the index of the first non-zero function. N (3, p+1) is scratch."""
    span = span_of(knots, p, u)
    nders = min(2, p) if second else 1
    _ders_at(knots, p, span, u, nders, ndu, left, right, a, N)
    first = span - p
    W = W1 = W2 = 0.0
    for j in range(p + 1):
        w = weights[first + j]
        N[0, j] *= w
        W += N[0, j]
        N[1, j] *= w
        W1 += N[1, j]
        if nders == 2:
            N[2, j] *= w
            W2 += N[2, j]
        else:
            N[2, j] = 0.0
    for j in range(p + 1):
        R = N[0, j] / W
        R1 = (N[1, j] - R * W1) / W
        out[0, j], out[1, j] = R, R1
        if second:
            out[2, j] = (N[2, j] - 2.0 * R1 * W1 - R * W2) / W
    return first


@njit
def nurbs_basis_into(knots, p, weights, u, first, out):
    """The rational basis and its first two derivatives at every u[i]: first[i] the index
    of the first non-zero function, out[i] (3, p+1) the values R, dR/du, d2R/du2."""
    ndu = np.zeros((p + 1, p + 1))
    left, right, a = np.zeros(p + 1), np.zeros(p + 1), np.zeros((2, p + 1))
    N = np.zeros((3, p + 1))
    for i in range(u.shape[0]):
        first[i] = _rational_at(knots, p, weights, u[i], ndu, left, right, a, N, out[i],
                                True)


@njit_parallel
def curve_points_into(knots, p, weights, points, u, nders, out):
    """Curve points and parametric derivatives up to nders (<= 2) at every u[i]:
    out[k, i] = sum_j R^(k)_{first+j}(u[i]) points[first+j], out (nders+1, m, 2); the
    points in pieces on the cores (each point alone, whatever the threads)."""
    pieces = (u.shape[0] + PIECE - 1) // PIECE
    for piece in prange(pieces):
        _curve_points_piece(knots, p, weights, points, u, nders, out, piece * PIECE,
                            min(u.shape[0], (piece + 1) * PIECE))


# the parameters of one thread's piece of curve_points_into
PIECE = 4096


@njit
def _curve_points_piece(knots, p, weights, points, u, nders, out, start, stop):
    """:func:`curve_points_into` for the parameters u[start:stop]."""
    ndu = np.zeros((p + 1, p + 1))
    left, right, a = np.zeros(p + 1), np.zeros(p + 1), np.zeros((2, p + 1))
    N, R = np.zeros((3, p + 1)), np.zeros((3, p + 1))
    for i in range(start, stop):
        first = _rational_at(knots, p, weights, u[i], ndu, left, right, a, N, R, nders == 2)
        for k in range(nders + 1):
            x = y = 0.0
            for j in range(p + 1):
                x += R[k, j] * points[first + j, 0]
                y += R[k, j] * points[first + j, 1]
            out[k, i, 0], out[k, i, 1] = x, y
