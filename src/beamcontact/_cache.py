"""JAX's persistent compilation cache for the command line (set by entry points only).

The fused time step takes 5-7 s to compile; the compiled executable is the same for every
run of the same model shape, so ``beamcontact run`` and the workers of ``beamcontact
sweep`` keep it on disk and a second run compiles in well under a second. The results are
identical (the same executable runs). Every compilation is cached, the small ones too:
a run compiles about 35 small functions besides the step (initial state, diagnostics,
checks), together about 1.5 s when each is compiled afresh. Location:
``$BEAMCONTACT_CACHE_DIR``, else ``$XDG_CACHE_HOME/beamcontact/jax``, else
``~/.cache/beamcontact/jax``; set ``BEAMCONTACT_CACHE_DIR`` to an empty string to switch
the cache off. Its ``exported/`` folder holds the traced programs of ``_persistent.py``,
its ``numba/`` folder the compiled native kernels (``_native.py``).
"""

import os
from pathlib import Path


def cache_dir() -> Path | None:
    """The cache folder, or None when switched off."""
    explicit = os.environ.get("BEAMCONTACT_CACHE_DIR")
    if explicit is not None:
        return Path(explicit) if explicit else None
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base) / "beamcontact" / "jax"


def jax_cache_dir() -> str | None:
    """The persistent compilation cache JAX uses or will use when imported (None: none),
    read without importing JAX."""
    from beamcontact._jax import imported, jax

    if imported():
        return jax.config.jax_compilation_cache_dir or None
    return os.environ.get("JAX_COMPILATION_CACHE_DIR") or None


def enable_compilation_cache() -> Path | None:
    """Point JAX at the cache folder (created if needed); returns it, or None when the
    cache is off or the folder cannot be created (then JAX simply compiles every time).
    JAX is not imported here: before it is, the settings go into the environment
    variables that JAX reads when imported (a native run never imports it)."""
    from beamcontact._jax import imported, jax

    path = cache_dir()
    if path is None:
        return None
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError:
        return None
    if imported():
        jax.config.update("jax_compilation_cache_dir", str(path))
        jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.0)
    else:
        os.environ["JAX_COMPILATION_CACHE_DIR"] = str(path)
        os.environ["JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS"] = "0"
    return path
