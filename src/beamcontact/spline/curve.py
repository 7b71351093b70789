"""Planar NURBS curves (paper eq. 40; P&T Ch. 4) and exact constructions of lines and arcs."""

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from beamcontact.spline.basis import nurbs_basis_derivatives
from beamcontact.spline.basis_native import curve_points_into


@dataclass(frozen=True, eq=False)
class BasisRows:
    """A (rows, n) matrix whose row i holds ``values[i]`` in the columns ``first[i]``,
    ``first[i] + 1``, ... (the basis functions of a curve that are nonzero at a
    parameter). ``rows @ x`` sums each row's terms in column order from zero, the order
    of SciPy's CSR product that it replaces, whose import took 0.06 s of each run's
    start (session 27)."""

    first: np.ndarray
    values: np.ndarray
    n: int

    @property
    def shape(self) -> tuple[int, int]:
        return (self.first.shape[0], self.n)

    @property
    def nnz(self) -> int:
        return self.values.size

    def __matmul__(self, x: np.ndarray) -> np.ndarray:
        x = np.asarray(x)
        out = np.zeros((self.first.shape[0], *x.shape[1:]), np.result_type(self.values, x))
        spread = (slice(None),) + (None,) * (x.ndim - 1)
        for j in range(self.values.shape[1]):
            out += self.values[:, j][spread] * x[self.first + j]
        return out

    def toarray(self) -> np.ndarray:
        """The dense matrix."""
        dense = np.zeros(self.shape)
        rows = np.arange(self.first.shape[0])[:, None]
        dense[rows, self.first[:, None] + np.arange(self.values.shape[1])] = self.values
        return dense


