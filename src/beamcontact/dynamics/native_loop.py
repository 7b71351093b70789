"""The time loop of the native engine, compiled (Numba): many steps per call, the same
rules as the host loop of dynamics/driver.py (docs/architecture.md, "One time step").

Each attempt reads as the time step of docs/theory.md: the predictor and its motion bound;
the contact set chosen at the predictor and the conservative advancement
(:func:`~beamcontact.contact.step_set_native.step_set_at`); Newton on the HHT residual,
the corrector and the diagnostics (:func:`~beamcontact.dynamics.native_step.attempt`);
the checks after the step (:func:`~beamcontact.contact.step_set_native.after_step`); the
step controller (:func:`~beamcontact.dynamics.control.decide`, the very function the host
loop calls). An accepted step is copied into the output buffers; the call returns when
t_end is reached, the controller stops the run, or after ``max_attempts`` attempts, so
that the caller writes the outputs, shows progress and honours Ctrl-C between calls
(:meth:`~beamcontact.dynamics.native_step.NativeEngine.advance`).

The energy of the start of a step under a set already evaluated there (the accepted
step's own set, or an earlier attempt's at the same state) is reused rather than summed
again: the same sum at the same state, so the result is the same either way.
"""

import numpy as np

from beamcontact._native import njit
from beamcontact.arrays_native import copy_1d, copy_2d, equal
from beamcontact.assembly import native_model as nmod
from beamcontact.contact import step_set_native as ssn
from beamcontact.dynamics.control import (
    ACCEPT,
    H_TRY,
    ITERATIONS,
    MOTION_FACTOR,
    STOP,
    T,
    decide,
    step_size,
    unfinished,
)
from beamcontact.dynamics.native_step import _predictor, attempt
from beamcontact.dynamics.report import (
    C_COUNT,
    C_COUNT_AFTER,
    C_FLAGS,
    C_ITERATIONS,
    MISSING_BLOCK,
    V_APPROACH,
    V_CONTACT,
    V_EC_BEFORE,
    V_GAP,
    V_KIN,
)

# why a call returned
BUDGET, DONE, STOPPED = range(3)


@njit
def _same_set(pairs, W, known_pairs, known_W, weights_of_pairs):
    """Whether two frozen sets are the same blocks with the same weights
    (``weights_of_pairs``: the weights are a function of the blocks, as an integrated
    law's arc-length weights, and are not compared)."""
    if pairs.shape != known_pairs.shape or W.shape != known_W.shape:
        return False
    for p in range(pairs.shape[0]):
        if pairs[p, 0] != known_pairs[p, 0] or pairs[p, 1] != known_pairs[p, 1]:
            return False
    return weights_of_pairs or equal(W, known_W)


