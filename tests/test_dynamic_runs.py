"""Dynamic runs through the CLI: output contract, restart identity, cut-back and recovery."""

import json
import os
import subprocess
import sys
import tomllib
from pathlib import Path

import h5py
import numpy as np
from test_cli import _to_toml

from beamcontact.io.results import read_history

REPO = Path(__file__).resolve().parents[1]
EXAMPLE = REPO / "examples" / "pinned_beam_vibration" / "case.toml"


def _case(tmp_path: Path, name: str, **changes) -> Path:
    raw = tomllib.loads(EXAMPLE.read_text())
    raw["analysis"]["t_end"] = 0.1
    raw["beams"][0]["elements"] = 6
    for key, value in changes.items():
        section, field = key.split(".")
        raw.setdefault(section, {})[field] = value
    path = tmp_path / f"{name}.toml"
    path.write_text(_to_toml(raw))
    return path


def _run(*args):
    return subprocess.run([sys.executable, "-m", "beamcontact.cli", "run", *map(str, args),
                           "--quiet"], capture_output=True, text=True, timeout=600)


def test_dynamic_outputs(tmp_path):
    out = tmp_path / "o"
    proc = _run(_case(tmp_path, "c"), "--out", out)
    assert proc.returncode == 0, proc.stderr
    h = read_history(out / "history.csv")
    for col in ("t", "mid_x", "mid_y", "mid_ux", "mid_uy", "E_kin", "E_strain", "E_gravity",
                "E_ext", "E_total", "p_x", "p_y", "newton_iters", "dt"):
        assert col in h, col
    assert h["t"][0] == 0.0 and abs(h["t"][-1] - 0.1) < 1e-12
    np.testing.assert_allclose(np.diff(h["t"])[1:], h["dt"][2:], rtol=1e-9)
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "completed" and summary["steps"] == 100
    assert 0 < summary["compile_time_s"] < summary["wall_time_s"]
    # the native loop's seconds per thread count: counts the process may use, seconds
    # that add up to at most the loop's own (with empty caches the driver's host loop
    # makes the steps while a helper compiles the loop: then none)
    threads = summary["loop_threads"]
    assert threads is not None and all(1 <= int(k) <= (os.cpu_count() or 1) for k in threads)
    assert sum(threads.values()) <= summary["solve_time_s"] + 1e-3
    # the steps' writing is part of the loop's time: 101 rows and states, 11 snapshots
    assert 0 < summary["writing_time_s"] < summary["solve_time_s"]
    assert summary["solver"]["threads"] >= max(map(int, threads), default=1)
    assert 0.0 <= summary["loop_probe_s"] <= threads.get("1", 0.0)
    assert summary["newton_iterations"] == int(h["newton_iters"].sum())
    # VTU every vtk_interval = 0.01 s: t = 0, 0.01, ..., 0.1
    assert (out / "beams.pvd").read_text().count("<DataSet") == 11
    with h5py.File(out / "results.h5") as f:
        for name in ("u", "v", "a", "f_pot", "load_theta", "load_tangent", "dt_next"):
            assert f["states"][name].shape[0] == 101
    for png in ("shapes", "points", "energies"):
        assert (out / "plots" / f"{png}.png").stat().st_size > 0


def test_a_loop_that_shared_its_cores_says_so():
    """The warning of a native loop that ran more than a tenth of its time on fewer
    threads than its process may use (other processes kept cores busy)."""
    from beamcontact.summary import shared_cores_warning

    assert shared_cores_warning(None, 2) is None  # the JAX engine
    assert shared_cores_warning({}, 2) is None  # the host loop made every step
    assert shared_cores_warning({"2": 1.7, "1": 0.1}, 2) is None  # 6 %
    assert shared_cores_warning({"1": 5.0}, 1) is None  # one thread is all it may use
    warning = shared_cores_warning({"1": 5.73, "2": 0.5}, 2)
    assert warning.startswith("the step loop ran 5.73 of its 6.23 s on fewer threads than "
                              "the 2 this process may use")
    # the first window on one thread, before the cores were read, is no sign of sharing
    assert shared_cores_warning({"1": 0.25, "2": 0.3}, 2, probe_s=0.25) is None
    assert shared_cores_warning({"1": 0.25}, 2, probe_s=0.25) is None
    assert shared_cores_warning({"1": 0.5, "2": 0.3}, 2, probe_s=0.25).startswith(
        "the step loop ran 0.25 of its 0.80 s")


def test_restart_equals_uninterrupted_run(tmp_path):
    full, part = tmp_path / "full", tmp_path / "part"
    assert _run(_case(tmp_path, "long", **{"analysis.t_end": 0.06}), "--out", full
                ).returncode == 0
    assert _run(_case(tmp_path, "short", **{"analysis.t_end": 0.03}), "--out", part
                ).returncode == 0
    # a crash after the last saved state leaves nothing extra; simulate a stale VTU entry
    proc = _run(_case(tmp_path, "long2", **{"analysis.t_end": 0.06}), "--out", part,
                "--restart")
    assert proc.returncode == 0, proc.stderr
    a, b = read_history(full / "history.csv"), read_history(part / "history.csv")
    assert a.keys() == b.keys()
    for k in a:
        if k not in ("step",):
            np.testing.assert_array_equal(a[k], b[k], err_msg=k)
    with h5py.File(full / "results.h5") as fa, h5py.File(part / "results.h5") as fb:
        np.testing.assert_array_equal(fa["states/u"][:], fb["states/u"][:])
        np.testing.assert_array_equal(fa["states/v"][:], fb["states/v"][:])
    sa = json.loads((full / "summary.json").read_text())
    sb = json.loads((part / "summary.json").read_text())
    assert sb["steps"] == sa["steps"] and sb["newton_iterations"] == sa["newton_iterations"]
    assert sb["restarted_from_step"] == 30
    assert (part / "beams.pvd").read_text() == (full / "beams.pvd").read_text()


def test_restart_rejects_a_changed_model(tmp_path):
    out = tmp_path / "o"
    assert _run(_case(tmp_path, "a", **{"analysis.t_end": 0.01}), "--out", out).returncode == 0
    proc = _run(_case(tmp_path, "b", **{"analysis.t_end": 0.02, "analysis.alpha": -0.1}),
                "--out", out, "--restart")
    assert proc.returncode == 2 and "analysis.alpha differs" in proc.stderr
    proc = _run(_case(tmp_path, "c", **{"analysis.t_end": 0.01}), "--out", out, "--restart")
    assert proc.returncode == 2 and "already reached" in proc.stderr


def test_cutback_and_recovery_of_the_nominal_step(tmp_path):
    """Three Newton iterations are not enough for a 10 ms step of this stiff beam: the driver
    halves the step, succeeds, and grows back to the nominal step. (Error control and the
    energy test are off: they would also, rightly, shorten these coarse steps.)"""
    out = tmp_path / "o"
    case = _case(tmp_path, "cut", **{"analysis.dt": 1e-2, "solver.max_iterations": 3,
                                     "solver.energy_tol": 0.0, "solver.error_tol": 0.0})
    proc = _run(case, "--out", out)
    assert proc.returncode == 0, proc.stderr
    h = read_history(out / "history.csv")
    summary = json.loads((out / "summary.json").read_text())
    assert summary["cutbacks"] > 0 and h["cutbacks"][-1] == summary["cutbacks"]
    assert h["dt"][1:].min() < 1e-2 and np.isclose(h["dt"][1:].max(), 1e-2)
    assert abs(h["t"][-1] - 0.1) < 1e-12
