"""SIGTERM and SIGHUP handled like Ctrl-C: what a batch scheduler sends before it kills a
job, or a closed terminal, ends a run with everything accepted kept, its summary.json
written (status "interrupted", saying which signal) and the run restartable.

:func:`stop_signals_interrupt` (used by the command line around a run) turns the first of
these signals into :class:`Terminated`, a ``KeyboardInterrupt``, raised in the main thread
where the runner already handles Ctrl-C; later ones are ignored until the run has written
what it holds. The exit code is then 128 + the signal's number (143 for SIGTERM, 129 for
SIGHUP), as a shell reports a process the signal killed.
"""

from __future__ import annotations

import signal
import threading
from collections.abc import Iterator
from contextlib import contextmanager

# the signals turned into an interrupt (SIGHUP does not exist on Windows)
STOP_SIGNALS = tuple(getattr(signal, name) for name in ("SIGTERM", "SIGHUP")
                     if hasattr(signal, name))


class Terminated(KeyboardInterrupt):
    """A run stopped by a signal; ``signum`` says which."""

    def __init__(self, signum: int):
        super().__init__(signal.Signals(signum).name)
        self.signum = signum

    @property
    def name(self) -> str:
        """The signal's name (e.g. "SIGTERM")."""
        return signal.Signals(self.signum).name


def as_interrupt(exc: BaseException) -> KeyboardInterrupt | None:
    """``exc`` as the interrupt it stands for: itself, or the KeyboardInterrupt (or
    :class:`Terminated`) that a signal raised while Python was inside a call of compiled
    code, which Numba's dispatcher then reports as a SystemError ("returned a result with
    an exception set") with the interrupt as its context (or the context of a
    SystemError of a Python function the compiled code called, as Numba's unpickling of
    constants); None for any other error."""
    while isinstance(exc, SystemError):
        exc = exc.__context__
    return exc if isinstance(exc, KeyboardInterrupt) else None


def interrupt_of(exc: BaseException) -> KeyboardInterrupt:
    """The interrupt ``exc`` stands for (:func:`as_interrupt`); any other error is raised
    again. For the handlers of KeyboardInterrupt and SystemError around a run."""
    interrupt = as_interrupt(exc)
    if interrupt is None:
        raise exc
    return interrupt


def stopped_by(exc: KeyboardInterrupt) -> str:
    """What stopped a run: "the user" (Ctrl-C) or "SIGTERM" and the like."""
    return exc.name if isinstance(exc, Terminated) else "the user"


@contextmanager
def stop_signals_interrupt() -> Iterator[None]:
    """Within the block, SIGTERM and SIGHUP raise :class:`Terminated` (the first one; later
    ones are ignored); the earlier handlers come back after it. Outside the main thread,
    where Python cannot set handlers, nothing changes."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    fired: list[int] = []

    def handler(signum, frame):
        del frame
        if fired:
            return
        fired.append(signum)
        raise Terminated(signum)

    previous = {s: signal.signal(s, handler) for s in STOP_SIGNALS}
    try:
        yield
    finally:
        for s, h in previous.items():
            signal.signal(s, h)
