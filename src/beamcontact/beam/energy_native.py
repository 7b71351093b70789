"""Native (Numba) strain kernels of the beam, beside :mod:`beamcontact.beam.energy`.

The JAX energies there are the definition; these are their gradients and Hessians written
out by hand for the CPU engine, tested against JAX's automatic differentiation to a
relative 1e-12 (tests/test_native_beam.py).

At a Gauss point the energy per unit xi depends on the four numbers y = (g1, g1') only
through the metric g and the curvature K (eqs. 12-14), so its derivatives split by the
chain rule into those of the fibre density psi(g, K) (eqs. 23-26, 30) and those of
g(y), K(y):

    dpsi/dy   = psi_g dg + psi_K dK,
    d2psi/dy2 = psi_gg dg dg^T + psi_gK (dg dK^T + dK dg^T) + psi_KK dK dK^T
                + psi_g d2g + psi_K d2K.

An element adds wq_q times these through the basis rows y_q = (dR_q x_e, ddR_q x_e), the
same sums as ``_beam_residual_tangent`` of assembly/system.py; dofs are ordered as
x_e.ravel() (x, y of each control point in turn).

Arrays are float64; the kernels write into arrays the caller owns and allocate only a
few scratch numbers per call (one array of them per block for
:func:`block_strain_residual_tangent`).
"""

import numpy as np

from beamcontact._native import njit, njit_inline, njit_parallel, prange


@njit_inline
def fibre_density_derivatives(g, K, g_ref, K_ref, eta, w_eta, E):
    """psi and its first and second derivatives in (g, K) at one Gauss point (eqs. 23-26,
    30 as in :func:`~beamcontact.beam.energy.fibre_strain_energy_density`).

    With h = 1 - eta K (eq. 13), the fibre strain s = (h^2 g - gbar*) / (2 gbar*)
    (gbar* = g0*^2 g* the reference fibre metric, eq. 14) is linear in g and quadratic in
    K, and psi = sum_k (1/2) c_k s_k^2 with c_k = E w_k g0*_k sqrt(g*) (eq. 26 over
    dV = g0* sqrt(g*) dxi dA).

    Returns:
        (psi, psi_g, psi_K, psi_gg, psi_gK, psi_KK).
    """
    sqrt_g_ref = np.sqrt(g_ref)
    psi = psi_g = psi_K = psi_gg = psi_gK = psi_KK = 0.0
    for k in range(eta.shape[0]):
        e = eta[k]
        g0_ref = 1.0 - e * K_ref
        gbar_ref = g0_ref * g0_ref * g_ref
        inv = 1.0 / gbar_ref  # one division per fibre: they dominate the loop's cost
        h = 1.0 - e * K
        s = 0.5 * (h * h * g - gbar_ref) * inv
        s_g = 0.5 * h * h * inv
        s_K = -e * h * g * inv
        s_gK = -e * h * inv
        s_KK = e * e * g * inv
        c = E * w_eta[k] * g0_ref * sqrt_g_ref
        cs = c * s
        psi += 0.5 * cs * s
        psi_g += cs * s_g
        psi_K += cs * s_K
        psi_gg += c * s_g * s_g  # s_gg = 0
        psi_gK += c * s_g * s_K + cs * s_gK
        psi_KK += c * s_K * s_K + cs * s_KK
    return psi, psi_g, psi_K, psi_gg, psi_gK, psi_KK


