"""Coarse-grained section-section potential (paper Sec. 2.2, eq. 9) as a contact-law
object (:mod:`beamcontact.contact.laws`)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from beamcontact._jax import jax, jnp, pytree


def cg_constant(m, R1, R2):
    """C(m, R1, R2) of eq. (9)."""
    gammaln = jax.scipy.special.gammaln
    log_c = ((2.5 - m) * jnp.log(2.0) + 1.5 * jnp.log(jnp.pi) + gammaln(m - 3.5)
             - 2.0 * gammaln(0.5 * m))
    return jnp.exp(log_c) * jnp.sqrt(R1 * R2 / (R1 + R2))


def cg_wall_constant(m, R):
    """C_w(m, R) = (2 pi)^(3/2) sqrt(R) Gamma(m - 9/2) / Gamma(m - 1) of the
    section-to-half-space potential (:mod:`beamcontact.contact.obstacles`)."""
    gammaln = jax.scipy.special.gammaln
    log_c = 1.5 * jnp.log(2.0 * jnp.pi) + gammaln(m - 4.5) - gammaln(m - 1.0)
    return jnp.exp(log_c) * jnp.sqrt(R)


def taylor_below(f, q, q_reg):
    """f(q) for q > q_reg, continued by its second-order Taylor polynomial at q_reg below
    (f', f'' by AD): a pair energy singular at q = 0 becomes one whose force grows
    linearly through q = 0, so Newton never meets the singularity."""
    f0, f1 = jax.jvp(f, (q_reg,), (jnp.ones_like(q_reg),))
    f2 = jax.grad(jax.grad(f))(q_reg)
    dq = q - q_reg
    return jnp.where(q > q_reg, f(jnp.where(q > q_reg, q, q_reg)),
                     f0 + f1 * dq + 0.5 * f2 * dq * dq)


def cg_potential(q, amplitude, m, q_reg):
    """amplitude * q^(7/2-m) for q >= q_reg, its quadratic Taylor continuation below."""
    return power_repulsion(q, amplitude, m - 3.5, q_reg)


def power_repulsion(q, amplitude, n, q_reg):
    """amplitude * q^(-n) for q >= q_reg, its quadratic Taylor continuation below."""
    q_safe = jnp.where(q > q_reg, q, q_reg)  # no negative powers of small q, even unused
    # exp(-n log q) rather than q ** -n: the derivatives of exp and log reuse the primal
    # values, so phi, phi' and phi'' cost one exp and one log per pair (a power's
    # derivative is another power)
    exact = amplitude * jnp.exp(-n * jnp.log(q_safe))
    phi0 = amplitude * q_reg ** (-n)
    dq = q - q_reg
    taylor = phi0 * (1.0 - n * dq / q_reg + 0.5 * n * (n + 1.0) * (dq / q_reg) ** 2)
    return jnp.where(q > q_reg, exact, taylor)


@pytree
@dataclass(frozen=True)
class CoarseGrained:
    """Coarse-grained section-section potential (eq. 9), per unit length of both axes:

        Phi(q) = k beta1 beta2 C(m, R1, R2) q^(7/2 - m),
        C = 2^(5/2 - m) pi^(3/2) sqrt(R1 R2 / (R1 + R2)) Gamma(m - 7/2) / Gamma(m/2)^2,

    for any m > 7/2 (steric repulsion m = 12), integrated over all pairs of contact points
    (reference arc-length weights). Below the regularisation gap q_reg (and for q <= 0)
    Phi is continued by its second-order Taylor polynomial at q_reg: the force grows
    linearly and Newton never meets the singularity at q = 0. Pairs with centre-line
    distance d > cutoff contribute nothing (the paper's cutoff).

    Attributes:
        k: k_m of eq. (9).
        exponent: m.
        q_reg: regularisation gap [m].
        cutoff: centre-line distance beyond which a pair contributes nothing [m].
    """

    k: float
    exponent: float
    q_reg: float
    cutoff: float

    closest_pairs: ClassVar[bool] = False

    def amplitude(self, R1, R2, beta12):
        """k beta1 beta2 C(m, R1, R2): depends on the pair of beams only, so it is
        computed once per block, not per point pair."""
        return self.k * beta12 * cg_constant(self.exponent, R1, R2)

    def pair_energy(self, d, R12, amplitude):
        """Coarse-grained energy density of one pair of sections (eq. 9 integrand)."""
        phi = cg_potential(d - R12, amplitude, self.exponent, self.q_reg)
        return jnp.where(d < self.cutoff, phi, 0.0)

    def interaction_distance(self):
        return self.cutoff

    def search_reach(self, r_max: float):
        """Half the cutoff: boxes closer than the cutoff are candidates."""
        del r_max
        return 0.5 * self.cutoff

    def obstacle_amplitude(self, R, beta12):
        """k beta beta_o C_w(m, R) of the section-to-half-space potential
        (:mod:`beamcontact.contact.obstacles`)."""
        return self.k * beta12 * cg_wall_constant(self.exponent, R)

    def obstacle_energy(self, q, R, amplitude, w):
        """w Phi_w(q): the section-to-half-space potential q^(9/2 - m) of one point with
        arc-length weight w, regularised below q_reg like eq. (9); nothing beyond the gap
        cutoff - 2 R."""
        phi = power_repulsion(q, amplitude, self.exponent - 4.5, self.q_reg)
        return jnp.where(q < self.cutoff - 2.0 * R, w * phi, 0.0)

    def advance_slack(self):
        """q_reg: below it the force is continued linearly, so a pair can be pushed to
        q <= 0."""
        return self.q_reg
