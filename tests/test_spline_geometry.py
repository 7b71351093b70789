"""Exact geometry: circular arcs; knot insertion and degree elevation leave curves unchanged."""

import numpy as np
import pytest

from beamcontact.spline import arc, elevate_degree, insert_knot, line, refine_knots
from beamcontact.spline.knots import interior_knots

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
    c = refine_knots(elevate_degree(arc([0.0, 0.0], 1.5, 0.2, 2.2), 2),
                     np.linspace(0, 1, 13)[1:-1])
    u = np.linspace(0.0, 1.0, 97)
    B = c.sparse_basis(u)
    assert B.nnz == len(u) * (c.degree + 1)
    np.testing.assert_array_equal(B.toarray(), c.basis_matrix(u)[0])
