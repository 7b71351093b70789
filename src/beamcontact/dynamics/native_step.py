"""The native engine of the time loop: one attempt at a time step compiled for the CPU
(Numba), the twin of :func:`~beamcontact.dynamics.step.fused_attempt` (docs/architecture.md,
"Engines").

The attempt reads as the time step of docs/theory.md: the Newmark predictor; Newton on the
HHT residual (paper eqs. 31-37, dynamics/hht.py), r = F_inertia + (1 + alpha) f_pot(u) -
alpha f_pot(u_n) with its tangent assembled from the element blocks of
:mod:`~beamcontact.assembly.native_model` into a bordered banded matrix
(:mod:`~beamcontact.solvers.bordered_native`), the same convergence and divergence tests
as :func:`~beamcontact.solvers.newton.newton`; the corrector (eqs. 33-35); the load state;
the local error estimate (Zienkiewicz & Xie 1991), the energy floor and the diagnostics,
reported in the order of :mod:`~beamcontact.dynamics.report`. The engine runs it inside
its compiled time loop (:meth:`NativeEngine.advance`, dynamics/native_loop.py), with the
step controller, energy account and rejection rules that the JAX engine's host loop
calls too (dynamics/control.py); :meth:`NativeEngine.attempt` makes one attempt for the
host loop.

Contact enters as the frozen set of the step (:class:`NativeContact`, the twin of
contact/step_set.py): its blocks are added to the residual and the tangent at every
Newton iterate (:func:`contact_blocks`); the contact energy of the solution is the one of
the last iterate's evaluation, and the energy of the set at the start of the step is
evaluated only when no earlier attempt knows it (the energy account's set-change jump).
"""

import time
from dataclasses import dataclass, replace

import numpy as np

from beamcontact import _native
from beamcontact._native import CoreShare, Stopwatch, njit, njit_uncounted
from beamcontact.arrays_native import EPS
from beamcontact.assembly import native_model as nmod
from beamcontact.assembly.model import LoadState
from beamcontact.contact import blocks_native
from beamcontact.contact import step_set_native as ssn
from beamcontact.contact.laws import coarse_grained_native as cgn
from beamcontact.dynamics.control import T
from beamcontact.dynamics.hht import DIVERGE_AFTER, DynState
from beamcontact.dynamics.report import (
    C_COUNT,
    C_COUNT_AFTER,
    C_FLAGS,
    C_ITERATIONS,
    CONVERGED,
    COUNTS,
    MISSING_BLOCK,
    V_APPROACH,
    V_CONTACT,
    V_EC_BEFORE,
    V_ERROR,
    V_EXT,
    V_FLOOR,
    V_GAP,
    V_GRAVITY,
    V_H,
    V_KIN,
    V_PX,
    V_PY,
    V_RESIDUAL,
    V_RESIDUAL0,
    V_STRAIN,
    VALUES,
    Attempt,
)
from beamcontact.solvers import bordered_native as bordered
from beamcontact.solvers.newton import NewtonOptions

_V = {name: i for i, name in enumerate(VALUES)}
# a Newton increment this fraction of the one before is taken for the quadratic phase:
# the iterate is expected to pass the convergence test (:func:`attempt`)
CONVERGING = 0.01


def beam_dofs(nm: nmod.NativeModel) -> list[np.ndarray]:
    """The dofs of each beam: the control points that elements connect, as connected
    components (an ElementBlock may hold several beams of one degree)."""
    parent = np.arange(nm.x_ref.shape[0])

    def root(c):
        while parent[c] != c:
            parent[c] = parent[parent[c]]
            c = parent[c]
        return c

    for e in range(nm.n_elements):
        cps = nm.conn[e, :nm.elem_n_loc[e]]
        for c in cps[1:]:
            parent[root(c)] = root(cps[0])
    roots = np.array([root(c) for c in range(nm.x_ref.shape[0])])
    groups = [np.flatnonzero(roots == r) for r in np.unique(roots)]
    return [np.stack([2 * g, 2 * g + 1], axis=-1).ravel() for g in groups]


class NativeSystem:
    """The bordered banded layout of a model's tangent: the dofs of the beam with the most
    dofs form the band, those of every other beam the border
    (:mod:`~beamcontact.solvers.bordered_native`); ``position[d]`` is the layout position
    of global dof d, and the work arrays are allocated once."""

    def __init__(self, nm: nmod.NativeModel, beam_dofs: list[np.ndarray]):
        band = max(range(len(beam_dofs)), key=lambda b: beam_dofs[b].size)
        order = np.concatenate([beam_dofs[band]]
                               + [d for b, d in enumerate(beam_dofs) if b != band])
        self.position = np.empty(nm.n_dof, dtype=np.int64)
        self.position[order] = np.arange(nm.n_dof)
        self.order = order
        n_b = beam_dofs[band].size
        self.block_positions = np.ascontiguousarray(self.position[nm.block_dofs])
        kl, ku = bordered.band_widths(self.block_positions, n_b)
        self.layout = bordered.layout(n_b, kl, ku, nm.n_dof - n_b)
        self.arrays = bordered.allocate(self.layout)
        self.free = np.ascontiguousarray(nm.free[order])  # in layout order


@njit
def _newmark(u, u_n, v_n, a_n, c_a, h, c_1, gamma, v_out, a_out):
    """Velocity and acceleration of the displacement u (eqs. 33-35), as
    :func:`~beamcontact.assembly.inertia.newmark_kinematics`."""
    for i in range(u.shape[0]):
        a = c_a * (u[i] - u_n[i] - h * v_n[i]) - c_1 * a_n[i]
        a_out[i] = a
        v_out[i] = v_n[i] + h * ((1.0 - gamma) * a_n[i] + gamma * a)


