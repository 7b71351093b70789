"""JAX, imported on first use, and the package's pytrees registered with it.

The native engine runs a case without JAX, whose import costs about 0.45 s of every run
(docs/engines.md). So the package imports JAX in one place: its modules take ``jax`` and
``jnp`` from here, names that import the real module at their first attribute access (as
PEP 562 does for a package's attributes), and declare the frozen dataclasses that travel
into jitted code with :func:`pytree`, which registers them with JAX once JAX is imported
(at once, when it already is). A module therefore runs no JAX at import: no ``jax.jit``
at module level (:func:`lazy_jit` defers it) and ``from __future__ import annotations``
where fields are annotated ``jax.Array``. tests/test_engine_seam.py checks that a native
run imports no JAX and that no module imports it but this one.
"""

import importlib
import sys
from functools import wraps

_PENDING: list[type] = []  # pytree classes declared before JAX was imported


def _register_pending() -> None:
    import jax

    while _PENDING:
        jax.tree_util.register_dataclass(_PENDING.pop(0))


# what copy, pickle and inspect look for on any object: asking must not import JAX
_PROBES = frozenset({"__wrapped__", "__signature__", "__getstate__", "__setstate__",
                     "__reduce__", "__reduce_ex__", "__copy__", "__deepcopy__",
                     "__getnewargs__", "__getnewargs_ex__", "__length_hint__"})


class _LazyModule:
    """A module imported at the first access of one of its attributes; each attribute is
    then kept on this object, so the next access costs what a module's does."""

    def __init__(self, name: str):
        self._name = name

    def __getattr__(self, attr: str):
        if attr in _PROBES:
            raise AttributeError(attr)
        module = importlib.import_module(self._name)
        _register_pending()
        value = getattr(module, attr)
        setattr(self, attr, value)
        return value

    def __repr__(self) -> str:
        return f"<{self._name}, imported on first use>"


jax = _LazyModule("jax")
jnp = _LazyModule("jax.numpy")


def imported() -> bool:
    """Whether JAX has been imported (by the package or by anyone else)."""
    return "jax" in sys.modules


def gpu_plugin_installed() -> bool:
    """Whether a GPU plugin of JAX is installed (found without importing JAX)."""
    from importlib.util import find_spec

    return any(find_spec(name) is not None
               for name in ("jax_cuda12_plugin", "jax_cuda13_plugin", "jax_rocm60_plugin"))


def pytree(cls: type) -> type:
    """Register the dataclass ``cls`` as a JAX pytree (``jax.tree_util.
    register_dataclass``: fields with ``metadata=dict(static=True)`` are static), now if
    JAX is imported, else when :data:`jax` or :data:`jnp` first imports it."""
    _PENDING.append(cls)
    if imported():
        _register_pending()
    return cls


def model_array(x, dtype=None):
    """``x`` as an array of the model (the case's data built on the host): a JAX array
    when JAX is imported already, as JAX code that closes over the model needs, else a
    NumPy array, so that a native run never imports JAX (the JAX engine moves such a
    model to its device once: :func:`on_device`)."""
    import numpy as np

    a = np.asarray(x, dtype=dtype)
    return jnp.asarray(a) if imported() else a


def on_device(tree):
    """``tree`` with every array leaf a JAX array on the default device: the JAX engine
    moves the model (built in NumPy) once, not at every call, and its jitted functions
    see the same arguments, never host constants, whoever built the model."""
    return jax.tree.map(jnp.asarray, tree)


def lazy_jit(fun=None, **options):
    """``jax.jit(fun, **options)``, made at the first call (a module-level jit would
    import JAX with the module)."""
    if fun is None:
        return lambda f: lazy_jit(f, **options)
    compiled = []

    @wraps(fun)
    def call(*args, **kwargs):
        if not compiled:
            compiled.append(jax.jit(fun, **options))
        return compiled[0](*args, **kwargs)

    return call
