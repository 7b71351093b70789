"""Saved traced programs (_persistent.py): a later process runs exactly what ``jax.jit``
would have, without tracing.

Asserted: the first call saves one program per signature (weakly and strongly typed
floats share it), a new wrapper of the same function (as in a new process) loads it
instead of tracing, and both give results bitwise equal to plain ``jax.jit``; a function
JAX cannot export (a host callback) is marked once and jitted as usual; a damaged file
is exported afresh; with the cache off nothing is written.
"""

from dataclasses import dataclass

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from beamcontact import _persistent
from beamcontact._persistent import persistent_jit


@jax.tree_util.register_dataclass
@dataclass(frozen=True)
class _Params:
    a: jax.Array
    scale: float = 1.0  # noqa: RUF009 (a data field of the pytree)


def _energy(x, p: _Params, h, *, n: int):
    """Something with a loop, a solve and a static argument."""
    K = jnp.eye(x.shape[0]) * (2.0 + p.a) + 0.1 * jnp.outer(x, x)
    for _ in range(n):
        x = x - h * jnp.linalg.solve(K, jnp.sin(x) * p.scale)
    return {"x": x, "e": jnp.sum(x**2)}


@pytest.fixture
def cache(tmp_path, monkeypatch):
    monkeypatch.setattr(_persistent, "_folder", lambda: tmp_path / "exported")
    return tmp_path / "exported"


def _args(h):
    x = jnp.linspace(0.1, 1.0, 7)
    return x, _Params(jnp.asarray(0.3), 1.5), h


def test_saved_program_gives_bitwise_the_jit_results(cache, monkeypatch):
    reference = jax.jit(_energy, static_argnames=("n",))(*_args(0.01), n=3)
    first = persistent_jit(_energy, static_argnames=("n",))
    out1 = first(*_args(0.01), n=3)  # a weakly typed h
    out2 = first(*_args(np.float64(0.01)), n=3)  # a strongly typed one: same program
    saved = sorted(p.suffix for p in cache.iterdir())
    assert saved == [".hlo", ".tree"]
    first(*_args(0.01), n=2)  # another static value is another program
    assert len(list(cache.glob("*.hlo"))) == 2
    # a new wrapper, as in a new process: the program is loaded, the function not traced
    calls = []
    monkeypatch.setattr(_persistent._Persistent, "_save",
                        lambda *a: calls.append(a) or None)
    later = persistent_jit(_energy, static_argnames=("n",))
    out3 = later(*_args(0.01), n=3)
    assert calls == []
    for out in (out1, out2, out3):
        assert jax.tree_util.tree_structure(out) == jax.tree_util.tree_structure(reference)
        for a, b in zip(jax.tree_util.tree_leaves(out), jax.tree_util.tree_leaves(reference),
                        strict=True):
            np.testing.assert_array_equal(np.asarray(a), np.asarray(b))


def test_host_callback_is_marked_and_jitted_as_usual(cache):
    def with_callback(x):
        y = jax.pure_callback(lambda v: np.asarray(v) * 2.0,
                              jax.ShapeDtypeStruct(x.shape, x.dtype), x)
        return y + 1.0

    f = persistent_jit(with_callback)
    np.testing.assert_array_equal(np.asarray(f(jnp.arange(3.0))), [1.0, 3.0, 5.0])
    assert [p.suffix for p in cache.iterdir()] == [".unsupported"]


def test_nothing_is_written_with_the_cache_off(tmp_path, monkeypatch):
    monkeypatch.setattr(_persistent, "_folder", lambda: None)
    f = persistent_jit(_energy, static_argnames=("n",))
    out = f(*_args(0.01), n=1)
    assert np.isfinite(float(out["e"]))
    assert not any(tmp_path.iterdir())


def test_a_damaged_saved_program_is_exported_afresh(cache):
    reference = jax.jit(_energy, static_argnames=("n",))(*_args(0.01), n=2)
    persistent_jit(_energy, static_argnames=("n",))(*_args(0.01), n=2)
    (saved,) = cache.glob("*.hlo")
    saved.write_bytes(b"not a program")
    out = persistent_jit(_energy, static_argnames=("n",))(*_args(0.01), n=2)
    np.testing.assert_array_equal(np.asarray(out["x"]), np.asarray(reference["x"]))
    assert saved.read_bytes() != b"not a program"  # written again


class _Alarm:
    """What a tampered cache file would make pickle build: code that runs on loading."""

    ran = False

    def __reduce__(self):
        return (_Alarm.ring, ())

    @staticmethod
    def ring():
        _Alarm.ran = True


def test_the_cache_holds_data_never_code(cache):
    """The output tree is JSON naming builtin containers and this package's classes: a
    pickle put in its place (which would run code when unpickled) is never unpickled,
    and the file is written afresh; a tree naming a class of another package is refused."""
    import pickle

    reference = jax.jit(_energy, static_argnames=("n",))(*_args(0.01), n=2)
    persistent_jit(_energy, static_argnames=("n",))(*_args(0.01), n=2)
    (tree,) = cache.glob("*.tree")
    tree.write_bytes(pickle.dumps(_Alarm()))
    out = persistent_jit(_energy, static_argnames=("n",))(*_args(0.01), n=2)
    assert not _Alarm.ran
    np.testing.assert_array_equal(np.asarray(out["x"]), np.asarray(reference["x"]))
    assert tree.read_bytes().startswith(b"{")  # JSON again
    # this package's pytrees go through the JSON form and back
    from beamcontact.assembly.model import LoadState
    from beamcontact.dynamics.hht import DynState

    state = DynState(0.0, 1.0, 2.0, 3.0, 4.0, LoadState(5.0, 6.0))
    treedef = jax.tree_util.tree_structure((state, None, {"b": 1, "a": [2]}))
    assert _persistent.tree_from_data(_persistent.tree_to_data(treedef)) == treedef
    foreign = {"type": "os:system", "aux": None, "children": []}
    with pytest.raises(ValueError, match="not a node of this package"):
        _persistent.tree_from_data(foreign)
