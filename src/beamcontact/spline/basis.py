"""B-spline and NURBS basis functions with derivatives.

Algorithms from L. Piegl & W. Tiller, *The NURBS Book*, 2nd ed., Springer 1997:
A2.1 (FindSpan) and A2.3 (DersBasisFuns); the rational basis (eq. 40 of the paper,
P&T eq. 4.2) is differentiated with the quotient rule. The basis is evaluated on the
host, once, at the quadrature and contact points (Lagrangian parametrisation), point by
point in the compiled kernels of :mod:`beamcontact.spline.basis_native`.
"""

import numpy as np

from beamcontact.spline import basis_native as native


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

    ``span`` and ``u`` are scalars or arrays of one shape (m,).

    Returns:
        Array (nders+1, degree+1), or (m, nders+1, degree+1); row k holds the k-th
        derivatives.
    """
    scalar = np.ndim(u) == 0
    u = np.ascontiguousarray(np.atleast_1d(u), dtype=float)
    span = np.ascontiguousarray(np.broadcast_to(np.asarray(span, np.int64), u.shape))
    ders = np.zeros((len(u), nders + 1, degree + 1))
    native.ders_basis_into(_floats(knots), int(degree), span, u, int(nders), ders)
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
    u = np.ascontiguousarray(np.atleast_1d(u), dtype=float)
    first = np.empty(len(u), dtype=np.int64)
    ders = np.empty((len(u), 3, degree + 1))
    native.nurbs_basis_into(_floats(knots), int(degree), _floats(weights), u, first, ders)
    return (int(first[0]), ders[0]) if scalar else (first, ders)


def _floats(a) -> np.ndarray:
    """A C-contiguous float64 array (what the compiled kernels take)."""
    return np.ascontiguousarray(a, dtype=float)
