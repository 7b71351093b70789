"""Checks of a case before it runs that need its discretisation (statics/restraint.py
holds the mechanics: rigid modes, supports, singular tangents)."""

from beamcontact.setup.model import supported_dofs
from beamcontact.statics.restraint import HINT, _plural, describe_modes, unrestrained_modes


def static_mechanisms(case, disc) -> list[str]:
    """Beams of a static case that their supports do not hold and that have no contact
    partner: one message per beam, naming the key (``beams[i] (name).supports``).

    A beam that may touch another (contact model other than "none", and listed in
    ``contact.pairs`` if given) is left to the solver: contact can hold it.
    """
    if case.analysis.kind != "static":
        return []
    fixed = supported_dofs(case, disc)
    partners = _contact_partners(case)
    found = []
    for i, (beam, info) in enumerate(zip(case.beams, disc.beams, strict=True)):
        if beam.name in partners:
            continue
        x = info.curve.points
        dofs = slice(2 * info.offset, 2 * (info.offset + info.n_cp))
        modes = unrestrained_modes(x, fixed[dofs])
        if modes.shape[1]:
            found.append(
                f"beams[{i}] ({beam.name}).supports: the beam is a mechanism in this static "
                f"analysis: {describe_modes(x, modes)} ({_plural(modes.shape[1])} not "
                f"restrained by its supports, and it has no contact partner); {HINT}")
    return found


def _contact_partners(case) -> set[str]:
    """Names of the beams that can be in contact with another beam or an obstacle."""
    if case.contact.model == "none":
        return set()
    if case.obstacles:
        return {b.name for b in case.beams}
    if len(case.beams) < 2:
        return set()
    if case.contact.pairs is None:
        return {b.name for b in case.beams}
    return {name for pair in case.contact.pairs if pair[0] != pair[1] for name in pair}
