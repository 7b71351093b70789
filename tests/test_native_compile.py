"""How the native kernels are compiled (beamcontact/_native.py, beamcontact/_warmup.py;
docs/engines.md, "Compilation"): a constant argument compiles no second kernel, a kernel
compiled inside another keeps IEEE arithmetic, the time of compiles is measured, a kernel
loads from the cache without parsing its LLVM bitcode, the helper that compiles the
time loop builds its model with the spline kernels run as Python, to the same numbers,
and no kernel makes Numba compile its error message for mismatched shapes (slow).

Each check runs in a fresh process with the kernel cache off, so that what it counts is
compiled there and then."""

import os
import subprocess
import sys
import tomllib
from pathlib import Path

import jax
import numpy as np
import pytest

from beamcontact import _native, _warmup
from beamcontact.io.case import parse_case
from beamcontact.setup.start import prepare


def _python(code: str, cache: str = "") -> str:
    env = {**os.environ, "BEAMCONTACT_CACHE_DIR": cache}
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True,
                         text=True, timeout=600)
    assert out.returncode == 0, out.stderr
    return out.stdout.strip()


_KERNELS = '''
import numpy as np
from beamcontact import _native

# the hooks of _native act on kernels of this package
def ours(func):
    func.__module__ = "beamcontact.test_kernels"
    return _native.njit(func)

@ours
def scaled(x, twice):
    return 2.0 * x if twice else x

@ours
def with_constant(x):
    return scaled(x, False) + scaled(x, True)

@ours
def with_variable(x, twice):
    return scaled(x, twice)

@ours
def terms(x):
    # a sum whose value depends on the order of its terms and a product-sum that a
    # fused multiply-add would round once instead of twice
    s = 0.0
    for i in range(x.shape[0]):
        s += x[i] * x[x.shape[0] - 1 - i] + 1e-17 * i
    return s

@ours
def outer(x):
    return terms(x)

@ours
def other(x):
    return 2.0 * terms(x)
'''


# Python that lists in ``compiles`` the names of the functions compiled from then on
_COMPILED_NAMES = '''
import numba.core.event
compiles = []
class Names(numba.core.event.Listener):
    def on_start(self, ev):
        compiles.append(ev.data["dispatcher"].py_func.__name__)
    def on_end(self, ev):
        pass
numba.core.event.register("numba:compile", Names())
'''


def _kernels_module(tmp_path, extra: str = "") -> str:
    """Write the test kernels (and ``extra``) as a module of the package into tmp_path
    (Numba's cache finds a kernel's module again by name); returns the Python lines that
    import it as ``k``, with numba, numpy as np and beamcontact._native."""
    (tmp_path / "test_kernels.py").write_text(_KERNELS + extra)
    return (f"import beamcontact; beamcontact.__path__.append({str(tmp_path)!r})\n"
            "import numba, numpy as np\nimport beamcontact.test_kernels as k\n"
            "from beamcontact import _native\n")


def _counts(kernel: str) -> str:
    """Python that prints the disk-cache hits and misses of the test kernel ``kernel``."""
    return (f"print(sum(k.{kernel}.stats.cache_hits.values()), "
            f"sum(k.{kernel}.stats.cache_misses.values()), flush=True)")

def test_a_constant_argument_compiles_the_kernel_once():
    """``scaled`` called with the constants False and True and with a variable: one
    compiled version (bool), not one per constant (_native._typed_without_constants)."""
    out = _python(_KERNELS + "print(with_constant(3.0), with_variable(3.0, True), "
                  "with_variable(3.0, False), len(scaled.signatures), scaled.signatures)")
    a, b, c, count, _ = out.split(maxsplit=4)
    assert (float(a), float(b), float(c)) == (9.0, 6.0, 3.0)
    assert int(count) == 1, out


