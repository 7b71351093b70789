"""Command line polish (issue 11 item 6): --version, help texts that keep their brackets,
progress displays within 80 columns, and the exit on an interrupted run."""

import gc
import io
import json
import os
import re
import subprocess
import sys
import time
import types

import pytest
import typer
from rich.console import Console
from rich.text import Text
from typer.testing import CliRunner

import beamcontact
from beamcontact.cli import app
from beamcontact.drawer import Drawer
from beamcontact.progress import ProgressInfo, SweepProgress, progress_bar

WIDTH = 80
LONG_TITLE = "Free fall of an elastic beam onto another beam, [solver] study " * 3
_ANSI = re.compile(r"\x1b\[[0-9;?]*[A-Za-z]")


def _cli(*args, **env):
    return subprocess.run([sys.executable, "-m", "beamcontact.cli", *args], capture_output=True,
                          text=True, timeout=120, env={**os.environ, **env})


def _lines(text: str) -> list[str]:
    """The screen lines of terminal output: escape sequences and carriage returns split it."""
    return re.split(r"[\r\n]", _ANSI.sub("\n", text))


def _widest(text: str) -> int:
    return max(len(line) for line in _lines(text))


# --- --version and help ------------------------------------------------------------------

def test_version_prints_the_package_version_without_jax():
    code = ("import sys\nfrom beamcontact.cli import main\n"
            "sys.argv = ['beamcontact', '--version']\n"
            "try:\n    main()\nexcept SystemExit as exc:\n    code = exc.code\n"
            "print('jax imported' if 'jax' in sys.modules else 'no jax', code)")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.splitlines() == [f"beamcontact {beamcontact.__version__}", "no jax 0"]


def test_version_through_the_command_line():
    proc = _cli("--version")
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout == f"beamcontact {beamcontact.__version__}\n"


def test_no_arguments_still_shows_help():
    proc = _cli(COLUMNS="100")
    assert "Usage: beamcontact" in proc.stdout
    for text in ("--version", "run", "sweep", "check", "compare"):
        assert text in proc.stdout


def test_run_help_keeps_square_brackets():
    proc = _cli("run", "--help", COLUMNS="100")
    assert proc.returncode == 0, proc.stderr
    assert "[solver]" in proc.stdout and "[output]" in proc.stdout
    assert "t_end,  and" not in proc.stdout


def test_sweep_help_keeps_square_brackets():
    proc = _cli("sweep", "--help", COLUMNS="100")
    assert proc.returncode == 0, proc.stderr
    assert "[0, -9.81]" in proc.stdout


@pytest.mark.parametrize("command", ["run", "sweep", "check", "compare"])
@pytest.mark.parametrize("columns", [80, 100])
def test_command_help_fills_the_terminal_width(command, columns):
    """The prose of a command's help wraps at the terminal's width only: no line of a
    paragraph ends early because the docstring's source line did."""
    proc = _cli(command, "--help", COLUMNS=str(columns))
    assert proc.returncode == 0, proc.stderr
    prose = proc.stdout.split("Usage:", 1)[1].split("╭", 1)[0].splitlines()[1:]
    lines = [line.strip() for line in prose]
    for line, after in zip(lines[:-1], lines[1:], strict=True):
        if line and after:  # inside a paragraph: the next word did not fit on this line
            assert len(line) + 1 + len(after.split()[0]) > columns - 2, (line, after)


def _help_texts():
    """(where, help text) of the app, every command and every parameter."""
    group = typer.main.get_command(app)
    yield "beamcontact", group.help or ""
    for name, command in group.commands.items():
        yield name, command.help or ""
        for param in command.params:
            yield f"{name} {param.name}", getattr(param, "help", None) or ""


@pytest.mark.parametrize("where,text", list(_help_texts()))
def test_no_help_text_loses_characters_to_markup(where, text):
    """Rich markup renders each help text to itself with only the escapes removed."""
    assert Text.from_markup(text).plain == text.replace("\\[", "["), where


# --- the run's progress bar --------------------------------------------------------------

def _drive(bar, infos, pause=0.0):
    for info in infos:
        bar(info)
        time.sleep(pause)


DYNAMIC = [ProgressInfo(0.0, "t", 0.0, 0),
           ProgressInfo(0.4, "t", 1.23456789e-5, 12, 1.234e-10, 123),
           ProgressInfo(1.0, "t", 12345.678, 987654, 1.0e-3, 7)]
STATIC = [ProgressInfo(0.5, "load_factor", 0.5, 5, None, 4),
          ProgressInfo(1.0, "load_factor", 1.0, 10, None, 3)]


