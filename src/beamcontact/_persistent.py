"""Traced programs kept on disk, so that a new process skips tracing (``jax.export``).

JAX's persistent compilation cache (``_cache.py``) saves the compiled executable, but it is
looked up by the lowered program, so every process still traces and lowers each function:
in a warm run of the stiff peer drop, 2.1 s of tracing (the fused step 1.1 s, the initial
state 0.7 s) against a step loop of 2-3 s. :func:`persistent_jit` is ``jax.jit`` that also
serialises the lowered program of each new signature (``jax.export``) to
``<cache>/exported/`` and, in a later process, deserialises it instead of tracing; the
executable then still comes from the compilation cache. The program is the same StableHLO,
so results are bitwise those of ``jax.jit`` (tests/test_persistent.py).

A saved program is used only by the same beamcontact source (a hash of every module), the
same JAX, platform and x64 setting, and the same argument structure, shapes, dtypes and
static arguments. Programs JAX cannot serialise (host callbacks: the sparse tangent), and
signatures whose structure has no stable text (an object shown by its address), are
simply jitted as usual. With the cache off (``BEAMCONTACT_CACHE_DIR=""``) or before the
command line has switched it on, this is plain ``jax.jit``.

The cache holds data, never code: the program is JAX's serialised StableHLO and its output
tree is JSON (:func:`tree_to_data`), which names builtin containers and classes of this
package only; nothing is unpickled. A damaged or foreign file is ignored and written
afresh.
"""

from __future__ import annotations

import functools
import hashlib
import importlib
import json
import os
from pathlib import Path

from beamcontact._jax import jax


@functools.cache
def _source_hash() -> str:
    """sha256 of every module of the package (any edit invalidates every saved program)."""
    h = hashlib.sha256()
    root = Path(__file__).resolve().parent
    for path in sorted(root.rglob("*.py")):
        h.update(str(path.relative_to(root)).encode())
        h.update(path.read_bytes())
    return h.hexdigest()


def _folder() -> Path | None:
    """<compilation cache>/exported, or None when JAX's persistent cache is not on."""
    base = jax.config.jax_compilation_cache_dir
    if not base:
        return None
    return Path(base) / "exported"


class _Persistent:
    """``jax.jit`` of a function that, while it is traced for a new signature, embeds the
    saved program of that signature (``Exported.call``) instead of tracing the function,
    exporting and saving it first when there is none. So every process, the first
    included, runs the same exported program. Calls go through ``jax.jit``'s own
    dispatch: nothing is added per call."""

    def __init__(self, fn, static_argnames: tuple[str, ...]):
        self.fn = fn
        self.static_argnames = static_argnames
        functools.update_wrapper(self, fn)

    @functools.cached_property
    def jitted(self):
        """The ``jax.jit`` of the tracing function, made at the first call (a module that
        declares a persistent function imports no JAX: beamcontact/_jax.py)."""
        return jax.jit(self._trace, static_argnames=self.static_argnames)

    def __call__(self, *args, **kwargs):
        return self.jitted(*args, **kwargs)

    def _trace(self, *args, **kwargs):
        statics = {k: kwargs.pop(k) for k in self.static_argnames if k in kwargs}
        leaves, treedef = jax.tree_util.tree_flatten((args, kwargs))
        # weak types only steer dtype promotion, and every float here is float64: one
        # program serves both (else each weak/strong mix of inputs would be saved apart)
        specs = [jax.ShapeDtypeStruct(leaf.aval.shape, leaf.aval.dtype) for leaf in leaves]
        path = self._path(treedef, specs, statics)
        program = None
        if path is not None:
            program = self._load(path) or self._save(path, treedef, specs, statics)
        if program is not None:
            exported, out_tree = program
            try:
                return jax.tree_util.tree_unflatten(out_tree, exported.call(*leaves))
            except Exception:  # noqa: BLE001 (a program that does not fit: trace instead)
                pass
        return self.fn(*args, **kwargs, **statics)

    def _path(self, treedef, specs, statics) -> Path | None:
        """Where the program of this signature is kept (None: not kept)."""
        folder = _folder()
        signature = repr((treedef, [(s.shape, str(s.dtype)) for s in specs],
                          sorted(statics.items())))
        if folder is None or " at 0x" in signature:
            return None
        key = hashlib.sha256("\n".join([
            f"{self.fn.__module__}.{self.fn.__qualname__}", _source_hash(), jax.__version__,
            jax.default_backend(), str(jax.config.jax_enable_x64), signature]).encode())
        return folder / f"{self.fn.__name__}-{key.hexdigest()[:32]}"

    @staticmethod
    def _load(path: Path):
        """(exported, output tree) saved at path, or None."""
        try:
            return (jax.export.deserialize(bytearray(path.with_suffix(".hlo").read_bytes())),
                    tree_from_data(json.loads(path.with_suffix(".tree").read_text())))
        except Exception:  # noqa: BLE001 (missing, damaged or foreign: export afresh)
            return None

    def _save(self, path: Path, treedef, specs, statics):
        """Export the program of one signature and write it; returns (exported, output
        tree), or None when JAX cannot export it (a host callback), which is marked so
        that later processes do not try again."""
        if path.with_suffix(".unsupported").exists():
            return None
        out_tree = []

        def flat(*leaves):
            a, k = jax.tree_util.tree_unflatten(treedef, leaves)
            out, tree = jax.tree_util.tree_flatten(self.fn(*a, **k, **statics))
            out_tree.append(tree)
            return out

        try:
            exported = jax.export.export(jax.jit(flat))(*specs)
            files = {".tree": json.dumps(tree_to_data(out_tree[0])).encode(),
                     ".hlo": exported.serialize()}
            program = (exported, out_tree[0])
        except Exception:  # noqa: BLE001 (what export rejects is JAX's to say)
            files, program = {".unsupported": b""}, None
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            # write, then rename: a concurrent process never reads half a file
            for suffix, data in files.items():
                tmp = path.with_suffix(f"{suffix}.{os.getpid()}.tmp")
                tmp.write_bytes(data)
                tmp.replace(path.with_suffix(suffix))
        except OSError:
            pass  # a read-only or full cache: the program is still used in this process
        return program


