"""Static large-deformation problems against independent references.

- end moment: the exact solution of this continuum model (uniform stretch and curvature,
  found from two scalar equations with the section integrals in closed form);
- tip load: the inextensible elastica solved with SciPy's solve_bvp;
- quarter-circle cantilever, small tip load: Castigliano's theorem (thin curved beam);
- h-refinement: L2 rate min(p+1, 2(p-1)) of a 4th-order problem (docs/architecture.md,
  "Verification").

Load stepping runs on the native engine (statics/native_step.py), as ``beamcontact run``
does; the end moment, the elastica and the mechanism checks run on the JAX engine too.
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from _builders import beam, bending_stiffness, static_case
from scipy.integrate import solve_bvp
from scipy.optimize import fsolve

from beamcontact.setup.model import build_model, point_sampler
from beamcontact.solvers.newton import NewtonOptions
from beamcontact.statics.driver import solve_static
from beamcontact.statics.native_step import NativeStatics
from beamcontact.statics.step import JaxStatics

ENGINES = {"native": NativeStatics, "jax": JaxStatics}


def _solve(case, engine="native"):
    model, disc = build_model(case)
    states = []
    res = solve_static(ENGINES[engine](model, None, NewtonOptions(), disc.length_scale),
                       case.analysis.load_steps,
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


@pytest.mark.parametrize("engine", ENGINES)
def test_end_moment_rolls_cantilever_into_exact_circle(engine):
    L, a, E = 1.0, 0.005, 1.0e9
    M = 2 * np.pi * bending_stiffness(E, a) / L
    case = static_case([beam(line=([0, 0], [L, 0]), degree=3, elements=16, radius=a, E=E,
                             supports=[{"at": "start", "type": "clamped"}])],
                       [{"beam": "b", "at": "end", "moment": M}], load_steps=10)
    model, disc, states = _solve(case, engine)
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


@pytest.mark.parametrize("engine", ENGINES)
def test_cantilever_tip_load_matches_elastica(engine):
    L, a, E = 1.0, 0.002, 1.0e9
    EI = bending_stiffness(E, a)
    k_max = 10.0
    # quartic, as in the paper: cubics need about twice the elements here (membrane locking)
    case = static_case([beam(line=([0, 0], [L, 0]), degree=4, elements=16, radius=a, E=E,
                             supports=[{"at": "start", "type": "clamped"}])],
                       [{"beam": "b", "at": "end", "force": [0.0, -k_max * EI / L**2]}],
                       load_steps=10)
    model, disc, states = _solve(case, engine)
    ks = [k_max * lam for lam, _, _ in states[1:]]
    ref = _elastica_tip(ks)
    # literature check of the reference (Mattiasson 1981): k = 1 -> vertical 0.30172 L
    assert abs(-ref[0, 1] - 0.30172) < 2e-5
    for (_lam, u, _), tip_ref in zip(states[1:], ref, strict=True):
        tip = _point(model, disc, u, "b", 1.0)
        deflection = tip - [L, 0.0]
        ref_deflection = tip_ref * L - [L, 0.0]
        # three significant digits in both components
        np.testing.assert_allclose(deflection, ref_deflection, rtol=5e-4, atol=0)


def _newton_decrements(residual_tangent, n_dof, iterations):
    """Plain Newton from u = 0 on the host; the Newton decrement of every iteration,
    e_k = sqrt(-r_k . du_k) = ||du_k||_K (K_k du_k = -r_k). It measures the error in the
    energy norm, whatever the scales of the dofs (axial vs bending), and is invariant
    under affine changes of the unknowns (Deuflhard), so its quadratic rate is clean."""
    u, e = np.zeros(n_dof), []
    for _ in range(iterations):
        r, K = (np.asarray(a) for a in residual_tangent(jnp.asarray(u)))
        du = np.linalg.solve(K, -r)
        e.append(np.sqrt(abs(r @ du)))
        u = u + du
    return np.array(e)


def test_newton_converges_quadratically_with_ad_tangent():
    """The AD tangent is consistent: Newton's error contracts quadratically,
    e_{k+1} <= C e_k^2, in the asymptotic range (from e_k < 1e-2 e_0 until the next
    error nears the round-off floor, measured by iterating on past convergence).

    The tip load 3 EI/L^2 in one step takes about a dozen iterations, four of them
    asymptotic. The order is the slope of log e_{k+1} against log e_k (2: quadratic,
    1: linear, as with an inconsistent tangent), and C_k = e_{k+1}/e_k^2 must not grow
    (with linear convergence it grows like 1/e_k). Round-off only moves the floor, which
    the selection excludes; the asserted number of iterations was not robust to it.
    """
    from threadpoolctl import threadpool_limits

    from beamcontact.assembly.model import initial_load_state
    from beamcontact.assembly.system import apply_supports, potential_residual_tangent

    L, a, E = 1.0, 0.01, 1.0e9
    EI = bending_stiffness(E, a)
    case = static_case([beam(line=([0, 0], [L, 0]), degree=4, elements=8, continuity=1,
                             radius=a, E=E, supports=[{"at": "start", "type": "clamped"}])],
                       [{"beam": "b", "at": "end", "force": [0.0, -3.0 * EI / L**2]}])
    model, _ = build_model(case)
    state = initial_load_state(model)

    @jax.jit
    def residual_tangent(u):
        return apply_supports(*potential_residual_tangent(u, model, 1.0, state), model.free)

    with threadpool_limits(limits=1, user_api="blas"):
        e = _newton_decrements(residual_tangent, model.n_dof, 24)
    floor = np.median(e[-6:])  # converged long before: round-off only
    assert floor < 1e-10 * e[0]
    k = np.nonzero((e[:-1] < 1e-2 * e[0]) & (e[1:] > 1e2 * floor))[0]
    assert len(k) >= 3, e
    order = np.polyfit(np.log(e[k]), np.log(e[k + 1]), 1)[0]
    assert 1.8 < order < 2.3, (order, e)
    C = e[k + 1] / e[k] ** 2
    assert np.all(C[1:] < 3.0 * C[:-1]), (C, e)


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


# --- singular stiffness: beams that the supports do not hold ------------------------------

def _restraint_case(supports, load_at=0.5, contact=None, upper=None):
    beams = [beam("b", line=([0, 0], [1, 0]), degree=3, elements=6, supports=supports)]
    if upper is not None:
        beams.append(upper)
    raw_contact = {} if contact is None else {"contact": contact}
    case = static_case(beams, [{"beam": "b", "at": load_at, "force": [0.0, -1.0]}],
                       load_steps=2)
    if raw_contact:
        from beamcontact.io.case import parse_case

        case = parse_case({**case.model_dump(exclude_none=True), **raw_contact})
    return case


@pytest.mark.parametrize(("supports", "modes"), [
    ([], 3), ([{"at": "start", "type": "pinned"}], 1),
    ([{"at": "end", "type": "clamped"}], 0),
    ([{"at": "start", "type": "pinned"}, {"at": "end", "type": "pinned"}], 0)])
def test_rigid_modes_left_free_by_the_supports(supports, modes):
    from beamcontact.setup.model import discretize, supported_dofs
    from beamcontact.statics.restraint import rigid_modes, unrestrained_modes

    case = _restraint_case(supports)
    disc = discretize(case)
    x = disc.beams[0].curve.points
    Q = unrestrained_modes(x, supported_dofs(case, disc))
    assert Q.shape == (2 * len(x), modes)
    np.testing.assert_allclose(Q.T @ Q, np.eye(modes), atol=1e-12)
    phi = rigid_modes(x)  # Q lies in the span of the rigid modes
    np.testing.assert_allclose(phi @ np.linalg.lstsq(phi, Q, rcond=None)[0], Q, atol=1e-12)


@pytest.mark.parametrize(("supports", "says"), [
    ([], "beam 'b' has 3 rigid-body modes not restrained by its supports (it can translate "
         "and rotate freely)"),
    ([{"at": "start", "type": "pinned"}],
     "beam 'b' has 1 rigid-body mode not restrained by its supports (it can rotate about "
     "(0, 0))")])
@pytest.mark.parametrize("engine", ENGINES)
def test_singular_stiffness_stops_at_once_naming_the_beam(supports, says, engine):
    """A mechanism under a transverse load stops before the first step with a reason,
    instead of halving the load increment on NaN residuals."""
    case = _restraint_case(supports)
    model, disc = build_model(case)
    steps = []
    engine = ENGINES[engine](model, None, NewtonOptions(), disc.length_scale)
    res = solve_static(engine, 2, on_step=steps.append, beam_names=[b.name for b in disc.beams])
    assert res.status == "failed" and res.steps == 0 and res.cutbacks == 0
    assert res.message.startswith("the stiffness matrix is singular: " + says), res.message
    assert res.message.endswith("add supports: clamp an end, or pin both ends")
    assert [s.step for s in steps] == [0]  # the initial state is still reported
    unnamed = solve_static(engine, 2)
    assert "beam #1 (control points 0-8) has" in unnamed.message


def _contact_pair(gap, upper_supports=(), lower_supports=None):
    """A free upper beam over a lower beam (IPIP), surface gap ``gap``."""
    pinned = [{"at": "start", "type": "pinned"}, {"at": "end", "type": "pinned"}]
    upper = beam("u", line=([0.25, 0.01 + gap], [0.75, 0.01 + gap]), degree=3, elements=4,
                 supports=list(upper_supports))
    return _restraint_case(pinned if lower_supports is None else lower_supports,
                           contact={"model": "ipip", "segments_per_element": 4,
                                    "penalty": 1e5}, upper=upper)


def _mechanism(case, engine):
    """The engine's reason for a singular tangent at the start of load stepping, with the
    contact set as solve_static finds it."""
    from beamcontact.setup.contact import build_contact

    model, disc = build_model(case)
    contact = build_contact(case, disc)
    statics = ENGINES[engine](model, contact, NewtonOptions(), disc.length_scale)
    state = statics.initial()
    cs = statics.complete_set(state, 0.5 * contact.reach,
                              contact.first_capacity(contact.all_pairs))[0]
    return statics.mechanism(state, cs, [b.name for b in disc.beams])


@pytest.mark.parametrize("engine", ENGINES)
def test_contact_can_hold_an_unsupported_beam(engine):
    """Pressed into a supported beam, a free beam is held by contact: no complaint; lifted
    off it, nothing holds it; two free beams pressed together still float as one: their
    energy is invariant under translations at any state, so those two modes are null
    vectors of the tangent (the rotation is not: the contact forces of the initial
    penetration are not zero, and the tangent of a rotation-invariant energy turns them)."""
    assert _mechanism(_contact_pair(-3e-3), engine) is None
    lifted = _mechanism(_contact_pair(1e-2), engine)
    assert "beam 'u' has 3 rigid-body modes not restrained by its supports or by contact" \
        in lifted
    both = _mechanism(_contact_pair(-3e-3, lower_supports=[]), engine)
    assert "beams 'b' and 'u' are held only by contact with each other: together they have " \
        "2 rigid-body modes" in both, both


def test_beam_ranges_from_connectivity():
    from beamcontact.statics.restraint import beam_ranges

    case = _contact_pair(1e-2)
    model, disc = build_model(case)
    assert beam_ranges([np.asarray(b.conn) for b in model.beams]) == [
        (b.offset, b.offset + b.n_cp) for b in disc.beams]
