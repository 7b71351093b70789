"""Compiling the native time loop in a helper process while a run with empty caches
compiles the rest (docs/engines.md, "Compilation").

With empty caches the native kernels take about 50 s to compile on one core (session 22).
The compiled time loop (:func:`beamcontact.dynamics.native_loop.run`) and its kernels are
a run's largest part, and a run needs them only after its start (the contact set at
t = 0, the initial acceleration, the first energies and checks). The loop's signature is
the same for every model, so a helper process compiles it on a tiny model of its own,
into the shared cache, while the run compiles its start on the other core; the run then
waits for the helper and loads the loop from the cache. The run starts the helper before
it builds its model (:func:`beamcontact.setup.start.compile_loop_early`), and the helper
builds its model with the kernels as Python (:func:`beamcontact._native.as_python`), so
that it does not wait for the spline kernels; a run of a small model makes its whole
start so (:func:`start_as_python`), and the helper compiles the start's kernels once it
has stored the loop. The two share kernels: the
helper compiles the loop's kernels one by one first (:func:`_kernel_calls`), in an order
that goes ahead of the start, and the run, its start done, compiles some of them
(:func:`help_while_waiting`), so that each loads from the cache what the other has
compiled. Once the helper has stored the attempt, a run makes its steps without the
loop until the loop is ready (:func:`steps_meanwhile`; dynamics/driver.py,
``_compiled_loop``), so a short run may end before its helper, which then finishes in
the background. The run that started the helper holds it there, once it has stored the
attempt, so that the steps have both cores, until the run ends or its remaining steps
look long enough for the loop to pay (:func:`release_if_long`). One helper per cache:
the first run that finds the cache without the loop takes a lock file and starts it,
the others wait for it too.

Files in the kernel cache folder (``_native._CACHE_DIR``), per install:
``loop-<key>.ready`` once the loop is in the cache, ``loop-<key>.lock`` (the helper's
process id) while it compiles, ``loop-<key>.steps`` once it has stored the attempt,
``loop-<key>.err`` (its error output) if it failed.
Without a cache (``BEAMCONTACT_CACHE_DIR=""``) nothing of this runs.
"""

import contextlib
import hashlib
import os
import subprocess
import sys
import time
from pathlib import Path

from beamcontact import _compile_claims, _native

# a helper that takes longer than this (or a lock older than it) is given up: the run
# compiles the loop itself
GIVE_UP_S = 900.0

_helper: subprocess.Popen | None = None
# set in the helper's environment: it neither starts nor waits for a helper
_IN_HELPER = "BEAMCONTACT_WARMUP_HELPER"
# set there too: once it has stored the attempt, it waits for a byte or the end of its
# input (the run that started it lets it go on, or has ended) before the loop itself
_HELD = "BEAMCONTACT_WARMUP_HELD"

# a run lets its held helper go on once its remaining steps look longer than this [s]
# (:func:`release_if_long`): the helper's last 10-13 s of compile (the loop, the spline
# kernels) slowed the steps made beside it by about a third (the bundled benchmark's
# 9.5 s of steps against about 6.5 s alone on both cores), and the compiled loop makes
# them about a fifth faster than the steps made from Python (session 29)
RELEASE_AFTER_S = 20.0
# ... judged after at least this many seconds of steps (the first steps' rate says little)
RELEASE_LOOK_S = 1.0


def _names() -> tuple[str, str]:
    """The names of the ready mark and the lock: Numba keys its cache by the path of the
    source file as well, so two installs of one version (two environments sharing the
    cache folder) each have their own."""
    source = Path(__file__).resolve().parent / "dynamics" / "native_loop.py"
    key = hashlib.sha256(str(source).encode()).hexdigest()[:12]
    return f"loop-{key}.ready", f"loop-{key}.lock"


def _errors(lock: Path) -> Path:
    """The helper's error output, ``loop-<key>.err`` beside its lock; the helper removes
    it when it has compiled the loop, so a file left there says why a helper failed (the
    run then compiles the loop itself)."""
    return lock.with_suffix(".err")


def _paths() -> tuple[Path, Path] | None:
    """The ready mark and the lock in the kernel cache folder (None: no cache)."""
    folder = _native._CACHE_DIR
    if folder is None:
        return None
    ready, lock = _names()
    return folder / ready, folder / lock