@pytest.mark.parametrize("width", [WIDTH, 110])
@pytest.mark.parametrize("infos", [DYNAMIC, STATIC], ids=["dynamic", "static"])
def test_progress_bar_fits_in_80_columns(width, infos):
    out = io.StringIO()
    with progress_bar(LONG_TITLE, console=Console(file=out, width=width)) as bar:
        _drive(bar, infos)
    lines = out.getvalue().splitlines()
    assert len(lines) == 2  # the title, then the bar in its last state
    assert max(len(line) for line in lines) <= WIDTH
    assert lines[0].startswith("Free fall of an elastic beam onto another beam, [solver]")
    assert lines[0].endswith("\u2026") and "Free fall" not in lines[1]
    assert "100%" in lines[1] and "eta" in lines[1]


def test_progress_bar_shows_time_step_and_iterations():
    out = io.StringIO()
    with progress_bar("drop", console=Console(file=out, width=110)) as bar:
        bar(ProgressInfo(0.25, "t", 0.75, 30, 2.5e-3, 3))
    title, line = out.getvalue().splitlines()
    assert title == "drop"
    assert re.search(r" 25% t 0\.75 s +dt 2\.5e-03 s it 3 +\d:\d\d:\d\d eta ", line), line


def test_progress_bar_redraws_in_place_within_80_columns():
    """On a terminal the bar is redrawn on one line (never wrapped) while the run goes on."""
    out = io.StringIO()
    console = Console(file=out, width=110, force_terminal=True)
    with progress_bar(LONG_TITLE, console=console) as bar:
        _drive(bar, [ProgressInfo(k / 4, "t", 0.3 * k, 10 * k, 1e-3, 2) for k in range(5)],
               pause=0.15)
    text = out.getvalue()
    assert _widest(text) <= WIDTH
    assert text.count("Free fall of an elastic beam") == 1
    assert "\r" in text  # redrawn in place


def test_disabled_progress_bar_draws_nothing(capsys):
    out = io.StringIO()
    with progress_bar("quiet run", enabled=False, console=Console(file=out, width=110)) as bar:
        assert bar(DYNAMIC[1]) is None
    assert out.getvalue() == ""
    assert capsys.readouterr() == ("", "")


def test_importing_progress_does_not_import_rich():
    code = "import sys, beamcontact.progress; print('rich' in sys.modules)"
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=120)
    assert proc.stdout.strip() == "False", proc.stderr


# --- the sweep's progress ------------------------------------------------------------------

def test_sweep_progress_fits_in_80_columns():
    long_name = "beams.upper.material.E=1e9_contact.penalty=1e6_flag=[true]_alpha=-0.33"
    out = io.StringIO()
    display = SweepProgress(3, console=Console(file=out, width=110, force_terminal=True))
    with display:
        events = display.events()
        events.started(2, 1)
        events.progress(long_name, 0.5, DYNAMIC[1].text())
        events.progress("short", 0.25, ProgressInfo(0.25, "t", 0.75, 30, 2.5e-3, 3).text())
        time.sleep(0.3)
        events.finished(types.SimpleNamespace(name="short"), {"status": "completed",
                                                              "wall_time_s": 1.5})
    lines = _lines(out.getvalue())
    assert max(len(line) for line in lines) <= WIDTH
    assert any("alpha=-0.33" in line for line in lines)  # names are cut from the left
    assert "short: completed (1.5 s)" in lines


def test_sweep_worker_forwards_fraction_and_text(monkeypatch):
    """A worker turns the runner's ProgressInfo into a JSON-simple event."""
    import distributed

    import beamcontact.sweep as sweep

    sent = []
    worker = types.SimpleNamespace(log_event=lambda topic, msg: sent.append((topic, msg)))
    monkeypatch.setattr(distributed, "get_worker", lambda: worker)

    def fake_member(member, run_dir, report):
        report(ProgressInfo(0.25, "t", 0.75, 30, 2.5e-3, 3))
        report(ProgressInfo(0.5, "t", 1.5, 60, 2.5e-3, 2))  # within 0.5 s: not sent
        return {"status": "completed"}

    monkeypatch.setattr(sweep, "run_member", fake_member)
    member = types.SimpleNamespace(name="m1")
    assert sweep._run_on_worker(member, "unused") == {"status": "completed"}
    assert [t for t, _ in sent] == [sweep.PROGRESS_TOPIC] * 2
    assert [m for _, m in sent] == [
        {"run": "m1", "fraction": 0.0, "info": "starting"},
        {"run": "m1", "fraction": 0.25, "info": "t 0.75 s  dt 2.5e-03 s  it 3"}]
    json.dumps([m for _, m in sent])  # JSON-simple


# --- run: progress callback and interrupts -----------------------------------------------

