"""beamcontact.drawer: the figures of a command-line run drawn by a process started with
the run, half by it and half by a forked copy of it, and what happens when the drawer
fails, hangs, or the run is interrupted or ends without figures: every figure is drawn
once where it can be, errors are raised in the run, and no process is left behind."""

import os
import pickle
import selectors
import sys
import textwrap
import time

import pytest

from beamcontact import drawer as drawer_module
from beamcontact._compile_claims import process_alive
from beamcontact.drawer import Drawer, draw_here

linux_only = pytest.mark.skipif(not sys.platform.startswith("linux")
                                or (os.cpu_count() or 1) < 2,
                                reason="the copy is forked on Linux, with a second core")

# functions the drawer can import: a module in a folder on its PYTHONPATH
_FIGURES = """
import os, time
from pathlib import Path

def mark(folder, name):
    Path(folder, name).write_text(str(os.getpid()))

def fails_unless_in(pid, folder, name):
    if os.getpid() != pid:
        raise OSError("no room")
    mark(folder, name)

def hangs_unless_in(pid, folder, name):
    if os.getpid() != pid:
        Path(folder, name + ".hung").write_text(str(os.getpid()))
        time.sleep(600)
    mark(folder, name)
"""


@pytest.fixture
def figures(tmp_path, monkeypatch):
    """The folder the test figures are written into; their module importable by the
    drawer (and here) as ``figs_for_tests``."""
    code = tmp_path / "code"
    code.mkdir()
    (code / "figs_for_tests.py").write_text(textwrap.dedent(_FIGURES))
    monkeypatch.syspath_prepend(str(code))
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join(
        [str(code), *([os.environ["PYTHONPATH"]] if os.environ.get("PYTHONPATH") else [])]))
    out = tmp_path / "out"
    out.mkdir()
    return out


def _mark(out, name):
    return ("figs_for_tests:mark", (str(out), name), {})


def _made_by(out, name) -> int:
    return int((out / name).read_text())


def _gone(pid: int, within: float = 10.0) -> bool:
    """Whether process ``pid`` ends within ``within`` seconds (a zombie counts: an orphan
    is collected by whatever adopted it, which in a container may never do so)."""
    deadline = time.monotonic() + within
    while time.monotonic() < deadline:
        if not process_alive(pid):
            return True
        time.sleep(0.02)
    return False


@linux_only
def test_the_halves_are_drawn_by_the_drawer_and_its_copy(figures):
    with Drawer.started() as drawer:
        assert drawer.draw([_mark(figures, "a"), _mark(figures, "b")],
                           [_mark(figures, "c"), _mark(figures, "d")])
        pid = drawer.process.pid
        # both have exited, the copy collected by the drawer, the drawer by the run
        assert drawer.process.returncode == 0
    here = os.getpid()
    assert _made_by(figures, "a") == _made_by(figures, "b") == pid != here
    copy = _made_by(figures, "c")
    assert copy == _made_by(figures, "d") not in (pid, here)
    with pytest.raises(ProcessLookupError):
        os.kill(copy, 0)


def test_plot_functions_by_name_are_those_of_beamcontact_plot(figures):
    draw_here([_mark(figures, "a")])
    assert _made_by(figures, "a") == os.getpid()
    from beamcontact import plot

    name, args, kwargs = ("plot_energies", ({"t": [0.0, 1.0], "E_total": [1.0, 1.0]},
                                            figures / "e.png"), {})
    draw_here([(name, args, kwargs)])
    assert (figures / "e.png").stat().st_size > 0 and callable(plot.plot_energies)


def test_no_drawer_on_one_core(monkeypatch):
    monkeypatch.setattr(drawer_module, "usable_cores", lambda: 1)
    with Drawer.started() as drawer:
        assert drawer is None


@linux_only
def test_a_drawer_with_another_beamcontact_leaves_the_figures_to_the_run(figures,
                                                                          monkeypatch):
    monkeypatch.setattr(drawer_module, "_package", lambda: "/elsewhere/beamcontact")
    with Drawer.started() as drawer:
        assert not drawer.draw([_mark(figures, "a")], [_mark(figures, "b")])
        assert drawer.process.returncode == 1
    assert _made_by(figures, "a") == _made_by(figures, "b") == os.getpid()
    assert drawer.failure == "RuntimeError: another beamcontact than the run's"


@linux_only
def test_a_run_without_figures_leaves_no_drawer_behind():
    with Drawer.started() as drawer:
        pid = drawer.process.pid
    assert drawer.process.poll() is not None and _gone(pid)
    # nor when its input closes: it exits by itself, cleanly
    with Drawer.started() as drawer:
        drawer.process.stdin.close()
        assert drawer.process.wait(timeout=120) == 0


@linux_only
def test_a_failing_drawer_leaves_every_figure_to_the_run(figures):
    here = os.getpid()
    fails = ("figs_for_tests:fails_unless_in", (here, str(figures), "c"), {})
    with Drawer.started() as drawer:
        assert not drawer.draw([_mark(figures, "a")], [fails])
    assert _made_by(figures, "a") == _made_by(figures, "c") == here
    assert drawer.failure == "OSError: no room"
    # where it fails here too, the error is the run's
    fails_everywhere = ("figs_for_tests:fails_unless_in", (-1, str(figures), "d"), {})
    with Drawer.started() as drawer, pytest.raises(OSError, match="no room"):
        drawer.draw([fails_everywhere], [])


