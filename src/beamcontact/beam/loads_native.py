"""Native (Numba) kernels of the point loads, beside :mod:`beamcontact.beam.loads`.

The JAX potential there is the definition; these kernels give its value, gradient and
Hessian in the load's control points by hand for the CPU engine, tested against
``jax.grad`` / ``jax.hessian`` to a relative 1e-12 (tests/test_native_model.py).

For one load at parameter xi_a, with r = R x_e and t = dR x_e (R, dR the basis and its
derivative there, rows of n_loc), the potential is

    Pi = -F . r - M theta(t),   theta = theta_n + phi,   phi = atan2(t_n x t, t_n . t),

the moment being work-conjugate to the rotation of the axis tangent, continued from the
last converged (theta_n, t_n). Derivatives of phi in t, by hand: with c = t_n x t and
d = t_n . t, dc/dt = J t_n (J the quarter turn, J w = (-w_y, w_x)), dd/dt = t_n and
d atan2(c, d) = (d dc - c dd) / (c^2 + d^2), so

    dphi/dt = (d J t_n - c t_n) / (c^2 + d^2) = J t / |t|^2,

since t = (d t_n + c J t_n) / |t_n|^2 and c^2 + d^2 = |t_n|^2 |t|^2: t_n drops out (phi
is the angle of t less a constant). With s = |t|^2 = t_x^2 + t_y^2,

    dphi/dt = (-t_y, t_x) / s,
    d2phi/dt2 = [[2 t_x t_y, t_y^2 - t_x^2], [t_y^2 - t_x^2, -2 t_x t_y]] / s^2.

The force is dead (Pi linear in r), so the gradient in dof (k, a) (order x_e.ravel()) is
-F_a R_k - M dR_k dphi/dt_a and the Hessian -M dR_k d2phi/dt_a dt_b dR_m. Padding
columns of a load (R = dR = 0, assembly/model.py PointLoads) give exact zeros.
"""

import numpy as np

from beamcontact._native import njit


@njit
def tangent_rotation(tx, ty, theta_n, tnx, tny):
    """theta_n + atan2(t_n x t, t_n . t): the total rotation of the tangent t continued
    from (theta_n, t_n), as :func:`~beamcontact.beam.loads.tangent_rotation`."""
    return theta_n + np.arctan2(tnx * ty - tny * tx, tnx * tx + tny * ty)


@njit
def _tangent(x_e, dR):
    """t = dR x_e at the load point."""
    tx = ty = 0.0
    for k in range(dR.shape[0]):
        tx += dR[k] * x_e[k, 0]
        ty += dR[k] * x_e[k, 1]
    return tx, ty


@njit
def point_load_potential(x_e, R, dR, force, moment, theta_n, t_n):
    """-F . r(xi_a) - M theta(xi_a) of one point load, as
    :func:`~beamcontact.beam.loads.point_load_potential` (same arguments: x_e (n_loc, 2),
    R, dR (n_loc,), force (2,), t_n (2,))."""
    rx = ry = 0.0
    for k in range(R.shape[0]):
        rx += R[k] * x_e[k, 0]
        ry += R[k] * x_e[k, 1]
    tx, ty = _tangent(x_e, dR)
    theta = tangent_rotation(tx, ty, theta_n, t_n[0], t_n[1])
    return -(force[0] * rx + force[1] * ry) - moment * theta


@njit
def point_load_residual_tangent(x_e, R, dR, force, moment, theta_n, t_n, scale, r_out,
                                k_out):
    """scale times the gradient (2 n_loc,) and Hessian (2 n_loc, 2 n_loc) of
    :func:`point_load_potential` in x_e.ravel(), written into r_out and k_out; returns
    scale times the potential. scale is the load factor lam of the assembly (1: the
    derivatives of ``point_load_potential`` itself). Formulas in the module docstring."""
    n = R.shape[0]
    rx = ry = 0.0
    for k in range(n):
        rx += R[k] * x_e[k, 0]
        ry += R[k] * x_e[k, 1]
    tx, ty = _tangent(x_e, dR)
    s = tx * tx + ty * ty
    inv_s = 1.0 / s
    mom = scale * moment
    # -M dphi/dt and -M d2phi/dt2, scaled
    gx, gy = mom * ty * inv_s, -mom * tx * inv_s
    h_xy = -mom * (ty * ty - tx * tx) * inv_s * inv_s
    h_xx = -mom * 2.0 * tx * ty * inv_s * inv_s
    fx, fy = scale * force[0], scale * force[1]
    for k in range(n):
        r_out[2 * k] = -fx * R[k] + gx * dR[k]
        r_out[2 * k + 1] = -fy * R[k] + gy * dR[k]
        for m in range(n):
            d = dR[k] * dR[m]
            k_out[2 * k, 2 * m] = h_xx * d
            k_out[2 * k, 2 * m + 1] = h_xy * d
            k_out[2 * k + 1, 2 * m] = h_xy * d
            k_out[2 * k + 1, 2 * m + 1] = -h_xx * d
    theta = tangent_rotation(tx, ty, theta_n, t_n[0], t_n[1])
    return scale * (-(force[0] * rx + force[1] * ry) - moment * theta)


@njit
def update_load_state(x, conn, dR, theta_n, t_n, theta_out, t_out):
    """Rotation and tangent of every load point at the converged control points x
    (n_cp, 2), as :func:`~beamcontact.assembly.system.update_load_state`: t = dR x_e and
    theta = theta_n + atan2(t_n x t, t_n . t), into theta_out (n_load,) and t_out
    (n_load, 2). conn, dR (n_load, n_loc) as in PointLoads. The outputs may be the inputs
    (each load reads its own old state before writing it)."""
    for i in range(conn.shape[0]):
        tx = ty = 0.0
        for k in range(conn.shape[1]):
            tx += dR[i, k] * x[conn[i, k], 0]
            ty += dR[i, k] * x[conn[i, k], 1]
        theta_out[i] = tangent_rotation(tx, ty, theta_n[i], t_n[i, 0], t_n[i, 1])
        t_out[i, 0] = tx
        t_out[i, 1] = ty
