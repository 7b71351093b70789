"""Static large-deformation problems against independent references.

- end moment: the exact solution of this continuum model (uniform stretch and curvature,
  found from two scalar equations with the section integrals in closed form);
- tip load: the inextensible elastica solved with SciPy's solve_bvp;
- quarter-circle cantilever, small tip load: Castigliano's theorem (thin curved beam);
- h-refinement: L2 rate min(p+1, 2(p-1)) of a 4th-order problem (DESIGN.md Sec. 6).
"""

import jax.numpy as jnp
import numpy as np
import pytest
from _builders import beam, bending_stiffness, static_case
from scipy.integrate import solve_bvp
from scipy.optimize import fsolve

from beamcontact.assembly.build import build_model, point_sampler
from beamcontact.solvers.newton import NewtonOptions
from beamcontact.statics.driver import solve_static


def _solve(case, steps=None):
    model, disc = build_model(case)
    states = []
    res = solve_static(model, case.analysis.load_steps, NewtonOptions(), disc.length_scale,
                       on_step=lambda s: states.append((s.load_factor, s.u, s.iterations)))
    assert res.status == "completed", res.message
    return model, disc, states


def _point(model, disc, u, beam_name, fraction):
    idx, R = point_sampler(disc, beam_name, fraction)
    return R @ (np.asarray(model.x_ref) + u.reshape(-1, 2))[idx]


# --- end moment: exact solution of the continuum model -----------------------------------

def _circle_moments(a, n_max=8):
    """int eta^n dA over a solid circle of radius a: 2 a^(n+2) B((n+1)/2, 3/2), odd n: 0."""
    from math import gamma

    return {n: 0.0 if n % 2 else 2 * a ** (n + 2) * gamma((n + 1) / 2) * gamma(1.5)
            / gamma(n / 2 + 2) for n in range(n_max + 1)}


def _exact_pure_bending(E, a, L, M):
    """Stretch lam and curvature k of a straight beam under end moment M.

    Fibre strain (Green-Lagrange, physical) 1/2 [(1 - eta k)^2 lam^2 - 1]; energy per length
    w = E/8 int [(1 - eta k)^2 lam^2 - 1]^2 dA; end rotation theta = k lam L; equilibrium
    dw/dlam = M k, dw/dk = M lam.
    """
    mom = _circle_moments(a)

    def integral(coeffs):  # int sum_n c_n eta^n dA
        return sum(c * mom[n] for n, c in enumerate(coeffs))

    P = np.polynomial.Polynomial

    def grad(v):
        lam, k = v
        s = P([1.0, -k]) ** 2  # (1 - eta k)^2
        f = s * lam**2 - 1.0
        dw_dlam = E / 8 * integral((2 * f * 2 * lam * s).coef)
        dw_dk = E / 8 * integral((2 * f * lam**2 * 2 * P([1.0, -k]) * P([0.0, -1.0])).coef)
        return [dw_dlam - M * k, dw_dk - M * lam]

    EI = E * np.pi * a**4 / 4
    lam, k = fsolve(grad, [1.0, M / EI], xtol=1e-13)
    return lam, k


def _arc_position(lam, k, s0):
    phi = k * lam * s0
    return np.column_stack([np.sin(phi) / k, (1.0 - np.cos(phi)) / k])


def test_section_moments_are_those_of_a_circle():
    a = 0.3
    m = _circle_moments(a)
    assert np.isclose(m[0], np.pi * a**2) and np.isclose(m[2], np.pi * a**4 / 4)
    assert np.isclose(m[4], np.pi * a**6 / 8)


def test_end_moment_rolls_cantilever_into_exact_circle():
    L, a, E = 1.0, 0.005, 1.0e9
    M = 2 * np.pi * bending_stiffness(E, a) / L
    case = static_case([beam(line=([0, 0], [L, 0]), degree=3, elements=16, radius=a, E=E,
                             supports=[{"at": "start", "type": "clamped"}])],
                       [{"beam": "b", "at": "end", "moment": M}], load_steps=10)
    model, disc, states = _solve(case)
    for lam_load, u, _ in states[1:]:
        lam, k = _exact_pure_bending(E, a, L, lam_load * M)
        fractions = np.linspace(0, 1, 21)
        num = np.array([_point(model, disc, u, "b", f) for f in fractions])
        np.testing.assert_allclose(num, _arc_position(lam, k, fractions * L), atol=2e-4 * L)
    tip = _point(model, disc, states[-1][1], "b", 1.0)
    assert np.linalg.norm(tip) < 2e-3 * L  # the acceptance criterion: back at the clamp


