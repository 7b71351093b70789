"""Small case builders shared by the tests (plain dicts, validated by parse_case)."""

import numpy as np

from beamcontact.io.case import parse_case


def beam(name="b", *, line=None, arc=None, degree=3, elements=8, continuity=None,
         radius=0.005, E=1.0e9, density=1000.0, supports=(), gravity=True):
    """A beam table with a circular section."""
    d = {"name": name, "degree": degree, "elements": elements,
         "section": {"shape": "circle", "radius": radius},
         "material": {"E": E, "density": density}, "supports": list(supports),
         "gravity": gravity}
    if continuity is not None:
        d["continuity"] = continuity
    if line is not None:
        d["line"] = {"start": list(line[0]), "end": list(line[1])}
    if arc is not None:
        d["arc"] = arc
    return d


def static_case(beams, loads=(), load_steps=1, points=(), gravity=(0.0, 0.0), **solver):
    """A validated static case."""
    raw = {"analysis": {"kind": "static", "load_steps": load_steps, "gravity": list(gravity)},
           "beams": list(beams), "loads": list(loads),
           "output": {"points": list(points)}}
    if solver:
        raw["solver"] = solver
    return parse_case(raw)


def bending_stiffness(E, radius):
    """E I of a solid circle."""
    return E * np.pi * radius**4 / 4.0
