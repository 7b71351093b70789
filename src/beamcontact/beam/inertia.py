from __future__ import annotations

from beamcontact._jax import jnp

"""Inertia of the planar Bernoulli-Euler beam (paper eqs. 15-22, 27-29).

The virtual work of the inertia forces, eq. (27)-(28), over the reference volume
dV ~ dA ds (the paper's approximation, which drops the g0 = 1 - eta K factor so that the
translational and rotational parts decouple, int eta dA = 0):

    delta Pi_kin = int [ rho A a . delta u + rho I P ] ds,
    P = -(2/g^2)(v1 . g1)(v1 . n)(delta u1 . n) + (1/g)(a1 . n)(delta u1 . n)     (eq. 29)

with v1 = dv/dxi, a1 = da/dxi, n the unit normal g2, all in the current configuration.
P = theta_ddot * delta theta, where theta is the rotation of the cross section:
delta theta = (n . delta u1)/sqrt(g) and theta_ddot = (n . a1)/sqrt(g)
- 2 (v1 . g1)(v1 . n)/g^(3/2) (tests/test_inertia.py checks this against Lagrange's
equations for T = 1/2 int rho I theta_dot^2 ds, differentiated by AD).

The translational part is a constant consistent mass matrix; the rotational part depends
on x, v and a. Inertia has no potential, so its tangent is the AD Jacobian of this local
force (``jax.jacfwd``), not a Hessian.
"""



def _normal(g1):
    g = jnp.sum(g1 * g1, axis=-1)
    n = jnp.stack([-g1[..., 1], g1[..., 0]], axis=-1) / jnp.sqrt(g)[..., None]
    return g, n


def rotational_acceleration(g1, v1, a1):
    """theta_ddot / sqrt(g) times the unit normal n at a point of the axis, from the
    tangent g1 = dr/dxi and its velocity v1 and acceleration a1 (last axis of length 2).

    rho I ds times this, paired with delta u1, is the rotational part of eq. (29).
    """
    g, n = _normal(g1)
    theta_ddot_over_sqrt_g = (jnp.sum(a1 * n, -1) / g
                              - 2.0 * jnp.sum(v1 * g1, -1) * jnp.sum(v1 * n, -1) / g**2)
    return theta_ddot_over_sqrt_g[..., None] * n


def element_inertia_force(x_e, v_e, a_e, R, dR, wq, g_ref, rho_area, rho_inertia):
    """Generalised inertia force of one element, shape (n_loc, 2).

    Args:
        x_e: positions of the control points (n_loc, 2).
        v_e: velocities of the control points (n_loc, 2).
        a_e: accelerations of the control points (n_loc, 2).
        R: basis at the Gauss points, (n_qp, n_loc).
        dR: first derivative of the basis at the Gauss points, (n_qp, n_loc).
        wq: Gauss weights times d xi / d xi_hat.
        g_ref: reference metric (n_qp,).
        rho_area: rho A.
        rho_inertia: rho I.
    """
    ds = wq * jnp.sqrt(g_ref)  # reference arc length weights
    trans = rho_area * jnp.einsum("q,qk,qd->kd", ds, R, R @ a_e)
    rot = rho_inertia * jnp.einsum("q,qk,qd->kd", ds, dR,
                                   rotational_acceleration(dR @ x_e, dR @ v_e, dR @ a_e))
    return trans + rot


def element_kinetic_energy(x_e, v_e, R, dR, wq, g_ref, rho_area, rho_inertia):
    """T = 1/2 int (rho A |v|^2 + rho I omega^2) ds with omega = (n . v1)/sqrt(g) (eq. 18)."""
    ds = wq * jnp.sqrt(g_ref)
    v = R @ v_e
    g1, v1 = dR @ x_e, dR @ v_e
    g, n = _normal(g1)
    omega2 = jnp.sum(v1 * n, -1) ** 2 / g
    return 0.5 * jnp.sum(ds * (rho_area * jnp.sum(v * v, -1) + rho_inertia * omega2))


def element_momentum(v_e, R, wq, g_ref, rho_area):
    """Linear momentum int rho A v ds of one element, shape (2,)."""
    return rho_area * jnp.einsum("q,qd->d", wq * jnp.sqrt(g_ref), R @ v_e)