@linux_only
def test_a_hanging_drawer_is_stopped_and_the_figures_drawn_here(figures, monkeypatch):
    monkeypatch.setattr(drawer_module, "STALL_S", 3.0)  # once it has imported
    here = os.getpid()
    hangs = ("figs_for_tests:hangs_unless_in", (here, str(figures), "c"), {})
    start = time.monotonic()
    with Drawer.started() as drawer:
        assert not drawer.draw([_mark(figures, "a")], [hangs])
    assert time.monotonic() - start < 60.0
    assert drawer.failure == "it reported no figure for 3 s"
    assert _made_by(figures, "c") == here
    hung = int((figures / "c.hung").read_text())  # the drawer's copy
    assert hung != here and _gone(hung)


@linux_only
def test_an_interrupt_stops_the_drawer_and_draws_nothing_here(figures, monkeypatch):
    here = os.getpid()
    hangs = ("figs_for_tests:hangs_unless_in", (here, str(figures), "c"), {})
    real = drawer_module._wait_for

    def interrupted(fd, event, timeout):
        """Ctrl-C while the run waits for the reports, once the figure hangs."""
        if event != selectors.EVENT_READ:
            return real(fd, event, timeout)
        deadline = time.monotonic() + 60.0
        while not (figures / "c.hung").exists() and time.monotonic() < deadline:
            time.sleep(0.02)
        raise KeyboardInterrupt

    monkeypatch.setattr(drawer_module, "_wait_for", interrupted)
    with Drawer.started() as drawer, pytest.raises(KeyboardInterrupt):
        drawer.draw([hangs], [])
    assert not (figures / "c").exists()
    assert drawer.process.poll() is not None
    assert _gone(int((figures / "c.hung").read_text()))


def test_waiting_takes_any_descriptor_number():
    """The run's pipes may have numbers past select()'s 1024 (a process with many files
    open, such as a notebook): the wait is a selector's."""
    resource = pytest.importorskip("resource")
    soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    high = 1500
    if hard != resource.RLIM_INFINITY and hard <= high:
        pytest.skip(f"at most {hard} descriptors here")
    resource.setrlimit(resource.RLIMIT_NOFILE, (max(soft, high + 1), hard))
    read, write = os.pipe()
    try:
        os.dup2(read, high)
        assert not drawer_module._wait_for(high, selectors.EVENT_READ, 0.01)
        os.write(write, b".")
        assert drawer_module._wait_for(high, selectors.EVENT_READ, 5.0)
    finally:
        for fd in (read, write, high):
            os.close(fd)
        resource.setrlimit(resource.RLIMIT_NOFILE, (soft, hard))


@linux_only
def test_a_run_warns_when_its_drawer_failed(tmp_path, monkeypatch):
    """The figures drawn by the run after its drawer failed: all there, and the summary
    says why the drawer did not draw them."""
    import beamcontact as bc
    from beamcontact.examples import path
    from beamcontact.runner import run_case

    case = bc.load_case(path("free_fall", "case_cg.toml"))
    case = case.model_copy(update={"analysis": case.analysis.model_copy(
        update={"t_end": 0.02})})
    monkeypatch.setattr(drawer_module, "_package", lambda: "/elsewhere/beamcontact")
    with Drawer.started() as drawer:
        summary = run_case(case, "", tmp_path / "out", drawer=drawer)
    assert summary["status"] == "completed"
    assert ("the figures were drawn by the run itself, not by its drawer process "
            "(beamcontact/drawer.py): RuntimeError: another beamcontact than the run's"
            in summary["warnings"])
    assert (tmp_path / "out" / "plots" / "energies.png").stat().st_size > 0


@linux_only
def test_a_run_draws_its_figures_in_the_drawer(tmp_path, monkeypatch):
    """A short run of the bundled drop: its figures sent as data (pickled), drawn by the
    drawer, not here."""
    import beamcontact as bc
    from beamcontact.examples import path
    from beamcontact.runner import run_case

    case = bc.load_case(path("free_fall", "case_cg.toml"))
    case = case.model_copy(update={"analysis": case.analysis.model_copy(
        update={"t_end": 0.02})})
    drawn, draw = [], Drawer.draw
    monkeypatch.setattr(Drawer, "draw", lambda self, *calls: drawn.append(draw(self, *calls))
                        or drawn[-1])
    with Drawer.started() as drawer:
        summary = run_case(case, "", tmp_path / "out", drawer=drawer)
    assert summary["status"] == "completed" and drawn == [True]
    for name in ("plots/shapes.png", "plots/points.png", "plots/energies.png",
                 "plots/snapshots.png", "animation.gif"):
        assert (tmp_path / "out" / name).stat().st_size > 0


def test_obstacles_reach_the_drawer_as_they_are():
    """The one object of the case in the figures' data: the obstacles (pydantic)."""
    import beamcontact as bc
    from beamcontact.examples import path

    case = bc.load_case(path("fibre_pile", "case_cg.toml"))
    assert len(case.obstacles) == 3
    assert pickle.loads(pickle.dumps(case.obstacles)) == case.obstacles


@pytest.mark.parametrize("signal_name", [None, "SIGTERM"])
def test_figures_interrupted_are_in_the_summary(signal_name):
    """A Ctrl-C or a signal while the figures are drawn: the summary keeps the status of
    the steps and says the figures were not drawn, and by what (the command line exits
    as interrupted then: tests/test_cli_polish.py)."""
    import signal

    from beamcontact import runner
    from beamcontact.stop_signals import Terminated

    class Record:
        def close(self):
            pass

        def plots(self, drawer):
            raise (KeyboardInterrupt() if signal_name is None
                   else Terminated(signal.Signals[signal_name]))

    summary = {"status": "completed"}
    runner._finish(Record(), summary, None)
    by = signal_name or "the user"
    assert summary == {"status": "completed", "figures": f"not drawn: interrupted by {by}",
                       "signal": signal_name}