def test_a_kernel_compiled_inside_another_computes_as_python():
    """``terms`` compiled first inside ``outer`` (its library then skips LLVM's module
    passes, _native._optimise_outermost_only; ``outer``'s runs them) and then called from
    Python: both give Python's float64 result bit for bit, so no pass reordered or fused
    the arithmetic."""
    out = _python(_KERNELS + '''
rng = np.random.default_rng(3)
x = rng.standard_normal(257) * 10.0 ** rng.integers(-8, 8, 257)
before = dict(_native.MODULE_PASSES)
via_outer = outer(x)
after = _native.MODULE_PASSES
print(_native.OPTIMISE_OUTERMOST_ONLY, after["skipped"] - before["skipped"],
      after["run"] - before["run"], via_outer.hex(), terms(x).hex(), terms.py_func(x).hex())
''')
    hooked, skipped, run, via_outer, direct, python = out.split()
    assert hooked == "True"  # with the Numba this package supports, the hook is in place
    assert int(skipped) >= 1 and int(run) >= 1, out  # terms' library skipped, outer's ran
    assert via_outer == direct == python



def test_a_kernel_compiled_inside_another_has_no_machine_code_of_its_own():
    """``terms`` compiled inside ``outer`` keeps its LLVM IR alone, linked into
    ``outer``'s library (_native._inner_without_machine_code): its dispatcher holds that
    version for compiles that call it, and a call of ``terms`` from Python compiles it
    whole (a version with code) instead of jumping to a null entry point; so does a
    later compile that calls it not. Every result is Python's bit for bit."""
    out = _python(_KERNELS + _COMPILED_NAMES + '''
x = np.linspace(-3.0, 5.0, 33) ** 3
via_outer = outer(x)
linked = [lib for lib in next(iter(outer.overloads.values())).library._linking_libraries
          if getattr(lib, "without_code", False)]
held = [int(getattr(r.library, "without_code", False)) for r in terms.overloads.values()]
via_other = other(x)  # typed against the version without code: no compile of terms
direct = terms(x)
print(_native.INNER_WITHOUT_MACHINE_CODE, len(linked), held, compiles.count("terms"),
      via_outer.hex(), (0.5 * via_other).hex(), direct.hex(), terms.py_func(x).hex(),
      [int(getattr(r.library, "without_code", False)) for r in terms.overloads.values()])
''')
    hooked, linked, held, terms_compiles, via_outer, via_other, direct, python, after = \
        out.split()
    assert hooked == "True"  # with the Numba this package supports, the hook is in place
    assert int(linked) >= 1, out  # terms' library, IR alone, linked into outer's
    assert held == "[1]"  # its version without code, for compiles that call it
    assert terms_compiles == "2"  # inside outer, then whole for the call from Python
    assert after == "[0]"  # the version the Python call got has machine code
    assert via_outer == via_other == direct == python


def test_a_kernel_compiled_for_linking_is_not_called_and_has_no_machine_code():
    """``_native.compile_for_linking(terms, x)`` compiles ``terms`` for x's types as a
    callee (no module passes, no machine code), without calling it; ``outer``, compiled
    next, links that version (``terms`` is not compiled again), and a call of ``terms``
    from Python compiles it whole. Every result is Python's bit for bit."""
    out = _python(_KERNELS + _COMPILED_NAMES + '''
x = np.linspace(-1.0, 4.0, 19) ** 3
before = _native.MODULE_PASSES["skipped"]
_native.compile_for_linking(terms, x)
held = [int(getattr(r.library, "without_code", False)) for r in terms.overloads.values()]
skipped = _native.MODULE_PASSES["skipped"] - before
via_outer = outer(x)
after_outer = compiles.count("terms")
direct = terms(x)
print(held, skipped, after_outer, compiles.count("terms"), via_outer.hex(), direct.hex(),
      terms.py_func(x).hex())
''')
    held, skipped, after_outer, terms_compiles, via_outer, direct, python = out.split()
    assert held == "[1]" and int(skipped) >= 1, out  # no module passes, no machine code
    assert after_outer == "1"  # outer linked it
    assert terms_compiles == "2"  # then whole for the call from Python
    assert via_outer == direct == python

