from __future__ import annotations

from beamcontact._jax import jnp

"""Potentials of point loads: a dead force and a moment at a parameter of the axis.

The moment M is work-conjugate to the rotation theta of the axis tangent at the load
point, so its potential is -M theta. A rotation-free beam has no rotation unknown; theta
is tracked incrementally from the last converged tangent t_n,
    theta = theta_n + atan2(t_n x t, t_n . t),
which is exact for any total rotation (several turns included) as long as one step
turns the tangent by less than pi. theta_n and t_n are array data (no recompilation).
"""



def tangent_rotation(t, theta_n, t_n):
    """Total rotation of the tangent t, continued from (theta_n, t_n)."""
    cross = t_n[0] * t[1] - t_n[1] * t[0]
    return theta_n + jnp.arctan2(cross, t_n @ t)


def point_load_potential(x_e, R, dR, force, moment, theta_n, t_n):
    """-F . r(xi_a) - M theta(xi_a) for one point load.

    Args:
        x_e: control points carrying the load point, shape (n_loc, 2).
        R: basis at the load point, shape (n_loc,).
        dR: first derivative of the basis at the load point, shape (n_loc,).
        force: dead force (2,).
        moment: scalar (counter-clockwise positive).
        theta_n: rotation at the last converged state.
        t_n: tangent at the last converged state.
    """
    r = R @ x_e
    t = dR @ x_e
    return -(force @ r) - moment * tangent_rotation(t, theta_n, t_n)
