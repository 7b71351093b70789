"""Outlier removal at a beam's free ends: the constraint u'''(end) = 0 on the displacement.

A smooth spline discretisation carries, at each end, a few modes whose frequencies lie far
above the continuum's (Cottrell, Reali, Bazilevs & Hughes, "Isogeometric analysis of
structural vibrations", CMAME 195, 2006): in the falling beam of the paper's benchmark its
two highest axial and bending modes. An implicit step controller resolves them and pays
for it in steps. Hiemstra, Hughes, Reali & Schillinger ("Removal of spurious outlier
frequencies and modes from isogeometric discretizations of second- and fourth-order
problems in one, two, and three dimensions", CMAME 387, 2021) remove them by conditions
on the highest derivatives at the boundary. The condition used here is the natural one of
an unloaded free end of a beam, shear-free: the third derivative of the displacement u
in the spline parameter vanishes there. The continuum solution of a straight end nearly
satisfies it (a free end carries no moment and no shear, and the axial strain at it
stays zero, so its derivative in time does too; the rotary inertia of the section
leaves EI w''' = rho I (w')_tt, a relative term of order (R/L)^2), so the space loses
its outliers and keeps the solution. A curved end does not: there the deformed axis has
r''' != 0 once its stretch varies (:func:`free_end` refuses it).

With an open knot vector only N_0 .. N_3 have a non-zero third derivative at the start
(P&T, The NURBS Book, eq. 2.10), so the constraint reads, per component,

    u_0 = w_1 u_1 + w_2 u_2 + w_3 u_3,    w_i = -N_i'''(0) / N_0'''(0),

with w = (3, -3, 1) for quartic C^1 splines of uniform knots, and sum w_i = 1 (the N_i'''
sum to 0), so rigid translations keep it; the end at the other side is its mirror image.
A straight reference with its Greville control points satisfies it as well (the third
derivative of a linear function is 0), so the constrained space holds the reference
curve and the constraint may be written on positions or displacements alike.

How the model uses it (setup/model.py): every basis row that sees the end control point
is folded, N_i <- N_i + w_i N_0 and N_0 <- 0 (:func:`fold_rows`: the element basis at
the Gauss points, the contact points, loads in the end element), so that the kernels of
both engines work in the constrained space unchanged; the end control point leaves the
solve as a supported one does, and after every Newton solve (and at t = 0) the engines
set its displacement, velocity and acceleration to the combination
(:func:`~beamcontact.assembly.system.tie_dependent` and its native twin), so that the
curve is the original basis's again and lies in the hull of its control points, which
the broad phase's boxes need.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from beamcontact.spline import NurbsCurve
from beamcontact.spline.basis import basis_derivatives, find_span

# the derivative that vanishes at a free end: u''' (shear-free)
ORDER = 3
# the lowest degree whose third derivative is not constant over the end element (for a
# cubic it is, and u''' = 0 there would make the whole end element a parabola)
MIN_DEGREE = 4


@dataclass(frozen=True)
class FreeEnd:
    """The constraint at one free end of a beam, in the beam's local numbering:
    u[dependent] = sum_k weights[k] u[masters[k]] for each component."""

    dependent: int
    masters: tuple[int, ...]
    weights: tuple[float, ...]


def free_end(curve: NurbsCurve, at: str) -> FreeEnd:
    """The constraint u'''(end) = 0 at ``at`` ("start" or "end") of a refined axis.

    Raises ValueError for a degree below :data:`MIN_DEGREE`, for rational weights in the
    end element (the weights above are those of the polynomial basis), for a curved end
    element (with a curved reference the deformed axis has r''' != 0 at a free end: a
    stretch that varies along a curved end turns its third derivative out of the
    tangent, so the condition would not be the continuum's) and for a straight end
    element that is not parametrised uniformly (its reference would not satisfy the
    condition, so the constrained space would not hold the reference curve)."""
    p = curve.degree
    if p < MIN_DEGREE:
        raise ValueError(f"remove_outliers needs degree >= {MIN_DEGREE}, got {p}")
    knots = np.asarray(curve.knots, float)
    n = curve.n_points
    xi = knots[0] if at == "start" else knots[-1]
    span = find_span(knots, p, xi)
    third = basis_derivatives(knots, p, span, xi, ORDER)[ORDER]
    local = np.arange(span - p, span + 1)  # the end element's control points
    if at == "start":
        dependent, masters = 0, (1, 2, 3)
    else:
        dependent, masters = n - 1, (n - 2, n - 3, n - 4)
    col = {int(c): k for k, c in enumerate(local)}
    weights = tuple(float(-third[col[m]] / third[col[dependent]]) for m in masters)
    w = np.asarray(curve.weights, float)[local]
    if np.ptp(w) > 1e-12 * np.max(w):
        raise ValueError(f"remove_outliers needs equal NURBS weights in the end element "
                         f"(the {at} of this axis is rational)")
    x = np.asarray(curve.points, float)
    end = x[local]
    chord = end[-1] - end[0]
    length = np.linalg.norm(chord)
    off_line = np.abs(chord[0] * (end[:, 1] - end[0, 1]) - chord[1] * (end[:, 0] - end[0, 0]))
    if np.max(off_line) > 1e-9 * length**2:
        raise ValueError(f"remove_outliers needs a straight end element (the {at} of this "
                         f"axis is curved)")
    gap = x[dependent] - sum(wk * x[m] for wk, m in zip(weights, masters, strict=True))
    if np.max(np.abs(gap)) > 1e-9 * length:
        raise ValueError(f"remove_outliers needs an end element parametrised uniformly "
                         f"along its length (the {at} of this axis is straight, but its "
                         f"third derivative is not zero there: give the axis as a line)")
    return FreeEnd(dependent, masters, weights)


def fold_rows(conn: np.ndarray, rows: np.ndarray, ends: tuple[FreeEnd, ...],
              offset: int = 0) -> np.ndarray:
    """Basis rows of the constrained space: wherever a row's control point (``conn``,
    global indices, beam's first at ``offset``) is an end's dependent one, its value w
    moves onto the masters (w_k times it each) and becomes 0.

    conn (..., n_loc) with rows (..., n_loc) or (..., k, n_loc) (one row per derivative);
    returns a folded copy (rows untouched where no end is met). Every master of an end
    lies in the same element as its dependent point, so it is in the row's ``conn``."""
    out = np.array(rows, dtype=float, copy=True)
    if not ends:
        return out
    extra = out.ndim - conn.ndim  # derivative axes between the point and the columns
    c = conn.reshape(conn.shape[:-1] + (1,) * extra + conn.shape[-1:])
    c = np.broadcast_to(c, out.shape)
    for end in ends:
        at_dep = c == offset + end.dependent
        value = np.sum(np.where(at_dep, out, 0.0), axis=-1, keepdims=True)
        for m, w in zip(end.masters, end.weights, strict=True):
            out = out + np.where(c == offset + m, w * value, 0.0)
        out = np.where(at_dep, 0.0, out)
    return out
