"""beamcontact: contact dynamics of slender elastic beams.

Planar, geometrically exact, rotation-free isogeometric Bernoulli-Euler beams
(Borkovic et al., "A note on beam-to-beam contact dynamics", Sec. 3-4).

The Python API (:mod:`beamcontact.api`)::

    import beamcontact as bc
    result = bc.simulate(bc.load_case("case.toml"))

Importing the package has no side effects: it imports neither JAX nor matplotlib (the
names below are loaded on first use) and changes no global setting. JAX must run in
float64: :func:`simulate` and the command line switch it on; a script that calls lower
layers itself calls :func:`enable_x64` (or sets ``JAX_ENABLE_X64=1``) first.
"""

import importlib
from typing import Any

from beamcontact._x64 import enable_x64, require_x64

__version__ = "0.1.0"

# public name -> module that defines it (imported on first access, PEP 562)
_LAZY = {
    "load_case": "beamcontact.api",
    "simulate": "beamcontact.api",
    "Result": "beamcontact.api",
    "SavedStates": "beamcontact.api",
    **{name: "beamcontact.io.case" for name in (
        "Case", "CaseError", "Analysis", "Beam", "Line", "Arc", "Nurbs", "CircleSection",
        "RectangleSection", "Material", "Support", "Load", "Contact", "Obstacle", "Wall",
        "Circle", "Solver", "Output", "OutputPoint")},
}

__all__ = ["enable_x64", "require_x64", "__version__", "examples", *_LAZY]


def __getattr__(name: str) -> Any:
    if name == "examples":  # the bundled examples (beamcontact/examples.py)
        return importlib.import_module("beamcontact.examples")
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'beamcontact' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(__all__)