@njit
def run(nm, ne, law, has_contact, system, no_contact, newton, ctl, limits, u, v, a, f_pot,
        theta, tangent, max_attempts, out_u, out_v, out_a, out_f, out_theta, out_tangent,
        out_values, out_counts, out_ctl, made, last_values, last_counts):
    """Attempts from the state (u, v, a, f_pot, theta, tangent) at time ctl[T] until t_end
    (returns DONE), a stop of the controller (STOPPED: the stopping attempt's report in
    last_values, last_counts) or ``max_attempts`` attempts (BUDGET).

    Every accepted step updates the state arrays in place and is copied into row k of
    the ``out_*`` buffers (its state, report and the controller's state after it);
    made[0] counts the accepted steps, made[1] the attempts.

    Arguments: nm the NativeModel; ne, law the contact elements and law
    (step_set_native); has_contact; system the bordered layout and work arrays
    (position, block positions, free dofs in layout order, band, B, C, D, ipiv, ipiv_s,
    kl, ku); no_contact the frozen set of no blocks; newton (alpha, rtol, utol, etol,
    dt_ref, total mass, max_iterations, diverge_after); ctl, limits the controller's state and
    settings (dynamics/control.py).
    """
    alpha, rtol, utol, etol, dt_ref, total_mass, max_iterations, diverge_after = newton
    position, positions, free_layout, band, B, C, D, ipiv, ipiv_s, kl, ku = system
    n = u.shape[0]
    nu, nv, na, nf = np.empty(n), np.empty(n), np.empty(n), np.empty(n)
    ntheta, ntangent = np.empty_like(theta), np.empty_like(tangent)
    values, counts = np.empty(last_values.shape[0]), np.empty(last_counts.shape[0], np.int64)
    # the contact energy at the current state of the sets evaluated there (NaN: none)
    known_pairs, known_W, known_e = no_contact[2], no_contact[3], np.nan
    tried_pairs, tried_W, tried_e = no_contact[2], no_contact[3], np.nan
    # the kinetic energy of the current state, once an accepted step has computed it
    e_kin = np.nan
    # an integrated law's weights follow from its blocks (step_set_native.frozen_set_at)
    integrated = not (law.points or law.zones)
    made[0] = made[1] = 0
    while made[1] < max_attempts:
        if not unfinished(ctl[T], limits):
            return DONE
        h = step_size(ctl[T], limits.t_end, ctl[H_TRY])
        frozen, h_used, e_before, count = no_contact, h, np.nan, 0
        motion, x0, x_pred = 0.0, nm.x_ref, nm.x_ref
        if has_contact:
            motion, x0, x_pred = _predictor(nm.x_ref, u, v, a, h, ctl[MOTION_FACTOR])
            pairs, W, count, h_used = ssn.step_set_at(x0, x_pred, v.reshape(-1, 2),
                                                      a.reshape(-1, 2), h, motion, ne, law)
            frozen = ssn.frozen_blocks(ne, law, pairs, W)
            if _same_set(pairs, W, known_pairs, known_W, integrated):
                e_before = known_e
            elif _same_set(pairs, W, tried_pairs, tried_W, integrated):
                e_before = tried_e
        attempt(nm, frozen, position, positions, free_layout, band, B, C, D, ipiv, ipiv_s,
                kl, ku, u, v, a, f_pot, theta, tangent, h_used, alpha, rtol, utol, etol,
                dt_ref, total_mass, max_iterations, diverge_after, e_before, e_kin, nu, nv,
                na, nf, ntheta, ntangent, values, counts)
        made[1] += 1
        if has_contact:
            if np.isnan(e_before):
                tried_pairs, tried_W, tried_e = frozen[2], frozen[3], values[V_EC_BEFORE]
            missing, count_after, gap, approach = ssn.after_step(
                x0, nmod._positions(nm.x_ref, nu), x_pred, motion, ne, law, frozen[2])
            values[V_GAP], values[V_APPROACH] = gap, approach
            counts[C_COUNT], counts[C_COUNT_AFTER] = count, count_after
            if missing:
                counts[C_FLAGS] |= MISSING_BLOCK
        ctl[ITERATIONS] += counts[C_ITERATIONS]
        outcome = decide(ctl, values, counts, h, limits)
        if outcome == STOP:
            copy_1d(last_values, values)
            copy_1d(last_counts, counts)
            return STOPPED
        if outcome != ACCEPT:
            continue
        copy_1d(u, nu)
        copy_1d(v, nv)
        copy_1d(a, na)
        copy_1d(f_pot, nf)
        copy_1d(theta, ntheta)
        copy_2d(tangent, ntangent)
        e_kin = values[V_KIN]
        if has_contact:
            known_pairs, known_W, known_e = frozen[2], frozen[3], values[V_CONTACT]
            tried_e = np.nan
        k = made[0]
        copy_1d(out_u[k], nu)
        copy_1d(out_v[k], nv)
        copy_1d(out_a[k], na)
        copy_1d(out_f[k], nf)
        copy_1d(out_theta[k], ntheta)
        copy_2d(out_tangent[k], ntangent)
        copy_1d(out_values[k], values)
        copy_1d(out_counts[k], counts)
        copy_1d(out_ctl[k], ctl)
        made[0] = k + 1
    return BUDGET