@njit
def _residual_tangent(nm, frozen, u, u_n, v_n, a_n, coeffs, alpha, f_pot_n, theta_n, tangent_n,
                      position, positions, free_layout, band, B, C, D, kl, ku, r, r_pot,
                      r_layout, k_blocks):
    """The HHT residual at u with supports applied (global numbering, into r), f_pot(u)
    (contact included) into r_pot, and the tangent assembled into the bordered arrays
    with its residual in layout order (r_layout); returns (||r||, the contact energy at
    u, the strain energy at u)."""
    e_strain = nmod.hht_residual_blocks(nm, u, u_n, v_n, a_n, coeffs, alpha, f_pot_n, theta_n,
                                        tangent_n, r, r_pot, k_blocks, True)
    # without contact blocks no entry couples the band's beam with the border
    coupled = frozen[2].shape[0] > 0
    bordered.zero(band, B, C, D, coupled)
    bordered.add_blocks(band, B, C, D, kl, ku, positions, k_blocks)
    e_contact = 0.0
    if coupled:
        e_contact = contact_blocks(nmod._positions(nm.x_ref, u), *frozen, 1.0 + alpha,
                                   position, band, B, C, D, kl, ku, r_pot, r)
    norm = bordered.supported_residual(band, B, C, D, kl, ku, free_layout, position, r,
                                       r_layout, coupled)
    return norm, e_contact, e_strain


@njit
def _residual(nm, frozen, u, u_n, v_n, a_n, coeffs, alpha, f_pot_n, theta_n, tangent_n, r, r_pot,
              k_blocks):
    """:func:`_residual_tangent` without the tangent: the supported HHT residual into r,
    f_pot(u) into r_pot, (||r||, the contact energy, the strain energy), the same numbers
    bit for bit; k_blocks is scratch."""
    e_strain = nmod.hht_residual_blocks(nm, u, u_n, v_n, a_n, coeffs, alpha, f_pot_n, theta_n,
                                        tangent_n, r, r_pot, k_blocks, False)
    e_contact = 0.0
    if frozen[2].shape[0] > 0:
        no = np.empty((0, 0))
        e_contact = contact_blocks(nmod._positions(nm.x_ref, u), *frozen, 1.0 + alpha,
                                   np.empty(0, np.int64), no, no, no, no, -1, -1, r_pot, r)
    return bordered.supported_norm(nm.free, r), e_contact, e_strain


@njit
def _remaining_error(band, B, C, D, kl, ku, ipiv, ipiv_s, position, r, r_layout, x,
                     coupled):
    """The error left in a Newton iterate whose supported residual is r: the largest
    component of the next increment, -K^-1 r, with the factors of the tangent that gave
    the iterate (still in band, B, C, D; Hairer & Wanner, Solving ODEs II, Sec. IV.8).
    r_layout and x are scratch."""
    for i in range(r.shape[0]):
        r_layout[position[i]] = -r[i]
    bordered.solve(band, B, C, D, kl, ku, ipiv, ipiv_s, r_layout, x, coupled)
    largest = 0.0
    for i in range(r.shape[0]):
        largest = max(largest, abs(x[i]))
    return largest


