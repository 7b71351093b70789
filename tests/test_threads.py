"""The thread count of the parallel kernels follows the cores other processes leave free
(_native.CoreShare): the count from the busy time of the cores, at least 1, at most the
process's own limit; results never depend on it (tests/test_native_loop.py)."""

import numba
import pytest

from beamcontact import _native


class _Clock:
    """A fake /proc/stat reading: wall, CPU time of all processes, of this process."""

    def __init__(self):
        self.now = (0.0, 0.0, 0.0)

    def advance(self, wall, others, own):
        w, busy, mine = self.now
        self.now = (w + wall, busy + others + own, mine + own)

    def __call__(self):
        return self.now


@pytest.fixture
def restore_threads():
    before = numba.get_num_threads()
    yield
    numba.set_num_threads(before)


@pytest.fixture
def two_cores(monkeypatch, restore_threads):
    monkeypatch.setattr(_native, "_most_threads", 2)


def test_threads_follow_the_free_cores(two_cores, monkeypatch):
    if numba.config.NUMBA_NUM_THREADS < 2:
        pytest.skip("one thread only on this machine")
    clock = _Clock()
    share = _native.CoreShare(window=0.25, sample=clock)
    share.cores = 2
    clock.advance(0.5, 0.0, 1.0)  # alone: both cores ours
    assert share.update() == 2 and numba.get_num_threads() == 2
    clock.advance(0.5, 0.5, 0.5)  # another process keeps one core busy
    assert share.update() == 1 and numba.get_num_threads() == 1
    clock.advance(0.1, 0.0, 0.1)  # too short a window: no new reading
    assert share.update() == 1
    clock.advance(0.5, 0.05, 0.5)  # it has gone (a little noise)
    assert share.update() == 2


def test_one_thread_until_the_first_reading(two_cores):
    """A run's loop starts while the drawer that the command line started imports on the
    other core: one thread until a window of readings says the cores are free."""
    if numba.config.NUMBA_NUM_THREADS < 2:
        pytest.skip("one thread only on this machine")
    clock = _Clock()
    share = _native.CoreShare(window=0.25, sample=clock)
    share.cores = 2
    assert share.threads == 1 and numba.get_num_threads() == 1
    clock.advance(0.1, 0.1, 0.1)  # within the first window: still one
    assert share.update() == 1
    clock.advance(0.4, 0.0, 0.4)  # the drawer asleep: both cores ours
    assert share.update() == 2 and numba.get_num_threads() == 2


def test_the_limit_of_a_sweep_worker_holds(monkeypatch, restore_threads):
    monkeypatch.setattr(_native, "_most_threads", 1)
    clock = _Clock()
    share = _native.CoreShare(window=0.25, sample=clock)
    share.cores = 2
    clock.advance(1.0, 0.0, 1.0)
    assert share.update() == 1 and numba.get_num_threads() == 1


def test_without_proc_stat_the_count_stays(two_cores):
    share = _native.CoreShare(sample=lambda: None)
    assert share.update() == share.most
