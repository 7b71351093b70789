"""Float64: the switch (set by entry points: CLI, simulate, examples, tests), its check, and
the conversion of host values to float64 arrays.

JAX is imported lazily so that validating a case (``beamcontact check``) stays fast.
"""


def enable_x64() -> None:
    """Make JAX compute in float64. Call before any JAX array is created."""
    import jax

    jax.config.update("jax_enable_x64", True)


def require_x64() -> None:
    """Raise a clear error when JAX would silently compute in float32."""
    import jax

    if not jax.config.read("jax_enable_x64"):
        raise RuntimeError(
            "beamcontact needs float64: set JAX_ENABLE_X64=1 or call "
            "beamcontact.enable_x64() before creating arrays"
        )


def as_float(x):
    """Host value -> float64 JAX array (never a silent float32)."""
    import jax.numpy as jnp
    import numpy as np

    return jnp.asarray(np.asarray(x, dtype=np.float64))