def test_a_version_without_machine_code_links_from_the_cache_and_python_compiles_whole(
        tmp_path):
    """The disk cache keeps ``terms``' IR alone when it was compiled inside ``outer``:
    another compile (``other``) links it from the cache and computes what Python does,
    and a call of ``terms`` from Python in a process that loaded that version for
    ``other`` compiles it whole rather than run it (no code to run)."""
    prelude, cache = _kernels_module(tmp_path), str(tmp_path / "cache")
    x = "np.linspace(-2.0, 7.0, 17) ** 3"
    assert _python(prelude + f"print(k.outer({x}).hex() == k.terms.py_func({x}).hex())",
                   cache) == "True"
    out = _python(prelude + f"a = k.other({x}); hits = sum(k.terms.stats.cache_hits.values())"
                  f"\nb = k.terms({x})\nprint(a.hex() == (2.0 * k.terms.py_func({x})).hex(),"
                  " hits, b.hex() == k.terms.py_func(" + x + ").hex(),"
                  " sum(k.terms.stats.cache_misses.values()))", cache)
    assert out == "True 1 True 1", out  # linked from the cache; then compiled whole


_SHAPE_ERRORS = """
import copy, sys, tempfile
from pathlib import Path
import numba.core.event
from beamcontact import _warmup, enable_x64
from beamcontact.io.case import parse_case
from beamcontact.runner import run_case

compiled = []


class Names(numba.core.event.Listener):
    def on_start(self, ev):
        func = ev.data["dispatcher"].py_func
        compiled.append(f"{func.__module__}.{func.__qualname__}")

    def on_end(self, ev):
        pass


numba.core.event.register("numba:compile", Names())
enable_x64()
for contact in ({"model": "cg", "segments_per_element": 2},
                {"model": "ipip", "pairing": "zones", "segments_per_element": 2},
                {"model": "ipip", "pairing": "points", "segments_per_element": 2}, None):
    case = copy.deepcopy(_warmup.TINY_CASE)
    case["solver"] = {"engine": "native"}
    if contact is None:  # statics: the load-stepping loop
        case["analysis"] = {"kind": "static", "load_steps": 2}
        case["loads"] = [{"beam": "a", "at": "end", "force": [0.0, -1.0]}]
    else:
        case["analysis"]["t_end"] = 3e-3
        case["contact"] = contact
    summary = run_case(parse_case(case), "", Path(tempfile.mkdtemp()) / "out")
    assert summary["status"] == "completed", summary
print(sum(name.startswith("beamcontact.") for name in compiled),
      sum("raise_with_shape_context" in name for name in compiled))
"""


@pytest.mark.slow
def test_a_second_process_compiles_no_kernel(tmp_path):
    """Every kernel of every native path (the runs of the test below) is written to the
    disk cache and loaded from there by the next process: a kernel that Numba cannot
    cache (one that asks Numba for its thread count in compiled code: "uses dynamic
    globals") would be compiled again by every run, 15 s of each peer drop. About a
    minute."""
    cache = str(tmp_path / "cache")
    counts = [int(_python(_SHAPE_ERRORS, cache).split()[0])]
    assert counts[0] > 50  # compiled here, with the cache empty
    # a later process may still compile whole for Python a kernel that an earlier one
    # compiled inside another (_native._cached_whole), or one that the helper of a cold
    # start was still writing (beamcontact/_warmup.py); an uncacheable kernel compiles
    # in every process
    while counts[-1] > 0 and len(counts) < 4:
        counts.append(int(_python(_SHAPE_ERRORS, cache).split()[0]))
    assert counts[-1] == 0, counts


@pytest.mark.slow
def test_no_kernel_compiles_the_error_message_of_mismatched_shapes():
    """An array assigned to a slice or row of another (``out[k] = values``) makes Numba
    compile its error message for mismatched shapes, about 2 s per process of a cold start
    (arrays_native.py). Runs of every native path (dynamics with each contact law,
    statics), the kernels compiled afresh: many kernels compiled, that message never.
    About a minute."""
    kernels, shape_errors = map(int, _python(_SHAPE_ERRORS).split())
    assert kernels > 50
    assert shape_errors == 0