@njit
def attempt(nm, frozen, position, positions, free_layout, band, B, C, D, ipiv, ipiv_s, kl,
            ku, u_n, v_n, a_n, f_pot_n, theta_n, tangent_n, h, alpha, rtol, utol, etol, dt_ref,
            total_mass, max_iterations, diverge_after, e_contact_n, e_kin_n, u, v, a, f_pot,
            theta, tangent, values, counts):
    """One attempt at a step h from (u_n, v_n, a_n, f_pot_n, theta_n, tangent_n) into (u, v, a,
    f_pot, theta, tangent) and the report vectors ``values``, ``counts``
    (:mod:`~beamcontact.dynamics.report`; meaningful state only when converged).

    ``frozen``: the frozen contact set, (conn, R, pairs, W, R12, amplitudes, law, m,
    q_reg, cutoff) as :func:`contact_blocks` takes them (no pairs: no contact); the step h
    is already shortened by the conservative advancement; ``e_contact_n`` is its energy
    at u_n and ``e_kin_n`` the kinetic energy of (u_n, v_n) when the caller knows them
    (NaN: computed here). The contact checks after the
    step (approach, gap, missed blocks) are the caller's.

    Newton stops on the tests of :func:`~beamcontact.solvers.newton.newton`, the same
    three: the residual (rtol), the increment (utol, scaled by (h/dt_ref)^2) and, when
    ``etol`` > 0, the error left in the iterate (the next increment with the factors in
    hand at most etol). With etol > 0 each iterate is evaluated without its tangent
    first (it usually passes), the tangent following only when it does not."""
    n = u_n.shape[0]
    beta = 0.25 * (1.0 - alpha) ** 2
    gamma = 0.5 - alpha
    coeffs = np.array([1.0 / (beta * h * h), h, (1.0 - 2.0 * beta) / (2.0 * beta), gamma])
    x_max = 0.0
    for i in range(n):
        u[i] = u_n[i] + h * v_n[i] + 0.5 * h * h * a_n[i]
        x_max = max(x_max, abs(nm.x_ref[i // 2, i % 2] + u_n[i]))
    # the increment tolerance of fused_attempt: utol (h / dt_ref)^2, not below round-off
    utol_h = max(utol * min((h / dt_ref) ** 2, 1.0), 8.0 * EPS * x_max)
    f_norm = 0.0
    for i in range(n):
        f_norm += (f_pot_n[i] * nm.free[i]) ** 2
    atol = rtol * np.sqrt(f_norm)
    r, r_layout, du = np.empty(n), np.empty(n), np.empty(n)
    k_blocks = np.empty((nm.block_dofs.shape[0], nm.block_dofs.shape[1],
                         nm.block_dofs.shape[1]))
    args = (position, positions, free_layout, band, B, C, D, kl, ku, r, f_pot, r_layout,
            k_blocks)
    norm0, e_contact, e_strain = _residual_tangent(nm, frozen, u, u_n, v_n, a_n, coeffs,
                                                   alpha, f_pot_n, theta_n, tangent_n, *args)
    done, failed = norm0 <= atol, not np.isfinite(norm0)
    k, rn, last_step = 0, norm0, 0.0
    coupled = frozen[2].shape[0] > 0
    while not done and not failed and k < max_iterations:
        step, finite = bordered.newton_update(band, B, C, D, kl, ku, ipiv, ipiv_s, position,
                                              r_layout, du, u, coupled)
        # an iterate expected to be the solution (its increment below the tolerance, or
        # fallen by CONVERGING, Newton's quadratic phase, or any iterate under the error
        # test) is checked on its residual alone; the tangent follows only if it is not
        # (the same residual, bit for bit)
        light = step <= utol_h or step <= CONVERGING * last_step or etol > 0.0
        # the last evaluation is at the solution: its contact and strain energies are the
        # step's
        if light:
            rn, e_contact, e_strain = _residual(nm, frozen, u, u_n, v_n, a_n, coeffs, alpha,
                                                f_pot_n, theta_n, tangent_n, r, f_pot, k_blocks)
        else:
            rn, e_contact, e_strain = _residual_tangent(nm, frozen, u, u_n, v_n, a_n, coeffs,
                                                        alpha, f_pot_n, theta_n, tangent_n, *args)
        converged = rn <= rtol * norm0 + atol or step <= utol_h
        if not converged and etol > 0.0 and np.isfinite(rn):
            converged = _remaining_error(band, B, C, D, kl, ku, ipiv, ipiv_s, position, r,
                                         r_layout, du, coupled) <= etol
        diverged = diverge_after > 0 and k + 1 >= diverge_after and rn > norm0
        failed = not np.isfinite(rn) or not finite or diverged
        done = converged and not failed
        k += 1
        if light and not done and not failed and k < max_iterations:
            _residual_tangent(nm, frozen, u, u_n, v_n, a_n, coeffs, alpha, f_pot_n, theta_n,
                              tangent_n, *args)
        last_step = step
    # the free ends' tied dofs follow their masters (v and a too: their Newmark values
    # agree only to round-off, which the acceleration's 1 / (beta h^2) amplifies)
    nmod.tie_dependent(nm, u)
    _newmark(u, u_n, v_n, a_n, coeffs[0], h, coeffs[2], gamma, v, a)
    nmod.tie_dependent(nm, v)
    nmod.tie_dependent(nm, a)
    nmod.update_load_state(nm, u, theta_n, tangent_n, theta, tangent)
    e_gravity, e_ext = nmod.external_energies(nm, nmod._positions(nm.x_ref, u), 1.0, theta,
                                              tangent)
    e_kin, p = nmod.kinetic_energy_momentum(nm, u, v)
    if np.isnan(e_kin_n):
        e_kin_n = nmod.kinetic_energy_momentum(nm, u_n, v_n)[0]
    da_max, forces = 0.0, 0.0
    for i in range(n):
        da_max = max(da_max, abs((a[i] - a_n[i]) * nm.free[i]))
        forces += abs(f_pot_n[i] * nm.free[i]) + abs(f_pot[i] * nm.free[i])
    # a tied end point is a control point of the curve like the others: its error counts
    for t in range(nm.tied.shape[0]):
        da_max = max(da_max, abs(a[nm.tied[t]] - a_n[nm.tied[t]]))
    values[:] = 0.0
    values[V_RESIDUAL], values[V_RESIDUAL0], values[V_H] = rn, norm0, h
    values[V_ERROR] = h * h * abs(beta - 1.0 / 6.0) * da_max
    values[V_GAP] = np.nan
    # what the converged solve can resolve of the energy (step.py's _energy_floor)
    values[V_FLOOR] = utol_h * (forces + (0.5 - alpha) / (beta * h)
                                * np.sqrt(2.0 * max(e_kin, e_kin_n) * total_mass))
    values[V_STRAIN], values[V_GRAVITY], values[V_EXT] = e_strain, e_gravity, e_ext
    values[V_KIN], values[V_PX], values[V_PY] = e_kin, p[0], p[1]
    if frozen[2].shape[0] > 0:
        values[V_CONTACT] = e_contact
        values[V_EC_BEFORE] = (contact_energy(nm, frozen, u_n) if np.isnan(e_contact_n)
                               else e_contact_n)
    counts[:] = 0
    counts[C_FLAGS] = CONVERGED if done else 0
    counts[C_ITERATIONS] = k


@njit
def initial_acceleration(nm, frozen, u, v, theta, tangent, position, positions,
                         free_layout, band, B, C, D, ipiv, ipiv_s, kl, ku, f_pot, a):
    """The consistent initial acceleration (paper Sec. 4, as
    :func:`~beamcontact.dynamics.hht.initial_state`): f_pot(u) with the contact of the
    frozen set ``frozen`` into f_pot, and a from M(u) a = -(F_inertia(u, v, 0) + f_pot)
    on the free dofs (0 on the supported ones) into a."""
    n = u.shape[0]
    blocks = np.empty((nm.block_dofs.shape[0], nm.block_dofs.shape[1],
                       nm.block_dofs.shape[1]))
    nmod.potential_residual_blocks(nm, u, 1.0, theta, tangent, f_pot, blocks)
    if frozen[2].shape[0] > 0:
        no = np.empty((0, 0))
        contact_blocks(nmod._positions(nm.x_ref, u), *frozen, 1.0, position, no, no, no,
                       no, -1, -1, f_pot, np.zeros(n))
    f0 = np.empty(n)
    nmod.inertia_force_mass_blocks(nm, u, v, f0, blocks)
    bordered.zero(band, B, C, D)
    bordered.add_blocks(band, B, C, D, kl, ku, positions, blocks)
    r_layout = np.empty(n)
    for i in range(n):
        r_layout[position[i]] = -(f0[i] + f_pot[i])
    # B and C are zero (no contact tangent is assembled here), so either value of the
    # flag gives the same numbers; the attempt's flag, a variable, lets the solver's
    # kernels be the attempt's (a constant would compile them a second time)
    coupled = frozen[2].shape[0] > 0
    bordered.apply_supports(band, B, C, D, kl, ku, free_layout, r_layout, coupled)
    a_layout = np.empty(n)
    bordered.factor_solve(band, B, C, D, kl, ku, ipiv, ipiv_s, r_layout, a_layout, coupled)
    for i in range(n):
        a[i] = a_layout[position[i]]
    nmod.tie_dependent(nm, a)


@njit
def contact_energy(nm, frozen, u):
    """The energy of the frozen contact set at displacement u: the sum in block order of
    :func:`~beamcontact.contact.blocks_native.block_energy`, the energy that
    :func:`contact_blocks` returns, bit for bit, without its forces and tangent."""
    ce_conn, ce_R, pairs, W, R12, amps, law, m, q_reg, cutoff = frozen
    energies = np.empty(pairs.shape[0])
    blocks_native.blocks_energy(nmod._positions(nm.x_ref, u), ce_conn, ce_R, pairs, W, R12,
                                amps, law, m, q_reg, cutoff, energies,
                                blocks_native.blocks_scratch(ce_conn, ce_R, pairs.shape[0]))
    energy = 0.0
    for p in range(pairs.shape[0]):
        energy += energies[p]
    return energy


@njit
def state_diagnostics(nm, u, v, theta, tangent, values):
    """The diagnostics of a state into ``values`` (the order of VALUES)."""
    e_strain, e_gravity, e_ext = nmod.energies(nm, u, 1.0, theta, tangent)
    e_kin, p = nmod.kinetic_energy_momentum(nm, u, v)
    values[V_STRAIN], values[V_GRAVITY], values[V_EXT] = e_strain, e_gravity, e_ext
    values[V_CONTACT], values[V_KIN], values[V_PX], values[V_PY] = 0.0, e_kin, p[0], p[1]


@njit
def contact_blocks(x, ce_conn, ce_R, pairs, W, R12, amps, law, m, q_reg, cutoff, scale,
                   position, band, B, C, D, kl, ku, r_pot, r):
    """The frozen contact set at control points x (n_cp, 2): its energy (returned), its
    force added to r_pot and, times ``scale`` (1 + alpha), to r (both global), and its
    tangent times ``scale`` added to the bordered matrix (kl = -1: no tangent, not even
    within the blocks: the forces alone, for the initial acceleration). The blocks
    (:func:`~beamcontact.contact.blocks_native.block_into`) are the JAX twin's
    (:func:`~beamcontact.contact.blocks.block_forces`)."""
    n_loc = ce_conn.shape[1]
    k2 = 4 * n_loc
    n_pairs = pairs.shape[0]
    F, K, energies = np.empty((n_pairs, k2)), np.empty((n_pairs, k2, k2)), np.empty(n_pairs)
    blocks_native.blocks_into(x, ce_conn, ce_R, pairs, W, R12, amps, law, m, q_reg, cutoff,
                              F, K, energies, kl >= 0,
                              blocks_native.blocks_scratch(ce_conn, ce_R, n_pairs))
    return _add_contact_blocks(ce_conn, pairs, F, K, energies, scale, position, band, B, C, D,
                               kl, ku, r_pot, r, np.empty(k2, dtype=np.int64))


@njit_uncounted
def _add_contact_blocks(ce_conn, pairs, F, K, energies, scale, position, band, B, C, D, kl,
                        ku, r_pot, r, dofs):
    """The blocks of :func:`contact_blocks` (forces F, tangents K, energies) added to the
    global forces and the bordered matrix, in block order; returns their energy. No
    reference counts for the views of a block (dofs: scratch of F's width)."""
    n_loc = ce_conn.shape[1]
    k2 = dofs.shape[0]
    energy = 0.0
    for p in range(pairs.shape[0]):
        e1, e2 = pairs[p, 0], pairs[p, 1]
        for a in range(n_loc):
            c1, c2 = ce_conn[e1, a], ce_conn[e2, a]
            dofs[2 * a], dofs[2 * a + 1] = 2 * c1, 2 * c1 + 1
            dofs[2 * n_loc + 2 * a], dofs[2 * n_loc + 2 * a + 1] = 2 * c2, 2 * c2 + 1
        energy += energies[p]
        f, kb = F[p], K[p]
        for i in range(k2):
            r_pot[dofs[i]] += f[i]
            r[dofs[i]] += scale * f[i]
        if kl >= 0:
            for i in range(k2):
                dofs[i] = position[dofs[i]]
                for j in range(k2):
                    kb[i, j] *= scale
            bordered.add_block(band, B, C, D, kl, ku, dofs, kb)
    return energy


@njit
def _predictor(x_ref, u, v, a, h, motion_factor):
    """(motion bound, x at the start, x at the predictor) of a step h: the bound of
    :func:`~beamcontact.dynamics.step.fused_attempt`, motion_factor 2 sqrt(2) (max|v| h +
    max|a| h^2 / 2), and the control points (n_cp, 2)."""
    v_max = a_max = 0.0
    for i in range(u.shape[0]):
        v_max = max(v_max, abs(v[i]))
        a_max = max(a_max, abs(a[i]))
    motion = motion_factor * 2.0 * np.sqrt(2.0) * (v_max * h + 0.5 * a_max * h * h)
    x0, x_pred = np.empty_like(x_ref), np.empty_like(x_ref)
    c = 0.5 * h * h
    for p in range(x_ref.shape[0]):
        for d in range(2):
            i = 2 * p + d
            x0[p, d] = x_ref[p, d] + u[i]
            x_pred[p, d] = x_ref[p, d] + (u[i] + h * v[i] + c * a[i])
    return motion, x0, x_pred


@dataclass(frozen=True)
class StateRows:
    """The states after k accepted steps as the compiled loop writes them, as arrays of
    k rows (times t, then u, v, a, f_pot (k, n_dof) and the load states' theta and
    tangent), and as a sequence of :class:`DynState` (made only when asked for)."""

    t: np.ndarray
    u: np.ndarray
    v: np.ndarray
    a: np.ndarray
    f_pot: np.ndarray
    theta: np.ndarray
    tangent: np.ndarray

    def __len__(self) -> int:
        return self.t.shape[0]

    def __getitem__(self, j: int) -> DynState:
        return DynState(float(self.t[j]), self.u[j], self.v[j], self.a[j], self.f_pot[j],
                        LoadState(theta=self.theta[j], tangent=self.tangent[j]))

    def __iter__(self):
        return (self[j] for j in range(len(self)))

    def arrays(self) -> tuple[np.ndarray, ...]:
        """(u, v, a, f_pot, theta, tangent), each (k, ...)."""
        return self.u, self.v, self.a, self.f_pot, self.theta, self.tangent


@dataclass(frozen=True)
class _Chosen:
    """The contact set of one attempt: the frozen set as :func:`attempt` takes it, the
    step after the conservative advancement, and what the checks after the step need."""

    frozen: tuple
    h: float
    x0: np.ndarray
    x_pred: np.ndarray
    motion: float
    count: int


def native_law(contact, ne: ssn.NativeContactElements) -> ssn.NativeLaw:
    """The contact law of ``contact`` (a ContactProblem) as the compiled step reads it:
    its parameters, and its amplitude and R1 + R2 for every element pair (the same
    elementwise arithmetic as per pair)."""
    law = contact.law
    E = ne.radius.shape[0]
    r1, r2 = np.repeat(ne.radius, E), np.tile(ne.radius, E)
    if law.closest_pairs:
        code, params = blocks_native.LAW_PENALTY, (0.0, 0.0, 0.0)
        amplitude = np.full(E * E, float(law.penalty))
    else:
        code = blocks_native.LAW_CG
        params = (float(law.exponent), float(law.q_reg), float(law.cutoff))
        b12 = np.repeat(ne.beta, E) * np.tile(ne.beta, E)
        amplitude = (float(law.k) * b12) * cgn.cg_constants(params[0], r1, r2)
    pairing = law.pairing if law.closest_pairs else None
    return ssn.NativeLaw(code, pairing == "points", pairing == "zones", float(contact.reach),
                         float(law.interaction_distance()), float(law.advance_slack()),
                         *params, np.ascontiguousarray(amplitude.reshape(E, E)),
                         np.ascontiguousarray((r1 + r2).reshape(E, E)),
                         np.ascontiguousarray(contact.local_element, dtype=np.int64))


class NativeContact:
    """The contact set of a step on the native engine, the twin of
    :mod:`~beamcontact.contact.step_set` (all-pairs broad phase; no self-contact, no
    obstacles): chosen at the predictor, the step shortened by the conservative
    advancement, the checks after the step, each compiled
    (:func:`~beamcontact.contact.step_set_native.step_set_at`, ``after_step``)."""

    def __init__(self, contact):
        self.problem = contact
        self.ne = ssn.native_contact_elements(contact.elements)
        self.law = native_law(contact, self.ne)

    def frozen_at(self, x, motion: float = 0.0) -> tuple:
        """The frozen set at configuration x for a motion of at most ``motion`` (0: the
        start of a run; the search margin of a load step)."""
        pairs, W, _ = ssn.frozen_set_at(x, motion, self.ne, self.law)
        return ssn.frozen_blocks(self.ne, self.law, pairs, W)

    def missed(self, x: np.ndarray, frozen: tuple) -> tuple[bool, float]:
        """After a load step at x: (did the search at x find an interacting block the
        frozen set lacks, the smallest surface gap)."""
        missing, _, gap = ssn.missed_blocks(x, self.ne, frozen[2], self.law.reach,
                                            self.law.interaction)
        return bool(missing), float(gap)

    def choose(self, s: DynState, h: float, motion_factor: float, x_ref) -> _Chosen:
        """The set at the predictor of a step h and the step after the advancement."""
        ne, law = self.ne, self.law
        v2, a2 = s.v.reshape(-1, 2), s.a.reshape(-1, 2)
        motion, x0, x_pred = _predictor(x_ref, s.u, s.v, s.a, h, motion_factor)
        pairs, W, count, h_used = ssn.step_set_at(x0, x_pred, v2, a2, h, motion, ne, law)
        return _Chosen(ssn.frozen_blocks(ne, law, pairs, W), h_used, x0, x_pred, motion,
                       int(count))

    def min_gap(self, x: np.ndarray, frozen: tuple) -> float:
        """The smallest surface gap at x (the post-step check's)."""
        return ssn.missed_blocks(x, self.ne, frozen[2], self.law.reach,
                                 self.law.interaction)[2]

    def check(self, chosen: _Chosen, u, x_ref, values, counts) -> None:
        """The checks after the step (:func:`~beamcontact.contact.step_set.after_step`)
        into the report vectors."""
        missing, count_after, gap, approach = ssn.after_step(
            chosen.x0, x_ref + u.reshape(-1, 2), chosen.x_pred, chosen.motion, self.ne,
            self.law, chosen.frozen[2])
        values[V_GAP], values[V_APPROACH] = gap, approach
        counts[C_COUNT], counts[C_COUNT_AFTER] = chosen.count, count_after
        if missing:
            counts[C_FLAGS] |= MISSING_BLOCK


# the contact argument of a model without contact: no element pairs
NO_CONTACT = (np.zeros((0, 1), np.int64), np.zeros((0, 1, 1)), np.zeros((0, 2), np.int64),
              np.zeros((0, 1, 1)), np.zeros(0), np.zeros(0), blocks_native.LAW_CG, 0.0, 0.0,
              0.0)


def _host(a) -> np.ndarray:
    """A writable C-contiguous float64 host copy of an array (JAX or NumPy): NumPy views
    of JAX arrays are read-only, and Numba compiles every kernel again for read-only
    arguments."""
    return np.array(a, dtype=np.float64, order="C", copy=True)


def _no_contact_elements() -> tuple[ssn.NativeContactElements, ssn.NativeLaw]:
    """Contact elements and a law of no elements, with the types of real ones (the
    compiled loop of a model without contact takes them and never reads them)."""
    f2, i2 = np.zeros((0, 1)), np.zeros((0, 1), np.int64)
    ne = ssn.NativeContactElements(i2, np.zeros((0, 1), np.bool_), np.zeros((0, 1, 1)), f2,
                                   f2.copy(), np.zeros(0), np.zeros(0),
                                   np.zeros(0, np.int64), np.zeros((1, 1), np.bool_), 0.0, 1)
    law = ssn.NativeLaw(blocks_native.LAW_CG, False, False, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0,
                        np.zeros((0, 0)), np.zeros((0, 0)), np.zeros(0, np.int64))
    return ne, law


# the compiled loop returns to Python after about this much wall time [s], to write the
# outputs, show progress and honour Ctrl-C
CALL_SECONDS = 0.1
# while a helper compiles the loop, whether it is ready is looked at this often [s]
LOOK_SECONDS = 0.1


class NativeEngine:
    """The native engine of the time loop (docs/architecture.md, "Engines"): the same
    interface as :class:`~beamcontact.dynamics.step.JaxEngine`; its states are
    :class:`~beamcontact.dynamics.hht.DynState` of NumPy arrays. It runs the time loop
    itself (:meth:`advance`, the compiled loop of dynamics/native_loop.py); :meth:`attempt`
    makes one attempt for the driver's host loop (the compiled loop's reference in the
    tests)."""

    name = "native"
    runs_loop = True
    fixed_capacity = False  # the candidate lists grow as they must (driver.Engine)

    def __init__(self, model, alpha: float, options: NewtonOptions, length: float,
                 dt_ref: float, contact=None):
        self.nm = nmod.native_arrays(model)
        self.contact = contact
        self._contact = None if contact is None else NativeContact(contact)
        self.system = NativeSystem(self.nm, beam_dofs(self.nm))
        self.alpha, self.options = float(alpha), options
        self.utol, self.etol = options.utol * length, options.etol * length
        self.dt_ref = float(dt_ref)
        nm = self.nm
        self.total_mass = float(np.sum(nm.rho_area[:, None] * nm.wq * np.sqrt(nm.g_ref)))
        # contact energies known from earlier attempts: (u, pairs, W, energy) of the
        # latest states, so that a step under an unchanged set does not evaluate the
        # energy of its start again (the same sum at the same state)
        self._energies: list[tuple] = []
        # (when, result) of the last look of loop_compiling, when its steps began, and
        # the thread count it set (0: none yet)
        self._looked: tuple[float, bool] | None = None
        self._meanwhile_since: float | None = None
        self._meanwhile_threads = 0
        # seconds of the compiled loop per thread count (_native.CoreShare), and of them
        # those on one thread before CoreShare's first reading, for the summary
        self.thread_seconds: dict[int, float] = {}
        self.probe_seconds = 0.0
        _native.set_threads(None)  # after another run that ended on one thread meanwhile

    def _known_energy(self, u: np.ndarray, frozen: tuple) -> float:
        """The contact energy of ``frozen`` at u if an earlier attempt computed it, else
        NaN."""
        for u_known, pairs, W, energy in self._energies:
            if (u_known is u and np.array_equal(pairs, frozen[2])
                    and np.array_equal(W, frozen[3])):
                return energy
        return np.nan

    def _remember(self, u: np.ndarray, frozen: tuple, energy: float) -> None:
        self._energies = [(u, frozen[2], frozen[3], energy)] + self._energies[:3]

    def loop_compiling(self, state: DynState, done: float = 0.0) -> bool:
        """Whether a helper is compiling the time loop into an empty cache and has
        stored the attempt (beamcontact/_warmup.py): then the driver's host loop makes
        the steps with :meth:`attempt` meanwhile (dynamics/driver.py), and :meth:`advance`
        goes on from there once the loop is ready. The first call helps the helper
        (``_warmup.RUN_HELPS``: the HHT residual and tangent, the solver's update, and
        the contact set at the predictor and the checks after a step, which
        :meth:`attempt` calls from Python) and waits until the helper has stored the
        attempt or the loop; later
        calls look again at most every LOOK_SECONDS. ``done``: the fraction of the run's
        time made, from which the helper this run holds is let go on
        (:func:`~beamcontact._warmup.release_if_long`)."""
        from beamcontact import _warmup

        now = time.perf_counter()
        if self._looked is None:
            s = state if isinstance(state.u, np.ndarray) else self.host_state(state)
            _warmup.help_while_waiting(self, s)
        elif not self._looked[1] or now < self._looked[0] + LOOK_SECONDS:
            return self._looked[1]
        compiling = _warmup.steps_meanwhile()
        if compiling:
            if self._meanwhile_since is None:  # after the wait for the helper's attempt
                self._meanwhile_since = time.perf_counter()
            _warmup.release_if_long(now - self._meanwhile_since, done)
        # one core for a helper that compiles meanwhile: with a thread of the kernels on
        # each, the helper compiled 30 % longer and the steps ran slower; every core
        # while it is held or done (the next engine made in this process starts on all
        # its threads again)
        threads = 1 if compiling and not _warmup.holding() else _native.most_threads()
        if threads != self._meanwhile_threads:
            _native.set_threads(threads)
            self._meanwhile_threads = threads
        self._looked = (now, compiling)
        return compiling

    def host_state(self, state: DynState) -> DynState:
        """``state`` with host arrays (the initial state comes from the JAX twin)."""
        ls = state.load_state
        return DynState(float(state.t), _host(state.u), _host(state.v), _host(state.a),
                        _host(state.f_pot), replace(ls, theta=_host(ls.theta),
                                                    tangent=_host(ls.tangent)))

    def attempt(self, state: DynState, h: float, motion_factor: float, capacity) -> Attempt:
        """One attempt at a step of at most h from ``state``: the contact set at the
        predictor and the conservative advancement (:class:`NativeContact`), the compiled
        :func:`attempt`, the contact checks at the solution. The candidate lists have no
        fixed capacity here; their counts are reported as the JAX twin's are."""
        del capacity
        s = state if isinstance(state.u, np.ndarray) else self.host_state(state)
        n = self.nm.n_dof
        frozen, h_used = NO_CONTACT, float(h)
        if self._contact is not None:
            chosen = self._contact.choose(s, float(h), motion_factor, self.nm.x_ref)
            frozen, h_used = chosen.frozen, chosen.h
        u, v, a, f_pot = (np.empty(n) for _ in range(4))
        theta = np.empty_like(s.load_state.theta)
        tangent = np.empty_like(s.load_state.tangent)
        values, counts = np.empty(len(VALUES)), np.empty(len(COUNTS), dtype=np.int64)
        sysm, lay = self.system, self.system.layout
        ar = sysm.arrays
        has_contact = frozen[2].shape[0] > 0
        e_before = self._known_energy(s.u, frozen) if has_contact else np.nan
        attempt(self.nm, frozen, sysm.position, sysm.block_positions, sysm.free, ar.band,
                ar.B, ar.C, ar.D, ar.ipiv, ar.ipiv_s, lay.kl, lay.ku, s.u, s.v, s.a, s.f_pot,
                s.load_state.theta, s.load_state.tangent, h_used, self.alpha,
                self.options.rtol, self.utol, self.etol, self.dt_ref, self.total_mass,
                self.options.max_iterations, DIVERGE_AFTER, e_before, np.nan, u, v, a, f_pot,
                theta, tangent, values, counts)
        if has_contact:
            if np.isnan(e_before):
                self._remember(s.u, frozen, float(values[V_EC_BEFORE]))
            self._remember(u, frozen, float(values[V_CONTACT]))
        if self._contact is not None:
            self._contact.check(chosen, u, self.nm.x_ref, values, counts)
        new = DynState(s.t + values[V_H], u, v, a, f_pot,
                       replace(s.load_state, theta=theta, tangent=tangent))
        return Attempt(new, values, counts)

    def advance(self, state: DynState, ctl: np.ndarray, limits, emit):
        """Run the time loop from ``state`` and the controller's state ``ctl`` to
        limits.t_end or a stop (dynamics/driver.py, :class:`~beamcontact.dynamics.
        driver.Engine`): calls of the compiled loop of about CALL_SECONDS each (the
        first makes one attempt), every accepted step emitted in order after each call,
        also when the call is interrupted. Returns (the last accepted state, the stopping
        attempt or None, the seconds until the first call returned that were not Numba's
        compiles: the wait for a helper compiling the loop into an empty cache, loading
        the loop, one attempt)."""
        from beamcontact import _warmup
        from beamcontact.dynamics import native_loop

        s = state if isinstance(state.u, np.ndarray) else self.host_state(state)
        watch = Stopwatch()
        _warmup.help_while_waiting(self, s)
        _warmup.wait()  # a helper compiling the loop into an empty cache
        u, v, a, f_pot = (np.array(x, dtype=np.float64) for x in (s.u, s.v, s.a, s.f_pot))
        theta = np.array(s.load_state.theta, dtype=np.float64)
        tangent = np.array(s.load_state.tangent, dtype=np.float64)
        if self._contact is None:
            ne, law = _no_contact_elements()
        else:
            ne, law = self._contact.ne, self._contact.law
        sysm, lay = self.system, self.system.layout
        ar = sysm.arrays
        system = (sysm.position, sysm.block_positions, sysm.free, ar.band, ar.B, ar.C, ar.D,
                  ar.ipiv, ar.ipiv_s, lay.kl, lay.ku)
        newton = (self.alpha, float(self.options.rtol), float(self.utol), float(self.etol),
                  self.dt_ref, self.total_mass, int(self.options.max_iterations),
                  int(DIVERGE_AFTER))
        last_values, last_counts = np.zeros(len(VALUES)), np.zeros(len(COUNTS), np.int64)
        made = np.zeros(2, np.int64)
        budget, first_s = 1, None
        cores = CoreShare()
        n = u.shape[0]
        # at most about 32 MB of buffers per call
        row = 8 * (4 * n + theta.size + tangent.size + len(VALUES) + len(COUNTS) + ctl.size)
        most = max(2**25 // row, 1)
        while True:
            out = (np.empty((budget, n)), np.empty((budget, n)), np.empty((budget, n)),
                   np.empty((budget, n)), np.empty((budget, *theta.shape)),
                   np.empty((budget, *tangent.shape)), np.empty((budget, len(VALUES))),
                   np.empty((budget, len(COUNTS)), np.int64), np.empty((budget, ctl.size)))
            made[:] = 0
            cores.update()
            probing = cores.probing
            t0 = time.perf_counter()
            try:
                why = native_loop.run(self.nm, ne, law, self._contact is not None, system,
                                      NO_CONTACT, newton, ctl, limits, u, v, a, f_pot, theta,
                                      tangent, budget, *out, made, last_values, last_counts)
            finally:
                k = int(made[0])
                if k:
                    emit(StateRows(out[8][:k, T], *(x[:k] for x in out[:6])), out[6][:k],
                         out[7][:k], out[8][:k])
            seconds = time.perf_counter() - t0
            self.thread_seconds[cores.threads] = (self.thread_seconds.get(cores.threads, 0.0)
                                                  + seconds)
            if probing:
                self.probe_seconds += seconds
            if first_s is None:
                first_s = watch.outside_compiles()  # waiting for the helper, loading
                _warmup.loop_ready()
            last = DynState(float(ctl[T]), u, v, a, f_pot,
                            LoadState(theta=theta, tangent=tangent))
            if why == native_loop.DONE:
                return last, None, first_s
            if why == native_loop.STOPPED:
                return last, Attempt(None, last_values, last_counts), first_s
            # the next call as long as CALL_SECONDS at the rate of this one
            rate = seconds / max(int(made[1]), 1)
            budget = int(min(max(CALL_SECONDS / max(rate, 1e-9), 1), most))

    def initial_state(self, v0: np.ndarray) -> DynState:
        """The state at t = 0: zero displacement, the velocity v0 (n_dof,) on the free
        dofs, the load state of the reference configuration and the consistent
        acceleration under the contact set there (:func:`initial_acceleration`)."""
        nm, sysm = self.nm, self.system
        lay, ar = sysm.layout, sysm.arrays
        u = np.zeros(nm.n_dof)
        v = np.array(v0, dtype=np.float64) * nm.free
        nmod.tie_dependent(nm, v)
        # zero rotation and the reference tangent at every load point
        tangent = np.einsum("lk,lkd->ld", nm.load_dR, nm.x_ref[nm.load_conn])
        theta = np.zeros(tangent.shape[0])
        frozen = NO_CONTACT if self._contact is None else self._contact.frozen_at(nm.x_ref)
        f_pot, a = np.empty(nm.n_dof), np.empty(nm.n_dof)
        initial_acceleration(nm, frozen, u, v, theta, tangent, sysm.position,
                             sysm.block_positions, sysm.free, ar.band, ar.B, ar.C, ar.D,
                             ar.ipiv, ar.ipiv_s, lay.kl, lay.ku, f_pot, a)
        return DynState(0.0, u, v, a, f_pot, LoadState(theta=theta, tangent=tangent))

    def energies(self, state: DynState, capacity) -> dict:
        """The diagnostics of ``state`` under the contact set at its configuration (the
        energy account's start, and the first row of a run): energies, momentum and
        the smallest surface gap (NaN without contact)."""
        del capacity
        s = state if isinstance(state.u, np.ndarray) else self.host_state(state)
        values = np.zeros(len(VALUES))
        state_diagnostics(self.nm, s.u, s.v, s.load_state.theta, s.load_state.tangent,
                          values)
        gap = np.nan
        if self._contact is not None:
            x = self.nm.x_ref + s.u.reshape(-1, 2)
            frozen = self._contact.frozen_at(x)
            values[V_CONTACT] = contact_energy(self.nm, frozen, s.u)
            gap = self._contact.min_gap(x, frozen)
        return {**{k: float(values[_V[k]]) for k in
                   ("E_strain", "E_gravity", "E_ext", "E_contact", "E_kin", "p_x", "p_y")},
                "min_gap": float(gap)}

    @staticmethod
    def at_time(state: DynState, t: float) -> DynState:
        """``state`` with its time set to t."""
        return replace(state, t=t)

    @staticmethod
    def time(state: DynState) -> float:
        """The time of ``state``."""
        return float(state.t)
