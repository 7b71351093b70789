"""Native (Numba) inertia kernels of the beam, beside :mod:`beamcontact.beam.inertia`.

The JAX force there (eq. 29) is the definition; these kernels compute it and its
Jacobians by hand for the CPU engine, tested against ``jax.jacfwd`` to a relative 1e-12
(tests/test_native_beam.py).

The element force is
    f_k = rho A sum_q ds_q R_qk a(xi_q) + rho I sum_q ds_q dR_qk m_q,
    m = phi n,   phi = (a1 . n) / g - 2 (v1 . g1)(v1 . n) / g^2                  (eq. 29)
with ds = wq sqrt(g*) and n = (-g1y, g1x) / sqrt(g) the unit normal. m depends on the
axis tangent g1, its velocity v1 and acceleration a1 at the point; its 2 x 2 Jacobians
M_x, M_v, M_a give the element Jacobians sum_q ds dR_q^T M dR_q (the translational part is
the constant consistent mass). Dofs are ordered as x_e.ravel().

In a time step v and a are Newmark's affine functions of the displacement (eqs. 33-35,
:func:`~beamcontact.assembly.inertia.newmark_kinematics`), and the HHT Newton needs
d/du = M_x + gamma / (beta dt) M_v + 1 / (beta dt^2) M_a:
:func:`element_inertia_residual_tangent` forms it as
:func:`~beamcontact.assembly.inertia.inertia_residual_tangent` does for one element.
"""

import numpy as np

from beamcontact._native import njit, njit_inline


@njit_inline
def rotational_point(g1x, g1y, v1x, v1y, a1x, a1y, m_out, jac_out, jacobians=True):
    """m = phi n of eq. (29) at one point (as
    :func:`~beamcontact.beam.inertia.rotational_acceleration`) into m_out (2,), and
    (``jacobians``) its Jacobians with respect to g1, v1 and a1 into jac_out[0], [1], [2]
    (each 2 x 2, [i, j] = dm_i / d(.)_j).

    With dn/dg1 = J / sqrt(g) - n g1^T / g (J the quarter turn):
        d(a1 . n)/dg1 = J^T a1 / sqrt(g) - (a1 . n) g1 / g (likewise for v1),
        dphi/dg1 = d(a1 . n)/dg1 / g - 2 (a1 . n) g1 / g^2
                   - 2 [(v1 . n) v1 + (v1 . g1) d(v1 . n)/dg1] / g^2
                   + 8 (v1 . g1)(v1 . n) g1 / g^3,
        dphi/dv1 = -2 [(v1 . n) g1 + (v1 . g1) n] / g^2,   dphi/da1 = n / g,
    and dm/d. = n dphi/d.^T, plus phi dn/dg1 for g1.
    """
    g = g1x * g1x + g1y * g1y
    sg = np.sqrt(g)
    nx, ny = -g1y / sg, g1x / sg
    an = a1x * nx + a1y * ny
    vn = v1x * nx + v1y * ny
    vg = v1x * g1x + v1y * g1y
    g2 = g * g
    phi = an / g - 2.0 * vg * vn / g2
    m_out[0] = phi * nx
    m_out[1] = phi * ny
    if not jacobians:
        return
    # J^T w = (w_y, -w_x)
    dan_x, dan_y = a1y / sg - an * g1x / g, -a1x / sg - an * g1y / g
    dvn_x, dvn_y = v1y / sg - vn * g1x / g, -v1x / sg - vn * g1y / g
    c8 = 8.0 * vg * vn / (g2 * g)
    dphi_gx = dan_x / g - 2.0 * an * g1x / g2 - 2.0 * (vn * v1x + vg * dvn_x) / g2 + c8 * g1x
    dphi_gy = dan_y / g - 2.0 * an * g1y / g2 - 2.0 * (vn * v1y + vg * dvn_y) / g2 + c8 * g1y
    dphi_vx = -2.0 * (vn * g1x + vg * nx) / g2
    dphi_vy = -2.0 * (vn * g1y + vg * ny) / g2
    # dn/dg1 = J / sqrt(g) - n g1^T / g, J = [[0, -1], [1, 0]]
    dn_xx, dn_xy = -nx * g1x / g, -1.0 / sg - nx * g1y / g
    dn_yx, dn_yy = 1.0 / sg - ny * g1x / g, -ny * g1y / g
    jac_out[0, 0, 0] = nx * dphi_gx + phi * dn_xx
    jac_out[0, 0, 1] = nx * dphi_gy + phi * dn_xy
    jac_out[0, 1, 0] = ny * dphi_gx + phi * dn_yx
    jac_out[0, 1, 1] = ny * dphi_gy + phi * dn_yy
    jac_out[1, 0, 0] = nx * dphi_vx
    jac_out[1, 0, 1] = nx * dphi_vy
    jac_out[1, 1, 0] = ny * dphi_vx
    jac_out[1, 1, 1] = ny * dphi_vy
    jac_out[2, 0, 0] = nx * nx / g
    jac_out[2, 0, 1] = nx * ny / g
    jac_out[2, 1, 0] = ny * nx / g
    jac_out[2, 1, 1] = ny * ny / g


