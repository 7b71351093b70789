"""B-spline and NURBS basis functions with derivatives.

Algorithms from L. Piegl & W. Tiller, *The NURBS Book*, 2nd ed., Springer 1997:
A2.1 (FindSpan) and A2.3 (DersBasisFuns); the rational basis (eq. 40 of the paper,
P&T eq. 4.2) is differentiated with the quotient rule. Host-side NumPy: the basis is
evaluated once at the quadrature points (Lagrangian parametrisation).
"""

import numpy as np

# the most parameters that nurbs_basis_derivatives evaluates in one piece
CHUNK = 4096


def find_span(knots: np.ndarray, degree: int, u):
    """Knot span index i with knots[i] <= u < knots[i+1] (P&T A2.1), for a scalar u (an
    int) or an array of them (an int array).

    The right end u = knots[-1] belongs to the last non-empty span.
    """
    n = len(knots) - degree - 2  # index of the last control point
    span = np.searchsorted(knots, u, side="right") - 1
    span = np.where(u >= knots[n + 1], n, np.where(u <= knots[degree], degree, span))
    return int(span) if np.ndim(span) == 0 else span.astype(int)


def basis_derivatives(knots: np.ndarray, degree: int, span, u, nders: int) -> np.ndarray:
    """Non-zero basis functions N_{span-p..span} and derivatives up to ``nders`` (P&T A2.3).

    ``span`` and ``u`` are scalars or arrays of one shape (m,): the algorithm runs on all
    points at once, each with exactly the scalar algorithm's arithmetic.

    Returns:
        Array (nders+1, degree+1), or (m, nders+1, degree+1); row k holds the k-th
        derivatives.
    """
    scalar = np.ndim(u) == 0
    u = np.atleast_1d(np.asarray(u, float))
    span = np.atleast_1d(np.asarray(span, int))
    m, p = len(u), degree
    ndu = np.zeros((m, p + 1, p + 1))
    left = np.zeros((m, p + 1))
    right = np.zeros((m, p + 1))
    ndu[:, 0, 0] = 1.0
    for j in range(1, p + 1):
        left[:, j] = u - knots[span + 1 - j]
        right[:, j] = knots[span + j] - u
        saved = np.zeros(m)
        for r in range(j):
            ndu[:, j, r] = right[:, r + 1] + left[:, j - r]
            temp = ndu[:, r, j - 1] / ndu[:, j, r]
            ndu[:, r, j] = saved + right[:, r + 1] * temp
            saved = left[:, j - r] * temp
        ndu[:, j, j] = saved
    ders = np.zeros((m, nders + 1, p + 1))
    ders[:, 0] = ndu[:, :, p]
    a = np.zeros((2, m, p + 1))
    for r in range(p + 1):
        s1, s2 = 0, 1
        a[0, :, 0] = 1.0
        for k in range(1, nders + 1):
            d = np.zeros(m)
            rk, pk = r - k, p - k
            if r >= k:
                a[s2, :, 0] = a[s1, :, 0] / ndu[:, pk + 1, rk]
                d = a[s2, :, 0] * ndu[:, rk, pk]
            j1 = 1 if rk >= -1 else -rk
            j2 = k - 1 if r - 1 <= pk else p - r
            for j in range(j1, j2 + 1):
                a[s2, :, j] = (a[s1, :, j] - a[s1, :, j - 1]) / ndu[:, pk + 1, rk + j]
                d = d + a[s2, :, j] * ndu[:, rk + j, pk]
            if r <= pk:
                a[s2, :, k] = -a[s1, :, k - 1] / ndu[:, pk + 1, r]
                d = d + a[s2, :, k] * ndu[:, r, pk]
            ders[:, k, r] = d
            s1, s2 = s2, s1
    factor = float(p)
    for k in range(1, nders + 1):
        ders[:, k] *= factor
        factor *= p - k
    return ders[0] if scalar else ders


def nurbs_basis_derivatives(knots: np.ndarray, degree: int, weights: np.ndarray, u):
    """Rational basis R_i (paper eq. 40) and its first two derivatives at u (a scalar, or
    an array of m parameters evaluated at once).

    Returns:
        (first, ders): ``first`` is the index of the first non-zero function and
        ``ders`` has shape (3, degree+1): R, dR/du, d2R/du2; for an array u, ``first``
        has shape (m,) and ``ders`` (m, 3, degree+1).
    """
    scalar = np.ndim(u) == 0
    u = np.atleast_1d(np.asarray(u, float))
    if len(u) > CHUNK:
        # in pieces that stay in the cache: the work arrays of A2.3 are (m, p + 1, p + 1)
        # and their columns strided, so the whole of a large m (the contact points of a
        # 10 000-element beam) ran from memory, many times slower; the same arithmetic
        parts = [nurbs_basis_derivatives(knots, degree, weights, u[i:i + CHUNK])
                 for i in range(0, len(u), CHUNK)]
        return (np.concatenate([f for f, _ in parts]),
                np.concatenate([d for _, d in parts]))
    span = find_span(knots, degree, u)
    first = span - degree
    N = basis_derivatives(knots, degree, span, u, min(2, degree))
    if N.shape[1] < 3:
        N = np.concatenate([N, np.zeros((len(u), 3 - N.shape[1], degree + 1))], axis=1)
    w = np.asarray(weights, float)[first[:, None] + np.arange(degree + 1)]
    A = N * w[:, None, :]  # weighted B-spline functions and their derivatives
    W, W1, W2 = (A[:, k].sum(axis=1)[:, None] for k in range(3))
    R = A[:, 0] / W
    R1 = (A[:, 1] - R * W1) / W
    R2 = (A[:, 2] - 2.0 * R1 * W1 - R * W2) / W
    ders = np.stack([R, R1, R2], axis=1)
    return (int(first[0]), ders[0]) if scalar else (first, ders)
