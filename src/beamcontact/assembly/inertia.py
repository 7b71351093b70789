"""Assembly of the inertia forces and their Newmark-consistent tangent.

Within a time step the velocity and acceleration are affine functions of the unknown
displacement (Newmark, paper eqs. 33-35):
    a = c_a (u - u_n - dt v_n) - c_1 a_n,     v = v_n + dt ((1 - gamma) a_n + gamma a),
with c_a = 1/(beta dt^2), c_1 = (1 - 2 beta)/(2 beta). The local force
F_e(x_e, v_e(u_e), a_e(u_e)) is differentiated with ``jax.jacfwd`` per element, which
gives dF/dx + gamma/(beta dt) dF/dv + 1/(beta dt^2) dF/da in one go.
"""

import jax
import jax.numpy as jnp

from beamcontact.assembly.model import Model, element_dofs
from beamcontact.beam.inertia import (
    element_inertia_force,
    element_kinetic_energy,
    element_momentum,
)


def newmark_kinematics(u, u_n, v_n, a_n, coeffs):
    """Velocity and acceleration for displacement u (any shape); coeffs (c_a, dt, c_1, gamma)."""
    c_a, dt, c_1, gamma = coeffs[0], coeffs[1], coeffs[2], coeffs[3]
    a = c_a * (u - u_n - dt * v_n) - c_1 * a_n
    v = v_n + dt * ((1.0 - gamma) * a_n + gamma * a)
    return v, a


def inertia_residual_tangent(u, u_n, v_n, a_n, coeffs, model: Model):
    """Global inertia force at u (with Newmark v, a) and its tangent d/du."""
    n = model.n_dof
    r = jnp.zeros(n)
    K = jnp.zeros((n, n))
    x_ref = model.x_ref
    un2, vn2, an2 = u_n.reshape(-1, 2), v_n.reshape(-1, 2), a_n.reshape(-1, 2)
    for blk in model.beams:
        c = blk.conn

        def local(xe_flat, xr, une, vne, ane, R, dR, wq, g_ref, blk=blk):
            x_e = xe_flat.reshape(-1, 2)
            v_e, a_e = newmark_kinematics(x_e - xr, une, vne, ane, coeffs)
            return element_inertia_force(x_e, v_e, a_e, R, dR, wq, g_ref, blk.rho_area,
                                         blk.rho_inertia).ravel()

        x_e = (x_ref + u.reshape(-1, 2))[c].reshape(c.shape[0], -1)
        args = (x_e, x_ref[c], un2[c], vn2[c], an2[c], blk.R, blk.dR, blk.wq, blk.g_ref)
        r_e = jax.vmap(local)(*args)
        k_e = jax.vmap(jax.jacfwd(local))(*args)
        dofs = element_dofs(c)
        r = r.at[dofs].add(r_e)
        K = K.at[dofs[:, :, None], dofs[:, None, :]].add(k_e)
    return r, K


def inertia_force_and_mass(u, v, a, model: Model):
    """Inertia force at (u, v, a) and the mass matrix dF/da (rotational part included)."""
    n = model.n_dof
    r = jnp.zeros(n)
    M = jnp.zeros((n, n))
    x = model.x_ref + u.reshape(-1, 2)
    v2, a2 = v.reshape(-1, 2), a.reshape(-1, 2)
    for blk in model.beams:
        c = blk.conn

        def local(ae_flat, x_e, v_e, R, dR, wq, g_ref, blk=blk):
            return element_inertia_force(x_e, v_e, ae_flat.reshape(-1, 2), R, dR, wq, g_ref,
                                         blk.rho_area, blk.rho_inertia).ravel()

        args = (a2[c].reshape(c.shape[0], -1), x[c], v2[c], blk.R, blk.dR, blk.wq, blk.g_ref)
        dofs = element_dofs(c)
        r = r.at[dofs].add(jax.vmap(local)(*args))
        M = M.at[dofs[:, :, None], dofs[:, None, :]].add(jax.vmap(jax.jacfwd(local))(*args))
    return r, M


def kinetic_energy_and_momentum(u, v, model: Model):
    """Kinetic energy (translation + rotation of the sections) and linear momentum (2,)."""
    x = model.x_ref + u.reshape(-1, 2)
    v2 = v.reshape(-1, 2)
    e_kin = 0.0
    p = jnp.zeros(2)
    for blk in model.beams:
        c = blk.conn
        e_kin += jnp.sum(jax.vmap(element_kinetic_energy, (0, 0, 0, 0, 0, 0, None, None))(
            x[c], v2[c], blk.R, blk.dR, blk.wq, blk.g_ref, blk.rho_area, blk.rho_inertia))
        p += jnp.sum(jax.vmap(element_momentum, (0, 0, 0, 0, None))(
            v2[c], blk.R, blk.wq, blk.g_ref, blk.rho_area), axis=0)
    return e_kin, p
