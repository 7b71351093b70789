"""From a validated case to its contact problem: the law (``Contact.law``), the contact
points of every element, the beam pairs that may touch."""

import numpy as np

from beamcontact.contact.points import contact_elements
from beamcontact.contact.problem import ContactProblem


def build_contact(case, disc) -> ContactProblem | None:
    """The contact problem of a validated case (None for contact.model = "none")."""
    c = case.contact
    radii = [b.section.half_depth for b in disc.beams]
    law = c.law(radii)
    if law is None or len(disc.beams) < 2:
        return None
    betas = c.densities if len(c.densities) == len(disc.beams) else [c.densities[0]] * len(
        disc.beams)
    beam_pairs = None if c.pairs is None else [
        (case.beam_index(a), case.beam_index(b)) for a, b in c.pairs]
    ce = contact_elements(disc, c.segments_per_element, betas, beam_pairs)
    beam_of = np.asarray(ce.beam)
    local, n_el = np.zeros_like(beam_of), np.zeros(len(disc.beams), dtype=np.int64)
    for e, b in enumerate(beam_of):
        local[e] = n_el[b]
        n_el[b] += 1
    return ContactProblem(law, ce, float(law.search_reach(max(radii))),
                          c.max_penetration_or(radii), beam_of, local)
