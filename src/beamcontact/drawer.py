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
its own, so that Ctrl-C reaches only the run, and exits when the run closes its input.

Whatever goes wrong, every figure is drawn once where it can be: a drawer that cannot be
started, exits with an error, or reports no figure for :data:`STALL_S` is stopped and
the run draws them all itself, so that their errors are the run's (an
:class:`~beamcontact.record.OutputError` with its reason). An interrupt of the run while
it waits stops the drawer and draws nothing more. ``tests/test_drawer.py``.
"""

import importlib
import os
import pickle
import select
import signal
import subprocess
import sys
from collections.abc import Iterator
from contextlib import contextmanager, suppress

# a figure: a function by name (of beamcontact.plot, or "module:function"), its
# positional and keyword arguments (pickled to the drawer: data, no objects of matplotlib)
Call = tuple[str, tuple, dict]

# a drawer that reports no finished figure for this long is stopped (a figure takes
# well under a second; the animation of 300 snapshots of a large model a few seconds)
STALL_S = 60.0


def draw_here(calls: list[Call]) -> None:
    """Make ``calls`` in this process."""
    for name, args, kwargs in calls:
        module, _, function = name.rpartition(":")
        getattr(importlib.import_module(module or "beamcontact.plot"), function)(
            *args, **kwargs)


class Drawer:
    """A process that imports :mod:`beamcontact.plot` and draws the figures it is sent
    (:meth:`draw`), or exits when its input closes without any."""

    def __init__(self, process: subprocess.Popen):
        self.process = process

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

    @classmethod
    def _start(cls) -> "Drawer | None":
        # one core: it would only take turns with the run; its pipes and process group
        # are POSIX's
        if (os.cpu_count() or 1) < 2 or os.name != "posix":
            return None
        try:
            process = subprocess.Popen(
                [sys.executable, "-m", "beamcontact.drawer"], stdin=subprocess.PIPE,
                stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, start_new_session=True)
        except OSError:
            return None
        return cls(process)

    def draw(self, first: list[Call], second: list[Call]) -> bool:
        """Draw ``first`` and ``second``, at the same time by the drawer and its copy;
        all here if the drawer fails (it is stopped first). Whether the drawer drew them.
        Call once."""
        n = len(first) + len(second)
        try:
            job = pickle.dumps((first, second))
        except (pickle.PicklingError, TypeError, AttributeError):  # drawn here then
            job = None
        try:
            drawn = n > 0 and job is not None and self._send(job) and self._finished(n)
        except BaseException:
            self.stop()
            raise
        if not drawn:
            self.stop()
            draw_here(first + second)
        return drawn

    def _send(self, job: bytes) -> bool:
        """Whether the drawer took ``job`` (it may still be importing: it is given
        STALL_S)."""
        fd, view = self.process.stdin.fileno(), memoryview(job)
        try:
            os.set_blocking(fd, False)
            while view:
                if not select.select([], [fd], [], STALL_S)[1]:
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
        file is closed); False if they exit first or report none for STALL_S."""
        reports, reported = self.process.stdout.fileno(), 0
        while reported < n:
            if not select.select([reports], [], [], STALL_S)[0]:
                return False
            got = os.read(reports, 64)
            if not got:  # both processes have exited
                return False
            reported += len(got)
        return True

    def stop(self) -> None:
        """Stop the drawer and its copy if they run, collect the drawer, close the
        pipes."""
        if self.process.returncode is None:
            # its session's group, the copy too (which may outlive it); until the drawer
            # is collected, its id cannot name another group
            with suppress(OSError):
                os.killpg(self.process.pid, signal.SIGKILL)
            self.process.wait()
        for stream in (self.process.stdin, self.process.stdout):
            with suppress(OSError):
                stream.close()


def _serve(jobs: int, reports: int) -> None:
    """The drawer: import, wait for the figures, draw them (half by a forked copy),
    report each drawn."""
    import beamcontact.plot  # noqa: F401  (what this process is for)

    chunks = []
    while chunk := os.read(jobs, 1 << 20):
        chunks.append(chunk)
    if not chunks:  # the run ended without figures
        return
    first, second = pickle.loads(b"".join(chunks))
    if second and sys.platform.startswith("linux"):  # a fork is safe there
        if os.fork() == 0:
            _draw_reporting(second, reports)
            return
        second = []
    _draw_reporting(first + second, reports)


def _draw_reporting(calls: list[Call], reports: int) -> None:
    for call in calls:
        draw_here([call])
        os.write(reports, b".")


if __name__ == "__main__":
    # the reports keep the pipe; anything printed goes nowhere
    _reports = os.dup(1)
    os.dup2(os.open(os.devnull, os.O_WRONLY), 1)
    code = 1
    try:
        _serve(0, _reports)
        code = 0
    finally:
        # without the interpreter's teardown (0.05-0.1 s with matplotlib): the run
        # waits for the reports, not for the exit, and every file is closed by then
        os._exit(code)
