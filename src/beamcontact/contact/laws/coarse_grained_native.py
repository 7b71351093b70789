"""Native (Numba) kernels of the coarse-grained law (paper Sec. 2.2, eq. 9).

The JAX law :class:`beamcontact.contact.laws.coarse_grained.CoarseGrained` stays the one
definition of the physics; these kernels are its closed-form derivatives, tested against
JAX AD of ``pair_energy`` / ``obstacle_energy`` (tests/test_native_contact.py). Every
kernel takes plain floats (no law object): cached Numba code cannot close over Python
objects.

With the gap q = d - R12 and n = m - 7/2 (pairs) or n = m - 9/2 (obstacles):

    P(q) = a q^(-n)                                          q > q_reg
    P(q) = P0 (1 - n t + n (n + 1) t^2 / 2), t = (q - q_reg) / q_reg     q <= q_reg

with P0 = a q_reg^(-n) (its quadratic Taylor polynomial at q_reg), and nothing at or
beyond the cutoff (centre-line distance d >= cutoff for pairs, gap q >= cutoff - 2 R for
obstacles).
"""

import math

import numpy as np

from beamcontact._native import njit, njit_uncounted

# blocks._pair_law evaluates the law at sqrt(max(s, S_FLOOR)) (no sqrt of 0): below the
# floor the energy is constant in s, so JAX AD gives f' = f'' = 0 there, and so do these
S_FLOOR = 1e-300


@njit
def cg_constant(m, R1, R2):
    """C(m, R1, R2) = 2^(5/2 - m) pi^(3/2) sqrt(R1 R2 / (R1 + R2)) Gamma(m - 7/2) /
    Gamma(m/2)^2 of eq. (9), for m > 7/2."""
    # through logarithms: Gamma(m - 7/2) alone overflows near m = 175, the ratio does not
    log_c = ((2.5 - m) * math.log(2.0) + 1.5 * math.log(math.pi) + math.lgamma(m - 3.5)
             - 2.0 * math.lgamma(0.5 * m))
    return math.exp(log_c) * math.sqrt(R1 * R2 / (R1 + R2))


@njit
def cg_constants(m, R1, R2):
    """:func:`cg_constant` of arrays of radii."""
    out = np.empty(R1.shape[0])
    for i in range(R1.shape[0]):
        out[i] = cg_constant(m, R1[i], R2[i])
    return out


@njit
def cg_wall_constant(m, R):
    """C_w(m, R) = (2 pi)^(3/2) sqrt(R) Gamma(m - 9/2) / Gamma(m - 1) of the
    section-to-half-space potential (eq. 9's counterpart for a rigid half-space,
    :mod:`beamcontact.contact.obstacles`), for m > 9/2."""
    log_c = 1.5 * math.log(2.0 * math.pi) + math.lgamma(m - 4.5) - math.lgamma(m - 1.0)
    return math.exp(log_c) * math.sqrt(R)


@njit
def inverse_power(q, inv, n):
    """q^(-n) for q > 0, given inv = 1 / q: by repeated squaring of inv (times sqrt(inv)
    for the half) when 2 n is a whole number below 64 (m = 12 gives n = 8.5: half the
    cost of a pair), else exp(-n log q), as the JAX law. Both agree to a few ulps."""
    twice = 2.0 * n
    if twice != math.floor(twice) or not 0.0 <= twice < 64.0:
        return math.exp(-n * math.log(q))
    k = int(n)
    base = inv
    p = 1.0
    while k:
        if k & 1:
            p *= base
        base *= base
        k >>= 1
    if twice != 2.0 * math.floor(n):
        p *= math.sqrt(inv)
    return p


@njit
def power_repulsion(q, amplitude, n, q_reg):
    """(P, dP/dq, d2P/dq2) of a q^(-n), continued below q_reg by its quadratic Taylor
    polynomial (the regularisation of eq. 9)."""
    if q > q_reg:
        # one division for the power and both derivatives: divisions are a good part of
        # a pair's cost
        inv = 1.0 / q
        p = amplitude * inverse_power(q, inv, n)
        d1 = -n * p * inv
        return p, d1, -(n + 1.0) * d1 * inv
    # below q_reg: the force grows linearly, so Newton never meets the singularity at 0
    p0 = amplitude * inverse_power(q_reg, 1.0 / q_reg, n)
    t = (q - q_reg) / q_reg
    d1 = p0 / q_reg
    d2 = n * (n + 1.0) * d1 / q_reg
    return p0 * (1.0 - n * t + 0.5 * n * (n + 1.0) * t * t), d1 * (-n + n * (n + 1.0) * t), d2


