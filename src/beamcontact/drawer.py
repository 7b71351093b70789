"""The figures of a command-line run, drawn by a process started with the run.

Importing matplotlib takes 0.2-0.4 s and the five figures of a dynamic run about 0.5 s
on one core: a third of a short run. ``beamcontact run`` therefore starts a drawer
(``python -m beamcontact.drawer``) before it imports its engine
(:meth:`Drawer.started`): the drawer imports :mod:`beamcontact.plot` on the second core
while the run imports Numba and builds its model on the first, then sleeps on its
input while the steps run. After the steps the run sends it the figures as calls by
name into :mod:`beamcontact.plot` with their data (:data:`Call`, pickled); the drawer
draws one half and, on Linux, a forked copy of itself the other half, one on each core,
and reports each figure drawn; the run waits for both.

A fresh interpreter, not a fork of the run: a forked copy shares the run's memory
copy-on-write, and every page the run then writes is copied (Python's reference counts
write to every object it touches): a copy that only slept made the start of a run
0.07 s slower (the model built in 0.12 s instead of 0.05 s, twice the page faults). The
drawer never imports JAX and writes nothing to the terminal; it runs in a session of
its own, so that Ctrl-C reaches only the run, and exits when the run closes its input
(a run that ends without figures asks it to end and gives it :data:`END_S` to do so
cleanly: matplotlib holds a lock file while it builds its font cache on a first import).
It runs with ``-P`` (no module of the working folder) and exits at once if the
beamcontact it imports is not the run's. It is started only where the process may use
two cores or more.

Whatever goes wrong, every figure is drawn once where it can be: a drawer that cannot be
started, exits with an error, is not ready within :data:`READY_S` or then reports no
figure for :data:`STALL_S` is stopped and the run draws them all itself, so that their
errors are the run's (an :class:`~beamcontact.record.OutputError` with its reason), and
:attr:`Drawer.failure` says why the drawer did not draw them (the last line of what it
wrote to its standard error, kept in a temporary file; the run's summary warns with it,
since a drawer that always fails doubles the figures' time). An
interrupt of the run while it waits stops the drawer and draws nothing more (the
command line then says so and exits as interrupted). ``tests/test_drawer.py``.
"""

import importlib
import os
import pickle
import selectors
import signal
import subprocess
import sys
import tempfile
import traceback
from collections.abc import Iterator
from contextlib import contextmanager, suppress

from beamcontact.cores import usable_cores

# a figure: a function by name (of beamcontact.plot, or "module:function"), its
# positional and keyword arguments (pickled to the drawer: data, no objects of matplotlib)
Call = tuple[str, tuple, dict]

# a drawer that reports no finished figure for this long is stopped (a figure takes
# well under a second; the animation of 300 snapshots of a large model a few seconds)
STALL_S = 60.0
# the time a drawer is given to import matplotlib (on a first import, it also builds its
# font cache)
READY_S = 120.0
# a drawer asked to stop before it drew gets this long to end cleanly, then SIGKILL
# (matplotlib holds a lock file while it builds its font cache)
END_S = 5.0

READY, DRAWN = b"r", b"."


def draw_here(calls: list[Call]) -> None:
    """Make ``calls`` in this process."""
    for name, args, kwargs in calls:
        module, _, function = name.rpartition(":")
        getattr(importlib.import_module(module or "beamcontact.plot"), function)(
            *args, **kwargs)