@njit_inline
def _row_dot(B, q, w_e):
    """B_q w_e for the basis row q of B (n_qp, n) and control-point values w_e (n, 2).
    Rows are indexed, not sliced: a slice is a new array whose reference count costs more
    than the sums."""
    sx = sy = 0.0
    for k in range(B.shape[1]):
        sx += B[q, k] * w_e[k, 0]
        sy += B[q, k] * w_e[k, 1]
    return sx, sy


@njit_inline
def _add_vector(B, q, fx, fy, r_out):
    """r += B_q^T f for the basis row q of B and a point vector f."""
    for k in range(B.shape[1]):
        r_out[2 * k] += B[q, k] * fx
        r_out[2 * k + 1] += B[q, k] * fy


@njit
def _add_matrix(B, q, J, k_out):
    """k += B_q^T J B_q (dofs (k, a), (m, b): B_qk J_ab B_qm) for the basis row q of B and
    a 2 x 2 J."""
    n = B.shape[1]
    for k in range(n):
        for a in range(2):
            j0 = B[q, k] * J[a, 0]
            j1 = B[q, k] * J[a, 1]
            for m in range(n):
                k_out[2 * k + a, 2 * m] += j0 * B[q, m]
                k_out[2 * k + a, 2 * m + 1] += j1 * B[q, m]


@njit
def _add_mass(B, q, mass, k_out):
    """k += mass B_q^T B_q on both directions (the translational mass, uncoupled in x, y)."""
    n = B.shape[1]
    for k in range(n):
        for m in range(n):
            c = mass * B[q, k] * B[q, m]
            k_out[2 * k, 2 * m] += c
            k_out[2 * k + 1, 2 * m + 1] += c


@njit_inline
def _add_mass_matrix(R, dR, q, mass, J, k_out):
    """k += mass R_q^T R_q on both directions, then dR_q^T J dR_q, in one pass over k:
    every entry receives the two terms in that order, the numbers of :func:`_add_mass`
    followed by :func:`_add_matrix`."""
    n = R.shape[1]
    for k in range(n):
        rk, d = mass * R[q, k], dR[q, k]
        j00, j01, j10, j11 = d * J[0, 0], d * J[0, 1], d * J[1, 0], d * J[1, 1]
        for m in range(n):
            c = rk * R[q, m]
            dm = dR[q, m]
            k_out[2 * k, 2 * m] = (k_out[2 * k, 2 * m] + c) + j00 * dm
            k_out[2 * k, 2 * m + 1] += j01 * dm
            k_out[2 * k + 1, 2 * m] += j10 * dm
            k_out[2 * k + 1, 2 * m + 1] = (k_out[2 * k + 1, 2 * m + 1] + c) + j11 * dm


@njit
def element_inertia_force(x_e, v_e, a_e, R, dR, wq, g_ref, rho_area, rho_inertia, f_out):
    """Generalised inertia force of one element (eq. 29) into f_out (2n,), as
    :func:`~beamcontact.beam.inertia.element_inertia_force` (raveled)."""
    f_out[:] = 0.0
    m = np.empty(2)
    jac = np.empty((3, 2, 2))
    for q in range(wq.shape[0]):
        ds = wq[q] * np.sqrt(g_ref[q])
        ax, ay = _row_dot(R, q, a_e)
        _add_vector(R, q, rho_area * ds * ax, rho_area * ds * ay, f_out)
        g1x, g1y = _row_dot(dR, q, x_e)
        v1x, v1y = _row_dot(dR, q, v_e)
        a1x, a1y = _row_dot(dR, q, a_e)
        rotational_point(g1x, g1y, v1x, v1y, a1x, a1y, m, jac)
        _add_vector(dR, q, rho_inertia * ds * m[0], rho_inertia * ds * m[1], f_out)


