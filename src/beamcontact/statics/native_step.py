"""The native engine of load stepping: one attempt at a load step compiled for the CPU
(Numba), the twin of :class:`~beamcontact.statics.step.JaxStatics` (docs/architecture.md,
"Engines").

An attempt: the contact set frozen at the last converged state with the loop's search
margin (:meth:`~beamcontact.dynamics.native_step.NativeContact.frozen_at`), Newton to
equilibrium at the new load factor lam (:func:`load_step`: the static residual
r = f_pot(u, lam) = grad Pi of assembly/native_model.py plus the frozen contact, its
tangent in the bordered banded matrix of the dynamic engine, the tests of
:func:`~beamcontact.solvers.newton.newton` with no absolute residual test), then the
contact checks at the solution. The load loop (statics/driver.py) is the one the JAX
engine uses.
"""

import numpy as np

from beamcontact._native import njit
from beamcontact.arrays_native import copy_1d
from beamcontact.assembly import native_model as nmod
from beamcontact.assembly.model import LoadState
from beamcontact.dynamics.native_step import (
    NO_CONTACT,
    NativeContact,
    NativeSystem,
    beam_dofs,
    contact_blocks,
    contact_energy,
)
from beamcontact.solvers import bordered_native as bordered
from beamcontact.solvers.newton import NewtonOptions
from beamcontact.statics.restraint import beam_modes, beam_ranges, singular_tangent_message
from beamcontact.statics.step import LoadAttempt, StaticState


@njit
def _residual_tangent(nm, contact, u, lam, theta_n, t_n, position, positions, free_layout,
                      band, B, C, D, kl, ku, r, r_layout, k_blocks):
    """The static residual at u with supports applied (global numbering, into r) and its
    tangent in the bordered arrays (its residual in layout order in r_layout); returns
    ||r||."""
    nmod.potential_residual_blocks(nm, u, lam, theta_n, t_n, r, k_blocks)
    bordered.zero(band, B, C, D)
    bordered.add_blocks(band, B, C, D, kl, ku, positions, k_blocks)
    if contact[2].shape[0] > 0:
        contact_blocks(nmod._positions(nm.x_ref, u), *contact, 1.0, position, band, B, C, D,
                       kl, ku, np.zeros(r.shape[0]), r)
    return bordered.supported_residual(band, B, C, D, kl, ku, free_layout, position, r,
                                       r_layout)


@njit
def load_step(nm, contact, position, positions, free_layout, band, B, C, D, ipiv, ipiv_s, kl,
              ku, u0, lam, theta_n, t_n, rtol, utol_abs, max_iterations, u, out):
    """Newton from the converged displacement u0 to equilibrium at load factor lam (the
    loads' rotations theta_n, t_n of u0, the contact set ``contact`` frozen) into u;
    out = (iterations, converged, ||r||, ||r_0||). Converged: ||r|| <= rtol ||r_0|| or
    max |du| <= utol_abs; a NaN or the iteration limit fails."""
    n = u0.shape[0]
    copy_1d(u, u0)
    r, r_layout, du = np.empty(n), np.empty(n), np.empty(n)
    k_blocks = np.empty((nm.block_dofs.shape[0], nm.block_dofs.shape[1],
                         nm.block_dofs.shape[1]))
    args = (position, positions, free_layout, band, B, C, D, kl, ku, r, r_layout, k_blocks)
    norm0 = _residual_tangent(nm, contact, u, lam, theta_n, t_n, *args)
    done, failed = norm0 <= 0.0, not np.isfinite(norm0)
    k, rn = 0, norm0
    while not done and not failed and k < max_iterations:
        step, finite = bordered.newton_update(band, B, C, D, kl, ku, ipiv, ipiv_s, position,
                                              r_layout, du, u)
        rn = _residual_tangent(nm, contact, u, lam, theta_n, t_n, *args)
        failed = not np.isfinite(rn) or not finite
        done = (rn <= rtol * norm0 or step <= utol_abs) and not failed
        k += 1
    out[0], out[1], out[2], out[3] = k, 1.0 if done else 0.0, rn, norm0


@njit
def reference_tangent(nm, contact, theta, tangent, position, positions, band, B, C, D, kl,
                      ku):
    """The tangent of the potential at u = 0 and load factor 0, the frozen contact
    included and no supports applied, as a dense matrix in the global numbering (for the
    check of a singular tangent only)."""
    n = nm.free.shape[0]
    u, r = np.zeros(n), np.empty(n)
    k_blocks = np.empty((nm.block_dofs.shape[0], nm.block_dofs.shape[1],
                         nm.block_dofs.shape[1]))
    nmod.potential_residual_blocks(nm, u, 0.0, theta, tangent, r, k_blocks)
    bordered.zero(band, B, C, D)
    bordered.add_blocks(band, B, C, D, kl, ku, positions, k_blocks)
    if contact[2].shape[0] > 0:
        contact_blocks(nmod._positions(nm.x_ref, u), *contact, 1.0, position, band, B, C, D,
                       kl, ku, np.zeros(n), np.zeros(n))
    dense = bordered.to_dense(band, B, C, D, kl, ku)
    K = np.empty((n, n))
    for i in range(n):
        for j in range(n):
            K[i, j] = dense[position[i], position[j]]
    return K


