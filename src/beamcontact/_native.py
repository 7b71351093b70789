"""The one place that imports Numba: the ``njit`` of the native CPU kernels.

The kernels compile in seconds, so their machine code is kept on disk. Numba's default
place for it is a ``__pycache__`` beside the source, which fails or clashes in a read-only
or shared install; it goes instead to a ``numba`` folder in the cache folder of
:mod:`beamcontact._cache` (``<cache>/numba/<hash of the kernel sources>``, see
:func:`_source_hash`), beside JAX's compiled programs, and nowhere when that cache
is switched off (``BEAMCONTACT_CACHE_DIR=""``) or cannot be created. Numba's cache locator
reads ``numba.config.CACHE_DIR`` once, when a function is decorated, so the folder is set
just for our decorations and the setting of other Numba users in the process is restored.

Options: float64 IEEE arithmetic as written (no fastmath: the kernels are checked against
JAX to 1e-12), NumPy's error model (x / 0 gives inf or nan as in JAX, no exception), and
the GIL released so that threads can run kernels side by side.

Importing this module imports neither JAX nor matplotlib.
"""

import hashlib
from pathlib import Path

import numba

from beamcontact._cache import cache_dir

_OPTIONS = {"fastmath": False, "error_model": "numpy", "nogil": True}


def _source_hash() -> str:
    """A hash of every native kernel's source. Numba's cache checks the timestamp of the
    file that holds a function, not of the files whose functions it calls, so a kernel
    that calls an edited law in another module would run the old law; a folder per
    version of the sources cannot."""
    package = Path(__file__).parent
    digest = hashlib.sha256()
    for path in sorted(package.rglob("*native*.py")):
        digest.update(path.relative_to(package).as_posix().encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()[:16]


def _numba_cache_dir() -> Path | None:
    """``numba/<hash of the kernel sources>`` inside the cache folder, created; None when
    off or not creatable."""
    base = cache_dir()
    if base is None:
        return None
    path = base / "numba" / _source_hash()
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError:
        return None
    return path


_CACHE_DIR = _numba_cache_dir()


def njit(func):
    """``numba.njit(func, cache=True, fastmath=False, error_model="numpy", nogil=True)``
    with the on-disk cache in the project's folder (compiled anew each process when the
    cache is off)."""
    if _CACHE_DIR is None:
        return numba.njit(func, cache=False, **_OPTIONS)
    saved = numba.config.CACHE_DIR
    numba.config.CACHE_DIR = str(_CACHE_DIR)
    try:
        return numba.njit(func, cache=True, **_OPTIONS)
    finally:
        numba.config.CACHE_DIR = saved