@njit_inline
def _point_derivatives(y0, y1, y2, y3, g_ref, K_ref, eta, w_eta, E, grad_out, hess_out,
                       tangent=True):
    """Gradient and Hessian in y of the energy per unit xi at y = (y0, y1, y2, y3)
    = (g1x, g1y, g1'x, g1'y); returns the energy (``tangent`` False: hess_out is left
    alone, the energy and gradient are the same numbers).

    g = g1 . g1 (eq. 12) and K = c g^(-3/2), c = g1 x g1' (eq. 10-11): dg = 2 (g1, 0),
    d2g = 2 diag(1, 1, 0, 0); dc = (g1'y, -g1'x, -g1y, g1x), d2c = 1 at (0, 3), (3, 0)
    and -1 at (1, 2), (2, 1); dK = dc / g^(3/2) - (3/2) (K / g) dg and
    d2K = d2c / g^(3/2) - (3/2) (dc dg^T + dg dc^T) / g^(5/2) + (15/4) (K / g^2) dg dg^T
          - (3/2) (K / g) d2g.
    """
    g = y0 * y0 + y1 * y1
    g15 = g * np.sqrt(g)
    K = (y0 * y3 - y1 * y2) / g15
    psi, p_g, p_K, p_gg, p_gK, p_KK = fibre_density_derivatives(g, K, g_ref, K_ref, eta,
                                                                 w_eta, E)
    inv_g, inv_g15 = 1.0 / g, 1.0 / g15
    dg = (2.0 * y0, 2.0 * y1, 0.0, 0.0)
    dc = (y3, -y2, -y1, y0)
    kg = 1.5 * K * inv_g
    dK = (dc[0] * inv_g15 - kg * dg[0], dc[1] * inv_g15 - kg * dg[1],
          dc[2] * inv_g15, dc[3] * inv_g15)
    for i in range(4):
        grad_out[i] = p_g * dg[i] + p_K * dK[i]
    if not tangent:
        return psi
    c_dcdg = -1.5 * p_K * inv_g * inv_g15
    c_dgdg = p_gg + 3.75 * p_K * K * inv_g * inv_g
    for i in range(4):
        for j in range(i, 4):  # symmetric
            h = (c_dgdg * dg[i] * dg[j] + p_gK * (dg[i] * dK[j] + dK[i] * dg[j])
                 + p_KK * dK[i] * dK[j] + c_dcdg * (dc[i] * dg[j] + dg[i] * dc[j]))
            hess_out[i, j] = h
            hess_out[j, i] = h
    # the constant second derivatives: d2g (diagonal in g1) and d2c (g1 x g1' pairs)
    diag = 2.0 * p_g - 2.0 * p_K * kg
    hess_out[0, 0] += diag
    hess_out[1, 1] += diag
    cross = p_K * inv_g15
    hess_out[0, 3] += cross
    hess_out[3, 0] += cross
    hess_out[1, 2] -= cross
    hess_out[2, 1] -= cross
    return psi


@njit
def point_strain_derivatives(y, g_ref, K_ref, eta, w_eta, E, grad_out, hess_out):
    """Gradient (4,) and Hessian (4, 4) of
    :func:`~beamcontact.beam.energy.point_strain_energy` (eqs. 23-26, 30) with respect to
    y = (g1x, g1y, g1'x, g1'y), written into grad_out and hess_out; returns the energy."""
    return _point_derivatives(y[0], y[1], y[2], y[3], g_ref, K_ref, eta, w_eta, E,
                              grad_out, hess_out)


@njit
def _element(x_e, dR, ddR, wq, g_ref, K_ref, eta, w_eta, E, r_out, k_out, grad, hess,
             tangent=True):
    """:func:`element_strain_residual_tangent` with scratch grad (4,), hess (4, 4)."""
    r_out[:] = 0.0
    if tangent:
        k_out[:, :] = 0.0
    energy = 0.0
    for q in range(wq.shape[0]):
        y0, y1, y2, y3 = _axis_at(x_e, dR, ddR, q)
        w = wq[q]
        energy += w * _point_derivatives(y0, y1, y2, y3, g_ref[q], K_ref[q], eta, w_eta, E,
                                         grad, hess, tangent)
        _add_point(dR, ddR, q, w, grad, hess, r_out, k_out, tangent)
    if tangent:
        _mirror_blocks(k_out)
    return energy


@njit
def _mirror_blocks(k_out):
    """Copy the 2 x 2 blocks above the block diagonal to below it (the Hessian is
    symmetric, so :func:`_add_point` forms only the upper blocks)."""
    n = k_out.shape[0] // 2
    for k in range(n):
        for m in range(k + 1, n):
            for a in range(2):
                for b in range(2):
                    k_out[2 * m + b, 2 * k + a] = k_out[2 * k + a, 2 * m + b]


@njit_inline
def _add_point(dR, ddR, q, w, grad, hess, r_out, k_out, tangent=True):
    """r += w D^T grad and (``tangent``) k += w D^T hess D for the basis rows
    D = (dR_q, ddR_q) of Gauss point q: y = (dR_q x_e, ddR_q x_e), so dof (k, a) enters
    y_a with dR_qk and y_(2+a) with ddR_qk. Only the 2 x 2 blocks (k, m >= k) of k are
    formed."""
    n = dR.shape[1]
    for k in range(n):
        d, dd = dR[q, k], ddR[q, k]
        for a in range(2):
            r_out[2 * k + a] += w * (d * grad[a] + dd * grad[2 + a])
            if not tangent:
                continue
            # row of D^T hess for dof (k, a), then times D for every dof (m, b)
            h0 = w * (d * hess[a, 0] + dd * hess[2 + a, 0])
            h1 = w * (d * hess[a, 1] + dd * hess[2 + a, 1])
            h2 = w * (d * hess[a, 2] + dd * hess[2 + a, 2])
            h3 = w * (d * hess[a, 3] + dd * hess[2 + a, 3])
            for m in range(k, n):
                k_out[2 * k + a, 2 * m] += h0 * dR[q, m] + h2 * ddR[q, m]
                k_out[2 * k + a, 2 * m + 1] += h1 * dR[q, m] + h3 * ddR[q, m]