def _files() -> tuple[Path, Path] | None:
    """:func:`_paths` for a run (None in the helper, which neither starts nor waits for
    a helper)."""
    return None if os.environ.get(_IN_HELPER) else _paths()


def _steps_mark(ready: Path) -> Path:
    """``loop-<key>.steps`` beside the ready mark: the helper has stored the kernels of
    an attempt (HELPER_ORDER of :func:`_kernel_calls`), so that a run can
    make its steps without the loop until the loop is ready."""
    return ready.with_suffix(".steps")


def _helper_works(lock: Path) -> bool:
    """Whether a helper is compiling the loop: this process's, still running, or
    another run's, whose lock is there and names a live process. (A helper outlives a
    run that finished its steps without the loop, and a closed terminal may kill it
    without its cleanup: its lock must not make the next run wait.)"""
    if _helper is not None:
        return _helper.poll() is None
    return _compile_claims.named_process_alive(lock)


def steps_meanwhile() -> bool:
    """Whether a run should make its steps without the compiled loop, from the attempts
    of its engine, because a helper is compiling the loop and has stored the attempt:
    True until the loop is ready (then the run loads it) or the helper is gone. Waits,
    at most GIVE_UP_S, until the helper has stored either."""
    files = _files()
    if files is None:
        return False
    ready, lock = files
    steps = _steps_mark(ready)
    deadline = time.monotonic() + GIVE_UP_S
    while (not ready.exists() and not steps.exists() and _helper_works(lock)
           and time.monotonic() < deadline):
        time.sleep(0.05)
    return not ready.exists() and steps.exists() and _helper_works(lock)


def loop_cached() -> bool:
    """Whether the kernel cache holds the compiled loop (its ready mark): a native run
    then normally compiles nothing."""
    paths = _paths()
    return paths is not None and paths[0].exists()


def loop_ready() -> None:
    """Mark the loop as compiled into the cache (after its first call in any process)."""
    paths = _paths()
    if paths is not None:
        with contextlib.suppress(OSError):
            paths[0].touch()


def start_if_cold() -> None:
    """Start the helper if the cache lacks the compiled loop and no helper runs."""
    global _helper
    files = _files()
    if files is None or _helper is not None or files[0].exists():
        return None
    lock = files[1]
    try:
        fd = os.open(lock, os.O_CREAT | os.O_EXCL | os.O_WRONLY)
        _steps_mark(files[0]).unlink(missing_ok=True)  # left by a helper that died
    except FileExistsError:
        try:
            if time.time() - lock.stat().st_mtime < GIVE_UP_S and _helper_works(lock):
                return None  # another run's helper compiles it
            lock.unlink()  # left by a helper that died
        except OSError:
            return None
        return start_if_cold()
    except OSError:
        return None
    try:
        with open(_errors(lock), "wb") as errors:
            # -P: no module of the working folder shadows the package's (as the drawer)
            _helper = subprocess.Popen([sys.executable, "-P", "-m", "beamcontact._warmup"],
                                       stdin=subprocess.PIPE, stdout=subprocess.DEVNULL,
                                       stderr=errors,
                                       env={**os.environ, _IN_HELPER: "1", _HELD: "1",
                                            # this process's cache, whatever the
                                            # environment says now
                                            "BEAMCONTACT_CACHE_DIR":
                                                str(_native._CACHE_DIR.parent.parent)})
        os.write(fd, str(_helper.pid).encode())
    except OSError:
        lock.unlink(missing_ok=True)
        _errors(lock).unlink(missing_ok=True)
    finally:
        os.close(fd)


def holding() -> bool:
    """Whether this run holds the helper it started (:func:`release`)."""
    return _helper is not None and _helper.stdin is not None and not _helper.stdin.closed


def helper_busy() -> bool:
    """Whether the helper this run started is still compiling (it finishes the loop
    after a short run has ended, :func:`release_if_long`)."""
    return _helper is not None and _helper.poll() is None


def release() -> None:
    """Let the helper this run started go on from the attempt to the loop itself. Until
    then (or the run's end, which closes the helper's input) it waits, so that the
    run's steps meanwhile have every core."""
    if holding():
        with contextlib.suppress(OSError, ValueError):
            _helper.stdin.write(b"r")
        with contextlib.suppress(OSError, ValueError):
            _helper.stdin.close()


