"""The one place that imports Numba: the ``njit`` of the native CPU kernels.

The kernels compile in seconds, so their machine code is kept on disk. Numba's default
place for it is a ``__pycache__`` beside the source, which fails or clashes in a read-only
or shared install; it goes instead to a ``numba`` folder in the cache folder of
:mod:`beamcontact._cache` (``<cache>/numba/<hash of the kernel sources>``, see
:func:`_source_hash`), beside JAX's compiled programs, and nowhere when that cache
is switched off (``BEAMCONTACT_CACHE_DIR=""``) or cannot be created; the folders of
other source versions unused for 30 days are removed. Numba's cache locator
reads ``numba.config.CACHE_DIR`` once, when a function is decorated, so the folder is set
just for our decorations and the setting of other Numba users in the process is restored.

Options: float64 IEEE arithmetic as written (no fastmath: the kernels are checked against
JAX to 1e-12), NumPy's error model (x / 0 gives inf or nan as in JAX, no exception), and
the GIL released so that threads can run kernels side by side.

Importing this module imports neither JAX nor matplotlib.
"""

import contextlib
import hashlib
import importlib
import os
import shutil
import struct
import sys
import time
from pathlib import Path

import numba
import numba.core.dispatcher
import numba.core.event
import numba.extending

from beamcontact import _compile_claims
from beamcontact._cache import cache_dir
from beamcontact.cores import usable_cores

_OPTIONS = {"fastmath": False, "error_model": "numpy", "nogil": True}


# modules without "native" in their name whose functions compiled kernels inline
# (:func:`jitable`): the step controller and the report layout it reads
_COMPILED_ELSEWHERE = ("dynamics/control.py", "dynamics/report.py")


def _kernel_modules() -> list[Path]:
    """The package's modules of native kernels (``*native*.py``), in a fixed order."""
    return sorted(Path(__file__).parent.rglob("*native*.py"))