def _cantilever_self_weight_errors(degree, elements):
    """L2 errors of the deflection of a clamped cantilever under a small uniform load.

    Exact (linear Euler-Bernoulli, deflection 4e-8 L so the geometric nonlinearity is
    far below the errors): w = -q/(24 EI) (x^4 - 4 L x^3 + 6 L^2 x^2).
    """
    L, a, E, rho, g = 1.0, 0.01, 1.0e9, 1000.0, 1e-3
    EI, q = bending_stiffness(E, a), rho * np.pi * a**2 * g
    errors, scale = [], q * L**4 / (8 * EI)
    for n in elements:
        case = static_case([beam(line=([0, 0], [L, 0]), degree=degree, elements=int(n), radius=a,
                                 E=E, density=rho, supports=[{"at": "start", "type": "clamped"}])],
                           gravity=(0.0, -g))
        model, disc, states = _solve(case)
        mesh = disc.beams[0].mesh
        x = np.asarray(model.x_ref) + states[-1][1].reshape(-1, 2)
        w = np.einsum("eqk,ek->eq", mesh.R, x[mesh.conn][..., 1])
        X = mesh.xi_qp * L
        exact = -q / (24 * EI) * (X**4 - 4 * L * X**3 + 6 * L**2 * X**2)
        errors.append(np.sqrt(np.sum(mesh.wq * (w - exact) ** 2)) / scale)
    return np.array(errors)


@pytest.mark.parametrize(("degree", "expected_rate"), [(2, 2.0), (3, 4.0)])
def test_h_refinement_rate_uniform_load(degree, expected_rate):
    """L2 rate min(p+1, 2(p-1)) of a 4th-order problem: 2 for p = 2, 4 for p = 3."""
    elements = np.array([4, 8, 16, 32])
    errors = _cantilever_self_weight_errors(degree, elements)
    rate = np.polyfit(np.log(1.0 / elements), np.log(errors), 1)[0]
    assert abs(rate - expected_rate) < 0.2, (errors, rate)


def test_quartic_reproduces_quartic_deflection():
    """The exact deflection is a quartic: degree-4 splines reproduce it to round-off."""
    errors = _cantilever_self_weight_errors(4, [1, 3])
    assert np.all(errors < 1e-7)


def test_h_refinement_rate_end_moment_nonlinear():
    """Large rotation (quarter circle): the cubic L2 rate 4 holds in the nonlinear regime."""
    L, a, E = 1.0, 0.01, 1.0e9
    M = 0.5 * np.pi * bending_stiffness(E, a) / L
    lam, k = _exact_pure_bending(E, a, L, M)
    elements = np.array([2, 4, 8, 16])
    errors = []
    for n in elements:
        case = static_case([beam(line=([0, 0], [L, 0]), degree=3, elements=int(n), radius=a,
                                 E=E, supports=[{"at": "start", "type": "clamped"}])],
                           [{"beam": "b", "at": "end", "moment": M}], load_steps=2)
        model, disc, states = _solve(case)
        mesh = disc.beams[0].mesh
        x = np.asarray(model.x_ref) + states[-1][1].reshape(-1, 2)
        num = np.einsum("eqk,ekd->eqd", mesh.R, x[mesh.conn])
        exact = _arc_position(lam, k, mesh.xi_qp.ravel() * L).reshape(num.shape)
        errors.append(np.sqrt(np.sum(mesh.wq[..., None] * (num - exact) ** 2)))
    rate = np.polyfit(np.log(1.0 / elements), np.log(errors), 1)[0]
    assert abs(rate - 4.0) < 0.3, (errors, rate)


# --- tip load: inextensible elastica ------------------------------------------------------

def _elastica_tip(load_params):
    """Tip (x, y)/L of a clamped inextensible elastica under a downward dead tip load.

    theta'' = k cos(theta), theta(0) = 0, theta'(1) = 0, x' = cos theta, y' = sin theta,
    with k = P L^2 / EI; solved by continuation in k.
    """
    s = np.linspace(0, 1, 201)
    guess = np.zeros((4, s.size))
    guess[2] = s
    tips = []
    for k in load_params:
        def rhs(_, y, k=k):
            return np.vstack([y[1], k * np.cos(y[0]), np.cos(y[0]), np.sin(y[0])])

        def bc(ya, yb):
            return np.array([ya[0], yb[1], ya[2], ya[3]])

        sol = solve_bvp(rhs, bc, s, guess, tol=1e-10, max_nodes=100000)
        assert sol.success
        guess = sol.sol(s)
        tips.append(sol.sol(1.0)[2:])
    return np.array(tips)