def test_the_compile_clock_counts_compiles_only():
    """``_native.compile_seconds`` grows by the wall time of a compile (the outermost of
    a nest, counted once: ``outer`` compiles ``terms`` inside it) and not at all by a
    call of compiled code; a Stopwatch splits its wall time into the two (the summary's
    ``compile_time_s``, runner.py)."""
    out = _python(_KERNELS + '''
import time
x = np.arange(4.0)
watch = _native.Stopwatch()
t0, c0 = time.perf_counter(), _native.compile_seconds()
outer(x)
wall, spent = time.perf_counter() - t0, _native.compile_seconds() - c0
c1 = _native.compile_seconds()
for _ in range(1000):
    outer(x)
print(wall, spent, _native.compile_seconds() - c1, watch.compiles(), watch.outside_compiles(),
      time.perf_counter() - watch.wall)
''')
    wall, spent, calls, compiles, outside, total = map(float, out.split())
    assert 0.5 * wall < spent <= wall  # a compile is most of a first call
    assert calls == 0.0
    assert compiles >= spent and outside >= 0.0
    assert abs(compiles + outside - total) < 1e-3

def test_a_kernel_compiled_inside_another_is_compiled_whole_for_python(tmp_path):
    """The less optimised library of ``terms`` compiled inside ``outer`` goes to the disk
    cache marked partial (_native._cached_whole): the next compile that calls ``terms``
    (``other``) links it from there, but the next call of ``terms`` from Python compiles
    it whole (a cache miss) and caches that, which later calls load."""
    prelude, cache = _kernels_module(tmp_path), str(tmp_path / "cache")

    def run(call: str, count: str) -> str:
        """Call kernel ``call`` in a new process; the cache hits and misses of ``count``."""
        return _python(prelude + f"k.{call}(np.arange(5.0))\n" + _counts(count), cache)

    assert run("outer", "outer") == "0 1"
    assert any(p.name.startswith("partial-") for p in (tmp_path / "cache").rglob("*"))
    assert run("other", "terms") == "1 0"  # linked from the cache into other
    assert run("terms", "terms") == "0 1"  # compiled whole for Python
    assert run("terms", "terms") == "1 0"
    assert not any(p.name.startswith("partial-") for p in (tmp_path / "cache").rglob("*"))
    assert run("outer", "outer") == "1 0"


def test_a_partial_version_never_replaces_a_whole_one_in_the_cache(tmp_path):
    """Two processes of a cold start race (beamcontact/_warmup.py): one compiles ``terms``
    whole for Python and stores it; the other, which found the cache without ``terms`` a
    moment before, compiles it inside ``outer`` and stores its partial version after.
    The whole version stays (_native._cached_whole), so the next call of ``terms`` from
    Python loads it instead of compiling it whole again."""
    prelude, cache = _kernels_module(tmp_path), str(tmp_path / "cache")

    def run(code: str, count: str) -> str:
        return _python(prelude + code + "\n" + _counts(count), cache)

    assert run("k.terms(np.arange(5.0))", "terms") == "0 1"  # whole, stored
    # the late process: its look into the cache came before the whole version was there
    assert run("k.terms._cache.load_overload = lambda *a: None; k.outer(np.arange(5.0))",
               "terms") == "0 1"
    assert not any(p.name.startswith("partial-") for p in (tmp_path / "cache").rglob("*"))
    assert run("k.terms(np.arange(5.0))", "terms") == "1 0"



