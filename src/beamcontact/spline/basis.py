"""B-spline and NURBS basis functions with derivatives.

Algorithms from L. Piegl & W. Tiller, *The NURBS Book*, 2nd ed., Springer 1997:
A2.1 (FindSpan) and A2.3 (DersBasisFuns); the rational basis (eq. 40 of the paper,
P&T eq. 4.2) is differentiated with the quotient rule. Host-side NumPy: the basis is
evaluated once at the quadrature points (Lagrangian parametrisation).
"""

import numpy as np


def find_span(knots: np.ndarray, degree: int, u: float) -> int:
    """Knot span index i with knots[i] <= u < knots[i+1] (P&T A2.1).

    The right end u = knots[-1] belongs to the last non-empty span.
    """
    n = len(knots) - degree - 2  # index of the last control point
    if u >= knots[n + 1]:
        return n
    if u <= knots[degree]:
        return degree
    return int(np.searchsorted(knots, u, side="right") - 1)


def basis_derivatives(knots: np.ndarray, degree: int, span: int, u: float,
                      nders: int) -> np.ndarray:
    """Non-zero basis functions N_{span-p..span} and derivatives up to ``nders`` (P&T A2.3).

    Returns:
        Array (nders+1, degree+1); row k holds the k-th derivatives.
    """
    p = degree
    ndu = np.zeros((p + 1, p + 1))
    left = np.zeros(p + 1)
    right = np.zeros(p + 1)
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
    ders = np.zeros((nders + 1, p + 1))
    ders[0] = ndu[:, p]
    a = np.zeros((2, p + 1))
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
                d += a[s2, j] * ndu[rk + j, pk]
            if r <= pk:
                a[s2, k] = -a[s1, k - 1] / ndu[pk + 1, r]
                d += a[s2, k] * ndu[r, pk]
            ders[k, r] = d
            s1, s2 = s2, s1
    factor = float(p)
    for k in range(1, nders + 1):
        ders[k] *= factor
        factor *= p - k
    return ders


def nurbs_basis_derivatives(knots: np.ndarray, degree: int, weights: np.ndarray,
                            u: float) -> tuple[int, np.ndarray]:
    """Rational basis R_i (paper eq. 40) and its first two derivatives at u.

    Returns:
        (first, ders): ``first`` is the index of the first non-zero function and
        ``ders`` has shape (3, degree+1): R, dR/du, d2R/du2.
    """
    span = find_span(knots, degree, u)
    first = span - degree
    N = basis_derivatives(knots, degree, span, u, min(2, degree))
    if N.shape[0] < 3:
        N = np.vstack([N, np.zeros((3 - N.shape[0], degree + 1))])
    w = np.asarray(weights)[first : span + 1]
    A = N * w  # weighted B-spline functions and their derivatives
    W, W1, W2 = A.sum(axis=1)
    R = A[0] / W
    R1 = (A[1] - R * W1) / W
    R2 = (A[2] - 2.0 * R1 * W1 - R * W2) / W
    return first, np.stack([R, R1, R2])
