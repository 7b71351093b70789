"""Newton's error test in time steps (``solver.newton_error_fraction``, docs/theory.md,
"Time integration"): Newton stops once the error left in its iterate is a small fraction
of the step's local error bound. Compared here with Newton run to the residual test on a
flexible pendulum (a pinned beam swinging under gravity, large rotations, alpha = 0) in
its first half second: the motion changes by far less than the steps themselves err
(measured against steps of a sixteenth of the tolerance), so does the energy the
integrator creates or removes, and the iterations fall. (Over longer runs a change this
small can still flip a step's acceptance somewhere; the two runs then take different
steps and differ by up to what such steps err.)"""

import copy

import numpy as np

import beamcontact as bc
from beamcontact.io.case import parse_case

SWING = {
    "title": "flexible pendulum",
    "analysis": {"kind": "dynamic", "t_end": 0.5, "dt": 0.02, "alpha": 0.0,
                 "gravity": [0.0, -9.81]},
    "beams": [{"name": "beam", "line": {"start": [0.0, 0.0], "end": [4.0, 0.0]},
               "degree": 4, "elements": 16, "section": {"shape": "circle", "radius": 0.1},
               "material": {"E": 1.0e6, "density": 1000.0},
               "supports": [{"at": "start", "type": "pinned"}]}],
    "output": {"points": [{"name": "tip", "beam": "beam", "at": "end"}]},
}


def _swing(**solver):
    raw = copy.deepcopy(SWING)
    raw["solver"] = {"engine": "native", **solver}
    result = bc.simulate(parse_case(raw))
    assert result.status == "completed"
    return result


def _tip(result, grid):
    h = result.history
    return np.column_stack([np.interp(grid, h["t"], h[f"tip_{c}"]) for c in "xy"])


def test_error_test_changes_the_motion_far_less_than_the_steps_err():
    default = _swing()
    full = _swing(newton_error_fraction=0.0)
    finer = _swing(newton_error_fraction=0.0, error_tol=2.5e-6 / 16, energy_tol=2.5e-4 / 16)
    grid = np.linspace(0.0, 0.5, 1001)
    newton = np.max(np.abs(_tip(default, grid) - _tip(full, grid)))
    steps = np.max(np.abs(_tip(full, grid) - _tip(finer, grid)))
    assert steps > 1e-5  # the pendulum's steps err measurably (0.1 mm at the tip)
    assert newton < 0.02 * steps, (newton, steps)
    # the energy the integrator created or removed (alpha = 0: its error alone)
    e_default, e_full, e_finer = (r.summary["energy"]["E_dissipated"]
                                  for r in (default, full, finer))
    assert abs(e_default - e_full) < 0.1 * abs(e_full - e_finer), (e_default, e_full, e_finer)
    assert default.summary["newton_iterations"] < 0.75 * full.summary["newton_iterations"]


def test_error_test_is_off_without_error_control():
    """Fixed steps (error_tol = 0) have no error bound to refer to: Newton runs to its
    residual test, whatever the fraction."""
    fixed = {"error_tol": 0.0, "energy_tol": 0.0}
    a = _swing(**fixed)
    b = _swing(newton_error_fraction=0.0, **fixed)
    np.testing.assert_array_equal(a.history["tip_y"].to_numpy(), b.history["tip_y"].to_numpy())
    assert a.summary["newton_iterations"] == b.summary["newton_iterations"]
