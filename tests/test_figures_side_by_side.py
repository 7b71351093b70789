"""record._side_by_side: the figures of a command-line run drawn half in a forked copy
of the process, and what happens when that copy fails, hangs or the parent is
interrupted: every figure is drawn once where it can be, errors are raised in the
parent, and no copy is left behind."""

import os
import sys
import time
import types

import pytest

from beamcontact import record

fork_only = pytest.mark.skipif(not sys.platform.startswith("linux")
                               or (os.cpu_count() or 1) < 2,
                               reason="forks on Linux with a second core only")


@pytest.fixture(autouse=True)
def _as_a_native_run(monkeypatch):
    """The process of a native run, which has not imported JAX (other tests of the
    session have: its fork warning is left out)."""
    monkeypatch.delitem(sys.modules, "jax", raising=False)


pytestmark = pytest.mark.filterwarnings("ignore:os.fork:RuntimeWarning")


def _mark(folder, name):
    """A call that writes the id of the process that made it into folder/name."""
    return lambda: (folder / name).write_text(str(os.getpid()))


def _made_by(folder, name):
    return int((folder / name).read_text())


@fork_only
def test_the_second_half_is_drawn_in_a_copy(tmp_path):
    record._side_by_side([_mark(tmp_path, "a"), _mark(tmp_path, "b")],
                         [_mark(tmp_path, "c"), _mark(tmp_path, "d")], fork=True)
    here = os.getpid()
    assert _made_by(tmp_path, "a") == _made_by(tmp_path, "b") == here
    copy = _made_by(tmp_path, "c")
    assert copy == _made_by(tmp_path, "d") != here
    with pytest.raises(ChildProcessError):  # collected: no zombie left
        os.waitpid(copy, os.WNOHANG)


def test_without_fork_everything_is_drawn_here(tmp_path, monkeypatch):
    record._side_by_side([_mark(tmp_path, "a")], [_mark(tmp_path, "c")], fork=False)
    assert _made_by(tmp_path, "a") == _made_by(tmp_path, "c") == os.getpid()
    # nor with JAX imported (the JAX engine): its threads and its fork warning
    monkeypatch.setitem(sys.modules, "jax", types.ModuleType("jax"))
    record._side_by_side([_mark(tmp_path, "a")], [_mark(tmp_path, "d")], fork=True)
    assert _made_by(tmp_path, "d") == os.getpid()


@fork_only
def test_a_failing_copy_leaves_its_half_to_the_parent(tmp_path):
    here = os.getpid()

    def fails_in_the_copy():
        if os.getpid() != here:
            raise OSError("no room")
        _mark(tmp_path, "c")()

    record._side_by_side([_mark(tmp_path, "a")], [fails_in_the_copy], fork=True)
    assert _made_by(tmp_path, "c") == here

    def fails_everywhere():
        raise OSError("no room")

    with pytest.raises(OSError, match="no room"):  # the parent's error is the run's
        record._side_by_side([_mark(tmp_path, "a")], [fails_everywhere], fork=True)


@fork_only
def test_a_hanging_copy_is_stopped_and_its_half_drawn_here(tmp_path, monkeypatch):
    monkeypatch.setattr(record, "FORK_GRACE_S", 0.3)
    here = os.getpid()

    def hangs_in_the_copy():
        if os.getpid() != here:
            time.sleep(600)
        _mark(tmp_path, "c")()

    start = time.monotonic()
    record._side_by_side([_mark(tmp_path, "a")], [hangs_in_the_copy], fork=True)
    assert time.monotonic() - start < 30.0
    assert _made_by(tmp_path, "c") == here


@fork_only
def test_an_interrupt_stops_the_copy_and_draws_nothing_more(tmp_path, monkeypatch):
    here = os.getpid()
    copies = []
    forked = record._forked
    monkeypatch.setattr(record, "_forked", lambda calls: copies.append(forked(calls))
                        or copies[-1])

    def interrupted():
        raise KeyboardInterrupt

    def slow_in_the_copy():
        if os.getpid() != here:
            time.sleep(600)
        _mark(tmp_path, "c")()

    with pytest.raises(KeyboardInterrupt):
        record._side_by_side([interrupted], [slow_in_the_copy], fork=True)
    assert not (tmp_path / "c").exists()
    assert copies and copies[0] > 0
    with pytest.raises(ChildProcessError):  # stopped and collected
        os.waitpid(copies[0], os.WNOHANG)
