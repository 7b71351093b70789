from __future__ import annotations

from beamcontact._jax import jnp

"""Local energies of the planar rotation-free Bernoulli-Euler beam (paper Sec. 3).

Pure JAX functions of one element's control points; forces and tangents come from
``jax.grad`` / ``jax.hessian`` of these (docs/architecture.md, "Energies and assembly").

Conventions (paper eqs. 10-14): g1 = dr/dxi, g = g1.g1, g2 = the unit normal obtained by
turning the unit tangent counter-clockwise, K = (x' y'' - y' x'') / g^(3/2) the signed
curvature (positive when the axis turns counter-clockwise). The fibre at eta along g2 has
tangent g0 g1 with g0 = 1 - eta K (eq. 13), so its metric is g_bar = g0^2 g (eq. 14).

Strain (eqs. 23-24): the Green-Lagrange strain of the equidistant fibre,
    eps_bar = (g_bar* - g_bar) / 2 = eps11 - eta kappa + eta^2 (K*^2 g* - K^2 g) / 2,
with eps11 = (g* - g)/2 and kappa = K* g* - K g (eq. 25). The coefficient of eta is
-kappa here and +kappa in eq. (23) as printed: eq. (23) measures eta (or K) with the
opposite sign. Its eta^2 term, written with chi = K* - K, is algebraically different
from the exact expression above; we use the exact fibre strain, which is zero for every
rigid motion and gives the exact circle under an end moment (tests/test_beam_energy.py,
tests/test_statics.py).

Stress (eq. 26): S^11 = E (g_bar^11)^2 eps_bar, g_bar^11 = 1 / g_bar (reference), so the
energy density is (1/2) E (eps_bar / g_bar)^2 per reference volume
dV = g0 sqrt(g) d xi dA.
"""



def axis_metric(x_e, dR, ddR):
    """Metric g = g11 (eq. 12) and signed curvature K at the Gauss points of one element.

    Args:
        x_e: control points of the element, shape (p+1, 2).
        dR: first derivatives of the basis at the Gauss points, shape (n_qp, p+1).
        ddR: second derivatives of the basis at the Gauss points, shape (n_qp, p+1).
    """
    return metric_and_curvature(dR @ x_e, ddR @ x_e)


def metric_and_curvature(g1, g1d):
    """g = g1 . g1 and K = (g1 x g1') / g^(3/2) from the axis tangent g1 = dr/dxi and its
    derivative g1' (last axis of length 2)."""
    g = jnp.sum(g1 * g1, axis=-1)
    K = (g1[..., 0] * g1d[..., 1] - g1[..., 1] * g1d[..., 0]) / g**1.5
    return g, K


def fibre_strain_energy_density(g, K, g_ref, K_ref, eta, w_eta, E):
    """Strain energy per unit parameter xi at each Gauss point (eqs. 23-26, 30).

    Args:
        g: current metric, shape (n_qp,).
        K: current curvature, shape (n_qp,).
        g_ref: reference metric, shape (n_qp,).
        K_ref: reference curvature, shape (n_qp,).
        eta: section quadrature points (fibre coordinates), shape (n_eta,).
        w_eta: section quadrature weights, shape (n_eta,).
        E: Young's modulus.
    """
    g0_ref = 1.0 - eta[None, :] * K_ref[:, None]
    gbar_ref = g0_ref**2 * g_ref[:, None]
    gbar = (1.0 - eta[None, :] * K[:, None]) ** 2 * g[:, None]
    strain = 0.5 * (gbar - gbar_ref) / gbar_ref  # physical Green-Lagrange strain
    density = 0.5 * E * strain**2 * g0_ref * jnp.sqrt(g_ref)[:, None]
    return density @ w_eta


def point_strain_energy(y, g_ref, K_ref, eta, w_eta, E):
    """Strain energy per unit xi at one Gauss point as a function of the four numbers
    y = (g1, g1') of the axis there (eqs. 23-26, 30).

    The element energy is sum_q wq_q of this with y_q = (dR_q x_e, ddR_q x_e), linear in
    the control points: its gradient and Hessian follow from the 4-vector derivatives by
    the basis rows (assembly/system.py), far cheaper than AD over a whole element.
    """
    g, K = metric_and_curvature(y[None, :2], y[None, 2:])
    return fibre_strain_energy_density(g, K, g_ref[None], K_ref[None], eta, w_eta, E)[0]


def element_strain_energy(x_e, dR, ddR, wq, g_ref, K_ref, eta, w_eta, E):
    """Strain energy of one element (eq. 30 integrated with p+1 Gauss points)."""
    g, K = axis_metric(x_e, dR, ddR)
    return jnp.sum(wq * fibre_strain_energy_density(g, K, g_ref, K_ref, eta, w_eta, E))


def element_gravity_potential(x_e, R, wq, g_ref, rho_area, gravity):
    """Potential of gravity on one element: -int rho A (g . r) ds (reference arc length)."""
    r = R @ x_e
    return -rho_area * jnp.sum(wq * jnp.sqrt(g_ref) * (r @ gravity))
