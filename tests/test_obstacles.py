"""Rigid obstacles ([[obstacles]]): the coarse-grained section-to-half-space law against the
quadrature of eq. (8), AD forces and tangents against finite differences, a beam resting
on a floor (its weight against the closed-form gap and penetration), a fast beam that
bounces off a floor without tunnelling, and the validation of the case tables."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from _builders import beam
from scipy.integrate import quad
from scipy.special import gamma

import beamcontact as bc
from beamcontact.contact.laws import CoarseGrained, Penalty
from beamcontact.contact.obstacles import obstacle_energy, obstacle_forces, obstacle_gaps
from beamcontact.io.case import CaseError, parse_case
from beamcontact.setup.contact import build_contact
from beamcontact.setup.model import build_model

R = 0.01
RHO = 1000.0
G = 9.81
FLOOR = {"name": "floor", "wall": {"point": [0.0, 0.0], "normal": [0.0, 2.0]}}


def _case(contact, obstacles, y0=0.05, kind="dynamic", v0=(0.0, 0.0), g=G, E=1e9,
          **analysis):
    """A free straight beam of 1 m, radius R, its axis at height y0 above x = [-0.5, 0.5]."""
    b = beam("beam", line=((-0.5, y0), (0.5, y0)), degree=3, elements=4, radius=R,
             density=RHO, E=E)
    b["initial_velocity"] = list(v0)
    an = {"kind": kind, "gravity": [0.0, -g], **analysis}
    return parse_case({"analysis": an, "beams": [b], "contact": contact,
                       "obstacles": obstacles,
                       "output": {"points": [{"name": "M", "beam": "beam", "at": 0.5}]}})


@pytest.mark.parametrize("m", [8.0, 12.0])
def test_cg_wall_law_is_the_small_gap_limit_of_eq8(m):
    """A straight beam parallel to a wall: eq. (8) per unit length is exactly the section
    (a disk of radius R) against the half-space, the point-to-half-space potential
    2 pi k beta beta_o h^(3-m) / ((m-2)(m-3)) integrated over the disk. The law of
    contact/obstacles.py is its small-gap limit; the relative difference is first order
    in q / R with the coefficient 3 / (8 (m - 11/2)) (from sqrt(1 - u / 2R) in the disk's
    chord)."""
    k, beta = 1e-23, 2.0
    law = CoarseGrained(k, m, 1e-12, 1.0)

    def exact(q):
        chord = lambda u: 2.0 * np.sqrt(u * (2 * R - u)) * (q + u) ** (3.0 - m)  # noqa: E731
        val = quad(chord, 0.0, 2 * R, points=[q, 10 * q, 100 * q], limit=500,
                   epsabs=0.0, epsrel=1e-13)[0]
        return k * beta * 2 * np.pi / ((m - 2) * (m - 3)) * val

    errors = []
    for q in (1e-3 * R, 1e-4 * R):
        amp = law.obstacle_amplitude(jnp.asarray(R), beta)
        ours = float(law.obstacle_energy(jnp.asarray(q), jnp.asarray(R), amp, 1.0))
        errors.append((ours - exact(q)) / exact(q) / (q / R))
    coefficient = 3.0 / (8.0 * (m - 5.5))
    assert errors[1] == pytest.approx(coefficient, rel=1e-3)
    assert errors[0] == pytest.approx(coefficient, rel=1e-2)
    # and the constant itself, written out with Gamma functions
    amp = float(law.obstacle_amplitude(jnp.asarray(R), 1.0))
    assert amp == pytest.approx(k * (2 * np.pi) ** 1.5 * np.sqrt(R) * gamma(m - 4.5)
                                / gamma(m - 1.0), rel=1e-12)


@pytest.mark.parametrize("law", [Penalty(1e5, R), CoarseGrained(1e-23, 12.0, 1e-5, 0.05)])
def test_obstacle_forces_are_the_derivatives_of_the_energy(law):
    """Gradient and Hessian of each element's obstacle energy (AD at the point level,
    then the basis rows) against central differences of the total energy, with a wall
    and a circle both in reach of a bent beam."""
    case = _case({"model": "ipip"}, [
        FLOOR, {"name": "post", "circle": {"center": [0.3, -0.095], "radius": 0.1}}], kind="static")
    model, disc = build_model(case)
    problem = build_contact(case, disc)
    ce, obs = problem.elements, problem.obstacles
    rng = np.random.default_rng(3)
    x = np.asarray(model.x_ref)
    x = x + np.stack([0 * x[:, 0], -0.0445 + 0.02 * (x[:, 0] + 0.5)], axis=1)
    x = jnp.asarray(x + 1e-3 * rng.standard_normal(x.shape))
    q = np.asarray(obstacle_gaps(x, ce, obs))
    assert q[..., 0].min() < 0.0 < q[..., 0].max()  # the wall: in and out of contact
    assert 0.0 < q[..., 1].min() < 0.03  # the circle: within the cutoff, not touching
    conn, f, k = obstacle_forces(x, ce, obs, law)
    n = x.size
    grad = np.zeros(n)
    hess = np.zeros((n, n))
    dofs = np.stack([2 * np.asarray(conn), 2 * np.asarray(conn) + 1], -1).reshape(len(conn), -1)
    for e in range(len(conn)):
        np.add.at(grad, dofs[e], np.asarray(f[e]))
        np.add.at(hess, (dofs[e][:, None], dofs[e][None, :]), np.asarray(k[e]))
    energy = jax.jit(lambda xf: obstacle_energy(xf.reshape(-1, 2), ce, obs, law))
    gfun = jax.jit(jax.grad(lambda xf: obstacle_energy(xf.reshape(-1, 2), ce, obs, law)))
    xf = x.ravel()
    h = 1e-7
    fd = np.array([(energy(xf.at[i].add(h)) - energy(xf.at[i].add(-h))) / (2 * h)
                   for i in range(n)])
    assert np.abs(grad).max() > 0.0
    assert np.allclose(grad, fd, rtol=1e-5, atol=1e-6 * np.abs(grad).max())
    fd_h = np.array([(gfun(xf.at[i].add(h)) - gfun(xf.at[i].add(-h))) / (2 * h)
                     for i in range(n)])
    assert np.allclose(hess, fd_h, rtol=1e-5, atol=1e-6 * np.abs(hess).max())


def test_circle_and_wall_gaps():
    """q = n . (p - p0) - R for a wall (the normal made unit length), |p - c| - r - R for a
    circle, at every contact point of a straight beam."""
    case = _case({"model": "ipip"}, [
        FLOOR, {"name": "post", "circle": {"center": [0.2, 0.3], "radius": 0.1}}], kind="static")
    model, disc = build_model(case)
    problem = build_contact(case, disc)
    ce = problem.elements
    x = np.asarray(model.x_ref)
    p = np.einsum("esk,ekd->esd", np.asarray(ce.R), x[np.asarray(ce.conn)])
    q = np.asarray(obstacle_gaps(jnp.asarray(x), ce, problem.obstacles))
    assert np.allclose(q[..., 0], p[..., 1] - R, rtol=0, atol=1e-15)
    assert np.allclose(q[..., 1], np.linalg.norm(p - [0.2, 0.3], axis=-1) - 0.1 - R,
                       rtol=0, atol=1e-15)


def test_cg_beam_resting_on_a_floor_carries_its_weight():
    """Statics, coarse-grained law: a straight beam on a floor, held sideways by two
    walls at its ends. Its weight rho A L g is carried by the floor's potential,
    L (m - 9/2) A_w q^(7/2 - m) (A_w = k C_w(m, R)), at the closed-form gap
    q* = ((m - 9/2) A_w / (rho A g))^(1 / (m - 7/2)); the walls at the ends push
    sideways only. The closed form is that of a rigid beam: a flexible one bends between
    its discrete support points, by an amount proportional to 1 / EI (relative gap
    differences of 2e-6 at E = 1e11 Pa, 2e-7 at 1e12), so the beam is made stiff."""
    k, m = 1e-23, 12.0
    cutoff = 0.05
    A_w = k * (2 * np.pi) ** 1.5 * np.sqrt(R) * gamma(m - 4.5) / gamma(m - 1.0)
    q_star = ((m - 4.5) * A_w / (RHO * np.pi * R**2 * G)) ** (1.0 / (m - 3.5))
    # the last contact point is half a segment (6.25 mm) inside the end; the side walls
    # stand at 1.5 q* from it, 5 mm beyond the ends
    side = 0.5 - 0.00625 + R + 1.5 * q_star
    walls = [FLOOR,
             {"name": "left", "wall": {"point": [-side, 0.0], "normal": [1.0, 0.0]}},
             {"name": "right", "wall": {"point": [side, 0.0], "normal": [-1.0, 0.0]}}]
    contact = {"model": "cg", "k": k, "exponent": m, "cutoff": cutoff,
               "segments_per_element": 20}
    case = _case(contact, walls, y0=R + 1.2 * q_star, kind="static", load_steps=4,
                 E=1e12)
    res = bc.simulate(case)
    assert res.summary["status"] == "completed"
    h = res.history
    assert h["load_factor"].iloc[-1] == pytest.approx(1.0)
    assert h["min_gap"].iloc[-1] == pytest.approx(q_star, rel=1e-6)
    # straight and level: the midpoint sits at the same gap
    assert R + 1.2 * q_star + h["M_uy"].iloc[-1] - R == pytest.approx(q_star, rel=1e-6)
    assert abs(h["M_ux"].iloc[-1]) < 1e-9


def test_ipip_beam_at_the_closed_form_penetration_stays_at_rest():
    """IPIP: each of the N contact points carries eps delta (weight 1), so a straight
    beam on a floor is in equilibrium at delta = rho A L g / (N eps). Started there at
    rest, it stays there: its midpoint moves by less than 1 % of delta in 0.02 s. With
    twice or half the reaction it would oscillate with an amplitude of about delta."""
    eps, segments = 1e5, 10
    N = 4 * segments
    delta = RHO * np.pi * R**2 * 1.0 * G / (N * eps)
    case = _case({"model": "ipip", "penalty": eps, "segments_per_element": segments},
                 [FLOOR], y0=R - delta, t_end=0.02, dt=1e-3, alpha=-0.1)
    res = bc.simulate(case)
    assert res.summary["status"] == "completed"
    h = res.history
    assert h["min_gap"].iloc[0] == pytest.approx(-delta, rel=1e-9)
    assert np.abs(h["M_uy"]).max() < 1e-2 * delta
    assert np.abs(h["p_y"]).max() < 1e-2 * delta * np.sqrt(eps * N * RHO * np.pi * R**2)


@pytest.mark.parametrize("model", ["ipip", "cg"])
def test_fast_beam_bounces_off_a_floor_without_tunnelling(model):
    """A beam thrown at 5 m/s (no gravity) at a floor 5 mm below it with a first step of
    10 ms (it would pass 5 cm through the floor): the advancement bound shortens the
    step, the smallest gap stays above -max_penetration, and with alpha = 0 the bounce is
    elastic (the vertical momentum reverses to within 2 %, E_total changes by less than
    0.5 %)."""
    contact = ({"model": "ipip", "penalty": 1e5, "segments_per_element": 5} if model == "ipip"
               else {"model": "cg", "k": 1e-23, "cutoff": 0.05, "segments_per_element": 5})
    case = _case(contact, [FLOOR], y0=R + 5e-3, v0=(0.0, -5.0), g=0.0, t_end=0.012,
                 dt=1e-2, alpha=0.0)
    res = bc.simulate(case)
    assert res.summary["status"] == "completed"
    h = res.history
    p0 = h["p_y"].iloc[0]
    assert p0 < 0.0
    assert h["min_gap"].min() > -R  # max_penetration: the radius by default
    assert h["min_gap"].min() < 1e-3  # it did reach the floor
    assert h["p_y"].iloc[-1] == pytest.approx(-p0, rel=2e-2)
    e = h["E_total"]
    assert np.abs(e - e.iloc[0]).max() < 5e-3 * h["E_kin"].iloc[0]


def _raw(**extra):
    raw = {"analysis": {"kind": "static"},
           "beams": [beam("beam", line=((0, 0.1), (1, 0.1)), radius=R)],
           "contact": {"model": "ipip"}, "obstacles": [FLOOR]}
    raw.update(extra)
    return raw


@pytest.mark.parametrize("change, message", [
    ({"obstacles": [{"name": "w"}]}, "give exactly one shape: wall or circle"),
    ({"obstacles": [{"name": "w", "wall": {"point": [0, 0], "normal": [0, 0]}}]},
     "normal must be a nonzero vector"),
    ({"obstacles": [{"name": "c", "circle": {"center": [0, 0], "radius": -1.0}}]},
     "obstacles[0] (c).circle.radius"),
    ({"obstacles": [FLOOR, FLOOR]}, "obstacles[1].name: duplicate obstacle name 'floor'"),
    ({"contact": {"model": "none"}}, "obstacles: need a contact law"),
    ({"obstacles": [{**FLOOR, "density": 2.0}]},
     "obstacles[0] (floor).density: applies to model \"cg\" only"),
    ({"contact": {"model": "cg", "exponent": 4.0, "cutoff": 0.1}},
     "contact.exponent: the coarse-grained law against an obstacle needs m > 4.5"),
])
def test_bad_obstacles_name_the_key(change, message):
    with pytest.raises(CaseError) as err:
        parse_case(_raw(**change))
    assert message in str(err.value)


def test_beam_inside_an_obstacle_is_an_input_error():
    """A beam that starts through a wall is reported with both names and the place."""
    case = _case({"model": "ipip"}, [FLOOR], y0=0.5 * R, t_end=0.01, dt=1e-3)
    with pytest.raises(CaseError, match="beam 'beam' penetrates obstacle 'floor' in the "
                                        "initial configuration: gap -0.005 m"):
        bc.simulate(case)


def test_single_free_beam_with_an_obstacle_is_not_a_static_mechanism():
    """An obstacle may hold a beam: the static check leaves it to the solver."""
    from beamcontact.setup.checks import static_mechanisms

    case = parse_case(_raw())
    assert static_mechanisms(case, build_model(case)[1]) == []
