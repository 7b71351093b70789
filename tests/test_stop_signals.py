"""Interrupts that Python would drop are kept (beamcontact.stop_signals.interrupts_kept)
and raised again where the work can stop: by raise_dropped (the step loop calls it after
each batch of steps), at the latest when the block ends.

A signal's handler runs at the main thread's next bytecode boundary; when that lies in a
garbage-collection callback (JAX registers one) or a finalizer, Python hands the
KeyboardInterrupt to sys.unraisablehook, prints it and goes on: a run went on to its
end after Ctrl-C (the compiled loop's interrupt test, once on a loaded machine), and the
first SIGTERM of a scheduler, after which later ones are ignored, would be lost for
good. Each test makes the handler run inside such a place, by raising the signal there
(``signal.raise_signal`` runs the handler before it returns).
"""

import gc
import signal
import sys
import threading
from contextlib import contextmanager
from pathlib import Path

import pytest

from beamcontact.stop_signals import (
    Terminated,
    interrupts_kept,
    raise_dropped,
    stop_signals_interrupt,
)

REPO = Path(__file__).resolve().parents[1]


class RaisesSignalWhenCollected:
    """An object whose finalizer raises ``signum`` (its handler runs inside it)."""

    def __init__(self, signum: int):
        self.signum = signum

    def __del__(self):
        signal.raise_signal(self.signum)


def _work(n: int = 200_000) -> int:
    """Bytecode after the drop: where an interrupt raised again arrives."""
    total = 0
    for i in range(n):
        total += i
    return total


@contextmanager
def printed():
    """The unraisable errors that reach the hook in place before (Python prints them), and
    Python's own SIGINT handler (a process started in the background by a
    non-interactive shell ignores SIGINT). Entered in the test itself: pytest before 8.4
    sets a hook of its own around each phase of a test."""
    handler = signal.signal(signal.SIGINT, signal.default_int_handler)
    seen = []
    hook, sys.unraisablehook = sys.unraisablehook, seen.append
    try:
        yield seen
    finally:
        sys.unraisablehook = hook
        signal.signal(signal.SIGINT, handler)


def test_python_drops_an_interrupt_raised_in_a_finalizer():
    """The defect the others guard against: without interrupts_kept, Ctrl-C raised in a
    finalizer is printed as unraisable and the code after it runs to its end."""
    with printed() as seen:
        RaisesSignalWhenCollected(signal.SIGINT)
        assert _work() == 200_000 * 199_999 // 2
    assert [type(u.exc_value) for u in seen] == [KeyboardInterrupt]


def test_ctrl_c_dropped_in_a_finalizer_is_raised_where_asked():
    with printed() as seen:
        with interrupts_kept():
            RaisesSignalWhenCollected(signal.SIGINT)
            _work()
            with pytest.raises(KeyboardInterrupt):
                raise_dropped()
            raise_dropped()  # once
        assert sys.unraisablehook == seen.append  # the earlier hook is back
    assert seen == []  # kept, not printed


def test_ctrl_c_dropped_in_a_garbage_collection_callback_is_raised_at_the_end():
    """As JAX's callback (jax._src.lib._xla_gc_callback) runs at every collection."""
    calls, finished = [], []

    def callback(phase, info):
        del info
        if phase == "start" and not calls:
            calls.append(phase)
            signal.raise_signal(signal.SIGINT)

    with printed() as seen:
        try:
            with pytest.raises(KeyboardInterrupt), interrupts_kept():
                # added inside the block: an automatic collection may run at any
                # allocation, and one before the block would drop the interrupt for good
                gc.callbacks.append(callback)
                gc.collect()
                finished.append(_work())
        finally:
            if callback in gc.callbacks:
                gc.callbacks.remove(callback)
    assert calls == ["start"] and finished and seen == []


def test_a_sigterm_dropped_before_the_step_loop_stops_it():
    """The first SIGTERM, dropped in a finalizer while the run prepares (the command
    line's block), is raised by the step loop's block; a second one, while the run writes
    what it holds, is ignored."""
    with printed() as seen, stop_signals_interrupt():
        RaisesSignalWhenCollected(signal.SIGTERM)
        with pytest.raises(Terminated) as caught, interrupts_kept():
            raise_dropped()
        signal.raise_signal(signal.SIGTERM)
        assert _work() == 200_000 * 199_999 // 2
    assert caught.value.signum == signal.SIGTERM and seen == []


def test_a_sigterm_dropped_after_the_work_is_let_go():
    """Dropped once the step loop has ended, it stops nothing: the run completes, and no
    later block raises it."""
    with printed() as seen:
        with stop_signals_interrupt():
            RaisesSignalWhenCollected(signal.SIGTERM)
        with interrupts_kept():
            raise_dropped()
    assert seen == []


