"""Native (Numba) kernels of the IPIP penalty law (paper Sec. 2.1, eqs. 3-5).

The JAX law :class:`beamcontact.contact.laws.penalty.Penalty` stays the one definition of
the physics; these kernels are its closed-form derivatives, tested against JAX AD of
``pair_energy`` / ``obstacle_energy`` (tests/test_native_contact.py). The amplitude of the
penalty law is the penalty eps itself (``Penalty.amplitude``), the same for every pair.
"""

import math

from beamcontact._native import njit
from beamcontact.contact.laws.coarse_grained_native import S_FLOOR, s_derivatives


@njit
def penalty_gap(q, eps):
    """(Pi, dPi/dq, d2Pi/dq2) of Pi = eps q^2 / 2 for q < 0, else 0 (eq. 3)."""
    if q < 0.0:
        return 0.5 * eps * q * q, eps * q, eps
    if q == 0.0:
        # Pi'' jumps at q = 0; JAX's minimum splits the derivative of a tie half and half,
        # so AD of eq. 3 gives eps / 4 there, which the JAX engine uses: the same here,
        # so that beams placed exactly touching get the same tangent from both engines
        return 0.0, 0.0, 0.25 * eps
    return 0.0, 0.0, 0.0


@njit
def penalty_pair(d, R12, eps):
    """(Pi, dPi/dd, d2Pi/dd2) of one closest point pair at centre-line distance d, gap
    q = d - R12 (eqs. 2-3)."""
    return penalty_gap(d - R12, eps)


@njit
def penalty_pair_s(s, R12, eps):
    """(f, df/ds, d2f/ds2) of f(s) = Pi(sqrt(s)) (eq. 3), s = r . r the squared distance,
    the scalar law whose derivatives the blocks lift (:mod:`beamcontact.contact.blocks`)."""
    d = math.sqrt(s if s > S_FLOOR else S_FLOOR)
    pi, d1, d2 = penalty_gap(d - R12, eps)
    return s_derivatives(s, d, pi, d1, d2)


@njit
def penalty_obstacle(q, eps):
    """(e, de/dq, d2e/dq2) of one contact point at gap q from a rigid obstacle: eps q^2 / 2
    for q < 0 (eq. 3) with weight 1, what a point of the "points" pairing carries in total
    (1/2 from each side), whatever its arc-length weight."""
    return penalty_gap(q, eps)
