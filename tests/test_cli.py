"""Command line: the bundled example end to end, output contract, and rejection of bad input."""

import copy
import json
import os
import subprocess
import sys
import time
import tomllib
from pathlib import Path

import h5py
import numpy as np
import pytest
import tomli_w

from beamcontact.cli import bundled_case
from beamcontact.io.results import read_history

REPO = Path(__file__).resolve().parents[1]
EXAMPLE = REPO / "examples" / "cantilever_end_moment" / "case.toml"


def _cli(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "beamcontact.cli", *map(str, args)],
                          capture_output=True, text=True, cwd=cwd, timeout=600)


def _write_case(path: Path, raw: dict) -> Path:
    path.write_text(_to_toml(raw), encoding="utf-8")
    return path


def _to_toml(raw: dict) -> str:
    return tomli_w.dumps(raw)


def test_bundled_case_is_the_free_fall_benchmark():
    expected = REPO / "examples" / "free_fall" / "case_cg.toml"
    assert bundled_case().read_text() == expected.read_text()


def test_run_end_moment_example_closes_circle(tmp_path):
    """Acceptance: a slender cubic cantilever under M = 2 pi EI/L; tip back within 0.2 % L."""
    out = tmp_path / "out"
    proc = _cli("run", EXAMPLE, "--out", out, "--quiet")
    assert proc.returncode == 0, proc.stderr
    h = read_history(out / "history.csv")
    # the full load itself, not the sum of ten increments of 0.1 (0.9999999999999999)
    assert h["load_factor"][-1] == 1.0
    assert json.loads((out / "summary.json").read_text())["final_load_factor"] == 1.0
    assert np.hypot(h["tip_x"][-1], h["tip_y"][-1]) < 2e-3 * 1.0
    # strain energy of the inextensible circle M^2 L / (2 EI) = pi M L; the Green-Lagrange
    # fibre strain adds O((k a)^2) = (2 pi 0.005)^2 = 1e-3 relative (test_statics.py has the
    # exact solution of the full model)
    M = 2 * np.pi * 1.0e9 * np.pi * 0.005**4 / 4
    assert h["E_strain"][-1] == pytest.approx(np.pi * M, rel=2e-3)
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "completed"
    assert summary["steps"] == 10 and summary["newton_iterations"] == h["newton_iters"].sum()
    assert 0 < summary["compile_time_s"] < summary["wall_time_s"]
    assert 0 < summary["writing_time_s"] < summary["solve_time_s"]  # 11 rows and snapshots
    vtus = sorted((out / "vtk").glob("*.vtu"))
    assert len(vtus) == 11 and (out / "beams.pvd").read_text().count("<DataSet") == 11
    assert (out / "plots" / "shapes.png").stat().st_size > 0
    with h5py.File(out / "results.h5") as f:
        assert f["states/u"].shape == (11, 38)
        np.testing.assert_allclose(f["states/parameter"][:], h["load_factor"])
        assert "cantilever" in f["model"]
    # overlay of runs (paper Figs. 7-10)
    png = tmp_path / "cmp.png"
    proc = _cli("compare", out, out, "--point", "tip", "--label", "a", "--label", "b",
                "--out", png)
    assert proc.returncode == 0 and png.stat().st_size > 0, proc.stderr
    proc = _cli("compare", out, "--point", "nowhere", "--out", png)
    assert proc.returncode == 2 and "no column 'nowhere_uy'" in proc.stderr


@pytest.mark.parametrize("stdout", ["full", "closed pipe"])
def test_a_run_goes_on_when_its_messages_cannot_be_written(tmp_path, stdout):
    """A log on a full disk or a reader of the messages gone (``| head -1``) loses the
    messages, not the run: every result is written, the exit status is the run's and
    standard error says what was lost."""
    if stdout == "full" and not Path("/dev/full").exists():
        pytest.skip("no /dev/full here")
    out = tmp_path / "out"
    cmd = [sys.executable, "-m", "beamcontact.cli", "run", str(EXAMPLE), "--out", str(out)]
    if stdout == "full":
        with open("/dev/full", "w") as full:
            proc = subprocess.run(cmd, stdout=full, stderr=subprocess.PIPE, text=True,
                                  timeout=600)
        code, err = proc.returncode, proc.stderr
    else:
        proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                text=True)
        proc.stdout.close()  # the reader is gone before the first line
        err = proc.stderr.read()
        code = proc.wait(timeout=600)
    assert code == 0, err
    reason = "No space left on device" if stdout == "full" else "Broken pipe"
    assert (f"warning: messages to standard output were lost from the first that could "
            f"not be written ({reason})") in err
    assert "Traceback" not in err
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "completed" and summary["steps"] == 10
    assert len(read_history(out / "history.csv")["load_factor"]) == 11
    assert (out / "plots" / "shapes.png").stat().st_size > 0


