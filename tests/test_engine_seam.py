"""The seam between the time loop and its engines (docs/architecture.md, "Engines").

The loop and the step controller are plain Python: they import no JAX, and they drive any
object with the engine interface. Checked with an engine written here, a point mass
falling under gravity whose attempts are exact (constant acceleration is what Newmark
integrates exactly): the loop must reach t_end in steps of dt, the state must follow the
closed form, and the energy account must close.
"""

import subprocess
import sys

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