def test_cantilever_tip_load_matches_elastica():
    L, a, E = 1.0, 0.002, 1.0e9
    EI = bending_stiffness(E, a)
    k_max = 10.0
    # quartic, as in the paper: cubics need about twice the elements here (membrane locking)
    case = static_case([beam(line=([0, 0], [L, 0]), degree=4, elements=16, radius=a, E=E,
                             supports=[{"at": "start", "type": "clamped"}])],
                       [{"beam": "b", "at": "end", "force": [0.0, -k_max * EI / L**2]}],
                       load_steps=10)
    model, disc, states = _solve(case)
    ks = [k_max * lam for lam, _, _ in states[1:]]
    ref = _elastica_tip(ks)
    # literature check of the reference (Mattiasson 1981): k = 1 -> vertical 0.30172 L
    assert abs(-ref[0, 1] - 0.30172) < 2e-5
    for (lam, u, _), tip_ref in zip(states[1:], ref, strict=True):
        tip = _point(model, disc, u, "b", 1.0)
        deflection = tip - [L, 0.0]
        ref_deflection = tip_ref * L - [L, 0.0]
        # three significant digits in both components
        np.testing.assert_allclose(deflection, ref_deflection, rtol=5e-4, atol=0)


def test_newton_converges_quadratically_with_ad_tangent():
    """Small load increments need few iterations thanks to the consistent tangent."""
    L, a, E = 1.0, 0.01, 1.0e9
    EI = bending_stiffness(E, a)
    case = static_case([beam(line=([0, 0], [L, 0]), degree=4, elements=8, continuity=1,
                             radius=a, E=E, supports=[{"at": "start", "type": "clamped"}])],
                       [{"beam": "b", "at": "end", "force": [0.0, -3.0 * EI / L**2]}],
                       load_steps=20)
    _, _, states = _solve(case)
    assert max(it for _, _, it in states[1:]) <= 6


# --- quarter circle: Castigliano ----------------------------------------------------------

@pytest.mark.parametrize("direction", ["x", "y"])
def test_quarter_circle_cantilever_small_tip_load_castigliano(direction):
    """Clamped at (R, 0), free at (0, R); bending-only Castigliano for a thin curved beam:
    Fx: dx = (3 pi/4 - 2) F R^3/EI, dy = F R^3 / (2 EI); Fy: dy = pi/4 F R^3/EI,
    dx = F R^3 / (2 EI).
    """
    Rc, a, E = 1.0, 0.004, 1.0e9
    EI = bending_stiffness(E, a)
    F = 1e-5 * EI / Rc**2  # linear range: deflection 1e-5 R
    arc = {"center": [0.0, 0.0], "radius": Rc, "start_angle": 0.0, "end_angle": np.pi / 2}
    force = [F, 0.0] if direction == "x" else [0.0, F]
    case = static_case([beam(arc=arc, degree=4, elements=8, continuity=3, radius=a, E=E,
                             supports=[{"at": "start", "type": "clamped"}])],
                       [{"beam": "b", "at": "end", "force": force}], load_steps=1)
    model, disc, states = _solve(case)
    d = _point(model, disc, states[-1][1], "b", 1.0) - [0.0, Rc]
    c = F * Rc**3 / EI
    exact = [(3 * np.pi / 4 - 2) * c, 0.5 * c] if direction == "x" else [0.5 * c, np.pi / 4 * c]
    np.testing.assert_allclose(d, exact, rtol=1e-3)


def test_gravity_sag_of_pinned_beam_small_load():
    """Linear Euler-Bernoulli: pinned-pinned under self weight, midspan 5 q L^4 / (384 EI).

    The supports pin the ends in both directions, so a small sag adds a tiny membrane
    (string) effect of relative size (w/r)^2 ~ 1e-5.
    """
    L, a, E, rho, g = 2.0, 0.01, 2.0e11, 7850.0, 0.0981
    EI = bending_stiffness(E, a)
    q = rho * np.pi * a**2 * g
    case = static_case([beam(line=([0, 0], [L, 0]), degree=4, elements=8, radius=a, E=E,
                             density=rho, supports=[{"at": "start", "type": "pinned"},
                                                    {"at": "end", "type": "pinned"}])],
                       gravity=(0.0, -g), load_steps=1)
    model, disc, states = _solve(case)
    w = _point(model, disc, states[-1][1], "b", 0.5)[1]
    exact = -5 * q * L**4 / (384 * EI)
    assert abs(w - exact) < 1e-3 * abs(exact)
    assert jnp.isfinite(w)