def test_a_block_ended_by_an_error_lets_a_dropped_interrupt_go():
    with printed() as seen:
        with pytest.raises(ValueError), interrupts_kept():
            RaisesSignalWhenCollected(signal.SIGINT)
            raise ValueError
        raise_dropped()
    assert seen == []


def test_other_unraisable_errors_reach_the_earlier_hook():
    class FailsWhenCollected:
        def __del__(self):
            raise ValueError("in a finalizer")

    with printed() as seen, interrupts_kept():
        FailsWhenCollected()
        raise_dropped()
    assert [type(u.exc_value) for u in seen] == [ValueError]


def test_another_thread_does_not_take_the_main_threads_interrupt():
    """A step loop in a worker thread (a sweep's threads) neither raises nor clears an
    interrupt kept for the main thread's run."""
    raised = []

    def worker():
        try:
            with interrupts_kept():
                raise_dropped()
        except KeyboardInterrupt:
            raised.append(True)

    with printed() as seen, pytest.raises(KeyboardInterrupt), interrupts_kept():
        RaisesSignalWhenCollected(signal.SIGINT)
        thread = threading.Thread(target=worker)
        thread.start()
        thread.join()
    assert raised == [] and seen == []


def test_after_the_block_its_hook_keeps_nothing():
    """A hook set inside the block and put back only after it (not last in, first out)
    leaves ours in place: outside its block it passes every error on, and the next
    block starts with nothing kept."""
    with printed() as seen:
        with interrupts_kept():
            theirs = sys.unraisablehook
            sys.unraisablehook = seen.append  # someone else's, for a while
        sys.unraisablehook = theirs  # put back after our block ended
        RaisesSignalWhenCollected(signal.SIGINT)
        with interrupts_kept():
            raise_dropped()
    assert [type(u.exc_value) for u in seen] == [KeyboardInterrupt]


def _drop_case() -> tuple[dict, object]:
    from beamcontact.api import load_case
    from beamcontact.io.case import parse_case
    from beamcontact.setup.start import dynamic_start, prepare

    case = load_case(REPO / "examples" / "free_fall" / "case_cg.toml")
    raw = case.model_dump(mode="json", exclude_none=True)
    return raw, dynamic_start(prepare(parse_case(raw)))


def test_a_step_loop_stops_after_a_dropped_interrupt_with_every_step_kept():
    """An interrupt dropped while the run's on_step works (here: in a finalizer there,
    as JAX's collection callback would drop it) stops the run after that batch of
    steps, every step handed over once, in order."""
    from beamcontact.dynamics.driver import solve_dynamic

    raw, start = _drop_case()
    rows = []

    def on_step(step):
        rows.append(step)
        if len(rows) == 5:
            RaisesSignalWhenCollected(signal.SIGINT)

    with printed() as seen, pytest.raises(KeyboardInterrupt):
        solve_dynamic(start.engine, start.state, raw["analysis"]["t_end"],
                      start.prepared.length, start.control, on_step=on_step)
    assert len(rows) >= 5 and rows[-1].t < raw["analysis"]["t_end"]
    assert [r.step for r in rows] == list(range(1, len(rows) + 1))
    assert seen == []


class FailingAttempts:
    """The engine's attempts one by one (the host loop), the tenth dropping an interrupt
    in a finalizer and then failing."""

    runs_loop = False

    def __init__(self, engine):
        self._engine, self.made = engine, 0
        self.name, self.contact = engine.name, engine.contact

    def __getattr__(self, name):
        return getattr(self._engine, name)

    def attempt(self, *args):
        self.made += 1
        if self.made == 10:
            RaisesSignalWhenCollected(signal.SIGINT)
            raise ValueError("the tenth attempt")
        return self._engine.attempt(*args)


def test_an_error_on_its_way_out_is_not_replaced_by_a_dropped_interrupt():
    """The steps accepted before an error are handed over as it leaves the loop; an
    interrupt dropped meanwhile does not take the error's place (the run failed; the
    interrupt came too late to stop it)."""
    from beamcontact.dynamics.driver import solve_dynamic

    raw, start = _drop_case()
    rows = []
    with printed() as seen, pytest.raises(ValueError, match="the tenth attempt"):
        solve_dynamic(FailingAttempts(start.engine), start.state, raw["analysis"]["t_end"],
                      start.prepared.length, start.control, on_step=rows.append)
    assert [r.step for r in rows] == list(range(1, len(rows) + 1)) and len(rows) >= 5
    assert seen == []
    raise_dropped()  # let go with the error