# the containers a saved output tree may hold besides the package's own pytree classes
_BUILTIN_NODES = {"tuple": tuple, "list": list, "dict": dict, "None": type(None)}


def tree_to_data(treedef) -> dict | None:
    """A program's output tree as JSON data (None for a leaf): each node's type (a builtin
    container, or a class of this package by module and name), its auxiliary data (the
    static fields; JSON values, tuples marked) and its children."""
    node = treedef.node_data()
    if node is None:
        return None
    kind, aux = node
    name = next((n for n, t in _BUILTIN_NODES.items() if t is kind),
                f"{kind.__module__}:{kind.__qualname__}")
    return {"type": name, "aux": _aux_to_data(aux),
            "children": [tree_to_data(c) for c in treedef.children()]}


def tree_from_data(data):
    """The tree of :func:`tree_to_data`. Only builtin containers and classes of this
    package are made: a damaged or foreign file raises (and the program is exported
    afresh), it never names code to run."""
    if data is None:
        return jax.tree_util.tree_structure(0)
    name = data["type"]
    kind = _BUILTIN_NODES.get(name)
    if kind is None:
        module, _, qualname = name.partition(":")
        if module.split(".")[0] != __package__ or "." in qualname:
            raise ValueError(f"not a node of this package: {name!r}")
        kind = getattr(importlib.import_module(module), qualname)
    children = [tree_from_data(c) for c in data["children"]]
    return jax.tree_util.PyTreeDef.from_node_data_and_children(
        jax.tree_util.default_registry, (kind, _aux_from_data(data["aux"])), children)


def _aux_to_data(aux):
    if isinstance(aux, tuple):
        return {"tuple": [_aux_to_data(a) for a in aux]}
    if isinstance(aux, list):
        return [_aux_to_data(a) for a in aux]
    if aux is None or isinstance(aux, bool | int | float | str):
        return aux
    raise TypeError(f"auxiliary data {aux!r} has no JSON form")


def _aux_from_data(data):
    if isinstance(data, dict):
        return tuple(_aux_from_data(a) for a in data["tuple"])
    if isinstance(data, list):
        return [_aux_from_data(a) for a in data]
    return data


def persistent_jit(fn=None, *, static_argnames: tuple[str, ...] = ()):
    """``jax.jit`` (static arguments by keyword only) whose lowered programs are kept on
    disk for later processes; see the module docstring."""
    if fn is None:
        return functools.partial(persistent_jit, static_argnames=tuple(static_argnames))
    return _Persistent(fn, tuple(static_argnames))
