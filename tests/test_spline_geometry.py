"""Exact geometry: circular arcs; knot insertion and degree elevation leave curves unchanged."""

import numpy as np
import pytest

from beamcontact.spline import arc, elevate_degree, insert_knot, line, refine_knots
from beamcontact.spline.knots import interior_knots
from beamcontact.spline.refine import _insert_homogeneous

U = np.linspace(0.0, 1.0, 201)


@pytest.mark.parametrize("sweep", [0.3, np.pi / 2, np.pi, 4.0, -5.5])
def test_arc_is_exact(sweep):
    c0, R, a0 = np.array([1.5, -2.0]), 2.5, 0.4
    c = arc(c0, R, a0, a0 + sweep)
    pts = c.evaluate(U)[0]
    np.testing.assert_allclose(np.linalg.norm(pts - c0, axis=1), R, rtol=0, atol=1e-13)
    np.testing.assert_allclose(pts[0], c0 + R * np.array([np.cos(a0), np.sin(a0)]), atol=1e-13)
    end = a0 + sweep
    np.testing.assert_allclose(pts[-1], c0 + R * np.array([np.cos(end), np.sin(end)]),
                               atol=1e-13)
    # the polar angle moves monotonically from start to end: the arc takes the asked way
    ang = np.unwrap(np.arctan2(pts[:, 1] - c0[1], pts[:, 0] - c0[0]))
    assert np.all(np.sign(np.diff(ang)) == np.sign(sweep))
    assert abs(c.arc_length() - R * abs(sweep)) < 1e-12 * R


@pytest.mark.parametrize("sweep", [np.pi / 2, 5.0])
def test_refinement_leaves_arc_unchanged(sweep):
    c = arc([0, 0], 1.0, 0.0, sweep)
    ref = c.evaluate(U, 2)
    e = elevate_degree(c, 3)
    assert e.degree == c.degree + 3
    np.testing.assert_allclose(e.evaluate(U, 2), ref, atol=1e-11 * np.abs(ref).max())
    r = refine_knots(e, [0.1, 0.3, 0.3, 0.5, 0.77])
    np.testing.assert_allclose(r.evaluate(U, 2), ref, atol=1e-10 * np.abs(ref).max())
    values, counts = interior_knots(r.knots, r.degree)
    np.testing.assert_allclose(values, [0.1, 0.3, 0.5, 0.77])
    np.testing.assert_array_equal(counts, [1, 2, 1, 1])


def test_elevation_raises_every_multiplicity():
    c = refine_knots(elevate_degree(line([0, 0], [3, 1]), 2), [0.25, 0.5, 0.5])
    e = elevate_degree(c, 2)
    _, counts = interior_knots(e.knots, e.degree)
    np.testing.assert_array_equal(counts, [3, 4])
    assert e.n_points == c.n_points + 2 * (2 + 1)
    np.testing.assert_allclose(e.evaluate(U, 2), c.evaluate(U, 2), atol=1e-11)


def test_knot_insertion_boehm_single_and_repeated():
    rng = np.random.default_rng(2)
    from beamcontact.spline import NurbsCurve, open_uniform_knots

    knots = open_uniform_knots(4, 3, 2)
    n = len(knots) - 5
    c = NurbsCurve(4, knots, rng.normal(size=(n, 2)), rng.uniform(0.5, 2, n))
    for u, times in ((0.1, 1), (1 / 3, 2), (0.8, 3)):
        ci = insert_knot(c, u, times)
        assert ci.n_points == c.n_points + times
        np.testing.assert_allclose(ci.evaluate(U, 2), c.evaluate(U, 2), atol=1e-10)
    with pytest.raises(ValueError):
        insert_knot(c, 1 / 3, 3)  # would exceed multiplicity p


def test_evaluate_sums_only_the_nonzero_basis_functions():
    """``evaluate`` (p+1 terms per parameter) equals the dense basis matrix times the
    control points to round-off, for points and both derivatives of a refined arc."""
    c = arc([0.3, -0.2], 2.0, 0.4, 2.9)
    c = refine_knots(elevate_degree(c, 2), np.repeat(np.linspace(0, 1, 41)[1:-1], 2))
    u = np.random.default_rng(5).random(300)
    new, dense = c.evaluate(u, 2), c.basis_matrix(u, 2) @ c.points
    for d in range(3):
        scale = np.abs(c.basis_matrix(u, 2)[d]).sum(axis=1).max() * np.abs(c.points).max()
        np.testing.assert_allclose(new[d], dense[d], rtol=0, atol=4e-16 * scale)


