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


@pytest.fixture
def ctrl_c():
    """Python's own SIGINT handler (a process started in the background by a
    non-interactive shell ignores SIGINT), and the unraisable errors printed."""
    handler = signal.signal(signal.SIGINT, signal.default_int_handler)
    dropped = []
    hook, sys.unraisablehook = sys.unraisablehook, dropped.append
    try:
        yield dropped
    finally:
        sys.unraisablehook = hook
        signal.signal(signal.SIGINT, handler)


def test_python_drops_an_interrupt_raised_in_a_finalizer(ctrl_c):
    """The defect the others guard against: without interrupts_kept, Ctrl-C raised in a
    finalizer is printed as unraisable and the code after it runs to its end."""
    RaisesSignalWhenCollected(signal.SIGINT)
    assert _work() == 200_000 * 199_999 // 2
    assert [type(u.exc_value) for u in ctrl_c] == [KeyboardInterrupt]


def test_ctrl_c_dropped_in_a_finalizer_is_raised_where_asked(ctrl_c):
    with interrupts_kept():
        RaisesSignalWhenCollected(signal.SIGINT)
        _work()
        with pytest.raises(KeyboardInterrupt):
            raise_dropped()
        raise_dropped()  # once
    assert ctrl_c == []  # kept, not printed
    assert sys.unraisablehook == ctrl_c.append  # the earlier hook is back


def test_ctrl_c_dropped_in_a_garbage_collection_callback_is_raised_at_the_end(ctrl_c):
    """As JAX's callback (jax._src.lib._xla_gc_callback) runs at every collection."""
    calls = []

    def callback(phase, info):
        del info
        if phase == "start" and not calls:
            calls.append(phase)
            signal.raise_signal(signal.SIGINT)

    gc.callbacks.append(callback)
    finished = []
    try:
        with pytest.raises(KeyboardInterrupt), interrupts_kept():
            gc.collect()
            finished.append(_work())
    finally:
        gc.callbacks.remove(callback)
    assert calls == ["start"] and finished and ctrl_c == []


def test_a_sigterm_dropped_before_the_step_loop_stops_it(ctrl_c):
    """The first SIGTERM, dropped in a finalizer while the run prepares (the command
    line's block), is raised by the step loop's block; a second one, while the run writes
    what it holds, is ignored."""
    with stop_signals_interrupt():
        RaisesSignalWhenCollected(signal.SIGTERM)
        with pytest.raises(Terminated) as caught, interrupts_kept():
            raise_dropped()
        signal.raise_signal(signal.SIGTERM)
        assert _work() == 200_000 * 199_999 // 2
    assert caught.value.signum == signal.SIGTERM and ctrl_c == []


def test_a_sigterm_dropped_after_the_work_is_let_go(ctrl_c):
    """Dropped once the step loop has ended, it stops nothing: the run completes, and no
    later block raises it."""
    with stop_signals_interrupt():
        RaisesSignalWhenCollected(signal.SIGTERM)
    with interrupts_kept():
        raise_dropped()
    assert ctrl_c == []


def test_a_block_ended_by_an_error_lets_a_dropped_interrupt_go(ctrl_c):
    with pytest.raises(ValueError), interrupts_kept():
        RaisesSignalWhenCollected(signal.SIGINT)
        raise ValueError
    raise_dropped()
    assert ctrl_c == []


def test_other_unraisable_errors_reach_the_earlier_hook(ctrl_c):
    class FailsWhenCollected:
        def __del__(self):
            raise ValueError("in a finalizer")

    with interrupts_kept():
        FailsWhenCollected()
        raise_dropped()
    assert [type(u.exc_value) for u in ctrl_c] == [ValueError]


def test_a_step_loop_stops_after_a_dropped_interrupt_with_every_step_kept(ctrl_c):
    """An interrupt dropped while the run's on_step works (here: in a finalizer there,
    as JAX's collection callback would drop it) stops the run after that batch of
    steps, every step handed over once, in order."""
    from beamcontact.api import load_case
    from beamcontact.dynamics.driver import solve_dynamic
    from beamcontact.io.case import parse_case
    from beamcontact.setup.start import dynamic_start, prepare

    case = load_case(REPO / "examples" / "free_fall" / "case_cg.toml")
    raw = case.model_dump(mode="json", exclude_none=True)
    start = dynamic_start(prepare(parse_case(raw)))
    rows = []

    def on_step(step):
        rows.append(step)
        if len(rows) == 5:
            RaisesSignalWhenCollected(signal.SIGINT)

    with pytest.raises(KeyboardInterrupt):
        solve_dynamic(start.engine, start.state, raw["analysis"]["t_end"],
                      start.prepared.length, start.control, on_step=on_step)
    assert len(rows) >= 5 and rows[-1].t < raw["analysis"]["t_end"]
    assert [r.step for r in rows] == list(range(1, len(rows) + 1))
    assert ctrl_c == []