def release_if_long(elapsed: float, done: float) -> None:
    """:func:`release` once the run's steps made meanwhile, ``elapsed`` seconds for the
    fraction ``done`` of its time, leave more than RELEASE_AFTER_S to go at that rate:
    then the loop is worth its compile (a long run), else the helper compiles it after
    the run (a short one, such as the bundled benchmark). Judged after RELEASE_LOOK_S
    of steps."""
    if (holding() and elapsed >= RELEASE_LOOK_S
            and elapsed * (1.0 - done) > RELEASE_AFTER_S * done):
        release()


def _held_until_released() -> None:
    """In a helper that has stored the attempt: wait for the run that started it to
    let it go on (a byte on its input) or to end (the input's end)."""
    if os.environ.get(_HELD):
        with contextlib.suppress(OSError):
            sys.stdin.buffer.read(1)


def wait() -> None:
    """Before the loop's first call: wait for a helper compiling it (this process's, or
    another run's), at most GIVE_UP_S."""
    global _helper
    files = _files()
    if files is None:
        return
    ready, lock = files
    release()
    if _helper is not None:
        # the loop is ready before the helper ends: it compiles the start's kernels then
        deadline = time.monotonic() + GIVE_UP_S
        while _helper.poll() is None and not ready.exists() and time.monotonic() < deadline:
            time.sleep(0.05)
        if _helper.poll() is None and not ready.exists():
            _helper.kill()
            _helper.wait()
        if _helper.poll() is not None:
            lock.unlink(missing_ok=True)
        _helper = None
        return
    deadline = time.monotonic() + GIVE_UP_S
    while _helper_works(lock) and not ready.exists() and time.monotonic() < deadline:
        time.sleep(0.2)


# the helper's model: two clamped beams of one element with coarse-grained contact
_BEAM = {"degree": 2, "elements": 1, "section": {"shape": "circle", "radius": 0.1},
         "material": {"E": 1e6, "density": 1000.0}}
TINY_CASE = {
    "analysis": {"kind": "dynamic", "t_end": 1e-3, "dt": 1e-3},
    "beams": [{**_BEAM, "name": "a", "line": {"start": [0.0, 0.0], "end": [1.0, 0.0]},
               "supports": [{"at": "start", "type": "clamped"}]},
              {**_BEAM, "name": "b", "line": {"start": [0.0, 0.25], "end": [1.0, 0.25]},
               "supports": [{"at": "start", "type": "clamped"}]}],
    "contact": {"model": "cg", "segments_per_element": 2}}


# a run of a model of at most this many elements (all beams together) makes its start
# with the kernels as Python while a helper fills an empty cache (:func:`start_as_python`)
START_AS_PYTHON_ELEMENTS = 100


def start_as_python(elements: int) -> bool:
    """Whether a run, about to build its model of ``elements`` elements, makes its start
    (the model's splines, the contact set at t = 0, the initial acceleration, the first
    energies) with the kernels as Python (:func:`beamcontact._native.as_python`): while
    the kernel cache lacks the compiled loop (a helper fills it, or is about to), if the
    model has at most START_AS_PYTHON_ELEMENTS elements. The bundled benchmark's 26
    take 0.4 s for the splines and 0.35 s for the rest as Python; compiled, they were
    the first 3.8 s and about 20 s more of a cold run's way to its steps (session 29).
    The kernels that the steps call many times compile as before, and the helper
    compiles the kernels of the start for the next run (:func:`_compile_start`)."""
    files = _files()
    return files is not None and not files[0].exists() and \
        elements <= START_AS_PYTHON_ELEMENTS


# the helper's model with two elements a beam: its build calls every spline kernel that
# a run's model build does (knot insertion included), with the same argument types
_START_CASE = {**TINY_CASE, "beams": [{**beam, "elements": 2}
                                      for beam in TINY_CASE["beams"]]}


