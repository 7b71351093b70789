"""HHT-alpha dynamics against closed forms, theory of the integrator, and independent ODEs."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
import scipy.linalg
from _builders import beam, bending_stiffness, static_case
from scipy.integrate import solve_ivp

from beamcontact.assembly.inertia import inertia_force_and_mass
from beamcontact.assembly.model import initial_load_state
from beamcontact.assembly.system import potential_residual_tangent
from beamcontact.dynamics.control import StepControl
from beamcontact.dynamics.driver import solve_dynamic
from beamcontact.dynamics.hht import initial_state
from beamcontact.dynamics.step import JaxEngine
from beamcontact.setup.model import build_model, point_sampler
from beamcontact.solvers.newton import NewtonOptions


def _simulate(model, disc, t_end, dt, alpha, u0=None, v0=None, **kw):
    n = model.n_dof
    u0 = jnp.zeros(n) if u0 is None else jnp.asarray(u0)
    v0 = jnp.zeros(n) if v0 is None else jnp.asarray(v0)
    state = initial_state(u0, v0, model, initial_load_state(model))
    steps = [(0.0, np.asarray(state.u), None)]
    engine = JaxEngine(model, None, alpha, NewtonOptions(**kw), disc.length_scale, dt)
    res = solve_dynamic(engine, state, t_end, disc.length_scale, StepControl.fixed(dt),
                        on_step=lambda s: steps.append((s.t, np.asarray(s.state.u),
                                                        s.diagnostics)))
    assert res.status == "completed", res.message
    return steps, res


def _point(model, disc, u, name, fraction):
    idx, R = point_sampler(disc, name, fraction)
    return R @ (np.asarray(model.x_ref) + u.reshape(-1, 2))[idx]


@pytest.mark.parametrize("alpha", [0.0, -0.1, -1.0 / 3.0])
def test_free_fall_is_exact(alpha):
    """An unsupported beam under gravity: y = y0 - g t^2 / 2, p_y = -m g t, for any alpha."""
    g, y0 = 9.81, 3.0
    case = static_case([beam(line=([0, y0], [1.5, y0]), degree=4, elements=4, radius=0.02)],
                       gravity=(0.0, -g))
    model, disc = build_model(case)
    steps, _ = _simulate(model, disc, 0.5, 0.02, alpha)
    mass = 1000.0 * np.pi * 0.02**2 * 1.5
    for t, u, diag in steps[1:]:
        for f in (0.0, 0.3, 1.0):
            p = _point(model, disc, u, "b", f)
            np.testing.assert_allclose(p, [1.5 * f, y0 - 0.5 * g * t**2], atol=1e-11)
        assert abs(diag["p_y"] + mass * g * t) < 1e-10 * mass * g
        assert abs(diag["E_strain"]) < 1e-20


def _cantilever(radius=0.01, elements=8, L=1.0, supports=("clamped",), gravity=(0.0, -9.81)):
    sup = [{"at": "start", "type": supports[0]}]
    if len(supports) > 1:
        sup.append({"at": "end", "type": supports[1]})
    case = static_case([beam(line=([0, 0], [L, 0]), degree=4, elements=elements,
                             continuity=3, radius=radius, E=2.0e11, density=7850.0,
                             supports=sup)], gravity=gravity)
    return build_model(case)


def test_energy_is_conserved_with_alpha_zero():
    """Cantilever released under gravity (tip deflection 1e-3 L: nearly linear); the
    trapezoidal rule conserves the quadratic energy, the rest is O((w/L)^2)."""
    model, disc = _cantilever(gravity=(0.0, -9.81))
    steps, _ = _simulate(model, disc, 0.2, 5e-4, 0.0)
    e_total = np.array([d["E_total"] for _, _, d in steps[1:]])
    e_kin = np.array([d["E_kin"] for _, _, d in steps[1:]])
    assert e_kin.max() > 1e-4  # it really vibrates
    assert np.abs(e_total).max() < 1e-6 * e_kin.max()


def _linear_modes(model):
    """Generalised eigenpairs of the linearised stiffness and the mass at rest (free dofs)."""
    n = model.n_dof
    _, K = jax.jit(potential_residual_tangent)(jnp.zeros(n), model, 1.0,
                                               initial_load_state(model))
    _, M = jax.jit(inertia_force_and_mass)(jnp.zeros(n), jnp.zeros(n), jnp.zeros(n), model)
    free = np.asarray(model.free) > 0.5
    K, M = np.asarray(K)[np.ix_(free, free)], np.asarray(M)[np.ix_(free, free)]
    w2, phi = scipy.linalg.eigh(K, M)
    return np.sqrt(w2), phi, M, free


def _sdof_hht(omega, dt, alpha, n_steps, q0=0.0, v0=1.0):
    """Independent scalar HHT (Hilber et al. 1977): q'' + omega^2 q = 0."""
    beta, gamma = 0.25 * (1 - alpha) ** 2, 0.5 - alpha
    k = omega**2
    q, v, a = q0, v0, -k * q0
    out = [q]
    for _ in range(n_steps):
        # a1 + (1+alpha) k q1 - alpha k q = 0, q1 = q + dt v + dt^2 ((1/2 - beta) a + beta a1)
        q_star = q + dt * v + dt**2 * (0.5 - beta) * a
        a1 = (alpha * k * q - (1 + alpha) * k * q_star) / (1 + (1 + alpha) * k * beta * dt**2)
        q1 = q_star + beta * dt**2 * a1
        v = v + dt * ((1 - gamma) * a + gamma * a1)
        q, a = q1, a1
        out.append(q)
    return np.array(out)


def _modal_response(alpha, dt, t_end, eps=1e-4):
    """Pinned-pinned beam started with velocity eps * phi_1: modal coordinate over time."""
    model, disc = _cantilever(supports=("pinned", "pinned"), gravity=(0.0, 0.0))
    omega, phi, M, free = _linear_modes(model)
    v0 = np.zeros(model.n_dof)
    v0[free] = eps * phi[:, 0]
    steps, _ = _simulate(model, disc, t_end, dt, alpha, v0=v0, rtol=1e-12)
    q = np.array([phi[:, 0] @ M @ u[free] for _, u, _ in steps]) / eps
    return omega[0], q, np.array([t for t, _, _ in steps])


@pytest.mark.parametrize(("alpha", "omega_dt"), [(0.0, 0.5), (-0.1, 0.5), (-0.3, 3.0)])
def test_beam_mode_follows_hht_recurrence(alpha, omega_dt):
    """A small-amplitude mode evolves exactly as the scalar HHT recurrence (amplitude decay
    and period error of the theory), including strong numerical damping at omega dt = 3."""
    model, _ = _cantilever(supports=("pinned", "pinned"), gravity=(0.0, 0.0))
    omega = _linear_modes(model)[0][0]
    dt = omega_dt / omega
    w, q, _ = _modal_response(alpha, dt, 40 * dt)
    ref = _sdof_hht(w, dt, alpha, len(q) - 1)
    np.testing.assert_allclose(q, ref, atol=1e-6 * np.abs(ref).max())


@pytest.mark.parametrize("alpha", [0.0, -0.1, -1.0 / 3.0])
def test_hht_spectral_radius_theory(alpha):
    """rho_inf = (1 + alpha)/(1 - alpha) (Hilber et al. 1977), and no amplification."""
    beta, gamma = 0.25 * (1 - alpha) ** 2, 0.5 - alpha

    def amplification(Omega):
        # columns: response of (q, dt v, dt^2 a) to unit initial values, via the recurrence
        A = np.zeros((3, 3))
        for j in range(3):
            x0 = np.eye(3)[j]
            q, v, a = x0[0], x0[1], x0[2]
            q_star = q + v + (0.5 - beta) * a
            a1 = (alpha * Omega**2 * q - (1 + alpha) * Omega**2 * q_star) / (
                1 + (1 + alpha) * Omega**2 * beta)
            q1 = q_star + beta * a1
            v1 = v + (1 - gamma) * a + gamma * a1
            A[:, j] = [q1, v1, a1]
        return A

    rho = [np.abs(np.linalg.eigvals(amplification(W))).max() for W in np.logspace(-2, 4, 200)]
    assert max(rho) <= 1.0 + 1e-12
    assert abs(rho[-1] - (1 + alpha) / (1 - alpha)) < 2e-3


@pytest.mark.parametrize("alpha", [0.0, -0.1])
def test_second_order_in_time(alpha):
    """Largest error of the modal response over one period against the exact sin(w t)/w
    (w the discrete first eigenfrequency): rate 2 in dt for every alpha."""
    model, _ = _cantilever(supports=("pinned", "pinned"), gravity=(0.0, 0.0))
    T = 2 * np.pi / _linear_modes(model)[0][0]
    errors = []
    for k in range(3):
        w, q, t = _modal_response(alpha, T / (40 * 2**k), T)
        errors.append(np.abs(q - np.sin(w * t) / w).max() * w)
    rate = np.log2(errors[0] / errors[1]), np.log2(errors[1] / errors[2])
    assert all(abs(r - 2.0) < 0.15 for r in rate), (errors, rate)


def _project(disc, name, func):
    """Control-point values of a scalar field given as a function of s/L (least squares)."""
    info = disc.beam(name)
    u = np.linspace(0, 1, 400)
    B = info.curve.basis_matrix(u)[0]
    s = np.array([info.curve.arc_length(x) for x in u]) / info.length
    coef, *_ = np.linalg.lstsq(B, func(s), rcond=None)
    return coef


def _period_from_zero_crossings(t, y):
    idx = np.where(np.sign(y[:-1]) * np.sign(y[1:]) < 0)[0]
    tc = t[idx] - y[idx] * (t[idx + 1] - t[idx]) / (y[idx + 1] - y[idx])
    return 2 * np.mean(np.diff(tc))


@pytest.mark.parametrize("mode", [1, 2])
def test_pinned_pinned_frequencies_with_rotary_inertia(mode):
    """Rayleigh beam: w^2 = (EI k^4 / rho A) / (1 + (I/A) k^2), k = n pi / L."""
    L, a, E, rho = 1.0, 0.04, 2.0e11, 7850.0
    model, disc = _cantilever(radius=a, elements=16, L=L, supports=("pinned", "pinned"),
                              gravity=(0.0, 0.0))
    k = mode * np.pi / L
    A, I = np.pi * a**2, np.pi * a**4 / 4  # noqa: E741 (I: second moment of area)
    w_eb = np.sqrt(E * I * k**4 / (rho * A))
    w_rayleigh = w_eb / np.sqrt(1 + I / A * k**2)
    T = 2 * np.pi / w_rayleigh
    coef = _project(disc, "b", lambda s: 1e-3 * np.sin(mode * np.pi * s))
    v0 = np.zeros((disc.n_cp, 2))
    v0[:, 1] = coef
    steps, _ = _simulate(model, disc, 3.2 * T, T / 400, 0.0, v0=v0.ravel())
    probe = 0.5 if mode == 1 else 0.25
    t = np.array([s[0] for s in steps])
    y = np.array([_point(model, disc, s[1], "b", probe)[1] for s in steps])
    w_num = 2 * np.pi / _period_from_zero_crossings(t, y)
    assert abs(w_num / w_rayleigh - 1) < 3e-4
    assert abs(w_num / w_eb - 1) > 0.4 * (1 - w_rayleigh / w_eb)  # rotary inertia matters


def test_clamped_free_first_frequency():
    """w_1 = (1.8751040687)^2 sqrt(EI / (rho A L^4)) for a slender cantilever."""
    L, a, E, rho = 1.0, 0.005, 2.0e11, 7850.0
    model, disc = _cantilever(radius=a, elements=12, L=L, gravity=(0.0, 0.0))
    beta_l = 1.8751040687
    w1 = beta_l**2 * np.sqrt(bending_stiffness(E, a) / (rho * np.pi * a**2 * L**4))
    sigma = (np.cosh(beta_l) + np.cos(beta_l)) / (np.sinh(beta_l) + np.sin(beta_l))

    def shape(s):
        x = beta_l * s
        return np.cosh(x) - np.cos(x) - sigma * (np.sinh(x) - np.sin(x))

    v0 = np.zeros((disc.n_cp, 2))
    v0[:, 1] = _project(disc, "b", lambda s: 1e-4 * shape(s))
    T = 2 * np.pi / w1
    steps, _ = _simulate(model, disc, 3.2 * T, T / 400, 0.0, v0=v0.ravel())
    t = np.array([s[0] for s in steps])
    y = np.array([_point(model, disc, s[1], "b", 1.0)[1] for s in steps])
    assert abs(2 * np.pi / _period_from_zero_crossings(t, y) / w1 - 1) < 3e-4


def test_stiff_pinned_beam_swings_like_rigid_pendulum():
    """Released from horizontal, pinned at one end: I_O phi'' = m g (L/2) cos(phi), with
    I_O = rho A L^3 / 3 + rho I L (the sections turn with the rod); solve_ivp reference."""
    L, a, E, rho, g = 1.0, 0.03, 1.0e13, 7850.0, 9.81
    case = static_case([beam(line=([0, 0], [L, 0]), degree=4, elements=4, radius=a, E=E,
                             density=rho, supports=[{"at": "start", "type": "pinned"}])],
                       gravity=(0.0, -g))
    model, disc = build_model(case)
    steps, _ = _simulate(model, disc, 0.8, 1e-3, 0.0)
    A, I = np.pi * a**2, np.pi * a**4 / 4  # noqa: E741 (I: second moment of area)
    m, I_O = rho * A * L, rho * A * L**3 / 3 + rho * I * L
    sol = solve_ivp(lambda _, y: [y[1], m * g * L / 2 * np.cos(y[0]) / I_O], (0, 0.8),
                    [0.0, 0.0], rtol=1e-12, atol=1e-12, dense_output=True)
    for t, u, _ in steps[::50]:
        phi = sol.sol(t)[0]
        tip = _point(model, disc, u, "b", 1.0)
        np.testing.assert_allclose(tip, [L * np.cos(phi), -L * np.sin(phi)], atol=1e-4 * L)


def test_per_beam_gravity_switch_and_initial_velocity():
    """Beam "a" falls; beam "b" has gravity off and drifts at its initial velocity."""
    from beamcontact.setup.model import uniform_velocities

    g, vel = 9.81, (0.4, -1.5)
    case = static_case([beam("a", line=([0, 0], [1, 0]), degree=3, elements=3),
                        {**beam("b", line=([0, 2], [1, 2]), degree=3, elements=3,
                                gravity=False), "initial_velocity": list(vel)}],
                       gravity=(0.0, -g))
    model, disc = build_model(case)
    v0 = uniform_velocities(disc, [b.initial_velocity for b in case.beams])
    steps, _ = _simulate(model, disc, 0.3, 0.05, -0.2, v0=v0)
    t, u, _ = steps[-1]
    np.testing.assert_allclose(_point(model, disc, u, "a", 0.5), [0.5, -0.5 * g * t**2],
                               atol=1e-12)
    np.testing.assert_allclose(_point(model, disc, u, "b", 0.5),
                               [0.5 + vel[0] * t, 2 + vel[1] * t], atol=1e-12)
