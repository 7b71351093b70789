"""Refinement that leaves the curve unchanged: knot insertion and degree elevation.

Both act on the weighted (homogeneous) control points, where a NURBS is a polynomial
B-spline (P&T Sec. 4.2).
"""

import numpy as np

from beamcontact.spline import refine_native
from beamcontact.spline.basis import basis_derivatives, find_span
from beamcontact.spline.curve import NurbsCurve
from beamcontact.spline.knots import interior_knots


def _insert_homogeneous(degree: int, knots: np.ndarray, pw: np.ndarray, u: float,
                        times: int) -> tuple[np.ndarray, np.ndarray]:
    """Boehm's knot insertion, P&T A5.1 (CurveKnotIns), ``times`` times at u."""
    p = degree
    k = find_span(knots, p, u)
    s = int(np.sum(np.isclose(knots, u, rtol=0.0, atol=1e-14)))
    if times + s > p:
        raise ValueError(f"knot {u} would exceed multiplicity {p} (has {s}, inserting {times})")
    if times <= 0:
        return knots, pw
    n = len(pw)
    new_knots = np.concatenate([knots[: k + 1], np.full(times, u), knots[k + 1 :]])
    q = np.zeros((n + times, pw.shape[1]))
    q[: k - p + 1] = pw[: k - p + 1]
    q[k - s + times :] = pw[k - s :]
    r = pw[k - p : k - s + 1].copy()
    for j in range(1, times + 1):
        L = k - p + j
        for i in range(p - j - s + 1):
            alpha = (u - knots[L + i]) / (knots[i + k + 1] - knots[L + i])
            r[i] = alpha * r[i + 1] + (1.0 - alpha) * r[i]
        q[L] = r[0]
        q[k + times - j - s] = r[p - j - s]
    L = k - p + times
    q[L + 1 : k - s] = r[1 : k - s - L]
    return new_knots, q


def insert_knot(curve: NurbsCurve, u: float, times: int = 1) -> NurbsCurve:
    """Insert knot u ``times`` times; the curve and its parametrisation are unchanged."""
    knots, pw = _insert_homogeneous(curve.degree, curve.knots, curve.homogeneous(), u, times)
    return NurbsCurve.from_homogeneous(curve.degree, knots, pw)


def refine_knots(curve: NurbsCurve, new_knots) -> NurbsCurve:
    """Insert every value of ``new_knots`` (repeats mean multiplicity): A5.1 at each
    value in ascending order, as :func:`insert_knot` one after the other, in time linear
    in the number of control points (:mod:`beamcontact.spline.refine_native`)."""
    values, counts = np.unique(np.asarray(new_knots, float), return_counts=True)
    pw = curve.homogeneous()
    knots = np.empty(len(curve.knots) + counts.sum())
    q = np.empty((len(pw) + counts.sum(), pw.shape[1]))
    failed = refine_native.insert_sorted_into(curve.degree, curve.knots, pw, values,
                                              counts.astype(np.int64), knots, q)
    if failed >= 0:
        raise ValueError(f"knot {values[failed]} would exceed multiplicity {curve.degree} "
                         f"(inserting {counts[failed]})")
    return NurbsCurve.from_homogeneous(curve.degree, knots, q)


def elevate_degree_homogeneous(degree: int, knots: np.ndarray, pw: np.ndarray,
                               t: int) -> tuple[np.ndarray, np.ndarray]:
    """Raise the degree by t without changing the curve.

    The elevated space has every distinct knot's multiplicity raised by t (P&T Sec. 5.5),
    and contains the homogeneous curve exactly. Instead of P&T A5.9's Bezier
    decomposition we interpolate the curve at the Greville abscissae of the elevated space;
    the Schoenberg-Whitney conditions hold there, so the collocation matrix is regular and
    the projection reproduces the curve to round-off.
    """
    if t == 0:
        return knots, pw
    q = degree + t
    values, counts = interior_knots(knots, degree)
    new_knots = np.concatenate([np.full(q + 1, knots[0]), np.repeat(values, counts + t),
                                np.full(q + 1, knots[-1])])
    n_new = len(new_knots) - q - 1
    greville = np.array([new_knots[i + 1 : i + q + 1].mean() for i in range(n_new)])
    B = np.zeros((n_new, n_new))
    rhs = np.zeros((n_new, pw.shape[1]))
    for k, uk in enumerate(greville):
        span = find_span(new_knots, q, uk)
        B[k, span - q : span + 1] = basis_derivatives(new_knots, q, span, uk, 0)[0]
        span_old = find_span(knots, degree, uk)
        N_old = basis_derivatives(knots, degree, span_old, uk, 0)[0]
        rhs[k] = N_old @ pw[span_old - degree : span_old + 1]
    return new_knots, np.linalg.solve(B, rhs)


def elevate_degree(curve: NurbsCurve, t: int = 1) -> NurbsCurve:
    """Degree elevation by t (p -> p + t); the curve is unchanged."""
    if t < 0:
        raise ValueError("degree elevation needs t >= 0")
    knots, pw = elevate_degree_homogeneous(curve.degree, curve.knots, curve.homogeneous(), t)
    return NurbsCurve.from_homogeneous(curve.degree + t, knots, pw)
