"""B-spline and NURBS curves: knot vectors, basis functions, refinement (Piegl & Tiller).

This package knows nothing of beams. ``degree`` is always the polynomial degree p.
"""

from beamcontact.spline.basis import basis_derivatives, find_span, nurbs_basis_derivatives
from beamcontact.spline.curve import NurbsCurve, arc, line
from beamcontact.spline.knots import interior_knots, open_uniform_knots
from beamcontact.spline.refine import elevate_degree, insert_knot, refine_knots

__all__ = [
    "NurbsCurve",
    "arc",
    "basis_derivatives",
    "elevate_degree",
    "find_span",
    "insert_knot",
    "interior_knots",
    "line",
    "nurbs_basis_derivatives",
    "open_uniform_knots",
    "refine_knots",
]