def test_check_accepts_valid_case():
    proc = _cli("check", EXAMPLE)
    assert proc.returncode == 0 and "valid" in proc.stdout


BASE = tomllib.loads(EXAMPLE.read_text())


def _mutate(path, value, base=BASE):
    raw = copy.deepcopy(base)
    node = raw
    for key in path[:-1]:
        node = node[key]
    if value is KeyError:
        del node[path[-1]]
    else:
        node[path[-1]] = value
    return raw


BAD = [  # (mutation, key the message must name)
    ((("beams", 0, "section", "radius"), -0.01), "beams[0] (cantilever).section.radius"),
    ((("beams", 0, "section", "radius"), 0.0), "beams[0] (cantilever).section.radius"),
    ((("beams", 0, "material", "E"), -1.0), "beams[0] (cantilever).material.E"),
    ((("beams", 0, "material", "E"), 0), "beams[0] (cantilever).material.E"),
    ((("beams", 0, "material", "density"), 0.0), "beams[0] (cantilever).material.density"),
    ((("beams", 0, "degree"), 1), "beams[0] (cantilever).degree"),
    ((("beams", 0, "continuity"), 3), "beams[0] (cantilever).continuity"),
    ((("beams", 0, "continuity"), 0), "beams[0] (cantilever).continuity"),
    ((("loads", 0, "beam"), "nobody"), "loads[0].beam"),
    ((("output", "points", 0, "beam"), "nobody"), "output.points[0].beam"),
    ((("loads", 0, "at"), 1.5), "loads[0].at"),
    ((("loads", 0, "at"), -0.1), "loads[0].at"),
    ((("output", "points", 0, "at"), "middle"), "output.points[0] (tip).at"),
    ((("beams", 0, "material", "density"), KeyError), "beams[0] (cantilever).material.density"),
    ((("analysis", "kind"), KeyError), "analysis.kind"),
    ((("beams", 0, "colour"), "red"), "beams[0] (cantilever).colour"),
    ((("analysis", "steps"), 3), "analysis.steps"),
    ((("beams", 0, "elements"), "many"), "beams[0] (cantilever).elements"),
    ((("beams", 0, "gravity"), "yes"), "beams[0] (cantilever).gravity"),
    ((("beams", 0, "section", "radius"), "thin"), "beams[0] (cantilever).section.radius"),
    ((("analysis", "load_steps"), 2.5), "analysis.load_steps"),
    ((("loads", 0, "moment"), [1.0]), "loads[0].moment"),
]
DYNAMIC = tomllib.loads((REPO / "examples" / "pinned_beam_vibration" / "case.toml").read_text())
BAD_DYNAMIC = [
    ((("analysis", "alpha"), 0.1), "analysis.alpha"),
    ((("analysis", "alpha"), -0.5), "analysis.alpha"),
    ((("analysis", "dt"), -1e-3), "analysis.dt"),
    ((("analysis", "t_end"), KeyError), "analysis"),
    ((("beams", 0, "initial_velocity"), [1.0]), "beams[0] (beam).initial_velocity"),
    ((("output", "vtk_interval"), 0.0), "output.vtk_interval"),
    ((("contact",), {"model": "ipip", "pairing": "nearest"}), "contact.pairing"),
    ((("contact",), {"model": "cg", "pairing": "points"}), "contact.pairing"),
    ((("contact",), {"model": "cg", "pairing": "zones"}), "contact.pairing"),
]


