"""From a validated case to its contact problem: the law (``Contact.law``), the contact
points of every element, the beam pairs that may touch (and each beam itself, under
self-contact), and the rigid obstacles."""

import numpy as np

from beamcontact.contact.obstacles import Obstacles, obstacles_from
from beamcontact.contact.points import contact_elements, self_exclusion
from beamcontact.contact.problem import ContactProblem


def build_obstacles(case) -> Obstacles | None:
    """The case's ``[[obstacles]]`` (None when there are none), walls first, then circles,
    each group in case order (:func:`obstacle_names` gives the same order)."""
    if not case.obstacles:
        return None
    beta = [1.0 if o.density is None else o.density for o in case.obstacles]
    both = list(zip(case.obstacles, beta, strict=True))
    walls = [(o.wall.point, o.wall.normal, b) for o, b in both if o.wall is not None]
    circles = [(o.circle.center, o.circle.radius, b) for o, b in both if o.circle is not None]
    return obstacles_from(walls, circles)


def obstacle_names(case) -> list[str]:
    """Obstacle names in the order of :func:`build_obstacles`."""
    return ([o.name for o in case.obstacles if o.wall is not None]
            + [o.name for o in case.obstacles if o.circle is not None])


def build_contact(case, disc) -> ContactProblem | None:
    """The contact problem of a validated case (None for contact.model = "none")."""
    c = case.contact
    radii = [b.section.half_depth for b in disc.beams]
    law = c.law(radii)
    obstacles = build_obstacles(case)
    if law is None or (len(disc.beams) < 2 and not c.self_contact and obstacles is None):
        return None
    betas = c.densities if len(c.densities) == len(disc.beams) else [c.densities[0]] * len(
        disc.beams)
    beam_pairs = None if c.pairs is None else [
        (case.beam_index(a), case.beam_index(b)) for a, b in c.pairs]
    exclusion = (c.self_exclusion if c.self_exclusion is not None
                 else self_exclusion(max(radii), float(law.interaction_distance())))
    ce = contact_elements(disc, c.segments_per_element, betas, beam_pairs, c.self_contact,
                          exclusion)
    beam_of = np.asarray(ce.beam)
    local, n_el = np.zeros_like(beam_of), np.zeros(len(disc.beams), dtype=np.int64)
    for e, b in enumerate(beam_of):
        local[e] = n_el[b]
        n_el[b] += 1
    return ContactProblem(law, ce, float(law.search_reach(max(radii))),
                          c.max_penetration_or(radii), beam_of, local, obstacles)
