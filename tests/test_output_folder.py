"""One run per output folder (io/output_folder.py): a second run meets the first's lock,
a folder with an earlier run's results is refused unless --overwrite (which removes
them) or --restart, and the refused run leaves the earlier results as they were."""

import subprocess
import sys
import time
import tomllib
from pathlib import Path

import numpy as np
import pytest
import tomli_w

REPO = Path(__file__).resolve().parents[1]
VIBRATION = REPO / "examples" / "pinned_beam_vibration" / "case.toml"


def _cli(*args):
    return subprocess.run([sys.executable, "-m", "beamcontact.cli", *map(str, args)],
                          capture_output=True, text=True, timeout=600)


def _case(tmp_path: Path, t_end: float, name: str = "case.toml") -> Path:
    raw = tomllib.loads(VIBRATION.read_text(encoding="utf-8"))
    raw["analysis"]["t_end"] = t_end
    raw["output"]["vtk_interval"] = 0.002
    path = tmp_path / name
    path.write_text(tomli_w.dumps(raw), encoding="utf-8")
    return path


def _files(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*"))
            if p.is_file() and p.name != ".beamcontact.lock"}


def _one_line(proc, *parts: str) -> None:
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and all(p in lines[0] for p in parts), proc.stderr
    assert "Traceback" not in proc.stderr


def test_a_used_folder_is_refused_unless_overwritten(tmp_path):
    out = tmp_path / "out"
    long_case, short_case = _case(tmp_path, 0.02, "long.toml"), _case(tmp_path, 0.006)
    assert _cli("run", long_case, "--out", out, "-q").returncode == 0
    before = _files(out)
    assert (out / "case.toml").read_text(encoding="utf-8") == long_case.read_text(
        encoding="utf-8")  # the effective case, as a sweep's runs have it
    refused = _cli("run", short_case, "--out", out, "-q")
    assert refused.returncode == 2
    _one_line(refused, f"--out {out}", "results of an earlier run", "--overwrite")
    assert _files(out) == before
    replaced = _cli("run", short_case, "--out", out, "-q", "--overwrite")
    assert replaced.returncode == 0, replaced.stderr
    # nothing of the longer earlier run is left beside the new one's files
    vtu = sorted(p.name for p in (out / "vtk").iterdir())
    assert len(vtu) == 4 and len(before) > len(_files(out))  # t = 0, 2, 4, 6 ms
    assert (out / "case.toml").read_text(encoding="utf-8") == short_case.read_text(
        encoding="utf-8")


_HOLD = """
import sys, time
from filelock import FileLock
lock = FileLock(sys.argv[1], timeout=0)
lock.acquire()
print("held", flush=True)
time.sleep(60)
"""


