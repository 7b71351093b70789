"""B-spline / NURBS basis: partition of unity, derivatives, continuity (P&T A2.1, A2.3)."""

import numpy as np
import pytest

from beamcontact.spline import (
    NurbsCurve,
    basis_derivatives,
    find_span,
    nurbs_basis_derivatives,
    open_uniform_knots,
)

FIG4_KNOTS = np.array([0, 0, 0, 0, 0.25, 0.5, 0.75, 0.75, 0.75, 1, 1, 1, 1.0])  # paper Fig. 4


def _all_basis(knots, degree, u, weights=None):
    """Dense basis values and two derivatives at u, shape (3, n)."""
    n = len(knots) - degree - 1
    w = np.ones(n) if weights is None else weights
    first, d = nurbs_basis_derivatives(knots, degree, w, u)
    out = np.zeros((3, n))
    out[:, first : first + degree + 1] = d
    return out


@pytest.mark.parametrize("degree", [1, 2, 3, 4, 6])
def test_partition_of_unity_and_nonnegativity(degree):
    knots = open_uniform_knots(degree, 7, degree - 1)
    for u in np.linspace(0, 1, 57):
        span = find_span(knots, degree, u)
        d = basis_derivatives(knots, degree, span, u, min(2, degree))
        assert abs(d[0].sum() - 1.0) < 1e-14
        assert np.all(d[0] >= -1e-15)
        assert np.allclose(d[1:].sum(axis=1), 0.0, atol=1e-10)  # derivatives of 1


@pytest.mark.parametrize("weights", [None, "random"])
def test_derivatives_against_central_differences(weights):
    p = 4
    knots = np.array([0, 0, 0, 0, 0, 0.2, 0.45, 0.45, 0.7, 1, 1, 1, 1, 1.0])
    n = len(knots) - p - 1
    w = None if weights is None else np.random.default_rng(0).uniform(0.5, 2.0, n)
    h = 1e-6
    for u in (0.07, 0.3, 0.52, 0.83):  # away from knots, where the basis is smooth
        d = _all_basis(knots, p, u, w)
        fd1 = (_all_basis(knots, p, u + h, w)[0] - _all_basis(knots, p, u - h, w)[0]) / (2 * h)
        fd2 = (_all_basis(knots, p, u + h, w)[1] - _all_basis(knots, p, u - h, w)[1]) / (2 * h)
        np.testing.assert_allclose(d[1], fd1, atol=1e-7 * max(1, np.abs(d[1]).max()))
        np.testing.assert_allclose(d[2], fd2, atol=1e-6 * max(1, np.abs(d[2]).max()))
        assert abs(d[0].sum() - 1.0) < 1e-14  # the rational basis is a partition of unity too


def test_continuity_at_knot_of_multiplicity_m():
    """C^(p-m): a cubic with a triple knot at 0.75 is C^0 there, C^2 at the simple knots."""
    p, jump = 3, 1e-11
    for u, smooth_ders in ((0.25, 3), (0.5, 3), (0.75, 1)):
        left = _all_basis(FIG4_KNOTS, p, u - jump)
        right = _all_basis(FIG4_KNOTS, p, u + jump)
        for k in range(min(smooth_ders, 3)):
            assert np.allclose(left[k], right[k], atol=1e-6), (u, k)
    left, right = _all_basis(FIG4_KNOTS, p, 0.75 - jump), _all_basis(FIG4_KNOTS, p, 0.75 + jump)
    assert not np.allclose(left[1], right[1], atol=1e-3)  # the first derivative jumps at C^0


def test_interpolation_at_triple_knot_paper_fig4():
    """Fig. 4: the cubic curve interpolates P6 where the knot 0.75 has multiplicity p = 3."""
    pts = np.random.default_rng(1).normal(size=(9, 2))
    c = NurbsCurve(3, FIG4_KNOTS, pts, np.ones(9))
    np.testing.assert_allclose(c.evaluate([0.75])[0, 0], pts[5], atol=1e-14)
    np.testing.assert_allclose(c.evaluate([0.0, 1.0])[0], pts[[0, -1]], atol=1e-14)
    # the basis of Fig. 4 (examples/studies/figures_4_6.py draws it): non-negative, a
    # partition of unity, and N_6(0.75) = 1 exactly where the knot is triple
    for u in np.linspace(0.0, 1.0, 81):
        values = _all_basis(FIG4_KNOTS, 3, u)[0]
        assert np.all(values >= 0.0) and abs(values.sum() - 1.0) < 1e-14
    assert _all_basis(FIG4_KNOTS, 3, 0.75)[0][5] == 1.0


def test_find_span_ends():
    knots = open_uniform_knots(3, 4, 2)
    assert find_span(knots, 3, 0.0) == 3
    assert find_span(knots, 3, 1.0) == len(knots) - 3 - 2
    assert find_span(knots, 3, 0.25) == 4