def _source_hash() -> str:
    """A hash of every native kernel's source. Numba's cache checks the timestamp of the
    file that holds a function, not of the files whose functions it calls, so a kernel
    that calls an edited law in another module would run the old law; a folder per
    version of the sources cannot."""
    package = Path(__file__).parent
    digest = hashlib.sha256()
    paths = {*_kernel_modules(), *(package / p for p in _COMPILED_ELSEWHERE)}
    for path in sorted(paths):
        digest.update(path.relative_to(package).as_posix().encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()[:16]


# a folder of compiled kernels that no version of the sources used for this long is removed
# (each upgrade or edit of the kernels starts a new folder of about 10 MB)
STALE_AFTER_S = 30 * 24 * 3600.0


def _numba_cache_dir() -> Path | None:
    """``numba/<hash of the kernel sources>`` inside the cache folder, created and marked
    as used now; the folders of other versions unused for ``STALE_AFTER_S`` are removed.
    None when off or not creatable."""
    base = cache_dir()
    if base is None:
        return None
    path = base / "numba" / _source_hash()
    try:
        path.mkdir(parents=True, exist_ok=True)
        os.utime(path)
    except OSError:
        return None
    _remove_stale(path)
    return path


def _remove_stale(current: Path) -> None:
    """Remove the sibling folders of ``current`` not used for ``STALE_AFTER_S`` (best
    effort: another process may be removing or using them)."""
    now = time.time()
    try:
        siblings = [p for p in current.parent.iterdir() if p.is_dir() and p != current]
    except OSError:
        return
    for folder in siblings:
        try:
            stale = now - folder.stat().st_mtime > STALE_AFTER_S
        except OSError:
            continue
        if stale:
            shutil.rmtree(folder, ignore_errors=True)


class _CompileClock(numba.core.event.Listener):
    """Times the outermost compile of each nest of Numba's compile events (a kernel's
    callees compile inside it). Loading compiled kernels from the disk cache is not a
    compile."""

    def __init__(self) -> None:
        self.total, self.depth, self.since = 0.0, 0, 0.0

    def on_start(self, ev) -> None:
        if self.depth == 0:
            self.since = time.perf_counter()
        self.depth += 1

    def on_end(self, ev) -> None:
        self.depth -= 1
        if self.depth == 0:
            self.total += time.perf_counter() - self.since


_CLOCK = _CompileClock()
numba.core.event.register("numba:compile", _CLOCK)


def compile_seconds() -> float:
    """The wall seconds this process has spent in Numba's compiles so far (one in
    progress included)."""
    running = time.perf_counter() - _CLOCK.since if _CLOCK.depth else 0.0
    return _CLOCK.total + running


class Stopwatch:
    """Wall seconds since it was made, and how many of them went to Numba's compiles
    (:func:`compile_seconds`): a run's compile time is its compiles plus what its first
    attempt spent outside them (the JAX engine tracing and compiling with XLA, the native
    engine waiting for the helper that compiles its loop)."""

    def __init__(self) -> None:
        self.wall, self.compiled = time.perf_counter(), compile_seconds()

    def compiles(self) -> float:
        """Seconds of Numba's compiles since the start."""
        return compile_seconds() - self.compiled

    def outside_compiles(self) -> float:
        """Wall seconds since the start, less those of Numba's compiles."""
        return time.perf_counter() - self.wall - self.compiles()


_CACHE_DIR = _numba_cache_dir()


def jitable(func):
    """``func`` unchanged for Python callers, and compiled into any :func:`njit` kernel
    that calls it (``numba.extending.register_jitable``): one function for a host loop
    and a compiled one. Its module must be listed in ``_COMPILED_ELSEWHERE`` so that the
    cache of the kernels that inline it follows its edits."""
    return numba.extending.register_jitable(func)


def njit_parallel(func):
    """:func:`njit` with ``parallel=True``: its ``numba.prange`` loops run on the cores
    (``NUMBA_NUM_THREADS``, or :func:`single_thread`). Used only where every iteration
    writes its own outputs, so that results do not depend on the number of threads.

    Numba starts its pool of threads when it compiles a parallel kernel or when Python
    calls one; a kernel loaded from the cache and called from another compiled function
    would find no pool (a segmentation fault, seen with the statics' Newton solve), so the
    pool is started here, with the first parallel kernel."""
    numba.get_num_threads()  # starts the pool (once)
    return _compiled(func, parallel=True)


def njit_parallel_uncounted(func):
    """:func:`njit_parallel` for a loop over elements that allocates nothing and keeps no
    array beyond the call: compiled without reference counting (Numba's ``_nrt=False``),
    so that the views it takes of its arguments per element (``dR[e]``, ``r_out[e]``, ...)
    cost no atomic increments and decrements of their parents' counts. Its caller holds
    every array it is given for the whole call, so no view outlives its parent (and, as
    for :func:`njit_uncounted`, it calls no kernel that returns a new array). For the
    element loop of the HHT residual (the peer drops' step loop 2-4 % shorter, session
    24) and the contact blocks' runs; the arithmetic is the same, bit for bit."""
    numba.get_num_threads()  # starts the pool (once)
    return _compiled(func, parallel=True, _nrt=False)


# the most threads the parallel kernels of this process may use (NUMBA_NUM_THREADS, or 1
# after single_thread)
_most_threads = numba.config.NUMBA_NUM_THREADS


def most_threads() -> int:
    """The most threads the parallel kernels of this process may use
    (``NUMBA_NUM_THREADS``, or 1 after :func:`single_thread`)."""
    return _most_threads


def single_thread() -> None:
    """Run the parallel kernels of this process on one thread (a sweep's worker: the
    cores are shared out between workers already)."""
    global _most_threads
    _most_threads = 1
    numba.set_num_threads(1)


# depth of the blocks of one_thread entered (the start of a run, on its main thread)
_serial = 0


def set_threads(count: int | None) -> None:
    """Run the parallel kernels on ``count`` threads from now on (None: the most this
    process may use, :func:`single_thread` or ``NUMBA_NUM_THREADS``); one within
    :func:`one_thread`."""
    most = 1 if _serial else _most_threads
    numba.set_num_threads(most if count is None else min(count, most))


@contextlib.contextmanager
def one_thread():
    """The parallel kernels on one thread within the block, then on the most again.

    For the start of a run (the model, the contact set at t = 0, the initial
    acceleration): a few calls of the kernels, as fast on one thread as on two (0.12 s
    for the stiff drop of benchmarks/peers.py either way), and never stalled by another
    process that keeps a core busy meanwhile, such as the figures' drawer importing
    matplotlib (:mod:`beamcontact.drawer`; beside it the start on two threads took
    0.25 s). :func:`set_threads` within the block keeps one thread."""
    global _serial
    _serial += 1
    numba.set_num_threads(1)
    try:
        yield
    finally:
        _serial -= 1
        set_threads(None)


def _cpu_sample() -> tuple[float, float, float] | None:
    """(wall clock, CPU seconds spent by all processes on the cores this process may use,
    CPU seconds of this process), or None where /proc/stat cannot be read."""
    try:
        allowed = {f"cpu{c}" for c in os.sched_getaffinity(0)}
        with open("/proc/stat") as f:
            lines = [line.split() for line in f if line.startswith("cpu")]
    except (OSError, AttributeError):
        return None
    tick = os.sysconf("SC_CLK_TCK")
    busy = 0
    for fields in lines:
        if fields[0] in allowed:
            # user nice system idle iowait irq softirq steal (guest time is in user)
            values = [int(v) for v in fields[1:9]]
            busy += sum(values) - values[3] - values[4]
    return time.monotonic(), busy / tick, time.process_time()


class CoreShare:
    """The threads of the parallel kernels follow the cores that other processes leave
    free, re-read whenever :meth:`update` is called at least ``window`` seconds after the
    last reading (the native time loop calls it each time it returns to Python).

    Numba's OpenMP threads spin at the end of each parallel loop, waiting for the others.
    When another process keeps a core busy, a thread of ours waits for a time slice on
    the core left, and each of the thousands of parallel loops of a run costs a slice:
    the bundled drop to 0.9 s took 23-54 s on two threads beside one busy process, 2.5 s
    on one thread (0.8 s on an idle machine; benchmarks/README.md, session 15). So the
    count is the cores this process may use, less those other processes kept busy since
    the last reading (rounded), at least 1 and at most the count the process started
    with (``NUMBA_NUM_THREADS``, or 1 in a sweep's worker). The results do not depend on
    the count (:func:`njit_parallel`). Without /proc/stat the count stays.

    Until the first reading the count is one: the command line's run reaches its loop
    while the drawer it started imports matplotlib on the other core (beamcontact/
    drawer.py), and two threads beside it made the stiff IPIP drop's loop 0.32-0.34 s
    instead of 0.14 s without a drawer (benchmarks/README.md, session 30); one window
    on one thread costs little where the cores are free."""

    def __init__(self, window: float = 0.25, sample=_cpu_sample):
        self.most = _most_threads
        self.cores = usable_cores()
        self.window, self._sample = window, sample
        self._last = sample() if self.most > 1 else None
        # one thread until the first reading (none to make: the count stays)
        self.probing = self._last is not None
        self.threads = 1 if self.probing else self.most
        numba.set_num_threads(self.threads)

    def update(self) -> int:
        """Set and return the thread count for the next parallel loops."""
        if self._last is None:
            numba.set_num_threads(self.threads)
            return self.threads
        now = self._sample()
        if now is None or now[0] - self._last[0] < self.window:
            return self.threads
        wall = now[0] - self._last[0]
        others = max(0.0, (now[1] - self._last[1]) - (now[2] - self._last[2])) / wall
        self._last = now
        self.probing = False
        self.threads = max(1, min(self.most, int(self.cores - others + 0.5)))
        numba.set_num_threads(self.threads)
        return self.threads


prange = numba.prange


# libraries of this process whose module passes ran, and those that skipped them
# (:func:`_optimise_outermost_only`)
MODULE_PASSES = {"run": 0, "skipped": 0}
# per compile in progress, innermost last: is the function compiled ours?
_COMPILING: list[bool] = []


def _optimise_outermost_only() -> bool:
    """Run LLVM's module optimisation only on the code of a compile that Python asked for,
    not again on each kernel that it compiles on the way (docs/engines.md,
    "Compilation"). Returns whether the hook is in place.

    Numba compiles a kernel's callees first, each into a library of its own that it
    optimises whole, then links them into the caller's library and optimises that whole
    again, so a kernel five calls deep is optimised five times: with empty caches, the
    bundled benchmark compiled 85 s on one core, 59 s without the repeats (session 22,
    benchmarks/README.md). Only the outermost library's code runs when the caller is
    compiled code (the callees are linked into it and optimised there, with everything
    inlined), so the libraries made while one of our kernels is compiled inside another
    compile (the kernel's own, and Numba's pieces of it: parallel loops, inlined
    subroutines) keep Numba's per-function passes and skip the module passes. Such a
    library is marked, and so is its entry in the disk cache (:func:`_cached_whole`):
    another compile links it from there, but a later process that calls the kernel from
    Python compiles it whole instead. In the process that compiled it, a Python call of
    that kernel runs the less optimised code. The arithmetic is unchanged, float for
    float: no fast-math, and LLVM keeps IEEE semantics at every level, so the results
    are the same bit for bit (tests/test_native_compile.py; the histories, as before).
    Kernels of other packages compiled outside ours are left as Numba makes them.
    Without the Numba internals this relies on (``numba.core.event``'s compile events,
    ``CPUCodeLibrary._optimize_final_module``), nothing changes."""
    try:
        from numba.core import codegen, event
        library_class = codegen.CPUCodeLibrary
        optimise = library_class._optimize_final_module
    except (ImportError, AttributeError):
        return False

    class _Compiles(event.Listener):
        def on_start(self, ev):
            dispatcher = ev.data.get("dispatcher")
            module = getattr(getattr(dispatcher, "py_func", None), "__module__", "") or ""
            _COMPILING.append(module.startswith("beamcontact."))

        def on_end(self, ev):
            if _COMPILING:
                _COMPILING.pop()

    def optimise_outermost(library):
        if len(_COMPILING) > 1 and _COMPILING[-1]:
            library.module_passes_skipped = True
            MODULE_PASSES["skipped"] += 1
            return
        MODULE_PASSES["run"] += 1
        optimise(library)

    event.register("numba:compile", _Compiles())
    library_class._optimize_final_module = optimise_outermost
    return True


OPTIMISE_OUTERMOST_ONLY = _optimise_outermost_only()


def _mark_without_code(library) -> None:
    """Mark ``library`` finalised without machine code (its IR alone, for linking:
    :func:`_inner_without_machine_code`)."""
    library.without_code = True
    library._finalized = True


def _inner_without_machine_code() -> bool:
    """Generate no machine code for a library whose module passes were skipped
    (:func:`_optimise_outermost_only`): a kernel compiled inside another compile, whose
    code only the outermost library runs (its LLVM IR linked into that library,
    optimised and compiled there). Returns whether the hooks are in place.

    Numba turns every library it finalises into machine code (MCJIT), also a callee's
    that nothing calls: in a cold start of the bundled benchmark that was 3.7 s of the
    run's compile and 3.2 s of its helper's (session 36, benchmarks/README.md). Such a
    library now keeps its IR alone and is marked ``without_code``; its entry point is a
    null pointer that nothing may call. So:

    - the dispatcher keeps such a version for the compiles that call the kernel (they
      are typed against it and link its IR) but not in its table for calls from Python:
      a call from Python outside a compile drops it and compiles the kernel whole (or
      loads a whole version from the cache);
    - the disk cache stores its IR with an empty object file (as a partial version,
      :func:`_cached_whole`); loaded, it is again a library without code, which only a
      compile that links it uses;
    - its environment (Numba's ``NumbaEnv`` global) is not set: as in a kernel loaded
      from the cache, only the outermost library's is.

    The machine code that runs is the outermost library's, and every result is the same
    bit for bit (IEEE arithmetic at every level; tests/test_native_compile.py). The code
    is not the same bytes, though: code generation rewrites a library's IR in place
    (LLVM's CodeGenPrepare and its neighbours), and the callers used to link that
    rewritten IR; the loop now takes 1.5-4 % longer warm (session 36). Without the Numba
    internals this relies on, nothing changes."""
    try:
        from numba.core import codegen
        from numba.core.compiler_lock import global_compiler_lock
        from numba.core.dispatcher import Dispatcher, _DispatcherBase
        from numba.core.sigutils import normalize_signature
        library_class = codegen.CPUCodeLibrary
        finalize = library_class._finalize_final_module
        serialize = library_class.serialize_using_object_code
        set_env = codegen.JITCPUCodegen.set_env
        add_overload = _DispatcherBase.add_overload
        compile_signature = Dispatcher.compile
        library_class._finalize_dynamic_globals  # noqa: B018
        library_class._verify_declare_only_symbols  # noqa: B018
    except (ImportError, AttributeError):
        return False

    def finalize_without_code(library):
        if not getattr(library, "module_passes_skipped", False):
            finalize(library)
            return
        library._finalize_dynamic_globals()
        library._verify_declare_only_symbols()
        _mark_without_code(library)

    def serialize_ir_alone(library):
        if getattr(library, "without_code", False):
            return (library.name, "object",
                    (b"", library._get_module_for_linking().as_bitcode()))
        return serialize(library)

    def set_env_where_defined(codegen_self, env_name, env):
        if codegen_self._engine.get_global_value_address(env_name):
            set_env(codegen_self, env_name, env)

    def add_overload_for_compiles(dispatcher, result):
        if getattr(result.library, "without_code", False):
            dispatcher.overloads[tuple(result.signature.args)] = result
        else:
            add_overload(dispatcher, result)

    def compile_with_code(dispatcher, sig):
        with global_compiler_lock:  # _COMPILING is read under the lock compiles hold
            if not _COMPILING:
                args = tuple(normalize_signature(sig)[0])
                found = dispatcher.overloads.get(args)
                if found is not None and getattr(found.library, "without_code", False):
                    del dispatcher.overloads[args]
            return compile_signature(dispatcher, sig)

    library_class._finalize_final_module = finalize_without_code
    library_class.serialize_using_object_code = serialize_ir_alone
    codegen.JITCPUCodegen.set_env = set_env_where_defined
    _DispatcherBase.add_overload = add_overload_for_compiles
    Dispatcher.compile = compile_with_code
    return True


def compile_for_linking(kernel, *args) -> None:
    """Compile ``kernel`` for the types of ``args`` as a compile inside another compiles
    it (LLVM's module passes skipped, no machine code: :func:`_optimise_outermost_only`,
    :func:`_inner_without_machine_code`), without calling it: for a process that
    compiles a kernel only so that a later compile, its own or another process's
    through the disk cache, links it (beamcontact/_warmup.py). A call from Python later
    compiles the kernel whole."""
    signature = tuple(kernel.typeof_pyval(a) for a in args)
    _COMPILING.append(True)  # as if inside a compile of ours
    try:
        kernel.compile(signature)
    finally:
        _COMPILING.pop()


def elf_global_symbols(object_code: bytes) -> set[str] | None:
    """The names of the global and weak symbols that a little-endian ELF64 object file
    defines (those a JIT can resolve), from its symbol table; None for any other file."""
    if object_code[:6] != b"\x7fELF\x02\x01":
        return None
    shoff, = struct.unpack_from("<Q", object_code, 0x28)
    entsize, count = struct.unpack_from("<HH", object_code, 0x3A)
    names: set[str] = set()
    for i in range(count):
        kind, = struct.unpack_from("<I", object_code, shoff + i * entsize + 4)
        if kind != 2:  # SHT_SYMTAB
            continue
        offset, size, link = struct.unpack_from("<QQI", object_code, shoff + i * entsize + 24)
        strtab, = struct.unpack_from("<Q", object_code, shoff + link * entsize + 24)
        for k in range(offset, offset + size, 24):  # Elf64_Sym
            name, info, _, section = struct.unpack_from("<IBBH", object_code, k)
            if name and section != 0 and info >> 4 in (1, 2):  # defined, GLOBAL or WEAK
                end = object_code.index(b"\0", strtab + name)
                names.add(object_code[strtab + name:end].decode())
    return names


def _load_without_bitcode() -> bool:
    """Load a compiled kernel from the disk cache without parsing the LLVM bitcode kept
    beside its machine code until a compile links it in. Returns whether the hook is in
    place.

    Numba's cache keeps, with a kernel's machine code, its LLVM bitcode (for a later
    compile that links it in) and parses it on every load, to list the symbols the
    machine code defines: 0.13 s of a warm run of the peer drop (3.6 MB of bitcode for
    its 11 entry points), and 0.10 s more to list them (session 23). A run that compiles
    nothing never links them. The symbols come instead from the machine code's own
    symbol table (:func:`elf_global_symbols`: the global and weak ones, which the JIT
    resolves), and the bitcode is parsed when a compile asks for it
    (``_get_module_for_linking``). An object file that is not ELF loads as before."""
    try:
        from llvmlite import binding
        from numba.core import codegen
        library_class = codegen.CPUCodeLibrary
        unserialize = library_class._unserialize.__func__
        for_linking = library_class._get_module_for_linking
    except (ImportError, AttributeError):
        return False

    def unserialize_lazily(cls, jit, state):
        name, kind, data = state
        if kind == "object" and data[0] == b"":  # IR alone (_inner_without_machine_code)
            library = jit.create_library(name)
            library.bitcode_unparsed = data[1]
            _mark_without_code(library)
            return library
        names = elf_global_symbols(data[0]) if kind == "object" else None
        if names is None:
            return unserialize(cls, jit, state)
        library = jit.create_library(name)
        library.enable_object_caching()
        library._set_compiled_object(data[0])
        library.bitcode_unparsed = data[1]
        library._finalize_final_module()
        jit._engine._defined_symbols |= names
        return library

    def module_for_linking(library):
        bitcode = getattr(library, "bitcode_unparsed", None)
        if bitcode is not None:
            library._shared_module = binding.parse_bitcode(bitcode)
            library.bitcode_unparsed = None
        return for_linking(library)

    library_class._unserialize = classmethod(unserialize_lazily)
    library_class._get_module_for_linking = module_for_linking
    return True


LOAD_WITHOUT_BITCODE = _load_without_bitcode()
# (a library without code loads only through the hook above)
INNER_WITHOUT_MACHINE_CODE = (OPTIMISE_OUTERMOST_ONLY and LOAD_WITHOUT_BITCODE
                              and _inner_without_machine_code())


def _load_without_refresh(cache):
    """``cache.load_overload`` without the refresh of Numba's compiler context that it
    starts with (``BaseContext.refresh``): what a loaded kernel needs to run is the
    runtime's functions (``rtsys.initialize``) and the symbols that importing
    ``numba.cpython.hashing`` defines; the refresh imports and registers the typing and
    lowering of all of Numba (and scipy.linalg with it), which only a compile needs, and
    a compile refreshes the context itself. The refresh took 0.26 s in a fresh process,
    imports included that a run also makes elsewhere (session 27). Without the Numba
    internals this relies on, Numba's load."""
    try:
        from numba.core.runtime import rtsys
        load = cache._load_overload
        guard = cache._guard_against_spurious_io_errors
    except (ImportError, AttributeError):
        return cache.load_overload

    def load_unrefreshed(signature, target_context):
        rtsys.initialize(target_context)
        import numba.cpython.hashing  # noqa: F401
        with guard():
            return load(signature, target_context)

    return load_unrefreshed


def _typed_without_constants(dispatcher):
    """``dispatcher``, compiled for the types of the values that compiled callers pass,
    never for the constants themselves.

    Numba compiles a kernel that compiled code calls for the argument types at the call,
    and a constant argument (``False``, ``0``, ``-1``) has a type of its own per value:
    a kernel called with ``tangent=False`` in one place and a variable in another was
    compiled twice, and with it every kernel it passes the constant on to (session 22:
    15 such second compiles in the bundled benchmark, about 7 s of its compile). So the
    call is typed with the constants' plain types (``types.unliteral``); Numba converts
    a constant to its plain type at the call. No kernel of ours dispatches on the value
    of a constant (``numba.literally``)."""
    from numba.core import types

    typed = dispatcher.get_call_template

    def get_call_template(args, kws):
        return typed(tuple(types.unliteral(a) for a in args),
                     {k: types.unliteral(v) for k, v in kws.items()})

    dispatcher.get_call_template = get_call_template
    return dispatcher


def _cached_whole(dispatcher):
    """``dispatcher``, whose compiled versions that skipped LLVM's module passes
    (:func:`_optimise_outermost_only`) are loaded from the disk cache only into another
    compile, never for a call from Python.

    Such a version is written to the cache as any other (its LLVM IR alone, no machine
    code: :func:`_inner_without_machine_code`), and a file
    ``partial-<key>`` beside it says that it is partial; a version compiled whole for
    the same signature replaces it and removes the file. A call from Python (no compile in
    progress) that would load a partial version compiles the kernel whole instead (and
    caches that); a compile that links the kernel loads it, since it optimises what it
    links. So the two processes of a cold start (beamcontact/_warmup.py) share every
    kernel through the cache, and a later Python call runs optimised code.

    A partial version never replaces a whole one: in a cold start the run compiled
    ``contact_energy`` whole for Python while the helper, which had looked in the cache
    a moment before, compiled it inside the attempt and stored its partial version after
    the run's, so the next run compiled it whole again (1.05 s of its 7.5 s; session
    27). And a kernel missing from the cache is compiled by one process at a time
    (beamcontact/_compile_claims.py): another process that misses it meanwhile waits
    and loads it."""
    cache = getattr(dispatcher, "_cache", None)
    save = getattr(cache, "save_overload", None)
    load = getattr(cache, "load_overload", None)
    if save is None or load is None:
        return dispatcher

    def partial_file(signature) -> Path:
        return kernel_file(dispatcher, "partial", signature)

    def holds_whole(signature, result) -> bool:
        try:
            key = cache._index_key(signature, result.codegen)
            held = key in cache._cache_file._load_index()
        except (AttributeError, OSError, EOFError, ValueError):
            return False  # Numba's internals changed: save as Numba would
        return held and not partial_file(signature).exists()

    def save_marked(signature, result):
        try:
            library = getattr(result, "library", None)
            partial = getattr(library, "module_passes_skipped", False)
            if partial and holds_whole(signature, result):
                return
            save(signature, result)
            with contextlib.suppress(OSError):
                if partial:
                    partial_file(signature).touch()
                else:
                    partial_file(signature).unlink(missing_ok=True)
        finally:
            claim = kernel_file(dispatcher, "compiling", signature)
            _compile_claims.release(claim)
            claims = _CLAIMED.get(id(dispatcher), [])
            if claim in claims:
                claims.remove(claim)

    load_unrefreshed = _load_without_refresh(cache)

    def load_whole_for_python(signature, target_context):
        if not _COMPILING and partial_file(signature).exists():
            return None  # a call from Python: compile it whole
        found = load_unrefreshed(signature, target_context)
        if found is not None and not _COMPILING and getattr(found.library, "without_code",
                                                            False):
            return None  # no machine code to call (its partial mark was lost)
        return found

    def load_or_claim(signature, target_context):
        found = load_whole_for_python(signature, target_context)
        if found is not None:
            return found
        claim = kernel_file(dispatcher, "compiling", signature)
        inside = bool(_COMPILING)  # this compile will be a partial version
        if not _compile_claims.take(claim, partial=inside):
            if not inside and _compile_claims.held_for_partial(claim):
                return None  # another's partial version would not do: compile it whole
            _compile_claims.wait(claim)  # another process compiles it
            found = load_whole_for_python(signature, target_context)
            if found is not None or not _compile_claims.take(claim, partial=inside):
                return found
        # stored by another process between the look above and the claim?
        found = load_whole_for_python(signature, target_context)
        if found is not None:
            _compile_claims.release(claim)
            return found
        _CLAIMED.setdefault(id(dispatcher), []).append(claim)
        return None

    cache.save_overload = save_marked
    cache.load_overload = load_or_claim
    return dispatcher


# the claims of each dispatcher's compiles in progress (_compile_claims), by its id,
# innermost last
_CLAIMED: dict[int, list[Path]] = {}


class _FailedCompiles(numba.core.event.Listener):
    """Releases the claim of a compile that failed (it stores nothing), so that another
    process waits no longer; a stored kernel releases its claim in ``save_marked``."""

    def on_start(self, ev):
        pass

    def on_end(self, ev):
        claims = _CLAIMED.get(id(ev.data.get("dispatcher")))
        # the exception the compile ended with (Numba 0.68's Event.is_failed tests the
        # opposite, and its compile events always carry a 3-tuple)
        details = getattr(ev, "_exc_details", None)
        if claims and details is not None and details[0] is not None:
            _compile_claims.release(claims.pop())


numba.core.event.register("numba:compile", _FailedCompiles())


def kernel_file(dispatcher, prefix: str, signature) -> Path:
    """``<prefix>-<key>`` in the kernel cache folder, the key naming the kernel of
    ``dispatcher`` compiled for ``signature`` (the argument types, as Numba's cache gets
    them): ``partial-`` marks a partial version (:func:`_cached_whole`), ``compiling-``
    a process's claim to compile it (beamcontact/_compile_claims.py)."""
    func = dispatcher.py_func
    # the source file too: two installs sharing the cache folder have caches of their own
    name = f"{func.__code__.co_filename}:{func.__module__}.{func.__qualname__}"
    key = hashlib.sha256(f"{name}{signature}".encode()).hexdigest()[:24]
    return _CACHE_DIR / f"{prefix}-{key}"


def _compiled(func, **options):
    """``numba.njit(func, **options)`` with the project's options and its on-disk cache
    (compiled anew each process when the cache is off), compiled for plain argument
    types (:func:`_typed_without_constants`), loaded for Python only when compiled whole
    (:func:`_cached_whole`)."""
    if _CACHE_DIR is None:
        return _typed_without_constants(numba.njit(func, cache=False, **options,
                                                   **_OPTIONS))
    saved = numba.config.CACHE_DIR
    numba.config.CACHE_DIR = str(_CACHE_DIR)
    try:
        return _cached_whole(_typed_without_constants(
            numba.njit(func, cache=True, **options, **_OPTIONS)))
    finally:
        numba.config.CACHE_DIR = saved


def njit(func):
    """``numba.njit(func, cache=True, fastmath=False, error_model="numpy", nogil=True)``
    with the on-disk cache in the project's folder (compiled anew each process when the
    cache is off)."""
    return _compiled(func)


def njit_uncounted(func):
    """:func:`njit` for a kernel that allocates nothing and keeps no array beyond the
    call (the linear solver's factorisations, a contact block with its work arrays):
    compiled without reference counting (Numba's ``_nrt=False``), so that its views
    (``band[j]``, ``W[i]``, a row of its work arrays) cost no atomic increments and
    decrements; its callers hold every array it is given. Numba refuses to compile an
    allocation in such a kernel or in the helpers inlined into it ("NRT required but not
    enabled"), but not a call of a counted kernel that returns a new array: that array
    would never be freed, so such a kernel calls only kernels that return numbers. The
    arithmetic is the same, bit for bit."""
    return _compiled(func, _nrt=False)


# the package's kernels by the id of the Python function each is compiled from, and the
# depth of the as_python blocks entered
_KERNELS: dict[int, numba.core.dispatcher.Dispatcher] = {}
_as_python_depth = 0


def _kernels_as_python(python: bool) -> None:
    """Every name in the package's modules that is bound to one of its kernels bound to
    the kernel's Python function (``python``), or back. The kernels' modules are
    imported first: one imported later would bind the Python functions of the kernels it
    imports, and its own kernels would compile with them (and fail)."""
    if python:
        package = Path(__file__).parent
        for path in _kernel_modules():
            parts = path.relative_to(package).with_suffix("").parts
            importlib.import_module(".".join((__package__, *parts)))
    for name, module in list(sys.modules.items()):
        if not name.startswith("beamcontact."):
            continue
        for attr, value in list(vars(module).items()):
            if python:
                if (isinstance(value, numba.core.dispatcher.Dispatcher)
                        and value.py_func.__module__.startswith("beamcontact.")):
                    _KERNELS[id(value.py_func)] = value
                    setattr(module, attr, value.py_func)
            elif id(value) in _KERNELS and _KERNELS[id(value)].py_func is value:
                setattr(module, attr, _KERNELS[id(value)])


@contextlib.contextmanager
def as_python(active: bool = True):
    """Within the block (if ``active``), the package's kernels run as the Python
    functions they are compiled from: every name in its modules bound to a kernel is
    bound to the kernel's Python function, also in a module imported within the block,
    and bound back after it.

    For the start of a small run while the kernel cache is empty
    (beamcontact/_warmup.py, :func:`~beamcontact._warmup.start_as_python`): the
    splines of its model, its contact set at t = 0, its initial acceleration and first
    energies, called once, take 0.35-0.75 s as Python for the bundled benchmark, against
    about 20 s of compile on its way to the steps (session 29). The numbers are those
    of the kernels bit for bit (no fast-math; tests/test_native_compile.py). Names bound
    in other ways (a kernel in a tuple) call the kernel, which is slower to start but
    the same. Not for threads that call kernels meanwhile."""
    global _as_python_depth
    if not active:
        yield
        return
    _as_python_depth += 1
    if _as_python_depth == 1:
        _kernels_as_python(True)
    try:
        yield
    finally:
        _as_python_depth -= 1
        if _as_python_depth == 0:
            _kernels_as_python(False)


def njit_inline(func):
    """:func:`njit` with ``inline="always"``, for the small helpers of the element
    kernels: Numba copies the function into each compiled caller, so no call passes
    arrays. A call to a compiled function passes every array as a structure and counts
    references on it; for the element kernels of the beam that was 20-35 % of their time
    (session 18: strain 1.04 -> 0.83 us an element, inertia 0.80 -> 0.67 us, the peer drop's
    whole process 6 % shorter). Inlining changes no arithmetic: the results are the same
    bit for bit."""
    return _compiled(func, inline="always")