@njit_inline
def _axis_at(x_e, dR, ddR, q):
    """y = (g1, g1') = (dR_q x_e, ddR_q x_e) at Gauss point q (eq. 10). Rows are indexed,
    not sliced: a slice is a new array whose reference count costs more than the sums."""
    y0 = y1 = y2 = y3 = 0.0
    for k in range(x_e.shape[0]):
        y0 += dR[q, k] * x_e[k, 0]
        y1 += dR[q, k] * x_e[k, 1]
        y2 += ddR[q, k] * x_e[k, 0]
        y3 += ddR[q, k] * x_e[k, 1]
    return y0, y1, y2, y3


@njit
def element_strain_residual_tangent(x_e, dR, ddR, wq, g_ref, K_ref, eta, w_eta, E, r_out,
                                    k_out):
    """Internal force (2n,) and tangent (2n, 2n) of one element, the gradient and Hessian
    of :func:`~beamcontact.beam.energy.element_strain_energy` (eq. 30 with the Gauss
    points of the element), written into r_out and k_out; returns the strain energy.

    Arguments, in call order:
        x_e: control points (n, 2).
        dR, ddR: basis derivatives at the Gauss points (n_qp, n).
        wq, g_ref, K_ref: Gauss weights, reference metric and curvature (n_qp,).
        eta, w_eta: section points and weights (n_eta,).
        E: Young's modulus.
    """
    return _element(x_e, dR, ddR, wq, g_ref, K_ref, eta, w_eta, E, r_out, k_out,
                    np.empty(4), np.empty((4, 4)))


@njit
def element_strain_energy(x_e, dR, ddR, wq, g_ref, K_ref, eta, w_eta, E):
    """Strain energy of one element (eq. 30 summed over its Gauss points), as
    :func:`~beamcontact.beam.energy.element_strain_energy`."""
    energy = 0.0
    for q in range(wq.shape[0]):
        y0, y1, y2, y3 = _axis_at(x_e, dR, ddR, q)
        g = y0 * y0 + y1 * y1
        K = (y0 * y3 - y1 * y2) / (g * np.sqrt(g))
        energy += wq[q] * fibre_density_derivatives(g, K, g_ref[q], K_ref[q], eta, w_eta,
                                                    E)[0]
    return energy


@njit_inline
def element_scratch(n_el, n):
    """The scratch of :func:`element_strain_at` for n_el elements of n control points,
    one row per element (x_e, grad, hess): an allocation per element costs more than
    its sums."""
    return np.empty((n_el, n, 2)), np.empty((n_el, 4)), np.empty((n_el, 4, 4))


@njit_inline
def element_strain_at(e, x, conn, dR, ddR, wq, g_ref, K_ref, eta, w_eta, E, x_e, grad, hess,
                      r_e, k_e, tangent):
    """Element e of a block (fields as :func:`block_strain_residual_tangent`): its control
    points gathered from x into the scratch x_e, its force into r_e and (``tangent``) its
    block into k_e; returns its strain energy."""
    for k in range(conn.shape[1]):
        x_e[k, 0] = x[conn[e, k], 0]
        x_e[k, 1] = x[conn[e, k], 1]
    return _element(x_e, dR[e], ddR[e], wq[e], g_ref[e], K_ref[e], eta[e], w_eta[e], E[e],
                    r_e, k_e, grad, hess, tangent)


@njit_parallel
def block_strain_residual_tangent(x, conn, dR, ddR, wq, g_ref, K_ref, eta, w_eta, E, r_out,
                                  k_out, tangent=True):
    """:func:`element_strain_residual_tangent` of every element of an ElementBlock
    (fields as in assembly/model.py; x the control points of the whole model (n_cp, 2)),
    into r_out (n_el, 2n) and k_out (n_el, 2n, 2n); returns the total strain energy. The
    elements on the cores, each whole on one thread: no sum depends on the threads.
    ``tangent`` False: k_out is left alone; the residual and the energy are the same
    numbers, bit for bit (the tangent's arithmetic is apart from theirs)."""
    n_el, n = conn.shape
    energies = np.empty(n_el)
    x_all, grad_all, hess_all = element_scratch(n_el, n)
    for e in prange(n_el):
        energies[e] = element_strain_at(e, x, conn, dR, ddR, wq, g_ref, K_ref, eta, w_eta, E,
                                        x_all[e], grad_all[e], hess_all[e], r_out[e],
                                        k_out[e], tangent)
    energy = 0.0
    for e in range(n_el):  # in element order, whatever the threads
        energy += energies[e]
    return energy