@njit
def element_inertia_jacobians(x_e, v_e, a_e, R, dR, wq, g_ref, rho_area, rho_inertia, f_out,
                              jx_out, jv_out, ja_out):
    """The element inertia force (eq. 29) into f_out (2n,) and its Jacobians with respect
    to x_e, v_e and a_e (each (2n, 2n), raveled dofs) into jx_out, jv_out, ja_out; ja is
    the mass matrix, translational and rotational."""
    f_out[:] = 0.0
    jx_out[:, :] = 0.0
    jv_out[:, :] = 0.0
    ja_out[:, :] = 0.0
    m = np.empty(2)
    jac = np.empty((3, 2, 2))
    for q in range(wq.shape[0]):
        ds = wq[q] * np.sqrt(g_ref[q])
        ax, ay = _row_dot(R, q, a_e)
        _add_vector(R, q, rho_area * ds * ax, rho_area * ds * ay, f_out)
        _add_mass(R, q, rho_area * ds, ja_out)
        g1x, g1y = _row_dot(dR, q, x_e)
        v1x, v1y = _row_dot(dR, q, v_e)
        a1x, a1y = _row_dot(dR, q, a_e)
        rotational_point(g1x, g1y, v1x, v1y, a1x, a1y, m, jac)
        rho_ds = rho_inertia * ds
        _add_vector(dR, q, rho_ds * m[0], rho_ds * m[1], f_out)
        for i in range(3):
            for a in range(2):
                for b in range(2):
                    jac[i, a, b] *= rho_ds
        _add_matrix(dR, q, jac[0], jx_out)
        _add_matrix(dR, q, jac[1], jv_out)
        _add_matrix(dR, q, jac[2], ja_out)


@njit_inline
def _newmark(d, d_n, v_n, a_n, coeffs):
    """Newmark v, a of one component (eqs. 33-35), as
    :func:`~beamcontact.assembly.inertia.newmark_kinematics`."""
    c_a, dt, c_1, gamma = coeffs[0], coeffs[1], coeffs[2], coeffs[3]
    a = c_a * (d - d_n - dt * v_n) - c_1 * a_n
    v = v_n + dt * ((1.0 - gamma) * a_n + gamma * a)
    return v, a


@njit
def element_inertia_residual_tangent(u_e, un_e, vn_e, an_e, xref_e, coeffs, R, dR, wq, g_ref,
                                     rho_area, rho_inertia, r_out, k_out, tangent=True):
    """One element's part of the HHT inertia residual and its tangent d/du (eqs. 29,
    33-36) into r_out (2n,) and k_out (2n, 2n), as
    :func:`~beamcontact.assembly.inertia.inertia_residual_tangent` forms them.

    Arguments, in call order:
        u_e, un_e, vn_e, an_e: displacement now and u, v, a of the last step (n, 2).
        xref_e: reference control points (n, 2); x = xref + u.
        coeffs: (c_a, dt, c_1, gamma) of the Newmark kinematics.
        R, dR: basis and its derivative at the Gauss points (n_qp, n).
        wq, g_ref: Gauss weights and reference metric (n_qp,).
        rho_area, rho_inertia: rho A and rho I.
        tangent: False: k_out is left alone (the residual is the same numbers).

    Newmark acts at the Gauss points on d = R_q u_e (translation) and d1 = dR_q u_e
    (rotation, with g1 = dR_q xref + d1) as in the JAX assembly; the point Jacobian of
    the rotational term is M_x + dt gamma c_a M_v + c_a M_a (dv/du = dt gamma c_a,
    da/du = c_a).
    """
    return _element_inertia(u_e, un_e, vn_e, an_e, xref_e, coeffs, R, dR, wq, g_ref,
                            rho_area, rho_inertia, r_out, k_out, np.empty(2),
                            np.empty((3, 2, 2)), np.empty((2, 2)), tangent)


@njit
def _element_inertia(u_e, un_e, vn_e, an_e, xref_e, coeffs, R, dR, wq, g_ref, rho_area,
                     rho_inertia, r_out, k_out, m, jac, J, tangent=True):
    """:func:`element_inertia_residual_tangent` with scratch m (2,), jac (3, 2, 2) and
    J (2, 2)."""
    c_a, dt, gamma = coeffs[0], coeffs[1], coeffs[3]
    r_out[:] = 0.0
    if tangent:
        k_out[:, :] = 0.0
    for q in range(wq.shape[0]):
        ds = wq[q] * np.sqrt(g_ref[q])
        rho_ds = rho_area * ds
        ax, ay, g1x, g1y, v1x, v1y, a1x, a1y = _point_kinematics(R, dR, q, u_e, un_e, vn_e,
                                                                 an_e, xref_e, coeffs)
        _add_vector(R, q, rho_ds * ax, rho_ds * ay, r_out)
        mass = rho_ds * c_a
        rotational_point(g1x, g1y, v1x, v1y, a1x, a1y, m, jac, tangent)
        rho_ds = rho_inertia * ds
        _add_vector(dR, q, rho_ds * m[0], rho_ds * m[1], r_out)
        if not tangent:
            continue
        for a in range(2):
            for b in range(2):
                J[a, b] = rho_ds * (jac[0, a, b] + dt * gamma * c_a * jac[1, a, b]
                                    + c_a * jac[2, a, b])
        _add_mass_matrix(R, dR, q, mass, J, k_out)