SUMMARY = {"status": "completed", "message": "t_end reached", "steps": 3,
           "newton_iterations": 7, "cutbacks": 0, "wall_time_s": 1.0, "compile_time_s": 0.5}


@pytest.fixture
def fake_runner(monkeypatch):
    """Replace the runner (and the compilation cache switch) for `run`; returns a dict in
    which the test puts what run_case does (``"do"``) and finds its progress callback."""
    import beamcontact._cache

    calls = {}

    def run_case(case, text, out, progress, restart=False, overwrite=False, drawer=None):
        calls["progress"] = progress
        calls["drawer"] = drawer
        return calls["do"](progress)

    module = types.ModuleType("beamcontact.runner")
    module.run_case = run_case
    monkeypatch.setitem(sys.modules, "beamcontact.runner", module)
    monkeypatch.setattr(beamcontact._cache, "enable_compilation_cache", lambda: None)
    return calls


@pytest.mark.parametrize(("by", "code"), [(None, 130), ("SIGTERM", 143)])
def test_a_run_interrupted_while_drawing_exits_as_interrupted(fake_runner, tmp_path, by,
                                                              code):
    """The steps completed, the figures were not drawn: the exit code says it was stopped
    (a scheduler's SIGTERM is not a success), the message what is there."""
    figures = f"not drawn: interrupted by {by or 'the user'}"
    fake_runner["do"] = lambda progress: {**SUMMARY, "figures": figures, "signal": by}
    result = CliRunner().invoke(app, ["run", "--out", str(tmp_path / "out")])
    assert result.exit_code == code, result.output
    assert "completed: t_end reached" in result.stdout
    assert (f"interrupted by {by or 'the user'} while drawing the figures: every result "
            f"but the figures is in") in result.stderr


def test_run_hands_a_progress_info_callback_to_the_runner(fake_runner, tmp_path):
    def do(progress):
        for info in DYNAMIC:
            progress(info)
        return SUMMARY

    fake_runner["do"] = do
    result = CliRunner().invoke(app, ["run", "--out", str(tmp_path / "out")])
    assert result.exit_code == 0, result.output
    assert result.stdout.count("Free fall of an elastic beam onto another beam") == 1
    assert "completed: t_end reached" in result.stdout
    # the command line's process is its own: its figures are drawn by a drawer
    if sys.platform.startswith("linux") and (os.cpu_count() or 1) > 1:
        assert isinstance(fake_runner["drawer"], Drawer)
    assert max(len(line) for line in result.stdout.splitlines()) <= WIDTH


@pytest.mark.parametrize("ends", ["completed", "interrupted"])
def test_the_collector_runs_while_the_steps_run_and_is_restored(fake_runner, tmp_path, ends):
    """`run` pauses Python's cyclic garbage collector while a run starts (what the start
    makes lives as long as the process), runs it while the steps run, pauses it again
    when they reach the end (the figures, the exit) and leaves it as it was, also when
    the run is interrupted."""
    seen = []

    def do(progress):
        seen.append(gc.isenabled())
        progress(ProgressInfo(0.5, "t", 1.0, 10, 1e-3, 2))
        seen.append(gc.isenabled())
        if ends == "interrupted":
            raise KeyboardInterrupt
        progress(ProgressInfo(1.0, "t", 2.0, 20, 1e-3, 2))
        seen.append(gc.isenabled())
        return SUMMARY

    fake_runner["do"] = do
    assert gc.isenabled()
    result = CliRunner().invoke(app, ["run", "--out", str(tmp_path / "out"), "--quiet"])
    assert result.exit_code == (0 if ends == "completed" else 130), result.output
    assert seen == ([False, True, False] if ends == "completed" else [False, True])
    assert gc.isenabled()


def test_interrupted_run_exits_130_and_says_where_results_are(fake_runner, tmp_path):
    out = tmp_path / "out"
    fake_runner["do"] = lambda progress: {**SUMMARY, "status": "interrupted",
                                          "message": "interrupted by the user"}
    result = CliRunner().invoke(app, ["run", "--out", str(out), "--quiet"])
    assert result.exit_code == 130
    message = f"interrupted; results up to the last accepted step are in {out}"
    assert result.stderr.strip() == message
    assert result.stdout == ""


def test_interrupt_outside_the_step_loop_exits_130(fake_runner, tmp_path):
    out = tmp_path / "out"

    def do(progress):
        raise KeyboardInterrupt

    fake_runner["do"] = do
    result = CliRunner().invoke(app, ["run", "--out", str(out)])
    assert result.exit_code == 130
    assert f"interrupted; results up to the last accepted step are in {out}" in result.stderr
