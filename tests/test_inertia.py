"""Inertia (paper eqs. 27-29) against Lagrange's equations differentiated by AD."""

import jax
import jax.numpy as jnp
import numpy as np
from _builders import beam, static_case

from beamcontact.assembly.inertia import inertia_force_and_mass, kinetic_energy_and_momentum
from beamcontact.beam.inertia import element_inertia_force, element_kinetic_energy
from beamcontact.setup.model import build_model


def _element():
    arc = {"center": [0.0, 0.0], "radius": 1.0, "start_angle": 0.3, "end_angle": 1.9}
    case = static_case([beam(arc=arc, degree=4, elements=3, radius=0.05, density=900.0)])
    model, _ = build_model(case)
    blk = model.beams[0]
    e = 1
    x_e = model.x_ref[blk.conn[e]]
    rng = np.random.default_rng(4)
    x_e = x_e + 0.05 * rng.normal(size=x_e.shape)
    v_e = jnp.asarray(rng.normal(size=x_e.shape))
    a_e = jnp.asarray(rng.normal(size=x_e.shape))
    data = (blk.R[e], blk.dR[e], blk.wq[e], blk.g_ref[e], blk.rho_area[e], blk.rho_inertia[e])
    return x_e, v_e, a_e, data


def test_eq29_equals_lagrange_equations_of_kinetic_energy():
    """d/dt dT/dv - dT/dx along (x, v, a) equals the eq. (27)-(29) force, T from eq. (18)."""
    x, v, a, data = _element()

    def T(x, v):
        return element_kinetic_energy(x, v, *data)

    dT_dv = jax.grad(T, argnums=1)
    # d/dt of dT/dv(x(t), v(t)) with xdot = v, vdot = a
    ddt = jax.jvp(dT_dv, (x, v), (v, a))[1]
    lagrange = ddt - jax.grad(T, argnums=0)(x, v)
    force = element_inertia_force(x, v, a, *data)
    np.testing.assert_allclose(force, lagrange, rtol=1e-11, atol=1e-11 * np.abs(force).max())


def test_mass_kinetic_energy_and_momentum_of_rigid_motions():
    """Closed forms; 1e-10 because the arc length of a rational axis is integrated with p+1
    Gauss points (the speed is not a polynomial)."""
    arc = {"center": [0.0, 0.0], "radius": 2.0, "start_angle": 0.0, "end_angle": 1.5}
    case = static_case([beam(arc=arc, degree=3, elements=5, radius=0.05, density=900.0)])
    model, disc = build_model(case)
    n = model.n_dof
    _, M = jax.jit(inertia_force_and_mass)(jnp.zeros(n), jnp.zeros(n), jnp.zeros(n), model)
    M = np.asarray(M)
    np.testing.assert_allclose(M, M.T, atol=1e-12 * M.max())
    assert np.all(np.linalg.eigvalsh(M) > 0)
    # total mass: a uniform unit acceleration in x gives rho A L (rotation-free: no rotary part)
    ones_x = np.tile([1.0, 0.0], n // 2)
    mass = 900.0 * np.pi * 0.05**2 * 2.0 * 1.5
    np.testing.assert_allclose(ones_x @ M @ ones_x, mass, rtol=1e-10)
    # rigid rotation about the arc centre with unit angular velocity: T = 1/2 (I_z) with
    # I_z = rho A L R^2 + rho I L (sections turn with the body)
    x = np.asarray(model.x_ref)
    v = np.column_stack([-x[:, 1], x[:, 0]]).ravel()
    e_kin, p = kinetic_energy_and_momentum(jnp.zeros(n), jnp.asarray(v), model)
    I_z = mass * 2.0**2 + 900.0 * np.pi * 0.05**4 / 4 * 3.0
    np.testing.assert_allclose(float(e_kin), 0.5 * I_z, rtol=1e-10)
    # momentum of that rotation: m * omega x r_centroid
    R, half = 2.0, 0.75
    centroid = R * np.sin(half) / half * np.array([np.cos(half), np.sin(half)])
    np.testing.assert_allclose(np.asarray(p), mass * np.array([-centroid[1], centroid[0]]),
                               rtol=1e-10)


def test_time_step_inertia_residual_and_tangent():
    """The Gauss-point assembly used in the time step equals the element force of eq. (29)
    at the Newmark v, a (assembled independently), and its tangent equals central
    differences of that residual."""
    from beamcontact.assembly.inertia import inertia_residual_tangent, newmark_kinematics
    from beamcontact.assembly.model import element_dofs
    from beamcontact.dynamics.hht import hht_coefficients

    arc = {"center": [0.0, 0.0], "radius": 1.0, "start_angle": 0.3, "end_angle": 2.4}
    case = static_case([beam(arc=arc, degree=4, elements=4, radius=0.05, density=900.0)])
    model, _ = build_model(case)
    n = model.n_dof
    rng = np.random.default_rng(7)
    u_n, v_n, a_n = (jnp.asarray(s * rng.normal(size=n)) for s in (0.05, 1.0, 10.0))
    u = u_n + jnp.asarray(0.01 * rng.normal(size=n))
    coeffs = hht_coefficients(-0.2, 1e-2)
    r, K = jax.jit(inertia_residual_tangent)(u, u_n, v_n, a_n, coeffs, model)

    v, a = newmark_kinematics(u, u_n, v_n, a_n, coeffs)
    x = model.x_ref + u.reshape(-1, 2)
    blk = model.beams[0]
    ref = np.zeros(n)
    for e in range(blk.conn.shape[0]):
        c = blk.conn[e]
        f = element_inertia_force(x[c], v.reshape(-1, 2)[c], a.reshape(-1, 2)[c], blk.R[e],
                                  blk.dR[e], blk.wq[e], blk.g_ref[e], blk.rho_area[e],
                                  blk.rho_inertia[e])
        np.add.at(ref, np.asarray(element_dofs(c)), np.asarray(f).ravel())
    np.testing.assert_allclose(r, ref, rtol=1e-12, atol=1e-12 * np.abs(ref).max())

    res = jax.jit(lambda w: inertia_residual_tangent(w, u_n, v_n, a_n, coeffs, model)[0])
    h = 1e-7
    fd = np.column_stack([(res(u.at[i].add(h)) - res(u.at[i].add(-h))) / (2 * h)
                          for i in range(n)])
    np.testing.assert_allclose(K, fd, rtol=0, atol=1e-6 * np.abs(K).max())