def test_sparse_basis_is_the_dense_basis():
    """The rows of p+1 basis functions equal the dense basis, and their product with
    control points is SciPy's CSR product bit for bit (the same order of the sums)."""
    import scipy.sparse as sp

    c = refine_knots(elevate_degree(arc([0.0, 0.0], 1.5, 0.2, 2.2), 2),
                     np.linspace(0, 1, 13)[1:-1])
    u = np.linspace(0.0, 1.0, 97)
    B = c.sparse_basis(u)
    assert B.nnz == len(u) * (c.degree + 1)
    np.testing.assert_array_equal(B.toarray(), c.basis_matrix(u)[0])
    x = np.random.default_rng(0).normal(size=(c.n_points, 2)) * 1e3
    m = c.degree + 1
    csr = sp.csr_matrix((B.values.ravel(), (B.first[:, None] + np.arange(m)).ravel(),
                         np.arange(0, len(u) * m + 1, m)), shape=B.shape)
    np.testing.assert_array_equal(B @ x, csr @ x)


@pytest.mark.parametrize("degree", [2, 3, 4, 5])
def test_refine_knots_is_boehm_knot_after_knot(degree):
    """refine_knots (all knots at once, in gap buffers; spline/refine_native.py) gives the
    weighted control points of A5.1 applied one knot after the other bit for bit:
    simple, repeated and existing knots, rational weights."""
    from beamcontact.spline import NurbsCurve, open_uniform_knots

    rng = np.random.default_rng(degree)
    knots = open_uniform_knots(degree, 4, degree - 1)
    n = len(knots) - degree - 1
    c = NurbsCurve(degree, knots, rng.normal(size=(n, 2)), rng.uniform(0.5, 2, n))
    existing = interior_knots(knots, degree)[0]
    new = np.concatenate([rng.random(60), np.repeat(rng.random(10), degree - 1),
                          existing[:1]])
    knots_1, pw_1 = c.knots, c.homogeneous()
    values, counts = np.unique(new, return_counts=True)
    for u, times in zip(values, counts, strict=True):
        knots_1, pw_1 = _insert_homogeneous(degree, knots_1, pw_1, float(u), int(times))
    one_by_one = NurbsCurve.from_homogeneous(degree, knots_1, pw_1)
    at_once = refine_knots(c, new)
    np.testing.assert_array_equal(at_once.knots, one_by_one.knots)
    np.testing.assert_array_equal(at_once.points, one_by_one.points)
    np.testing.assert_array_equal(at_once.weights, one_by_one.weights)
    with pytest.raises(ValueError, match="multiplicity"):
        refine_knots(c, np.repeat(existing[:1], degree))  # the existing one plus p


@pytest.mark.parametrize("geometry", ["line", "arc"])
def test_parameters_at_lengths_split_a_curve_into_equal_lengths(geometry):
    """10 000 targets: the arc length at each parameter is its fraction of the length to
    round-off (Newton to a few ulps, no target sent back to bisection by round-off),
    and a beam axis refined into 10 000 elements has elements of one length."""
    from beamcontact.beam.mesh import refine_axis

    c = line([0.0, 0.0], [10.0, 3.0]) if geometry == "line" else arc([0, 0], 2.0, 0.1, 2.6)
    fine = elevate_degree(c, 3 - c.degree)
    fractions = np.arange(1, 10_000) / 10_000
    u = fine.parameters_at_lengths(fractions)
    assert np.all(np.diff(u) > 0.0)
    length = fine.arc_length()
    for k in range(0, len(u), 499):
        assert abs(fine.arc_length(u[k]) / length - fractions[k]) < 1e-15
    refined = refine_axis(c, 3, 10_000, 2)
    breaks = np.unique(refined.knots)
    assert len(breaks) == 10_001
    segments = np.diff([refined.arc_length(b) for b in breaks[::97]])
    np.testing.assert_allclose(segments, segments[0], rtol=1e-12)