def test_a_kernel_claimed_by_another_process_is_waited_for_and_loaded(tmp_path):
    """A process that misses a kernel in the cache while another process holds the claim
    to compile it (beamcontact/_compile_claims.py) waits, and loads the kernel once it is
    in the cache, instead of compiling it too; a claim whose process has died claims
    nothing."""
    import shutil
    import time

    prelude, stats = _kernels_module(tmp_path), _counts("terms")
    compiled, waiting = str(tmp_path / "compiled"), str(tmp_path / "waiting")
    _python(prelude + "k.terms(np.arange(5.0))", compiled)
    claim = Path(_python(prelude + "print(_native.kernel_file(k.terms, 'compiling', "
                                   "(numba.typeof(np.arange(5.0)),)))", waiting))

    holder = subprocess.Popen(["sleep", "60"])
    try:
        claim.write_text(str(holder.pid))
        waiter = subprocess.Popen(
            [sys.executable, "-c", prelude + "print('calling', flush=True)\n"
             "k.terms(np.arange(5.0))\n" + stats],
            env={**os.environ, "BEAMCONTACT_CACHE_DIR": waiting}, stdout=subprocess.PIPE,
            text=True)
        assert waiter.stdout.readline().strip() == "calling"
        time.sleep(2.0)  # it has looked into the cache and found the claim
        assert waiter.poll() is None  # waiting
        shutil.copytree(compiled, waiting, dirs_exist_ok=True)  # the holder stored it
        claim.unlink()
        out, _ = waiter.communicate(timeout=60)
        assert waiter.returncode == 0
        assert out.strip() == "1 0"  # loaded, not compiled
    finally:
        holder.kill()
        holder.wait()

    dead = subprocess.Popen(["true"])
    dead.wait()
    fresh = str(tmp_path / "fresh")
    claim = Path(_python(prelude + "print(_native.kernel_file(k.terms, 'compiling', "
                                   "(numba.typeof(np.arange(5.0)),)))", fresh))
    claim.write_text(str(dead.pid))
    start = time.monotonic()
    assert _python(prelude + "k.terms(np.arange(5.0))\n" + stats, fresh) == "0 1"
    assert time.monotonic() - start < 30.0
    assert not claim.exists()  # released once stored


def test_a_failed_compile_releases_its_claim(tmp_path):
    """A kernel whose compile fails stores nothing, so its claim
    (beamcontact/_compile_claims.py) is released at once (``_native._FailedCompiles``),
    not only when the process ends: another process would wait for it otherwise."""
    prelude = _kernels_module(tmp_path, '''
@ours
def broken(x):
    return x + "not a number"
''')
    out = _python(
        prelude + "try:\n    k.broken(np.arange(3.0))\nexcept Exception as exc:\n"
        "    print(type(exc).__name__)\n"
        "print(sorted(p.name.split('-')[0] for p in _native._CACHE_DIR.iterdir() "
        "if p.name.startswith('compiling-')))", str(tmp_path / "cache"))
    assert out.splitlines() == ["TypingError", "[]"]


def test_a_kernel_loads_from_the_cache_without_parsing_its_bitcode(tmp_path):
    """A kernel loaded from the disk cache for a call from Python keeps the LLVM bitcode
    stored with it unparsed (_native._load_without_bitcode): the JIT knows the symbols of
    its machine code from the object file's symbol table, exactly those the bitcode
    exports; a compile that links the kernel (``other`` calls ``terms``) parses the
    bitcode then. Every result is Python's, bit for bit."""
    cache = str(tmp_path / "cache")
    prelude = _kernels_module(tmp_path) + "x = np.arange(5.0) / 3.0\n"
    _python(prelude + "k.terms(x)", cache)  # compiled whole and cached
    out = _python(prelude + '''
from llvmlite import binding
from numba.core.registry import cpu_target
loaded = k.terms(x)
library = k.terms.overloads[k.terms.signatures[0]].library
unparsed = library.bitcode_unparsed is not None
module = binding.parse_bitcode(library.bitcode_unparsed)
L = binding.Linkage
exported = {v.name for vs in (module.functions, module.global_variables) for v in vs
            if not v.is_declaration and v.linkage not in (L.internal, L.private)}
engine = cpu_target.target_context.codegen()._engine
known = all(engine.is_symbol_defined(name) for name in exported)
linked = k.other(x)
print(_native.LOAD_WITHOUT_BITCODE, sum(k.terms.stats.cache_hits.values()), unparsed,
      len(exported) > 0 and known, library.bitcode_unparsed is None, loaded.hex(),
      (0.5 * linked).hex(), k.terms.py_func(x).hex())
''', cache)
    hooked, hits, unparsed, known, parsed, loaded, linked, python = out.split()
    assert (hooked, hits, unparsed, known, parsed) == ("True", "1", "True", "True", "True")
    assert loaded == linked == python


