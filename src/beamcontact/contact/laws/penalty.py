"""IPIP penalty law (paper Sec. 2.1, eqs. 3-5) as a contact-law object
(:mod:`beamcontact.contact.laws`)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import ClassVar

from beamcontact._jax import jnp, pytree


@pytree
@dataclass(frozen=True)
class Penalty:
    """IPIP penalty law (eqs. 3-5): Pi = eps q^2 / 2 for q < 0, else 0, acting on the
    closest pairs of integration points.

    Attributes:
        penalty: eps [N/m].
        max_penetration: a step whose smallest gap falls below -max_penetration is redone
            shorter [m]; also the advancement slack (the force acts only once the beams
            overlap).
        pairing: which pairs are closest (:mod:`beamcontact.contact.select`): "points",
            every point with its closest point on the other beam (the contact energy is
            continuous: the default), or "zones", the paper's closest pair of each contact
            zone. Static: part of the compiled signature ("points" are chosen inside the
            step, "zones" on the host).
    """

    penalty: float
    max_penetration: float
    pairing: str = field(default="points", metadata=dict(static=True))

    closest_pairs: ClassVar[bool] = True

    def amplitude(self, R1, R2, beta12):
        """The penalty, the same for every pair (one value per block)."""
        del R2, beta12  # the penalty is not scaled by radii or densities (eq. 3)
        return jnp.full_like(R1, self.penalty)

    def pair_energy(self, d, R12, amplitude):
        """Penalty energy eps q^2 / 2 of one closest point pair for q < 0 (eq. 3)."""
        return 0.5 * amplitude * jnp.minimum(d - R12, 0.0) ** 2

    def obstacle_amplitude(self, R, beta12):
        """The penalty (eq. 3), as for a beam pair."""
        del beta12
        return jnp.full_like(R, self.penalty)

    def obstacle_energy(self, q, R, amplitude, w):
        """eps q^2 / 2 for q < 0 of one point against a rigid obstacle, weight 1 (what a
        point of the "points" pairing carries in total, 1/2 from each side)."""
        del R, w
        return 0.5 * amplitude * jnp.minimum(q, 0.0) ** 2

    def interaction_distance(self) -> float:
        """No cutoff: every candidate block is kept; the selection picks the pairs."""
        return math.inf

    def search_reach(self, r_max: float) -> float:
        """Boxes grow by the largest radius: blocks closer than two radii are candidates."""
        return r_max

    def advance_slack(self):
        return self.max_penetration
