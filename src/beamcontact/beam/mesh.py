"""Isogeometric beam mesh: refined NURBS axis, elements, and basis values at Gauss points.

The reference geometry is refined without change (degree elevation, then knot insertion
at equal reference arc-length fractions), and the rational basis R, dR/dxi, d2R/dxi2 is
evaluated once at the p+1 Gauss points of every element (Lagrangian parametrisation).
"""

from dataclasses import dataclass

import numpy as np

from beamcontact.beam.free_ends import FreeEnd, fold_rows
from beamcontact.spline import NurbsCurve, elevate_degree, nurbs_basis_derivatives, refine_knots
from beamcontact.spline.knots import element_breaks


def refine_axis(curve: NurbsCurve, degree: int, elements: int, continuity: int) -> NurbsCurve:
    """Elevate ``curve`` to ``degree`` and split it into ``elements`` equal-length elements.

    New knots get multiplicity degree - continuity. Interior knots the geometry already
    has stay element boundaries (so a NURBS given with interior knots may end with more
    elements than asked for).
    """
    if degree < curve.degree:
        raise ValueError(f"degree {degree} is below the geometry's degree {curve.degree}")
    fine = elevate_degree(curve, degree - curve.degree)
    existing = element_breaks(fine.knots)
    new = fine.parameters_at_lengths(np.arange(1, elements) / elements)
    # the nearest existing break of each new knot, on either side (existing is sorted)
    right = np.clip(np.searchsorted(existing, new), 0, len(existing) - 1)
    left = np.clip(right - 1, 0, len(existing) - 1)
    nearest = np.minimum(np.abs(existing[left] - new), np.abs(existing[right] - new))
    new = new[nearest > 1e-10]
    return refine_knots(fine, np.repeat(new, degree - continuity))


@dataclass(frozen=True, eq=False)
class BeamMesh:
    """Elements of one beam with basis data at the Gauss points.

    Attributes:
        curve: the refined reference axis (its control points are the unknowns' reference).
        conn: local control-point indices of each element, shape (n_el, p+1).
        breaks: element boundaries in the parameter, shape (n_el+1,).
        R, dR, ddR: rational basis and derivatives at Gauss points, shape (n_el, n_qp, p+1).
        wq: Gauss weight times d xi / d xi_hat, shape (n_el, n_qp).
        xi_qp: parameters of the Gauss points, shape (n_el, n_qp).
        free_ends: the ends whose outliers are removed (beam/free_ends.py); R, dR, ddR are
            then the folded rows of the constrained space.
    """

    curve: NurbsCurve
    conn: np.ndarray
    breaks: np.ndarray
    R: np.ndarray
    dR: np.ndarray
    ddR: np.ndarray
    wq: np.ndarray
    xi_qp: np.ndarray
    free_ends: tuple[FreeEnd, ...] = ()

    @property
    def n_elements(self) -> int:
        """Number of elements (non-empty knot spans)."""
        return len(self.conn)


def build_mesh(curve: NurbsCurve, n_qp: int | None = None,
               free_ends: tuple[FreeEnd, ...] = ()) -> BeamMesh:
    """Element connectivity and basis at ``n_qp`` Gauss points per element (default p+1),
    folded into the constrained space of ``free_ends`` (:func:`fold_rows`)."""
    p = curve.degree
    n_qp = p + 1 if n_qp is None else n_qp
    x, w = np.polynomial.legendre.leggauss(n_qp)
    breaks = element_breaks(curve.knots)
    n_el = len(breaks) - 1
    # every element at once (the basis is computed point by point, the same numbers as
    # element by element; a loop over 10 000 elements cost seconds)
    a, b = breaks[:-1, None], breaks[1:, None]
    xi_qp = 0.5 * (b - a) * x + 0.5 * (a + b)
    wq = 0.5 * (b - a) * w
    first, d = nurbs_basis_derivatives(curve.knots, p, curve.weights, xi_qp.ravel())
    ders = d.reshape(n_el, n_qp, 3, p + 1).transpose(2, 0, 1, 3)
    last = first.reshape(n_el, n_qp)[:, -1]
    conn = (last[:, None] + np.arange(p + 1)).astype(np.int64)
    if free_ends:
        # rows (n_el, n_qp, 3, p + 1) against conn (n_el, p + 1)
        ders = fold_rows(conn, ders.transpose(1, 2, 0, 3), free_ends).transpose(2, 0, 1, 3)
    return BeamMesh(curve=curve, conn=conn, breaks=breaks, R=np.ascontiguousarray(ders[0]),
                    dR=np.ascontiguousarray(ders[1]), ddR=np.ascontiguousarray(ders[2]),
                    wq=wq, xi_qp=xi_qp, free_ends=tuple(free_ends))


def point_basis(curve: NurbsCurve, u: float) -> tuple[np.ndarray, np.ndarray]:
    """Control-point indices and (R, dR, ddR) of shape (3, p+1) at parameter u."""
    first, d = nurbs_basis_derivatives(curve.knots, curve.degree, curve.weights, u)
    return np.arange(first, first + curve.degree + 1), d
