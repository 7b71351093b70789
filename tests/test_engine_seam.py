"""The seam between the time loop and its engines (docs/architecture.md, "Engines").

The loop and the step controller are plain Python: they import no JAX, and they drive any
object with the engine interface. Checked with an engine written here, a point mass
falling under gravity whose attempts are exact (constant acceleration is what Newmark
integrates exactly): the loop must reach t_end in steps of dt, the state must follow the
closed form, and the energy account must close.
"""

import ast
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from beamcontact.dynamics.control import StepControl
from beamcontact.dynamics.driver import solve_dynamic
from beamcontact.dynamics.report import COUNTS, VALUES, Attempt, StepFlags


def test_time_loop_and_controller_import_no_jax():
    code = ("import sys, beamcontact.dynamics.driver, beamcontact.dynamics.control; "
            "print('jax' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True)
    assert out.stdout.strip() == "False"


# a native run through the runner, as the command line makes it, up to its plots: the
# bundled drops (both laws, both IPIP pairings) shortened, and the cantilever statics
_NATIVE_RUN = """
import sys, tomllib
from pathlib import Path
import beamcontact
from beamcontact.io.case import parse_case
from beamcontact.record import RunRecord
from beamcontact.runner import run_case

RunRecord.plots = lambda self, fork=False: print("before plots:", sorted(
    m for m in ("jax", "matplotlib") if m in sys.modules))
beamcontact.enable_x64()
for path, changes in [("examples/free_fall/case_cg.toml", {"t_end": 0.76}),
                      ("examples/free_fall/case_ipip.toml", {"t_end": 0.76}),
                      ("examples/cantilever_end_moment/case.toml", {})]:
    data = tomllib.loads(Path(path).read_text())
    data["analysis"].update(changes)
    # native asked for: "auto" takes the JAX engine where a JAX GPU plugin is installed
    data.setdefault("solver", {})["engine"] = "native"
    summary = run_case(parse_case(data), "", Path(sys.argv[1]) / Path(path).stem)
    print(summary["solver"]["engine_used"], summary["status"])
"""


def test_a_native_run_imports_no_jax(tmp_path):
    """The native engine's runs (dynamics with either law, statics) import neither JAX
    nor matplotlib before they draw (beamcontact/_jax.py): 0.45 s and 0.4 s of every
    run. The engine is
    asked for by name: "auto" picks the JAX engine on a machine with a JAX GPU plugin
    (as on the lent H200 where this test once failed for that)."""
    repo = Path(__file__).resolve().parents[1]
    out = subprocess.run([sys.executable, "-c", _NATIVE_RUN, str(tmp_path)],
                         capture_output=True, text=True, check=True, cwd=repo)
    lines = out.stdout.split("\n")
    assert lines.count("before plots: []") == 3, out.stdout
    assert lines.count("native completed") == 3, out.stdout


def test_only_one_module_imports_jax():
    """Every module of the package takes JAX from beamcontact/_jax.py, so that its
    pytrees are registered whenever JAX is used and nothing imports JAX early."""
    package = Path(__file__).resolve().parents[1] / "src" / "beamcontact"
    offenders = []
    for path in sorted(package.rglob("*.py")):
        if path.name == "_jax.py":
            continue
        for node in ast.walk(ast.parse(path.read_text())):
            names = ([a.name for a in node.names] if isinstance(node, ast.Import) else
                     [node.module or ""] if isinstance(node, ast.ImportFrom) else [])
            if any(n == "jax" or n.startswith("jax.") for n in names):
                offenders.append(f"{path.relative_to(package)}:{node.lineno}")
    assert offenders == []


_BLAS_THREADS = """
import sys
import tomllib
from pathlib import Path
from threadpoolctl import threadpool_info
import beamcontact
from beamcontact.io.case import parse_case
from beamcontact.runner import execute

data = tomllib.loads(Path("examples/pinned_beam_vibration/case.toml").read_text())
data["analysis"]["t_end"] = 0.005
data["solver"] = {"engine": sys.argv[1]}
threads = set()
beamcontact.enable_x64()
execute(parse_case(data), "", None, lambda info: threads.update(
    lib["num_threads"] for lib in threadpool_info() if lib["user_api"] == "blas"))
print(sorted(threads), "scipy.linalg" in sys.modules)
"""


@pytest.mark.parametrize("engine", ["jax", "native"])
def test_blas_runs_on_one_thread_in_a_fresh_process(engine):
    """A run limits BLAS to one thread (runner.execute: a threaded LU's round-off
    depends on the thread count), also when JAX, and with it the OpenBLAS its LAPACK
    calls, is first imported inside the run: a limit set before a library is loaded
    does not reach it. A native run whose kernels compile loads that library too
    (Numba's compiler imports scipy.linalg.cython_blas), though its kernels call no
    BLAS; one whose loop is cached (the second here) loads no kernel that imports it."""
    from beamcontact import _warmup

    repo = Path(__file__).resolve().parents[1]
    for run in range(2):
        out = subprocess.run([sys.executable, "-c", _BLAS_THREADS, engine],
                             capture_output=True, text=True, check=True, cwd=repo)
        threads, linalg = out.stdout.strip().rsplit(" ", 1)
        assert threads == "[1]", out.stdout + out.stderr
        paths = _warmup._paths()
        if run == 0 and paths is not None:  # a helper of a cold first run may outlive it
            # (it compiles the spline kernels after the loop is ready)
            deadline = time.monotonic() + 600.0
            while _warmup._helper_works(paths[1]) and time.monotonic() < deadline:
                time.sleep(0.2)
    if engine == "native" and os.environ.get("BEAMCONTACT_CACHE_DIR") != "":
        assert linalg == "False"


class FallingMass:
    """An engine of one point mass m under gravity g; its state is (t, y, v)."""

    name = "test"
    contact = None

    def __init__(self, m: float, g: float):
        self.m, self.g = m, g

    def _energies(self, y: float, v: float) -> dict:
        return {"E_strain": 0.0, "E_gravity": self.m * self.g * y, "E_ext": 0.0,
                "E_contact": 0.0, "E_kin": 0.5 * self.m * v * v, "p_x": 0.0,
                "p_y": self.m * v}

    def attempt(self, state, h, motion_factor, capacity):
        t, y, v = state
        y1, v1 = y + v * h - 0.5 * self.g * h * h, v - self.g * h
        report = {**dict.fromkeys(VALUES, 0.0), **self._energies(y1, v1), "h": h,
                  "min_gap": float("nan")}
        counts = {**dict.fromkeys(COUNTS, 0), "flags": int(StepFlags.CONVERGED),
                  "iterations": 1}
        return Attempt((t + h, y1, v1), np.array([report[k] for k in VALUES]),
                       np.array([counts[k] for k in COUNTS]))

    def energies(self, state, capacity):
        return self._energies(state[1], state[2])

    def at_time(self, state, t):
        return (t, *state[1:])

    def time(self, state):
        return state[0]


def test_the_loop_drives_any_engine():
    m, g, y0, v0, dt, t_end = 2.0, 9.81, 10.0, 3.0, 0.01, 1.0
    steps = []
    res = solve_dynamic(FallingMass(m, g), (0.0, y0, v0), t_end, 1.0,
                        StepControl(dt, 1e-6 * dt, error_tol=1e-6, energy_tol=1e-9),
                        on_step=steps.append)
    assert res.status == "completed", res.message
    assert res.steps == round(t_end / dt) and res.cutbacks == 0
    t, y, v = res.state
    assert t == pytest.approx(t_end, abs=1e-15)
    assert y == pytest.approx(y0 + v0 * t_end - 0.5 * g * t_end**2, rel=1e-13)
    assert v == pytest.approx(v0 - g * t_end, rel=1e-13)
    e0 = m * g * y0 + 0.5 * m * v0 * v0
    for s in steps:  # the account closes at every step, and nothing was dissipated
        d = s.diagnostics
        assert d["E_total"] == pytest.approx(e0, rel=1e-13)
        assert abs(d["E_dissipated"]) < 1e-12 * e0 and d["E_set_change"] == 0.0
