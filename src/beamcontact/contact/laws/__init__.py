"""Contact laws (paper Sec. 2) as objects: parameters as named fields, the energy of one
point pair as a method.

A law is a frozen dataclass registered as a JAX pytree, so it travels into jitted code as
an argument (its class is part of the compiled signature; its parameters are data, so a
new penalty value reuses the compiled code). Every law provides

* ``amplitude(R1, R2, beta12)``: the factor of the pair energy that depends on the pair of
  beams only (computed once per block of point pairs);
* ``pair_energy(d, R12, amplitude)``: the energy of one pair of contact points at
  centre-line distance d, with R12 = R1 + R2 (gap q = d - R12, eq. 2);
* ``interaction_distance()``: the centre-line distance beyond which a pair contributes
  nothing (inf: no cutoff);
* ``search_reach(r_max)``: how far the broad phase grows each element's box (r_max: the
  largest radius of the beams);
* ``advance_slack()``: the distance added to a gap in the conservative advancement
  (:mod:`beamcontact.contact.advance`), i.e. how far into a gap the law lets a pair go
  before its force stops it;
* ``obstacle_amplitude(R, beta12)`` and ``obstacle_energy(q, R, amplitude, w)``: the
  energy of one contact point (radius R, arc-length weight w) at gap q from a rigid
  obstacle (:mod:`beamcontact.contact.obstacles`);
* ``closest_pairs`` (class attribute): True when the law acts only on the closest point
  pairs (IPIP, chosen on the host each step by the law's ``pairing`` rule, "zones" or
  "points", :mod:`beamcontact.contact.select`), False when it is integrated over all
  point pairs (coarse-grained).

A new law is one more class like these in a file of its own, plus its entry in the case
schema (``io/case.py``: ``Contact.model``, its parameters and ``Contact.law()``); see
docs/contact_laws.md, "Adding a contact law".
"""

from typing import ClassVar, Protocol

from beamcontact.contact.laws.coarse_grained import (
    CoarseGrained,
    cg_constant,
    cg_potential,
    taylor_below,
)
from beamcontact.contact.laws.penalty import Penalty

__all__ = ["ContactLaw", "CoarseGrained", "Penalty", "cg_constant", "cg_potential",
           "taylor_below"]


class ContactLaw(Protocol):
    """What the contact kernels and the step control ask of a law (see the module
    docstring); a law is a frozen dataclass registered with
    ``jax.tree_util.register_dataclass``."""

    closest_pairs: ClassVar[bool]

    def amplitude(self, R1, R2, beta12): ...

    def pair_energy(self, d, R12, amplitude): ...

    def obstacle_amplitude(self, R, beta12): ...

    def obstacle_energy(self, q, R, amplitude, w): ...

    def interaction_distance(self) -> float: ...

    def search_reach(self, r_max: float) -> float: ...

    def advance_slack(self) -> float: ...
