"""Float64: the switch (set by entry points: CLI, simulate, examples, tests), its check, and
the conversion of host values to float64 arrays.

JAX is not imported here: a run on the native engine never imports it (beamcontact/_jax.py).
Before JAX is imported the switch is the environment variable ``JAX_ENABLE_X64``, which
JAX reads when it is imported (also in the processes a run starts); after, its config.
"""

import os

# the values JAX's boolean environment variables read as true
_TRUE = ("y", "yes", "t", "true", "on", "1")


def enable_x64() -> None:
    """Make JAX compute in float64. Call before any JAX array is created."""
    from beamcontact._jax import imported, jax

    if imported():
        jax.config.update("jax_enable_x64", True)
    else:
        os.environ["JAX_ENABLE_X64"] = "1"


def require_x64() -> None:
    """Raise a clear error when JAX would silently compute in float32."""
    from beamcontact._jax import imported, jax

    if imported():
        on = bool(jax.config.read("jax_enable_x64"))
    else:
        on = os.environ.get("JAX_ENABLE_X64", "").lower() in _TRUE
    if not on:
        raise RuntimeError(
            "beamcontact needs float64: set JAX_ENABLE_X64=1 or call "
            "beamcontact.enable_x64() before creating arrays"
        )


def as_float(x):
    """Host value -> float64 array of the model (never a silent float32): NumPy's, or
    JAX's when JAX is imported already (:func:`beamcontact._jax.model_array`)."""
    import numpy as np

    from beamcontact._jax import model_array

    return model_array(x, np.float64)