def test_a_second_run_meets_the_first_runs_lock(tmp_path):
    """Another process holds the folder (as a running run does): a run into it stops at
    once with exit code 2 and writes nothing; once that process is gone (killed, without
    releasing anything itself) the folder is free again."""
    out = tmp_path / "out"
    case = _case(tmp_path, 0.004)
    assert _cli("run", case, "--out", out, "-q").returncode == 0
    before = _files(out)
    holder = subprocess.Popen([sys.executable, "-c", _HOLD, str(out / ".beamcontact.lock")],
                              stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "held"
        for args in ((), ("--overwrite",), ("--restart",)):
            second = _cli("run", case, "--out", out, "-q", *args)
            assert second.returncode == 2
            _one_line(second, f"--out {out}", "another beamcontact run is writing")
            assert _files(out) == before
    finally:
        holder.kill()
        holder.wait()
    time.sleep(0.1)
    assert _cli("run", case, "--out", out, "-q", "--overwrite").returncode == 0


def test_restart_and_overwrite_exclude_each_other(tmp_path):
    proc = _cli("run", _case(tmp_path, 0.004), "--out", tmp_path / "out", "--restart",
                "--overwrite")
    assert proc.returncode == 2
    _one_line(proc, "--restart", "--overwrite")


def test_a_full_disk_ends_the_run_with_its_summary(tmp_path, monkeypatch):
    """The disk fills during a run (its free space reported below what the next batch of
    states needs, as shutil.disk_usage would): the run stops with exit code 1 and one
    line, summary.json says why and where, and what was written is whole and readable:
    history.csv up to the last step and results.h5 up to the last state that fitted."""
    import json

    import h5py
    from typer.testing import CliRunner

    import beamcontact.io.results as results
    import beamcontact.record as record
    from beamcontact.cli import app
    from beamcontact.io.results import read_history

    flushes = []

    def free(path):
        if path.name == "results.h5":  # the writer of the states asks before each batch
            flushes.append(path)
            return 2**40 if len(flushes) < 3 else 0
        return 2**40

    monkeypatch.setattr(results, "free_space", free)
    monkeypatch.setattr(record, "free_space", free)
    monkeypatch.setattr(results.StateWriter, "flush_seconds", 0.0)  # a batch per state
    out = tmp_path / "out"
    result = CliRunner().invoke(app, ["run", str(_case(tmp_path, 0.01)), "--out", str(out),
                                      "-q"])
    assert result.exit_code == 1, result.output
    assert "Traceback" not in result.output
    summary = json.loads((out / "summary.json").read_text(encoding="utf-8"))
    assert summary["status"] == "output_failed"
    # the steps of the compiled loop's call that met the full disk are in history.csv
    # (written before the states); how many there are depends on the machine's speed
    steps = summary["steps"]
    assert steps >= 2
    history = read_history(out / "history.csv")
    assert list(history["step"]) == list(range(steps + 1))
    assert "its disk is full" in summary["message"]
    assert f"t = {history['t'][-1]:.6g} s after {steps} steps" in summary["message"]
    with h5py.File(out / "results.h5", "r") as f:
        # the first state, then the first call's single step; the third batch did not fit
        assert list(f["states/step"][:]) == [0, 1]


_SIGNALLED = """
import os, signal, sys, threading
from beamcontact.cli import main
from beamcontact.record import RunRecord

rows, signum, at_step = RunRecord.rows, int(sys.argv[3]), int(sys.argv[4])
def send_at_step(self, steps, *args, **kwargs):
    rows(self, steps, *args, **kwargs)
    if at_step in [int(s) for s in steps]:
        # as a scheduler would, from outside the main thread; joined, so that the signal
        # has arrived before the run goes on (the compiled loop may hold the GIL)
        sender = threading.Thread(target=os.kill, args=(os.getpid(), signum))
        sender.start()
        sender.join()
RunRecord.rows = send_at_step
sys.argv = ["beamcontact", "run", sys.argv[1], "--out", sys.argv[2], "-q"]
main()
"""


def test_sigterm_and_sighup_stop_a_run_like_ctrl_c(tmp_path):
    """What a batch scheduler sends before it kills: exit 128 + the signal, one line,
    summary.json with status "interrupted" naming the signal, every accepted step kept,
    and --restart continues to the end."""
    import json
    import signal

    # long enough that the compiled loop's call holding step 20 (about 0.1 s of steps,
    # however fast the machine) ends well before t_end
    raw = tomllib.loads(VIBRATION.read_text(encoding="utf-8"))
    raw["analysis"]["t_end"] = 10.0
    raw["output"]["vtk_interval"] = 0.5
    case = tmp_path / "case.toml"
    case.write_text(tomli_w.dumps(raw), encoding="utf-8")
    for sig in (signal.SIGTERM, signal.SIGHUP):
        out = tmp_path / sig.name
        proc = subprocess.run([sys.executable, "-c", _SIGNALLED, str(case), str(out),
                               str(int(sig)), "20"], capture_output=True, text=True,
                              timeout=600)
        assert proc.returncode == 128 + int(sig), proc.stderr
        _one_line(proc, f"stopped by {sig.name}", str(out))
        summary = json.loads((out / "summary.json").read_text(encoding="utf-8"))
        assert summary["status"] == "interrupted" and summary["signal"] == sig.name
        assert 20 <= summary["steps"] < 5000
        rest = _cli("run", case, "--out", out, "-q", "--restart")
        assert rest.returncode == 0, rest.stderr
        done = json.loads((out / "summary.json").read_text(encoding="utf-8"))
        assert done["status"] == "completed" and done["t_final"] == 10.0


def test_a_dense_tangent_larger_than_the_memory_is_refused_before_it_is_made(tmp_path,
                                                                           monkeypatch):
    """linear_solver = "dense" for more dofs than the machine holds (here a machine of
    1 kB): exit 2 and one line that says what to change, nothing allocated or run."""
    from typer.testing import CliRunner

    import beamcontact.setup.start as start
    from beamcontact.cli import app

    monkeypatch.setattr(start, "physical_memory", lambda: 2**10)
    raw = tomllib.loads(VIBRATION.read_text(encoding="utf-8"))
    raw["solver"] = {"engine": "jax", "linear_solver": "dense"}
    case = tmp_path / "dense.toml"
    case.write_text(tomli_w.dumps(raw), encoding="utf-8")
    result = CliRunner().invoke(app, ["run", str(case), "--out", str(tmp_path / "o"), "-q"])
    assert result.exit_code == 2
    assert "solver.linear_solver: the dense tangent of" in result.output
    assert 'use linear_solver = "sparse"' in result.output
    assert not (tmp_path / "o" / "history.csv").exists()


def test_a_restarted_run_counts_the_whole_run(tmp_path):
    """Stopped by SIGTERM early and continued with --restart through the first impact,
    the bundled IPIP drop ends with the history of an uninterrupted run byte for byte
    (a restart inside a contact episode: tests/test_free_fall.py), and its
    summary counts the whole run as that one's does: steps, Newton iterations (of every
    attempt), cut-backs and rejections by kind, and the message's step count."""
    import json
    import signal

    raw = tomllib.loads((REPO / "examples" / "free_fall" / "case_ipip.toml").read_text(
        encoding="utf-8"))
    raw["analysis"]["t_end"] = 0.85
    case = tmp_path / "drop.toml"
    case.write_text(tomli_w.dumps(raw), encoding="utf-8")
    whole, parts = tmp_path / "whole", tmp_path / "parts"
    assert _cli("run", case, "--out", whole, "-q").returncode == 0
    stopped = subprocess.run(
        [sys.executable, "-c", _SIGNALLED, str(case), str(parts), str(int(signal.SIGTERM)),
         "20"], capture_output=True, text=True, timeout=600)
    assert stopped.returncode == 143, stopped.stderr
    # the signal comes with step 20, and the run stops once the compiled loop's call
    # that made it has handed all of its steps over: how many depends on the machine
    # (a call lasts a fixed time), so an early step, far from the end
    stopped_at = json.loads((parts / "summary.json").read_text(encoding="utf-8"))
    assert stopped_at["status"] == "interrupted" and stopped_at["steps"] >= 20
    assert _cli("run", case, "--out", parts, "-q", "--restart").returncode == 0
    assert (whole / "history.csv").read_bytes() == (parts / "history.csv").read_bytes()
    a, b = (json.loads((d / "summary.json").read_text(encoding="utf-8"))
            for d in (whole, parts))
    assert b["restarted_from_step"] is not None
    assert a["rejections"], "the impact has rejected attempts to count"
    for key in ("steps", "newton_iterations", "cutbacks", "rejections", "message"):
        assert a[key] == b[key], key


def test_restart_with_a_damaged_or_missing_history_or_series(tmp_path):
    """--restart after a damaged history.csv (a junk line) or a missing one: exit 2 and
    one line, the folder as it was; a last line cut short (a kill in mid-write) and a
    missing or damaged beams.pvd are not in the way: the run goes on, the ParaView
    series made again from results.h5, one VTU file per snapshot and every one listed."""
    import re

    case = _case(tmp_path, 0.01)
    longer = _case(tmp_path, 0.016, "longer.toml")
    out = tmp_path / "out"
    assert _cli("run", case, "--out", out, "-q").returncode == 0
    history = out / "history.csv"
    good = history.read_text(encoding="utf-8")
    lines = good.splitlines(keepends=True)
    history.write_text("".join(lines[:3] + ["junk\n"] + lines[3:]), encoding="utf-8")
    before = _files(out)
    damaged = _cli("run", longer, "--out", out, "-q", "--restart")
    _one_line(damaged, "--restart:", "history.csv is damaged (line 4 has 1 values",
              "without --restart")
    assert damaged.returncode == 2 and _files(out) == before
    history.unlink()
    missing = _cli("run", longer, "--out", out, "-q", "--restart")
    _one_line(missing, "--restart:", "history.csv is missing")
    history.write_text(good + good.splitlines()[-1][:7], encoding="utf-8")  # cut short
    for pvd, target, snapshots in (("missing", longer, 9),  # t = 0, 2, ..., 16 ms
                                   ("damaged", _case(tmp_path, 0.02, "l2.toml"), 11)):
        (out / "beams.pvd").unlink()
        if pvd == "damaged":
            (out / "beams.pvd").write_text("<VTKFile", encoding="utf-8")
        proc = _cli("run", target, "--out", out, "-q", "--restart")
        assert proc.returncode == 0, proc.stderr
        listed = re.findall(r'file="([^"]+)"', (out / "beams.pvd").read_text())
        on_disk = sorted(f"vtk/{p.name}" for p in (out / "vtk").iterdir())
        assert listed == on_disk and len(listed) == snapshots, pvd


def test_a_full_disk_keeps_the_states_that_fit_in_order(tmp_path, monkeypatch):
    """States queued in blocks (one per call of the compiled loop): when the disk has
    room for some of them only, results.h5 keeps exactly the first ones that fit, across
    blocks, and says the disk is full."""
    import h5py

    import beamcontact.io.results as results
    from beamcontact.io.results import DISK_RESERVE, OutputError, StateWriter

    monkeypatch.setattr(StateWriter, "flush_seconds", 1e9)
    writer = StateWriter(tmp_path / "results.h5", "", [], 3, "t")
    u = np.arange(15.0).reshape(5, 3)
    writer.write_many([1, 2], [0.1, 0.2], u[:2])
    writer.write_many([3, 4, 5], [0.3, 0.4, 0.5], u[2:])
    row = 8 + 8 + 3 * 8  # step, parameter, u: bytes of one state
    # the writer asks for twice the bytes it writes: room for three states
    monkeypatch.setattr(results, "free_space", lambda path: DISK_RESERVE + 2 * 3 * row)
    with pytest.raises(OutputError, match="its disk is full"):
        writer.close()
    with h5py.File(tmp_path / "results.h5", "r") as f:
        assert list(f["states/step"][:]) == [1, 2, 3]
        assert np.array_equal(f["states/parameter"][:], [0.1, 0.2, 0.3])
        assert np.array_equal(f["states/u"][:], u[:3])