@pytest.mark.parametrize(("mutation", "key"), BAD, ids=[k for _, k in BAD])
def test_bad_input_is_rejected_naming_the_key(tmp_path, mutation, key):
    case = _write_case(tmp_path / "bad.toml", _mutate(*mutation))
    for command in (("check", case), ("run", case, "--out", tmp_path / "o", "--quiet")):
        proc = _cli(*command)
        assert proc.returncode == 2, proc.stdout + proc.stderr
        lines = proc.stderr.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith(f"error: {key}:"), proc.stderr
        assert "Traceback" not in proc.stderr
    assert not (tmp_path / "o").exists()  # nothing runs on invalid input


@pytest.mark.parametrize(("mutation", "key"), BAD_DYNAMIC, ids=[k for _, k in BAD_DYNAMIC])
def test_bad_dynamic_input_is_rejected_naming_the_key(tmp_path, mutation, key):
    case = _write_case(tmp_path / "bad.toml", _mutate(*mutation, base=DYNAMIC))
    proc = _cli("check", case)
    assert proc.returncode == 2, proc.stdout + proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"error: {key}:"), proc.stderr


def test_library_refuses_float32(tmp_path):
    code = ("import beamcontact, pathlib\n"
            "from beamcontact.io.case import read_case_file\n"
            "from beamcontact.runner import run_case\n"
            f"case, text = read_case_file({str(EXAMPLE)!r})\n"
            "run_case(case, text, pathlib.Path('unused'))\n")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          env={"PATH": "/usr/bin:/bin", "JAX_ENABLE_X64": "0"}, cwd=tmp_path)
    assert proc.returncode != 0 and "beamcontact needs float64" in proc.stderr
    assert not (tmp_path / "unused").exists()  # refused before its folder was made


def test_unreadable_and_malformed_files(tmp_path):
    proc = _cli("check", tmp_path / "missing.toml")
    assert proc.returncode == 2 and "cannot read" in proc.stderr
    (tmp_path / "bad.toml").write_text("title = \n")
    proc = _cli("check", tmp_path / "bad.toml")
    assert proc.returncode == 2 and "invalid TOML" in proc.stderr


def test_solver_failure_keeps_results_and_says_why(tmp_path):
    """A load far beyond what one Newton solve can take with no cut-backs allowed: exit 1,
    the message says where it stopped, and the converged steps are on disk."""
    raw = copy.deepcopy(BASE)
    raw["loads"][0]["moment"] *= 40.0
    raw["analysis"]["load_steps"] = 4
    raw["solver"] = {"max_iterations": 4, "max_cutbacks": 1}
    case = _write_case(tmp_path / "hard.toml", raw)
    out = tmp_path / "o"
    proc = _cli("run", case, "--out", out, "--quiet")
    assert proc.returncode == 1
    assert "Newton did not converge at load factor" in proc.stdout
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "failed" and "last converged load factor" in summary["message"]
    h = read_history(out / "history.csv")
    assert len(h["load_factor"]) == summary["steps"] + 1