@njit_inline
def _point_kinematics(R, dR, q, u_e, un_e, vn_e, an_e, xref_e, coeffs):
    """At Gauss point q: Newmark's acceleration (ax, ay) of the axis point d = R_q u, and
    the axis tangent g1 = dR_q xref + d1 with d1 = dR_q u, its velocity v1 and
    acceleration a1 from Newmark on d1 (:func:`_newmark`). Returns (ax, ay, g1x, g1y,
    v1x, v1y, a1x, a1y).

    The 18 sums over the control points are made in one pass (each in the order of k, so
    each is the number it would be alone): separate passes, one per pair of sums, took
    2.5 times as long."""
    d_x = d_y = dn_x = dn_y = vn_x = vn_y = an_x = an_y = 0.0  # R_q (u, u_n, v_n, a_n)
    e_x = e_y = en_x = en_y = wn_x = wn_y = bn_x = bn_y = 0.0  # dR_q (u, u_n, v_n, a_n)
    g_x = g_y = 0.0  # dR_q xref
    for k in range(R.shape[1]):
        b, c = R[q, k], dR[q, k]
        d_x += b * u_e[k, 0]
        d_y += b * u_e[k, 1]
        dn_x += b * un_e[k, 0]
        dn_y += b * un_e[k, 1]
        vn_x += b * vn_e[k, 0]
        vn_y += b * vn_e[k, 1]
        an_x += b * an_e[k, 0]
        an_y += b * an_e[k, 1]
        e_x += c * u_e[k, 0]
        e_y += c * u_e[k, 1]
        en_x += c * un_e[k, 0]
        en_y += c * un_e[k, 1]
        wn_x += c * vn_e[k, 0]
        wn_y += c * vn_e[k, 1]
        bn_x += c * an_e[k, 0]
        bn_y += c * an_e[k, 1]
        g_x += c * xref_e[k, 0]
        g_y += c * xref_e[k, 1]
    ax = _newmark(d_x, dn_x, vn_x, an_x, coeffs)[1]
    ay = _newmark(d_y, dn_y, vn_y, an_y, coeffs)[1]
    v1x, a1x = _newmark(e_x, en_x, wn_x, bn_x, coeffs)
    v1y, a1y = _newmark(e_y, en_y, wn_y, bn_y, coeffs)
    return ax, ay, g_x + e_x, g_y + e_y, v1x, v1y, a1x, a1y


@njit_inline
def element_kinetic_energy(x_e, v_e, R, dR, wq, g_ref, rho_area, rho_inertia):
    """T = 1/2 sum_q ds_q (rho A |v|^2 + rho I omega^2), omega = (n . v1) / sqrt(g)
    (eq. 18), as :func:`~beamcontact.beam.inertia.element_kinetic_energy`."""
    T = 0.0
    for q in range(wq.shape[0]):
        ds = wq[q] * np.sqrt(g_ref[q])
        vx, vy = _row_dot(R, q, v_e)
        g1x, g1y = _row_dot(dR, q, x_e)
        v1x, v1y = _row_dot(dR, q, v_e)
        g = g1x * g1x + g1y * g1y
        sg = np.sqrt(g)
        vn = (-v1x * g1y + v1y * g1x) / sg
        T += ds * (rho_area * (vx * vx + vy * vy) + rho_inertia * vn * vn / g)
    return 0.5 * T


@njit_inline
def element_momentum(v_e, R, wq, g_ref, rho_area, p_out):
    """Linear momentum rho A sum_q ds_q v(xi_q) of one element into p_out (2,), as
    :func:`~beamcontact.beam.inertia.element_momentum`."""
    p_out[0] = p_out[1] = 0.0
    for q in range(wq.shape[0]):
        ds = wq[q] * np.sqrt(g_ref[q])
        vx, vy = _row_dot(R, q, v_e)
        p_out[0] += rho_area * ds * vx
        p_out[1] += rho_area * ds * vy