@dataclass(frozen=True, eq=False)
class NurbsCurve:
    """A planar NURBS curve on the parameter domain [0, 1].

    Attributes:
        degree: polynomial degree p.
        knots: open knot vector, shape (n + p + 1,), from 0 to 1.
        points: Cartesian control points, shape (n, 2).
        weights: positive-denominator weights, shape (n,).
    """

    degree: int
    knots: np.ndarray
    points: np.ndarray
    weights: np.ndarray

    def __post_init__(self) -> None:
        # float64 C-contiguous, as the compiled basis takes them (a frozen dataclass)
        for name in ("knots", "points", "weights"):
            object.__setattr__(self, name, np.ascontiguousarray(getattr(self, name),
                                                                dtype=float))
        n = len(self.points)
        if len(self.knots) != n + self.degree + 1 or len(self.weights) != n:
            raise ValueError(f"inconsistent NURBS: {n} points, {len(self.weights)} weights, "
                             f"{len(self.knots)} knots for degree {self.degree} "
                             f"(need points + degree + 1 knots)")

    @property
    def n_points(self) -> int:
        """Number of control points."""
        return len(self.points)

    def homogeneous(self) -> np.ndarray:
        """Weighted control points (w x, w y, w), shape (n, 3)."""
        return np.column_stack([self.points * self.weights[:, None], self.weights])

    @staticmethod
    def from_homogeneous(degree: int, knots: np.ndarray, pw: np.ndarray) -> "NurbsCurve":
        """Curve from weighted control points (w x, w y, w)."""
        w = pw[:, 2]
        return NurbsCurve(degree, np.asarray(knots, float), pw[:, :2] / w[:, None], w.copy())

    def basis_matrix(self, u: np.ndarray, nders: int = 0) -> np.ndarray:
        """Dense rational basis (and derivatives) at parameters u: shape (nders+1, len(u), n)."""
        u = np.atleast_1d(np.asarray(u, float))
        out = np.zeros((3, len(u), self.n_points))
        first, ders = nurbs_basis_derivatives(self.knots, self.degree, self.weights, u)
        rows = np.arange(len(u))[:, None]
        out[:, rows, first[:, None] + np.arange(self.degree + 1)] = ders.transpose(1, 0, 2)
        return out[: nders + 1]

    def sparse_basis(self, u: np.ndarray) -> "BasisRows":
        """The rational basis at parameters u as a (len(u), n) matrix of p+1 consecutive
        entries per row: points = sparse_basis(u) @ control points, in memory linear in
        both."""
        u = np.atleast_1d(np.asarray(u, float))
        first, ders = nurbs_basis_derivatives(self.knots, self.degree, self.weights, u)
        return BasisRows(first, np.ascontiguousarray(ders[:, 0]), self.n_points)

    def evaluate(self, u: np.ndarray, nders: int = 0) -> np.ndarray:
        """Points and parametric derivatives: shape (nders+1, len(u), 2), nders <= 2.

        Sums the p+1 basis functions that are nonzero at each parameter, never the dense
        basis matrix: its size, parameters x control points, made the arc-length table of
        an 800-element beam a 6 GB array (and 8 s)."""
        u = np.ascontiguousarray(np.atleast_1d(u), dtype=float)
        out = np.empty((nders + 1, len(u), 2))
        curve_points_into(self.knots, self.degree, self.weights, self.points, u, nders, out)
        return out

    def arc_length(self, u: float = 1.0) -> float:
        """Arc length from parameter 0 to u."""
        grid, cumulative = self._length_table
        k = int(np.clip(np.searchsorted(grid, u, side="right") - 1, 0, len(grid) - 1))
        return float(cumulative[k] + self._length_between(grid[k], u))

    def _length_between(self, a, b, n_gauss: int = 12):
        """Arc length from a to b (scalars or arrays of the same shape; 0 where b <= a),
        by Gauss-Legendre: accurate inside one cell of the length table."""
        a, b = np.asarray(a, float), np.asarray(b, float)
        x, w = np.polynomial.legendre.leggauss(n_gauss)
        uq = 0.5 * (b - a)[..., None] * x + 0.5 * (a + b)[..., None]
        speed = np.linalg.norm(self.evaluate(uq.ravel(), 1)[1], axis=1).reshape(uq.shape)
        out = np.where(b > a, 0.5 * (b - a) * (speed @ w), 0.0)
        return float(out) if out.ndim == 0 else out

    @cached_property
    def _length_table(self) -> tuple[np.ndarray, np.ndarray]:
        """Cumulative arc length on a fine grid, cached: every knot span cut into
        max(4, 32 / spans) cells, so at least 32 cells over the curve.

        Composite Gauss-Legendre resolves the strongly varying speed of long single-segment
        arcs (32 cells); a refined curve has the same parametrisation cut at its knots, so
        a few cells per span keep that resolution without a grid that grows with the
        square of the refinement.
        """
        breaks = np.unique(self.knots)
        subdivisions = max(4, -(-32 // (len(breaks) - 1)))
        grid = np.unique(np.concatenate([np.linspace(a, b, subdivisions + 1)
                                         for a, b in zip(breaks[:-1], breaks[1:], strict=True)]))
        return grid, np.concatenate([[0.0], np.cumsum(self._length_between(grid[:-1],
                                                                           grid[1:]))])

    def parameters_at_lengths(self, fractions) -> np.ndarray:
        """Parameters u whose arc length from the start is ``fractions`` of the total.

        All at once: each target is bracketed by a cell of the length table and found by
        Newton's method on the arc length (its derivative is the speed), safeguarded by
        bisection of the bracket; a target stops once its Newton step is below a few ulps
        of u (or of its cell), so that round-off in the arc length never sends a
        converged target back to bisection."""
        f = np.atleast_1d(np.asarray(fractions, float))
        out = np.clip(f, 0.0, 1.0)
        grid, cumulative = self._length_table
        target = f * cumulative[-1]
        k = np.clip(np.searchsorted(cumulative, target) - 1, 0, len(grid) - 2)
        lo, hi, rest = grid[k], grid[k + 1], target - cumulative[k]
        span = cumulative[k + 1] - cumulative[k]
        on_grid = (rest <= 1e-14 * span) | (rest >= (1.0 - 1e-14) * span)
        out = np.where(on_grid, np.where(rest < 0.5 * span, lo, hi), out)
        todo = np.flatnonzero((f > 0.0) & (f < 1.0) & ~on_grid)
        a, lo, hi, rest = lo[todo], lo[todo].copy(), hi[todo].copy(), rest[todo]
        u = lo + (hi - lo) * rest / span[todo]
        tol = 4.0 * np.finfo(float).eps * np.maximum(np.abs(u), hi - lo)
        active = np.arange(len(u))
        for _ in range(100):
            if active.size == 0:
                break
            ua, la, ha = u[active], lo[active], hi[active]
            g = self._length_between(a[active], ua) - rest[active]
            step = g / np.linalg.norm(self.evaluate(ua, 1)[1], axis=1)
            new = ua - step
            done = (np.abs(step) <= tol[active]) | (g == 0.0)
            la, ha = np.where(g < 0.0, ua, la), np.where(g > 0.0, ua, ha)
            outside = ~((new > la) & (new < ha)) & ~done
            u[active] = np.where(outside, 0.5 * (la + ha), np.where(g == 0.0, ua, new))
            lo[active], hi[active] = la, ha
            active = active[~done]
        out[todo] = u
        return out


def line(start, end) -> NurbsCurve:
    """Straight segment as a degree-1 B-spline."""
    pts = np.array([start, end], dtype=float)
    return NurbsCurve(1, np.array([0.0, 0.0, 1.0, 1.0]), pts, np.ones(2))


def arc(center, radius: float, start_angle: float, end_angle: float) -> NurbsCurve:
    """Exact circular arc as one rational quadratic segment (P&T Sec. 7.3).

    The middle weight is w1 = cos(theta/2) for the sweep theta = end - start. The weighted
    middle point w1 * P1 = w1 * c + R * e_mid stays finite for every |theta| < 2 pi, so arcs
    longer than a half circle (w1 <= 0) are exact too: the denominator
    (1-u)^2 + 2 w1 u (1-u) + u^2 >= (1 + w1)/2 > 0 on [0, 1]. A single segment keeps the
    parametrisation C-infinity, which the rotation-free beam needs (no G1-only joints).
    Round-off grows like 1 / (1 + w1) as the sweep approaches 2 pi (the denominator nearly
    vanishes at mid-parameter), so nearly closed rings lose a few digits.
    """
    sweep = end_angle - start_angle
    if not 0.0 < abs(sweep) < 2.0 * np.pi:
        raise ValueError(f"arc sweep must satisfy 0 < |end_angle - start_angle| < 2 pi, "
                         f"got {sweep}")
    c = np.asarray(center, float)
    mid = 0.5 * (start_angle + end_angle)
    w1 = np.cos(0.5 * sweep)
    p0 = c + radius * np.array([np.cos(start_angle), np.sin(start_angle)])
    p2 = c + radius * np.array([np.cos(end_angle), np.sin(end_angle)])
    pw1 = np.concatenate([w1 * c + radius * np.array([np.cos(mid), np.sin(mid)]), [w1]])
    pw = np.array([[*p0, 1.0], pw1, [*p2, 1.0]])
    if abs(w1) < 1e-3:
        # P1 would sit near infinity; elevate once so every control point is finite.
        from beamcontact.spline.refine import elevate_degree_homogeneous

        knots, pw = elevate_degree_homogeneous(2, np.array([0, 0, 0, 1, 1, 1.0]), pw, 1)
        return NurbsCurve.from_homogeneous(3, knots, pw)
    return NurbsCurve.from_homogeneous(2, np.array([0, 0, 0, 1, 1, 1.0]), pw)