@pytest.mark.parametrize("engine", ["jax", "native"])
def test_compilation_cache_location_and_identical_results(tmp_path, monkeypatch, engine):
    from beamcontact._cache import cache_dir

    monkeypatch.setenv("BEAMCONTACT_CACHE_DIR", "")
    assert cache_dir() is None
    monkeypatch.delenv("BEAMCONTACT_CACHE_DIR")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert cache_dir() == tmp_path / "xdg" / "beamcontact" / "jax"

    raw = tomllib.loads((REPO / "examples" / "pinned_beam_vibration" / "case.toml").read_text())
    raw["analysis"]["t_end"] = 0.02
    raw["solver"] = {"engine": engine}
    case = _write_case(tmp_path / "c.toml", raw)
    env = {**os.environ, "BEAMCONTACT_CACHE_DIR": str(tmp_path / "cache")}
    runs = []
    # off, filling, reading (native: filling and reading; without a cache the kernels
    # compile as when filling it, a minute of the suite for nothing new)
    for k, cache in enumerate((None, env, env) if engine == "jax" else (env, env)):
        out = tmp_path / f"o{k}"
        proc = subprocess.run([sys.executable, "-m", "beamcontact.cli", "run", str(case),
                               "--out", str(out), "--quiet"], capture_output=True, text=True,
                              timeout=600, env=cache or {**os.environ,
                                                          "BEAMCONTACT_CACHE_DIR": ""})
        assert proc.returncode == 0, proc.stderr
        runs.append((out / "history.csv").read_text())
    assert any((tmp_path / "cache").iterdir())  # the compiled step was stored
    if engine == "jax":  # and its traced program (the third run embeds it, not tracing)
        assert any((tmp_path / "cache" / "exported").glob("fused_attempt-*.hlo"))
    else:  # the native kernels, in a folder of their own, the time loop compiled by the
        # helper beside the first run (beamcontact._warmup), which may outlive the runs
        # (they make their steps without the loop meanwhile) and then is done and gone
        deadline = time.monotonic() + 600
        while (any((tmp_path / "cache" / "numba").glob("*/loop-*.lock"))
               and time.monotonic() < deadline):
            time.sleep(0.5)
        assert any((tmp_path / "cache" / "numba").rglob("*.nbi"))
        assert not any((tmp_path / "cache" / "numba").glob("*/loop-*.steps"))
        assert any((tmp_path / "cache" / "numba").glob("*/loop-*.ready"))
        assert not any((tmp_path / "cache" / "numba").glob("*/loop-*.lock"))
        # and succeeded: a helper that fails leaves its error output, and the run
        # compiles the loop itself
        errors = list((tmp_path / "cache" / "numba").glob("*/loop-*.err"))
        assert not errors, errors[0].read_text()
        # the helper's kernel calls and the run's help pass the loop's own types: the
        # loop compiled no second version of any of them (nor did the start, of the
        # solver's kernels)
        for name in ("native_step.contact_blocks", "bordered_native.newton_update",
                     "native_step._residual_tangent", "native_step._residual",
                     "native_step.attempt", "step_set_native.step_set_at",
                     "step_set_native.after_step", "bordered_native.factor_solve",
                     "bordered_native.apply_supports"):
            assert _stored_versions(tmp_path / "cache" / "numba", name) == 1, name
    assert all(run == runs[0] for run in runs)


def _stored_versions(folder: Path, name: str) -> int:
    """The number of compiled versions (signatures) of the kernel ``name`` ("module.func")
    in Numba's cache index under ``folder``."""
    import pickle

    (index,) = folder.rglob(f"{name}-*.nbi")
    with open(index, "rb") as f:
        pickle.load(f)  # Numba's version
        _, overloads = pickle.loads(f.read())
    return len(overloads)


# --- mechanisms: static beams that nothing holds -------------------------------------------

def _one_line_error(proc, start):
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(start), proc.stderr
    assert "Traceback" not in proc.stderr


@pytest.mark.parametrize(("supports", "says"), [
    ([], "it can translate and rotate freely (3 rigid-body modes"),
    ([{"at": "start", "type": "pinned"}], "it can rotate about (0, 0) (1 rigid-body mode")])
def test_static_mechanism_without_contact_is_invalid_input(tmp_path, supports, says):
    """No contact partner can hold the beam: exit 2 before anything runs, naming the key."""
    raw = _mutate(("beams", 0, "supports"), supports)
    raw["loads"] = [{"beam": "cantilever", "at": "end", "force": [0.0, -1.0]}]
    case = _write_case(tmp_path / "mech.toml", raw)
    for command in (("check", case), ("run", case, "--out", tmp_path / "o", "--quiet")):
        proc = _cli(*command)
        assert proc.returncode == 2, proc.stdout + proc.stderr
        _one_line_error(proc, "error: beams[0] (cantilever).supports: the beam is a mechanism")
        assert says in proc.stderr and "add supports" in proc.stderr
    assert not (tmp_path / "o").exists()


def test_static_beam_not_held_by_contact_stops_the_solver(tmp_path):
    """A free beam above a supported one may be held by contact, so the case is valid; at
    the start nothing holds it (no penetration): the solver stops at once, exit 1."""
    raw = copy.deepcopy(BASE)
    raw["beams"][0]["supports"] = [{"at": "start", "type": "pinned"},
                                   {"at": "end", "type": "pinned"}]
    upper = copy.deepcopy(raw["beams"][0])
    upper.update(name="upper", line={"start": [0.25, 0.02], "end": [0.75, 0.02]}, supports=[],
                 elements=4)
    raw["beams"].append(upper)
    raw["loads"] = [{"beam": "upper", "at": 0.5, "force": [0.0, -1.0]}]
    raw["contact"] = {"model": "ipip", "segments_per_element": 4}
    case = _write_case(tmp_path / "float.toml", raw)
    assert _cli("check", case).returncode == 0
    out = tmp_path / "o"
    proc = _cli("run", case, "--out", out, "--quiet")
    assert proc.returncode == 1, proc.stdout + proc.stderr
    assert "failed: the stiffness matrix is singular: beam" in proc.stdout
    assert "3 rigid-body modes not restrained by its supports or by contact" in proc.stdout
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "failed" and summary["steps"] == 0
    assert len(read_history(out / "history.csv")["load_factor"]) == 1


