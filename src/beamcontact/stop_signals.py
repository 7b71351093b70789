"""SIGTERM and SIGHUP handled like Ctrl-C: what a batch scheduler sends before it kills a
job, or a closed terminal, ends a run with everything accepted kept, its summary.json
written (status "interrupted", saying which signal) and the run restartable.

:func:`stop_signals_interrupt` (used by the command line around a run) turns the first of
these signals into :class:`Terminated`, a ``KeyboardInterrupt``, raised in the main thread
where the runner already handles Ctrl-C; later ones are ignored until the run has written
what it holds. The exit code is then 128 + the signal's number (143 for SIGTERM, 129 for
SIGHUP), as a shell reports a process the signal killed.

:func:`interrupts_kept` (around the step loop, and inside :func:`stop_signals_interrupt`)
keeps an interrupt that Python would drop: a signal's handler runs at the next bytecode
boundary of the main thread, which can lie inside a garbage-collection callback (JAX
registers one that runs at every collection) or a finalizer, where Python prints the
KeyboardInterrupt as "Exception ignored" and goes on; the run would not stop at Ctrl-C,
nor at a scheduler's SIGTERM at all. Such an interrupt is kept and raised again where
the step loop next hands over its steps.
"""

from __future__ import annotations

import signal
import sys
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


def _in_main_thread() -> bool:
    return threading.current_thread() is threading.main_thread()


@contextmanager
def stop_signals_interrupt() -> Iterator[None]:
    """Within the block, SIGTERM and SIGHUP raise :class:`Terminated` (the first one;
    later ones are ignored); the earlier handlers come back after it. One that Python
    drops is kept (:func:`interrupts_kept`) for the step loop to raise; one still kept
    when the block ends is let go (the work it was to stop has ended). Outside the main
    thread, where Python cannot set handlers, nothing changes."""
    if not _in_main_thread():
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
        with interrupts_kept(raise_at_end=False):
            yield
    finally:
        for s, h in previous.items():
            signal.signal(s, h)


# the interrupt that Python dropped in the main thread while a block of interrupts_kept
# was open there, not yet raised again (at most one: a later one replaces it); and how
# many such blocks are open. Only the main thread reads or writes them.
_DROPPED: list[KeyboardInterrupt] = []
_OPEN = [0]


def raise_dropped() -> None:
    """Raise the interrupt that Python dropped (:func:`interrupts_kept`), if any, in the
    main thread (where signals are handled); elsewhere nothing happens."""
    if _DROPPED and _in_main_thread():
        raise _DROPPED.pop()


@contextmanager
def interrupts_kept(*, raise_at_end: bool = True) -> Iterator[None]:
    """Within the block, a KeyboardInterrupt (Ctrl-C, or :class:`Terminated`) that Python
    drops in the main thread, raised inside a garbage-collection callback or a finalizer
    and handed to ``sys.unraisablehook``, is kept and raised again by
    :func:`raise_dropped` (called where an interrupt may stop the work: the step loops
    call it after handing over accepted steps), or when the block ends (unless not
    ``raise_at_end``: then it is let go; a block ending with an error lets it go too).
    Raising it from the hook is no use: anything raised there is dropped too, and a
    simulated signal would be handled before the hook returns. Any other unraisable error
    goes to the earlier hook, which comes back after the block (unless the block set
    another); outside the block the hook only passes everything on. Blocks nest (one
    dropped in the outer block is raised by the inner one); the outermost starts with
    none kept. Outside the main thread nothing changes. ``tests/test_stop_signals.py``."""
    if not _in_main_thread():
        yield
        return
    if _OPEN[0] == 0:
        _DROPPED.clear()
    previous, open_ = sys.unraisablehook, [True]

    def hook(unraisable) -> None:
        exc = unraisable.exc_value
        if open_[0] and isinstance(exc, KeyboardInterrupt) and _in_main_thread():
            _DROPPED[:] = [exc.with_traceback(None)]
        else:
            previous(unraisable)

    sys.unraisablehook = hook
    _OPEN[0] += 1
    ended = False
    try:
        yield
        ended = True
    finally:
        open_[0] = False
        if sys.unraisablehook is hook:
            sys.unraisablehook = previous
        _OPEN[0] -= 1
        if not (ended and raise_at_end):
            _DROPPED.clear()
    raise_dropped()
