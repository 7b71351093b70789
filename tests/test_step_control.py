"""The step after an accepted step (dynamics/control.py, docs/theory.md "Adaptive steps"):
the elementary controller h (tol / e)^(1/3) with its safety factor and bounds, no growth
right after a rejection, and a step shortened by the conservative advancement bound
growing back towards the step attempted, but only as far as its own error allows."""

import numpy as np
import pytest

from beamcontact.dynamics import control as c
from beamcontact.dynamics.report import (
    C_FLAGS,
    C_ITERATIONS,
    CONVERGED,
    COUNTS,
    V_ERROR,
    V_H,
    VALUES,
)

TOL, DT = 1e-6, 1e-3
LIMITS = c.Limits(t_end=1.0, dt=DT, dt_min=1e-9, tol=TOL, energy_tol=0.0,
                  max_cutbacks=40, max_penetration=np.inf)


def _accept(h_attempted, h_used, error, rejected_before, iterations=2, limits=LIMITS):
    """H_TRY after ``decide`` accepts an attempt at h_attempted that took h_used."""
    ctl = c.new_state(0.0, h_attempted,
                      c.EnergyAccount(0.0, 0.0, dict.fromkeys(c.DIAGNOSTICS, 0.0)))
    ctl[c.CONSECUTIVE] = 1.0 if rejected_before else 0.0
    values = np.zeros(len(VALUES))
    values[V_H], values[V_ERROR] = h_used, error
    counts = np.zeros(len(COUNTS), np.int64)
    counts[C_FLAGS], counts[C_ITERATIONS] = CONVERGED, iterations
    assert c.decide(ctl, values, counts, h_attempted, limits) == c.ACCEPT
    return ctl[c.H_TRY]


def _elementary(h, error):
    return h * c.SAFETY * (TOL / error) ** (1.0 / 3.0)


@pytest.mark.parametrize("rejected_before", [False, True])
def test_a_full_step_follows_its_error(rejected_before):
    h, e = 4e-4, 0.5 * TOL
    grown = _elementary(h, e)
    assert 1.0 < grown / h < c.GROW_MAX
    expected = h if rejected_before else grown  # no growth right after a rejection
    assert _accept(h, h, e, rejected_before) == pytest.approx(expected, rel=1e-15)


@pytest.mark.parametrize("rejected_before", [False, True])
def test_a_step_shortened_by_the_advancement_keeps_to_its_error(rejected_before):
    """h = 1e-3 attempted, 4e-4 taken (the advancement bound) with its error near the
    tolerance: the next step is the elementary controller's from 4e-4 (a little
    shorter), not twice 4e-4, whose error would be about 8 times the tolerance."""
    e = 0.99 * TOL
    assert _accept(1e-3, 4e-4, e, rejected_before) == pytest.approx(_elementary(4e-4, e),
                                                                     rel=1e-15)


@pytest.mark.parametrize("rejected_before", [False, True])
def test_a_step_shortened_by_the_advancement_grows_back_towards_the_step_attempted(
        rejected_before):
    """With a small error the short step may double, also right after a rejection; but
    right after a rejection (of a step longer than the one attempted) not beyond the
    step attempted."""
    e = 1e-4 * TOL
    assert _accept(1e-3, 4e-4, e, rejected_before) == pytest.approx(c.GROW_MAX * 4e-4,
                                                                     rel=1e-15)
    expected = 5e-4 if rejected_before else c.GROW_MAX * 4e-4
    assert _accept(5e-4, 4e-4, e, rejected_before) == pytest.approx(expected, rel=1e-15)


@pytest.mark.parametrize("rejected_before", [False, True])
def test_at_fixed_steps_a_shortened_step_grows_back_towards_the_step_attempted(
        rejected_before):
    """Without error control (error_tol = 0, the fixed steps of the paper) a step that
    the advancement bound shortened doubles back towards the step attempted, after a
    rejection and after a hard Newton solve too."""
    limits = LIMITS._replace(tol=0.0)
    h = _accept(1e-3, 4e-4, 0.0, rejected_before, iterations=c.GROW_ITERATIONS + 1,
                limits=limits)
    assert h == pytest.approx(c.GROW_MAX * 4e-4, rel=1e-15)