def _compile_start() -> None:
    """In the helper, the loop compiled and marked ready: the kernels of a run's start
    into the cache for the next run (the spline kernels of the model's build, the
    contact set at t = 0, the initial acceleration, the first energies and the smallest
    gap), by making the start of a run of its model with them: the helper built its own
    model with the kernels as Python, and a small run that started it made its whole
    start so (:func:`start_as_python`), so that no one has compiled them yet. In a
    process of its own (``python -m beamcontact._warmup start``): the helper holds
    versions of some of them compiled inside the loop (the contact energy), which its
    calls from Python would use, so that the whole versions a run loads would never
    reach the cache (the first warm run compiled the contact energy, 1.1 s)."""
    from beamcontact.io.case import parse_case
    from beamcontact.setup.start import dynamic_start, prepare

    begin = dynamic_start(prepare(parse_case(_START_CASE)))
    begin.engine.energies(begin.state, None)


def _compile_loop() -> None:
    """The helper: one step of a tiny model with coarse-grained contact, which compiles
    the loop (and the kernels it calls) into the cache."""
    import numpy as np

    from beamcontact import enable_x64
    from beamcontact.assembly.model import LoadState
    from beamcontact.dynamics.control import EnergyAccount, Limits, StepControl, new_state
    from beamcontact.dynamics.hht import DynState
    from beamcontact.dynamics.native_step import NativeEngine
    from beamcontact.dynamics.report import DIAGNOSTICS
    from beamcontact.io.case import parse_case
    from beamcontact.setup.start import prepare

    enable_x64()
    # its model's splines as Python: the loop calls none of them, so the helper starts
    # on the loop's kernels at once instead of after the spline kernels (about 5 s,
    # session 22); it compiles them last (_compile_start)
    with _native.as_python():
        p = prepare(parse_case(TINY_CASE))
    engine = NativeEngine(p.model, 0.0, p.options, p.length, 1e-3, p.contact)
    nm = engine.nm
    tangent = np.einsum("lk,lkd->ld", nm.load_dR, nm.x_ref[nm.load_conn])
    zero = np.zeros(nm.n_dof)
    state = DynState(0.0, zero, zero.copy(), zero.copy(), zero.copy(),
                     LoadState(theta=np.zeros(tangent.shape[0]), tangent=tangent))
    account = EnergyAccount(0.0, 0.0, dict.fromkeys(DIAGNOSTICS, 0.0))
    limits = Limits.of(StepControl(1e-3, 1e-9), 1e-3, p.length, p.contact.max_penetration)
    calls = _kernel_calls(engine, state)
    for name in HELPER_ORDER:
        calls[name]()
    paths = _paths()
    if paths is not None:  # a run may step without the loop from now on
        _steps_mark(paths[0]).touch()
    _held_until_released()
    for name in HELPER_AFTER:
        calls[name]()
    engine.advance(state, new_state(0.0, 1e-3, account), limits, lambda *_: None)


# the helper's order of the loop's kernels (:func:`_kernel_calls`): the contact blocks
# and the solver (which the run's start needs once it has its contact set), then what
# the start needs late or never (the HHT residual, the attempt); compiling the loop alone
# would compile its kernels in the order of its body, the order in which the start
# compiles the same kernels beside it, so that both processes would compile the same
# kernel at the same time; in this order each loads from the cache more of what the
# other has compiled
HELPER_ORDER = ("contact_blocks", "newton_update", "_residual_tangent", "_residual", "attempt")
# ... then, once it has stored the attempt and is let go on (:func:`release`)
HELPER_AFTER = ("step_set_at", "after_step")
# the run's help, in its order, once its start is done and while it would otherwise wait
# for the helper (:func:`help_while_waiting`): the HHT residual and tangent and the
# solver's update, which the helper comes to after the contact blocks (a start made as
# Python gets here long before; after a compiled start the helper has them), then the
# checks after a step and the contact set at the predictor (which its steps need)
RUN_HELPS = ("_residual_tangent", "newton_update", "after_step", "step_set_at")