# --- output folders and files that cannot be written ----------------------------------------

def test_output_that_cannot_be_created_is_invalid_input(tmp_path):
    """A regular file in the way of --out: one line naming the path and why, exit 2."""
    blocker = tmp_path / "some_file.txt"
    blocker.write_text("not a folder")
    runs = tmp_path / "run"
    (runs).mkdir()
    (runs / "history.csv").write_text("step,load_factor,tip_uy\n0,0.0,0.0\n1,1.0,-0.1\n")
    cases = [
        (("run", EXAMPLE, "--out", blocker / "sub", "--quiet"),
         f"error: --out {blocker / 'sub'}: cannot use this output folder: {blocker} is a "
         f"file, not a folder"),
        (("run", EXAMPLE, "--out", blocker, "--quiet"),
         f"error: --out {blocker}: cannot use this output folder: it is a file"),
        (("sweep", EXAMPLE, "--set", "analysis.load_steps=2,3", "--out", blocker / "s"),
         f"error: --out {blocker / 's'}: cannot use this output folder: {blocker} is a file"),
        (("compare", runs, "--point", "tip", "--out", blocker / "c.png"),
         f"error: --out {blocker / 'c.png'}: cannot write this file: {blocker} is a file"),
        (("compare", runs, "--point", "tip", "--out", runs),
         f"error: --out {runs}: cannot write this file: it is a folder"),
    ]
    for command, start in cases:
        proc = _cli(*command)
        assert proc.returncode == 2, proc.stdout + proc.stderr
        _one_line_error(proc, start)
    assert blocker.read_text() == "not a folder"
    # a missing folder of the PNG is created
    proc = _cli("compare", runs, "--point", "tip", "--out", tmp_path / "new" / "c.png")
    assert proc.returncode == 0 and (tmp_path / "new" / "c.png").stat().st_size > 0


def test_output_folder_without_write_permission(tmp_path, monkeypatch):
    """The probe writes a temporary file: a folder where that fails is named with the
    reason (simulated, since tests may run as root, who may write anywhere)."""
    import beamcontact.cli as cli

    def refuse(*_, **__):
        raise PermissionError(13, "Permission denied")

    assert cli._folder_problem(tmp_path / "a" / "b") is None
    monkeypatch.setattr(cli.tempfile, "TemporaryFile", refuse)
    assert cli._folder_problem(tmp_path / "a" / "b") == \
        f"cannot write in {tmp_path} (permission denied)"
    assert cli._folder_problem(tmp_path) == "cannot write in it (permission denied)"
    assert not (tmp_path / "a").exists()  # nothing is created by the check


@pytest.mark.skipif(os.geteuid() == 0, reason="root may write in read-only folders")
def test_read_only_output_folder_is_invalid_input(tmp_path):
    locked = tmp_path / "locked"
    locked.mkdir(mode=0o555)
    proc = _cli("run", EXAMPLE, "--out", locked / "o", "--quiet")
    assert proc.returncode == 2
    _one_line_error(proc, f"error: --out {locked / 'o'}: cannot use this output folder: "
                          f"cannot write in {locked} (permission denied)")


@pytest.mark.parametrize("busy", [True, False])
def test_a_run_says_when_its_helper_still_compiles(monkeypatch, capsys, busy):
    """A run whose helper (started with empty caches) still compiles the time loop when
    the run ends says so: the next run started before it is done is slower."""
    from beamcontact import _warmup, cli

    monkeypatch.setattr(_warmup, "helper_busy", lambda: busy)
    cli._helper_note()
    err = capsys.readouterr().err
    assert ("goes on compiling the native kernels" in err) == busy