class Drawer:
    """A process that imports :mod:`beamcontact.plot` and draws the figures it is sent
    (:meth:`draw`), or exits when its input closes without any."""

    def __init__(self, process: subprocess.Popen, errors):
        self.process = process
        self._ready = False
        # its standard error (a temporary file), and why it did not draw (None: it did,
        # or was not asked to)
        self._errors = errors
        self.failure: str | None = None

    @classmethod
    @contextmanager
    def started(cls) -> Iterator["Drawer | None"]:
        """A drawer for the block (None where none can be started), stopped after it."""
        drawer = cls._start()
        try:
            yield drawer
        finally:
            if drawer is not None:
                drawer.stop()
                drawer._errors.close()

    @classmethod
    def _start(cls) -> "Drawer | None":
        # one core: it would only take turns with the run; its pipes and process group
        # are POSIX's
        if usable_cores() < 2 or os.name != "posix" or not sys.executable:
            return None
        errors = None
        try:  # no module of the working folder (-P); it checks it has our package
            errors = tempfile.TemporaryFile()  # noqa: SIM115  (closed by started())
            process = subprocess.Popen(
                [sys.executable, "-P", "-m", "beamcontact.drawer", _package()],
                stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=errors,
                start_new_session=True)
        except OSError:
            if errors is not None:
                errors.close()
            return None
        return cls(process, errors)

    def draw(self, first: list[Call], second: list[Call]) -> bool:
        """Draw ``first`` and ``second``, at the same time by the drawer and its copy;
        all here if the drawer fails (it is stopped first). Whether the drawer drew them.
        Call once."""
        n = len(first) + len(second)
        try:
            job = pickle.dumps((first, second))
        except Exception:  # noqa: BLE001  (drawn here, where the error shows)
            job = None
        try:
            drawn = n > 0 and job is not None and self._send(job) and self._finished(n)
        except BaseException:
            self.stop(hung=True)
            raise
        if not drawn:
            self.stop(hung=True)
            if n > 0:
                self.failure = self.failure or self._reason(job is None)
            draw_here(first + second)
        return drawn

    def _reason(self, unpicklable: bool) -> str:
        """Why the drawer did not draw: the last line of its standard error (its
        exception), else how it ended."""
        if unpicklable:
            return "the figures' data could not be sent to it (not picklable)"
        last = ""
        with suppress(OSError, ValueError):
            self._errors.seek(0)
            lines = self._errors.read().decode(errors="replace").strip().splitlines()
            last = lines[-1].strip() if lines else ""
        if last:
            return last
        code = self.process.returncode
        return "it ended" if code is None else f"it ended with status {code}"

    def _send(self, job: bytes) -> bool:
        """Whether the drawer took ``job`` (it reads once it has imported)."""
        fd, view = self.process.stdin.fileno(), memoryview(job)
        try:
            os.set_blocking(fd, False)
            while view:
                if not _wait_for(fd, selectors.EVENT_WRITE, READY_S):
                    self.failure = f"it did not read the figures within {READY_S:g} s"
                    return False
                view = view[os.write(fd, view):]
        except OSError:  # the drawer has exited
            return False
        finally:
            with suppress(OSError):
                self.process.stdin.close()
        return True

    def _finished(self, n: int) -> bool:
        """Whether the drawer and its copy report ``n`` figures drawn (each after its
        file is closed) and exit; False if they exit first, or report nothing for
        READY_S before the drawer is ready and STALL_S after."""
        reports, reported = self.process.stdout.fileno(), 0
        while True:
            limit = STALL_S if self._ready else READY_S
            if not _wait_for(reports, selectors.EVENT_READ, limit):
                self.failure = (f"it reported no figure for {limit:g} s" if self._ready
                                else f"it was not ready within {limit:g} s")
                return False
            got = os.read(reports, 64)
            if not got:  # both processes have exited
                break
            self._ready = self._ready or READY in got
            reported += got.count(DRAWN)
        return self.process.wait() == 0 and reported == n

    def stop(self, hung: bool = False) -> None:
        """Stop the drawer and its copy if they run (at once if ``hung``, else after
        END_S to end cleanly), collect the drawer, close the pipes."""
        if self.process.returncode is None:
            # its session's group, the copy too; until the drawer is collected, its id
            # cannot name another group
            with suppress(OSError):
                os.killpg(self.process.pid, signal.SIGKILL if hung else signal.SIGTERM)
            try:
                self.process.wait(timeout=None if hung else END_S)
            except subprocess.TimeoutExpired:
                with suppress(OSError):
                    os.killpg(self.process.pid, signal.SIGKILL)
                self.process.wait()
        for stream in (self.process.stdin, self.process.stdout):
            with suppress(OSError):
                stream.close()


def _wait_for(fd: int, event: int, timeout: float) -> bool:
    """Whether ``fd`` becomes ready for ``event`` (selectors.EVENT_READ or EVENT_WRITE)
    within ``timeout`` seconds (a selector, not select.select: any descriptor number)."""
    with selectors.DefaultSelector() as selector:
        selector.register(fd, event)
        return bool(selector.select(timeout))


def _package() -> str:
    """The folder of the beamcontact package this process runs."""
    import beamcontact

    return os.path.dirname(os.path.realpath(beamcontact.__file__))


def _serve(jobs: int, reports: int, package: str) -> None:
    """The drawer: import, say so, wait for the figures, draw them (half by a forked
    copy), report each drawn. It exits at once if its beamcontact is not the run's
    (in ``package``): the run draws them then."""
    if _package() != package:
        raise RuntimeError("another beamcontact than the run's")
    import beamcontact.plot  # noqa: F401  (what this process is for)

    os.write(reports, READY)
    chunks = []
    while chunk := os.read(jobs, 1 << 20):
        chunks.append(chunk)
    if not chunks:  # the run ended without figures
        return
    first, second = pickle.loads(b"".join(chunks))
    copy = None
    if second and sys.platform.startswith("linux") and usable_cores() > 1:  # a fork is safe there
        with suppress(OSError):  # else both halves here
            copy = os.fork()
        if copy == 0:
            _draw_reporting(second, reports)
            return
        if copy is not None:
            second = []
    _draw_reporting(first + second, reports)
    if copy is not None:
        _, status = os.waitpid(copy, 0)
        if os.waitstatus_to_exitcode(status) != 0:  # its error is on our standard error
            raise SystemExit(1)


def _draw_reporting(calls: list[Call], reports: int) -> None:
    for call in calls:
        draw_here([call])
        os.write(reports, DRAWN)


def _end(*_) -> None:
    raise SystemExit(1)  # unwinds: a lock file matplotlib holds is removed


if __name__ == "__main__":
    signal.signal(signal.SIGTERM, _end)
    # the reports keep the pipe; anything printed goes nowhere
    _reports = os.dup(1)
    os.dup2(os.open(os.devnull, os.O_WRONLY), 1)
    code = 1
    try:
        _serve(0, _reports, sys.argv[1])
        code = 0
    except SystemExit:  # stopped, or the copy failed and said why
        pass
    except BaseException:  # noqa: BLE001  (to the run's file of our standard error)
        traceback.print_exc()
        sys.stderr.flush()
    finally:
        # without the interpreter's teardown (0.05-0.1 s with matplotlib): every file is
        # closed by then
        os._exit(code)