class NativeStatics:
    """The native engine of load stepping (docs/architecture.md, "Engines"): the interface
    of :class:`~beamcontact.statics.step.JaxStatics`; its states are
    :class:`~beamcontact.statics.step.StaticState` of NumPy arrays, its contact sets the
    frozen tuples of the native kernels."""

    name = "native"

    def __init__(self, model, contact, options: NewtonOptions, length: float):
        self.model, self.contact, self.options = model, contact, options
        self.nm = nmod.native_arrays(model)
        self._contact = None if contact is None else NativeContact(contact)
        self.system = NativeSystem(self.nm, beam_dofs(self.nm))
        self.utol = options.utol * length

    def initial(self) -> StaticState:
        """The unloaded reference state: zero displacement and rotation, the reference
        tangent at every load point."""
        nm = self.nm
        tangent = np.einsum("lk,lkd->ld", nm.load_dR, nm.x_ref[nm.load_conn])
        return StaticState(np.zeros(nm.n_dof),
                           LoadState(theta=np.zeros(tangent.shape[0]), tangent=tangent))

    def _x(self, u: np.ndarray) -> np.ndarray:
        return self.nm.x_ref + u.reshape(-1, 2)

    def complete_set(self, state: StaticState, margin: float, capacity):
        """The contact set at ``state`` with the search margin (complete: the native
        search has no capacity); (set, capacity)."""
        return self._contact.frozen_at(self._x(state.u), margin), capacity

    def attempt(self, state: StaticState, lam: float, margin: float,
                capacity) -> LoadAttempt:
        """Newton at load factor lam from ``state`` with the contact set frozen there (its
        candidates grown by ``margin``), and the contact checks at the solution."""
        frozen = NO_CONTACT
        if self._contact is not None:
            frozen = self._contact.frozen_at(self._x(state.u), margin)
        sysm, lay = self.system, self.system.layout
        ar = sysm.arrays
        u, out = np.empty(self.nm.n_dof), np.empty(4)
        ls = state.load_state
        load_step(self.nm, frozen, sysm.position, sysm.block_positions, sysm.free, ar.band,
                  ar.B, ar.C, ar.D, ar.ipiv, ar.ipiv_s, lay.kl, lay.ku, state.u, float(lam),
                  ls.theta, ls.tangent, float(self.options.rtol), float(self.utol),
                  int(self.options.max_iterations), u, out)
        converged, gap, missing = bool(out[1]), float("inf"), False
        if converged and self._contact is not None:
            missing, gap = self._contact.missed(self._x(u), frozen)
        return LoadAttempt(u, converged, int(out[0]), float(out[2]), float(out[3]),
                           None if self._contact is None else frozen, gap, missing)

    def accept(self, state: StaticState, attempt: LoadAttempt) -> StaticState:
        """The state of an accepted attempt: its displacement, the loads' rotations
        continued to it."""
        ls = state.load_state
        theta, tangent = np.empty_like(ls.theta), np.empty_like(ls.tangent)
        nmod.update_load_state(self.nm, attempt.u, ls.theta, ls.tangent, theta, tangent)
        return StaticState(attempt.u, LoadState(theta=theta, tangent=tangent))

    def values(self, state: StaticState, lam: float, cs) -> dict:
        """Energies (contact included) and the smallest gap (NaN without contact)."""
        ls = state.load_state
        e_strain, e_gravity, e_ext = nmod.energies(self.nm, state.u, float(lam), ls.theta,
                                                   ls.tangent)
        d = {"E_strain": e_strain, "E_gravity": e_gravity, "E_ext": e_ext, "E_contact": 0.0,
             "min_gap": float("nan")}
        if self._contact is not None:
            d["E_contact"] = contact_energy(self.nm, cs, state.u)
            d["min_gap"] = self._contact.min_gap(self._x(state.u), cs)
        return d

    def mechanism(self, state: StaticState, cs, beam_names) -> str | None:
        """Why the tangent at the reference state is singular, or None
        (statics/restraint.py; the tangent is assembled, at load factor 0 with the
        contact set ``cs``, only when the supports leave some beam free)."""
        nm = self.nm
        free = nm.free > 0.5
        ranges = beam_ranges([np.asarray(b.conn) for b in self.model.beams])
        if not any(m.shape[1] for m in beam_modes(nm.x_ref, free, ranges)):
            return None
        if beam_names is None or len(beam_names) != len(ranges):
            labels = [f"#{i + 1} (control points {a}-{b - 1})"
                      for i, (a, b) in enumerate(ranges)]
        else:
            labels = [repr(name) for name in beam_names]
        sysm, lay = self.system, self.system.layout
        ar = sysm.arrays
        K = reference_tangent(nm, NO_CONTACT if cs is None else cs, state.load_state.theta,
                              state.load_state.tangent, sysm.position, sysm.block_positions,
                              ar.band, ar.B, ar.C, ar.D, lay.kl, lay.ku)
        return singular_tangent_message(K, free, nm.x_ref, ranges, labels,
                                        contact=self.contact is not None)

    @staticmethod
    def displacement(state: StaticState) -> np.ndarray:
        """The displacement of ``state`` on the host."""
        return np.asarray(state.u)
