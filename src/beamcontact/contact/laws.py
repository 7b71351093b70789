"""Pair laws of the two contact models (paper Sec. 2), as energies of one point pair.

Both take the centre-line distance d of two contact integration points, the radii R1, R2
and a parameter vector ``params`` = (penalty, k, m, q_reg, cutoff); the gap is
q = d - R1 - R2 (eq. 2).

* IPIP penalty (eqs. 3-5): Pi = eps q^2 / 2 for q < 0, else 0.
* Coarse-grained section-section potential (eq. 9), per unit length of both axes:
      Phi(q) = k beta1 beta2 C(m, R1, R2) q^(7/2 - m),
      C = 2^(5/2 - m) pi^(3/2) sqrt(R1 R2 / (R1 + R2)) Gamma(m - 7/2) / Gamma(m/2)^2,
  for any m > 7/2 (steric repulsion m = 12). Below the regularisation gap q_reg (and for
  q <= 0) Phi is continued by its second-order Taylor polynomial at q_reg: the force grows
  linearly and Newton never meets the singularity at q = 0. Pairs with d > cutoff
  contribute nothing (the paper's cutoff on the centre-line distance).
"""

import jax.numpy as jnp
from jax.scipy.special import gammaln

PENALTY, K, EXPONENT, Q_REG, CUTOFF = range(5)


def cg_constant(m, R1, R2):
    """C(m, R1, R2) of eq. (9)."""
    log_c = ((2.5 - m) * jnp.log(2.0) + 1.5 * jnp.log(jnp.pi) + gammaln(m - 3.5)
             - 2.0 * gammaln(0.5 * m))
    return jnp.exp(log_c) * jnp.sqrt(R1 * R2 / (R1 + R2))


def cg_potential(q, amplitude, m, q_reg):
    """amplitude * q^(7/2-m) for q >= q_reg, its quadratic Taylor continuation below."""
    n = m - 3.5
    q_safe = jnp.where(q > q_reg, q, q_reg)  # no negative powers of small q, even unused
    # exp(-n log q) rather than q ** -n: the derivatives of exp and log reuse the primal
    # values, so phi, phi' and phi'' cost one exp and one log per pair (a power's
    # derivative is another power)
    exact = amplitude * jnp.exp(-n * jnp.log(q_safe))
    phi0 = amplitude * q_reg ** (-n)
    dq = q - q_reg
    taylor = phi0 * (1.0 - n * dq / q_reg + 0.5 * n * (n + 1.0) * (dq / q_reg) ** 2)
    return jnp.where(q > q_reg, exact, taylor)


def cg_amplitude(R1, R2, beta12, params):
    """k beta1 beta2 C(m, R1, R2): depends on the pair of beams only, so it is computed
    once per block, not per point pair."""
    return params[K] * beta12 * cg_constant(params[EXPONENT], R1, R2)


def cg_pair_energy(d, R12, amplitude, params):
    """Coarse-grained energy density of one pair of sections (eq. 9 integrand).

    Args:
        d: centre-line distance.
        R12: R1 + R2.
        amplitude: :func:`cg_amplitude`.
    """
    phi = cg_potential(d - R12, amplitude, params[EXPONENT], params[Q_REG])
    return jnp.where(d < params[CUTOFF], phi, 0.0)


def ipip_amplitude(R1, R2, beta12, params):
    """The penalty parameter (same for every pair), one per block."""
    del R2, beta12
    return jnp.full_like(R1, params[PENALTY])


def ipip_pair_energy(d, R12, amplitude, params):
    """Penalty energy eps q^2 / 2 of one closest point pair for q < 0 (eq. 3)."""
    del params
    return 0.5 * amplitude * jnp.minimum(d - R12, 0.0) ** 2


# law name -> (per-block amplitude, per-pair energy of the distance)
LAWS = {"cg": (cg_amplitude, cg_pair_energy), "ipip": (ipip_amplitude, ipip_pair_energy)}