def _kernel_calls(engine, state) -> dict:
    """The loop's kernels by name, each as a call on the engine's model with the types
    the loop passes (HELPER_ORDER, HELPER_AFTER, RUN_HELPS). Those that Python never
    calls in a run (the contact blocks, the solver's update, the HHT residual with and
    without its tangent: the attempt calls them) are compiled for linking only
    (:func:`~beamcontact._native.compile_for_linking`: no module passes, no machine code;
    2-6 s of a cold start, session 36); the attempt and the contact set's kernels, which
    the steps made without the loop call from Python, are called."""
    import numpy as np

    from beamcontact.assembly import native_model as nmod
    from beamcontact.contact import step_set_native as ssn
    from beamcontact.dynamics import native_step as ns
    from beamcontact.dynamics.report import COUNTS, VALUES
    from beamcontact.solvers import bordered_native as bordered

    nm, sysm = engine.nm, engine.system
    ne, law = ns._no_contact_elements() if engine._contact is None else (
        engine._contact.ne, engine._contact.law)
    lay, ar = sysm.layout, sysm.arrays
    s, n = state, nm.n_dof
    frozen = ssn.frozen_blocks(ne, law, ns.NO_CONTACT[2], ns.NO_CONTACT[3])
    x = nmod._positions(nm.x_ref, s.u)
    v = s.v.reshape(-1, 2)
    r, r_pot, r_layout, du = (np.zeros(n) for _ in range(4))
    blocks = np.zeros((nm.block_dofs.shape[0], nm.block_dofs.shape[1],
                       nm.block_dofs.shape[1]))
    # the engine's bordered arrays are scratch: every assembly zeroes them
    band, B, C, D = ar.band, ar.B, ar.C, ar.D
    system = (sysm.position, sysm.block_positions, sysm.free, band, B, C, D, lay.kl, lay.ku)
    history = (s.u, s.u, s.v, s.a, np.zeros(4), 0.0, s.f_pot, s.load_state.theta,
               s.load_state.tangent)
    out = [np.empty(n) for _ in range(4)] + [
        np.empty_like(s.load_state.theta), np.empty_like(s.load_state.tangent),
        np.empty(len(VALUES)), np.empty(len(COUNTS), np.int64)]
    link = _native.compile_for_linking
    return {
        "contact_blocks": lambda: link(
            ns.contact_blocks, x, *frozen, 1.0, sysm.position, band, B, C, D, lay.kl,
            lay.ku, r_pot, r),
        "newton_update": lambda: link(
            bordered.newton_update, band, B, C, D, lay.kl, lay.ku, ar.ipiv, ar.ipiv_s,
            sysm.position, r_layout, du, s.u.copy(), False),
        "_residual_tangent": lambda: link(
            ns._residual_tangent, nm, frozen, *history, *system, r, r_pot, r_layout, blocks),
        "_residual": lambda: link(ns._residual, nm, frozen, *history, r, r_pot, blocks),
        "attempt": lambda: ns.attempt(
            nm, frozen, sysm.position, sysm.block_positions, sysm.free, band, B, C, D,
            ar.ipiv, ar.ipiv_s, lay.kl, lay.ku, s.u, s.v, s.a, s.f_pot, s.load_state.theta,
            s.load_state.tangent, 1e-3, 0.0, 1e-8, 1e-9, 1e-9, 1e-3, 1.0, 10, 4, np.nan,
            np.nan, *out),
        "step_set_at": lambda: ssn.step_set_at(x, x.copy(), v, v.copy(), 1e-3, 0.0, ne, law),
        "after_step": lambda: ssn.after_step(x, x.copy(), x.copy(), 0.0, ne, law, frozen[2]),
    }


def help_while_waiting(engine, state) -> None:
    """Before the loop's first call of a run whose helper is still compiling: the
    kernel calls RUN_HELPS (:func:`_kernel_calls`), so that the helper loads them from
    the cache when it gets there (one that the helper compiles meanwhile is waited for
    and loaded, beamcontact/_compile_claims.py)."""
    files = _files()
    if files is None or files[0].exists() or (_helper is None and not files[1].exists()):
        return
    calls = _kernel_calls(engine, state)
    for name in RUN_HELPS:
        if files[0].exists():
            return
        calls[name]()


if __name__ == "__main__":
    if sys.argv[1:] == ["start"]:
        from beamcontact import enable_x64

        enable_x64()
        _compile_start()
        raise SystemExit
    paths = _paths()
    try:
        _compile_loop()
        loop_ready()
        if paths is not None:
            _errors(paths[1]).unlink(missing_ok=True)
        # for the next run; this one needs the loop only
        subprocess.run([sys.executable, "-P", "-m", "beamcontact._warmup", "start"],
                       stdin=subprocess.DEVNULL, check=False)
    finally:
        if paths is not None:
            _steps_mark(paths[0]).unlink(missing_ok=True)
            paths[1].unlink(missing_ok=True)