def test_the_symbols_of_an_object_file_are_those_its_bitcode_exports():
    """_native.elf_global_symbols of a compiled library's machine code: the global and weak
    symbols, the very names its LLVM module defines without internal or private
    linkage (what Numba's own load lists from the bitcode, less the names no JIT lookup
    can resolve)."""
    import numba
    from llvmlite import binding

    from beamcontact import _native

    x = np.arange(6.0)
    # compiled here, never loaded from the disk cache (a loaded library has no object
    # code to serialise again: the test failed on every run after the first)
    kernel = numba.njit(lambda a: np.sort(a)[::-1].copy(), cache=False, **_native._OPTIONS)
    kernel(x)
    library = kernel.overloads[kernel.signatures[0]].library
    _, kind, (object_code, bitcode) = library.serialize_using_object_code()
    module = binding.parse_bitcode(bitcode)
    L = binding.Linkage
    exported = {v.name for vs in (module.functions, module.global_variables) for v in vs
                if not v.is_declaration and v.linkage not in (L.internal, L.private)}
    assert kind == "object" and len(exported) > 2
    assert _native.elf_global_symbols(object_code) == exported
    assert _native.elf_global_symbols(b"\xcf\xfa\xed\xfe" + object_code[4:]) is None

def _start(data: dict) -> tuple[list, dict]:
    """The arrays of a dynamic case's model and of its state at t = 0 (the contact set
    there, the initial acceleration), and its first energies."""
    from beamcontact.setup.start import dynamic_start

    p = prepare(parse_case(data))
    begin = dynamic_start(p)
    state = begin.state
    contact = None if p.contact is None else p.contact.elements
    leaves = jax.tree_util.tree_leaves((p.model, contact)) + [
        state.u, state.v, state.a, state.f_pot, state.load_state.theta,
        state.load_state.tangent]
    return leaves, begin.engine.energies(state, None)


def _kernels_bound_to_python() -> list[str]:
    """The names in the package's modules bound to a kernel's Python function."""
    return [f"{name}.{attr}" for name, module in list(sys.modules.items())
            if name.startswith("beamcontact.")
            for attr, value in vars(module).items() if id(value) in _native._KERNELS
            and _native._KERNELS[id(value)].py_func is value]


@pytest.mark.parametrize("case", ["tiny", "free_fall/case_cg.toml", "free_fall/case_ipip.toml",
                                  "pinned_beam_vibration/case.toml"])
def test_a_start_made_with_the_kernels_as_python_is_the_compiled_one(case):
    """The start of a run with the kernels as Python (_native.as_python: the helper's
    model, and the start of a small run while the cache lacks the loop): every array of
    the model (control points, basis functions at the quadrature and contact points) and
    of the state at t = 0 (its contact set, the initial acceleration) and the first
    energies are those of the compiled kernels, bit for bit (the helper's tiny model
    starts in contact, the bundled drops in free flight, the vibrating beam has no
    contact), and the kernels are bound again after the block."""
    from beamcontact import examples

    data = (_warmup.TINY_CASE if case == "tiny" else
            tomllib.loads(examples.path(*case.split("/")).read_text()))
    with _native.as_python():
        python, python_energies = _start(data)
        assert len(_kernels_bound_to_python()) > 100
    assert _kernels_bound_to_python() == []
    compiled, energies = _start(data)
    assert python_energies == energies
    if case == "tiny":
        assert energies["E_contact"] > 0.0  # contact at t = 0
    if case.startswith("pinned"):
        assert np.abs(np.asarray(compiled[-4])).max() > 1.0  # a0: falling under gravity
    assert len(python) == len(compiled)
    for ours, kernels in zip(python, compiled, strict=True):
        ours, kernels = np.asarray(ours), np.asarray(kernels)
        # the same values, dtype and layout (Numba compiles a kernel again for another)
        np.testing.assert_array_equal(ours, kernels)
        assert ours.dtype == kernels.dtype and ours.flags.c_contiguous == \
            kernels.flags.c_contiguous


