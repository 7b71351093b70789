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


def enable_compilation_cache() -> Path | None:
    """Point JAX at the cache folder (created if needed); returns it, or None when the
    cache is off or the folder cannot be created (then JAX simply compiles every time)."""
    import jax

    path = cache_dir()
    if path is None:
        return None
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError:
        return None
    jax.config.update("jax_compilation_cache_dir", str(path))
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.0)
    return path
