"""beamcontact: contact dynamics of slender elastic beams.

Planar, geometrically exact, rotation-free isogeometric Bernoulli-Euler beams
(Borkovic et al., "A note on beam-to-beam contact dynamics", Sec. 3-4).

Importing the package has no side effects. JAX must run in float64: call
:func:`enable_x64` (the CLI does) or set ``JAX_ENABLE_X64=1`` before creating arrays.
"""

from beamcontact._x64 import enable_x64, require_x64

__all__ = ["enable_x64", "require_x64", "__version__"]
__version__ = "0.1.0"