def test_a_cold_run_of_a_small_model_makes_its_start_as_python(tmp_path, monkeypatch):
    """While the kernel cache lacks the loop, a run of a model of at most
    START_AS_PYTHON_ELEMENTS elements makes its start with the kernels as Python; a
    larger one, or one with the loop cached or without a cache, compiles them (or loads
    them)."""
    monkeypatch.setattr(_warmup, "_files", lambda: (tmp_path / "loop.ready",
                                                    tmp_path / "loop.lock"))
    limit = _warmup.START_AS_PYTHON_ELEMENTS
    assert not _warmup.start_as_python(limit + 1)
    assert _warmup.start_as_python(limit)
    (tmp_path / "loop.ready").touch()
    assert not _warmup.start_as_python(1)
    monkeypatch.setattr(_warmup, "_files", lambda: None)  # no cache, or in the helper
    assert not _warmup.start_as_python(1)


_HELD_HELPER = '''
from beamcontact import _warmup
_warmup._held_until_released()
print("on", flush=True)
'''


@pytest.mark.parametrize("how", ["released", "run ended"])
def test_a_held_helper_goes_on_when_released_or_when_its_run_ends(how):
    """The helper waits, once it has stored the attempt, for its run to let it go on (a
    byte on its input) or to end (the end of its input, also when the run is killed)."""
    env = {**os.environ, _warmup._HELD: "1"}
    helper = subprocess.Popen([sys.executable, "-c", _HELD_HELPER], env=env,
                              stdin=subprocess.PIPE, stdout=subprocess.PIPE)
    try:
        with pytest.raises(subprocess.TimeoutExpired):
            helper.wait(timeout=3.0)  # held (the import takes well under that)
        if how == "released":
            helper.stdin.write(b"r")
            helper.stdin.flush()
        else:
            helper.stdin.close()
        assert helper.wait(timeout=60) == 0
        assert helper.stdout.read() == b"on\n"
    finally:
        helper.kill()
        helper.wait()


def test_a_run_releases_its_helper_when_its_remaining_steps_look_long(monkeypatch):
    """A run holds its helper while its steps made meanwhile leave at most
    RELEASE_AFTER_S to go at their rate, judged after RELEASE_LOOK_S of them, and lets
    it go on (once) when they leave more."""
    helper = subprocess.Popen([sys.executable, "-c", "import sys; sys.stdin.buffer.read(1)"],
                              stdin=subprocess.PIPE)
    monkeypatch.setattr(_warmup, "_helper", helper)
    try:
        look, after = _warmup.RELEASE_LOOK_S, _warmup.RELEASE_AFTER_S
        _warmup.release_if_long(0.5 * look, 1e-6)  # too early to judge
        # 2 look seconds for a tenth of the run: 18 look seconds to go
        _warmup.release_if_long(2 * look, 0.1 if 18 * look <= after else 0.99)
        assert _warmup.holding() and helper.poll() is None
        _warmup.release_if_long(2 * look, 2 * look / (2 * look + 1.01 * after))
        assert not _warmup.holding()
        assert helper.wait(timeout=60) == 0
        _warmup.release_if_long(2 * look, 1e-6)  # released once; nothing more to do
        _warmup.release()
    finally:
        helper.kill()
        helper.wait()
