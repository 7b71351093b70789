"""Assembly of the inertia forces and their Newmark-consistent tangent.

Within a time step the velocity and acceleration are affine functions of the unknown
displacement (Newmark, paper eqs. 33-35):
    a = c_a (u - u_n - dt v_n) - c_1 a_n,     v = v_n + dt ((1 - gamma) a_n + gamma a),
with c_a = 1/(beta dt^2), c_1 = (1 - 2 beta)/(2 beta). The local force, a function of
x, v(u) and a(u), is differentiated with ``jax.jacfwd`` (per Gauss point in the time
step, per element for the mass matrix), which gives
dF/dx + gamma/(beta dt) dF/dv + 1/(beta dt^2) dF/da in one go.
"""

from __future__ import annotations

from beamcontact._jax import jax, jnp
from beamcontact.assembly.model import Model, element_dofs
from beamcontact.beam.inertia import (
    element_inertia_force,
    element_kinetic_energy,
    element_momentum,
    rotational_acceleration,
)
from beamcontact.solvers import linear


def newmark_kinematics(u, u_n, v_n, a_n, coeffs):
    """Velocity and acceleration for displacement u (any shape); coeffs (c_a, dt, c_1, gamma)."""
    c_a, dt, c_1, gamma = coeffs[0], coeffs[1], coeffs[2], coeffs[3]
    a = c_a * (u - u_n - dt * v_n) - c_1 * a_n
    v = v_n + dt * ((1.0 - gamma) * a_n + gamma * a)
    return v, a


def inertia_residual_tangent(u, u_n, v_n, a_n, coeffs, model: Model):
    """Global inertia force at u (with Newmark v, a) and its tangent d/du.

    Eq. (29) pairs the axis acceleration with R delta u and the rotational term with
    dR delta u, and Newmark is linear, so both are point functions of the axis
    displacement d = R_q u_e (translation) or its derivative d1 = dR_q u_e (rotation) at
    each Gauss point; ``jax.jacfwd`` gives their 2 x 2 Jacobians there, and the element
    tangent is sum_q R_q^T J_q R_q + dR_q^T J1_q dR_q.
    """
    n = model.n_dof
    r = jnp.zeros(n)
    K = linear.zeros(n, model.sparse)
    u2, un2, vn2, an2 = (w.reshape(-1, 2) for w in (u, u_n, v_n, a_n))
    for blk in model.beams:
        c = blk.conn
        ds = blk.wq * jnp.sqrt(blk.g_ref)  # reference arc length weights (E, Q)

        def at_points(B, w, c=c):  # (E, Q, 2): B_q applied to the element's w
            return jnp.einsum("eqk,ekd->eqd", B, w[c])

        def translation(d, d_n, v_n, a_n, rho_ds):
            return rho_ds * newmark_kinematics(d, d_n, v_n, a_n, coeffs)[1]

        def rotation(d1, g1_ref, d1_n, v1_n, a1_n, rho_ds):
            v1, a1 = newmark_kinematics(d1, d1_n, v1_n, a1_n, coeffs)
            return rho_ds * rotational_acceleration(g1_ref + d1, v1, a1)

        def both(f):
            return jax.vmap(jax.vmap(f)), jax.vmap(jax.vmap(jax.jacfwd(f)))

        t_args = (*(at_points(blk.R, w) for w in (u2, un2, vn2, an2)),
                  blk.rho_area[:, None] * ds)
        r_args = (at_points(blk.dR, u2), at_points(blk.dR, model.x_ref),
                  *(at_points(blk.dR, w) for w in (un2, vn2, an2)),
                  blk.rho_inertia[:, None] * ds)
        (t_f, t_j), (r_f, r_j) = both(translation), both(rotation)
        r_e = (jnp.einsum("eqk,eqa->eka", blk.R, t_f(*t_args))
               + jnp.einsum("eqk,eqa->eka", blk.dR, r_f(*r_args)))
        k_e = (jnp.einsum("eqk,eqab,eql->ekalb", blk.R, t_j(*t_args), blk.R)
               + jnp.einsum("eqk,eqab,eql->ekalb", blk.dR, r_j(*r_args), blk.dR))
        n_el, n_loc = c.shape
        dofs = element_dofs(c)
        r = r.at[dofs].add(r_e.reshape(n_el, 2 * n_loc))
        K = linear.scatter(K, dofs, k_e.reshape(n_el, 2 * n_loc, 2 * n_loc))
    return r, K


def inertia_force_and_mass(u, v, a, model: Model):
    """Inertia force at (u, v, a) and the mass matrix dF/da (rotational part included)."""
    n = model.n_dof
    r = jnp.zeros(n)
    M = linear.zeros(n, model.sparse)
    x = model.x_ref + u.reshape(-1, 2)
    v2, a2 = v.reshape(-1, 2), a.reshape(-1, 2)
    for blk in model.beams:
        c = blk.conn

        def local(ae_flat, x_e, v_e, R, dR, wq, g_ref, rho_area, rho_inertia):
            return element_inertia_force(x_e, v_e, ae_flat.reshape(-1, 2), R, dR, wq, g_ref,
                                         rho_area, rho_inertia).ravel()

        args = (a2[c].reshape(c.shape[0], -1), x[c], v2[c], blk.R, blk.dR, blk.wq, blk.g_ref,
                blk.rho_area, blk.rho_inertia)
        dofs = element_dofs(c)
        r = r.at[dofs].add(jax.vmap(local)(*args))
        M = linear.scatter(M, dofs, jax.vmap(jax.jacfwd(local))(*args))
    return r, M


def kinetic_energy_and_momentum(u, v, model: Model):
    """Kinetic energy (translation + rotation of the sections) and linear momentum (2,)."""
    x = model.x_ref + u.reshape(-1, 2)
    v2 = v.reshape(-1, 2)
    e_kin = 0.0
    p = jnp.zeros(2)
    for blk in model.beams:
        c = blk.conn
        e_kin += jnp.sum(jax.vmap(element_kinetic_energy)(
            x[c], v2[c], blk.R, blk.dR, blk.wq, blk.g_ref, blk.rho_area, blk.rho_inertia))
        p += jnp.sum(jax.vmap(element_momentum)(
            v2[c], blk.R, blk.wq, blk.g_ref, blk.rho_area), axis=0)
    return e_kin, p