@njit
def cg_pair(d, R12, amplitude, m, q_reg, cutoff):
    """(Phi, dPhi/dd, d2Phi/dd2) of one pair of sections at centre-line distance d:
    eq. (9), Phi = amplitude q^(7/2 - m) with q = d - R12, regularised below q_reg, zero
    for d >= cutoff."""
    if d >= cutoff:
        return 0.0, 0.0, 0.0
    return power_repulsion(d - R12, amplitude, m - 3.5, q_reg)


@njit
def cg_pair_s(s, R12, amplitude, m, q_reg, cutoff):
    """(f, df/ds, d2f/ds2) of f(s) = Phi(sqrt(s)) (eq. 9), s = r . r the squared distance,
    the scalar law whose derivatives the blocks lift (:mod:`beamcontact.contact.blocks`)."""
    d = math.sqrt(s if s > S_FLOOR else S_FLOOR)
    phi, d1, d2 = cg_pair(d, R12, amplitude, m, q_reg, cutoff)
    return s_derivatives(s, d, phi, d1, d2)


@njit_uncounted
def cg_pair_s_many(s, count, R12, amplitude, m, q_reg, cutoff, f, f1, f2, d, inv, base):
    """:func:`cg_pair_s` of each of s[:count] into f, f1, f2 (f, df/ds, d2f/ds2), bitwise
    the same numbers, computed pass by pass over the arrays so that the compiler can
    use SIMD instructions: the square roots and divisions of the law are most of the
    cost of a coarse-grained block.

    Every element takes the operations of :func:`cg_pair_s`'s common branch (q > q_reg,
    d < cutoff, s above the floor, an exponent 2 n whole and below 64) in the same order;
    the elements of any other branch, and every element when the exponent is not of
    that kind, are then taken by :func:`cg_pair_s` itself. d, inv and base: work arrays
    of at least ``count`` entries (the caller's: an allocation per call cost more than
    the law at a few pairs)."""
    n = m - 3.5
    twice = 2.0 * n
    if twice != math.floor(twice) or not 0.0 <= twice < 64.0:
        for i in range(count):
            f[i], f1[i], f2[i] = cg_pair_s(s[i], R12, amplitude, m, q_reg, cutoff)
        return
    for i in range(count):
        si = s[i]
        di = math.sqrt(si if si > S_FLOOR else S_FLOOR)
        d[i] = di
        inv[i] = 1.0 / (di - R12)
        f[i] = 1.0
    for i in range(count):
        base[i] = inv[i]
    # inverse_power's repeated squaring, one pass per bit
    k = int(n)
    while k:
        if k & 1:
            for i in range(count):
                f[i] *= base[i]
        for i in range(count):
            base[i] *= base[i]
        k >>= 1
    half = twice != 2.0 * math.floor(n)
    for i in range(count):
        p = f[i]
        if half:
            p *= math.sqrt(inv[i])
        p = amplitude * p
        d1 = -n * p * inv[i]
        d2 = -(n + 1.0) * d1 * inv[i]
        inv_d = 1.0 / d[i]
        f[i] = p
        f1[i] = 0.5 * d1 * inv_d
        f2[i] = 0.25 * (d2 - d1 * inv_d) * inv_d * inv_d
    for i in range(count):  # the other branches, element by element
        if not (s[i] > S_FLOOR and d[i] < cutoff and d[i] - R12 > q_reg):
            f[i], f1[i], f2[i] = cg_pair_s(s[i], R12, amplitude, m, q_reg, cutoff)


@njit
def s_derivatives(s, d, phi, d1, d2):
    """(f, f', f'') in s of f(s) = phi(d), d = sqrt(max(s, S_FLOOR)), from (phi, dphi/dd,
    d2phi/dd2): f' = phi' / (2 d), f'' = (phi'' - phi' / d) / (4 d^2), and no derivatives
    at or below the floor (shared with the penalty law)."""
    if not s > S_FLOOR:
        return phi, 0.0, 0.0
    inv = 1.0 / d
    return phi, 0.5 * d1 * inv, 0.25 * (d2 - d1 * inv) * inv * inv


@njit
def cg_obstacle(q, R, amplitude, w, m, q_reg, cutoff):
    """(e, de/dq, d2e/dq2) of one contact point (radius R, arc-length weight w) at gap q
    from a rigid obstacle: w Phi_w(q), Phi_w = amplitude q^(9/2 - m) (the section-to-half-
    space counterpart of eq. 9), regularised below q_reg like eq. (9), zero for
    q >= cutoff - 2 R (the gap at which two sections of the beam stop interacting)."""
    if q >= cutoff - 2.0 * R:
        return 0.0, 0.0, 0.0
    p, d1, d2 = power_repulsion(q, amplitude, m - 4.5, q_reg)
    return w * p, w * d1, w * d2
