"""The model as flat NumPy arrays, and the native (Numba) global residuals and element
tangent blocks of the potential and of the inertia, beside assembly/system.py and
assembly/inertia.py.

The JAX assembly is the definition; these functions evaluate the same sums with the
native kernels of beam/energy_native.py, beam/inertia_native.py and beam/loads_native.py,
tested against it to a relative 1e-12 (tests/test_native_model.py).

Layout (:class:`NativeModel`, made once by :func:`native_arrays`): the elements of all
ElementBlocks of ``model.beams`` are concatenated in their order (block 0's elements, then
block 1's, ...; ``block_index`` says which block each came from). Blocks of different
degree, Gauss or section point counts are padded to the largest of each (n_loc, n_qp,
n_eta) by entries that contribute exact zeros, so that every kernel runs on whole
C-contiguous rows with no counts:
    - control points: basis columns R = dR = ddR = 0, conn 0 (control point 0), as the
      padding of PointLoads in assembly/model.py;
    - Gauss points: a copy of the element's first Gauss point with weight wq = 0 (a
      finite point times zero: a zero weight on a zero basis row would make g = 0 and
      the curvature 0/0);
    - section points: eta = 0 with weight 0.
Where nothing is padded (one degree, as every example) the arrays are those of the model.

Tangent blocks: the global tangent is sum_b scatter(block_dofs[b], block_k[b]) over the
n_el + n_load blocks of ``block_dofs`` (n_blocks, 2 n_loc) — the elements in the order
above, then the point loads — each dense (2 n_loc, 2 n_loc) in the dofs of
``block_dofs[b]`` (x_e.ravel() order, global dof 2 c + a of control point c). Padding
entries hold exact zeros at dofs 0, 1. The caller owns and preallocates ``block_k``
(:func:`new_blocks`) and the global vectors; nothing here forms an n x n matrix. No
supports are applied (``free`` is carried for the caller, as ``apply_supports`` does in
JAX).

Potential (static total potential of assembly/system.py with load factor lam):
    Pi(u) = sum_e Pi_int,e + lam (sum_e Pi_grav,e + sum_l Pi_load,l)
(eqs. 23-26, 30; gravity -int rho A g . r ds; loads beam/loads.py). HHT (eqs. 31-37,
dynamics/hht.py): r = r_inertia + (1 + alpha) r_pot - alpha f_pot_n, K = K_i + (1 + alpha)
K_p with lam = 1; both tangents share the element blocks, so they are added per block.

State arrays are float64, C-contiguous: u and the like flat (n_dof,) in the global
numbering; the load state as theta (n_load,) and tangent (n_load, 2) (LoadState).
"""

from typing import NamedTuple

import numpy as np

from beamcontact._native import (
    njit,
    njit_inline,
    njit_parallel,
    njit_parallel_uncounted,
    njit_uncounted,
    prange,
)
from beamcontact.beam import energy_native, inertia_native, loads_native


class NativeModel(NamedTuple):
    """A Model (assembly/model.py) as flat arrays; layout in the module docstring.

    Shapes (n_el elements of all blocks, n_load loads, n_loc, n_qp, n_eta the padded
    counts): x_ref (n_cp, 2); free (n_dof,); gravity (2,); tied (n_t,), tie_masters
    (n_t, 3) int64 and tie_weights (n_t, 3) (Model's); conn (n_el, n_loc) int64;
    elem_n_loc, block_index (n_el,) int64 (the element's real number of control points
    and its ElementBlock in model.beams); R, dR, ddR (n_el, n_qp, n_loc); wq, g_ref,
    K_ref (n_el, n_qp); eta, w_eta (n_el, n_eta); E, rho_area, rho_inertia, gravity_on
    (n_el,); load_conn (n_load, n_loc) int64; load_R, load_dR (n_load, n_loc);
    load_force (n_load, 2); load_moment (n_load,); block_dofs (n_el + n_load, 2 n_loc)
    int64.
    """

    x_ref: np.ndarray
    free: np.ndarray
    gravity: np.ndarray
    tied: np.ndarray
    tie_masters: np.ndarray
    tie_weights: np.ndarray
    conn: np.ndarray
    elem_n_loc: np.ndarray
    block_index: np.ndarray
    R: np.ndarray
    dR: np.ndarray
    ddR: np.ndarray
    wq: np.ndarray
    g_ref: np.ndarray
    K_ref: np.ndarray
    eta: np.ndarray
    w_eta: np.ndarray
    E: np.ndarray
    rho_area: np.ndarray
    rho_inertia: np.ndarray
    gravity_on: np.ndarray
    load_conn: np.ndarray
    load_R: np.ndarray
    load_dR: np.ndarray
    load_force: np.ndarray
    load_moment: np.ndarray
    block_dofs: np.ndarray

    @property
    def n_dof(self) -> int:
        """Number of dofs, 2 per control point."""
        return self.free.shape[0]

    @property
    def n_elements(self) -> int:
        """Number of elements of all beams."""
        return self.conn.shape[0]

    @property
    def n_blocks(self) -> int:
        """Number of tangent blocks: the elements, then the loads."""
        return self.block_dofs.shape[0]


def _f64(a) -> np.ndarray:
    """A writable float64 copy (NumPy views of JAX arrays are read-only, and Numba
    compiles every kernel again for read-only arguments)."""
    return np.array(a, dtype=np.float64, order="C", copy=True)


def _pad_last(a: np.ndarray, n: int) -> np.ndarray:
    """Zero columns appended to the last axis up to n."""
    width = [(0, 0)] * (a.ndim - 1) + [(0, n - a.shape[-1])]
    return np.pad(a, width)


def _pad_points(a: np.ndarray, n_qp: int) -> np.ndarray:
    """Axis 1 (Gauss points) extended to n_qp by copies of point 0."""
    extra = np.repeat(a[:, :1], n_qp - a.shape[1], axis=1)
    return np.concatenate([a, extra], axis=1)


def _dofs(conn: np.ndarray) -> np.ndarray:
    """Dofs in x_e.ravel() order, as assembly/model.py's element_dofs."""
    return np.stack([2 * conn, 2 * conn + 1], axis=-1).reshape(conn.shape[0],
                                                                2 * conn.shape[1])


def native_arrays(model) -> NativeModel:
    """The flat arrays of a JAX :class:`~beamcontact.assembly.model.Model` (host copies;
    ``model.sparse`` plays no part: the blocks serve either storage)."""
    blocks = model.beams
    ld = model.loads
    n_loc = max([b.conn.shape[1] for b in blocks] + [ld.conn.shape[1]])
    n_qp = max(b.wq.shape[1] for b in blocks)
    n_eta = max(b.eta.shape[1] for b in blocks)
    parts: dict[str, list] = {}
    for i, b in enumerate(blocks):
        conn = np.asarray(b.conn, dtype=np.int64)
        n_el = conn.shape[0]
        wq = _f64(b.wq)
        padded_wq = np.zeros((n_el, n_qp))
        padded_wq[:, :wq.shape[1]] = wq
        fields = {
            "conn": _pad_last(conn, n_loc),
            "elem_n_loc": np.full(n_el, conn.shape[1], dtype=np.int64),
            "block_index": np.full(n_el, i, dtype=np.int64),
            "wq": padded_wq,
            "eta": _pad_last(_f64(b.eta), n_eta),
            "w_eta": _pad_last(_f64(b.w_eta), n_eta),
        }
        for name in ("R", "dR", "ddR"):
            fields[name] = _pad_points(_pad_last(_f64(getattr(b, name)), n_loc), n_qp)
        for name in ("g_ref", "K_ref"):
            fields[name] = _pad_points(_f64(getattr(b, name)), n_qp)
        for name in ("E", "rho_area", "rho_inertia", "gravity_on"):
            fields[name] = _f64(getattr(b, name))
        for name, value in fields.items():
            parts.setdefault(name, []).append(value)
    el = {name: np.ascontiguousarray(np.concatenate(v)) for name, v in parts.items()}
    load_conn = _pad_last(np.asarray(ld.conn, dtype=np.int64), n_loc)
    return NativeModel(
        x_ref=_f64(model.x_ref), free=_f64(model.free), gravity=_f64(model.gravity),
        tied=np.array(model.tied, dtype=np.int64).reshape(-1),
        tie_masters=np.array(model.tie_masters, dtype=np.int64).reshape(-1, 3),
        tie_weights=_f64(model.tie_weights).reshape(-1, 3),
        **el,
        load_conn=np.ascontiguousarray(load_conn),
        load_R=np.ascontiguousarray(_pad_last(_f64(ld.R), n_loc)),
        load_dR=np.ascontiguousarray(_pad_last(_f64(ld.dR), n_loc)),
        load_force=_f64(ld.force).reshape(-1, 2), load_moment=_f64(ld.moment).reshape(-1),
        block_dofs=np.ascontiguousarray(np.concatenate([_dofs(el["conn"]),
                                                        _dofs(load_conn)])))


def new_blocks(nm: NativeModel) -> np.ndarray:
    """An uninitialised block_k (n_blocks, 2 n_loc, 2 n_loc) for :func:`potential_residual_blocks`
    and :func:`hht_residual_blocks` (every block is overwritten)."""
    m = nm.block_dofs.shape[1]
    return np.empty((nm.n_blocks, m, m))


# ------------------------------------------------------------------------------ compiled


@njit
def tie_dependent(nm, w):
    """In place, w[tied[t]] = sum_k tie_weights[t, k] w[tie_masters[t, k]] for a
    displacement, velocity or acceleration w (n_dof,): the free ends' constraints
    (beam/free_ends.py), as :func:`beamcontact.assembly.system.tie_dependent`."""
    for t in range(nm.tied.shape[0]):
        s = 0.0
        for k in range(nm.tie_masters.shape[1]):
            s += nm.tie_weights[t, k] * w[nm.tie_masters[t, k]]
        w[nm.tied[t]] = s


@njit
def _positions(x_ref, u):
    """x = x_ref + u (flat u) as (n_cp, 2)."""
    return x_ref + u.reshape(x_ref.shape)


@njit_inline
def _gather(w, conn_e, w_e):
    """w_e[k] = w[conn_e[k]] for control-point values w (n_cp, 2)."""
    for k in range(conn_e.shape[0]):
        w_e[k, 0] = w[conn_e[k], 0]
        w_e[k, 1] = w[conn_e[k], 1]


@njit_inline
def _scatter_add(dofs, r_e, r_out):
    """r_out[dofs] += r_e."""
    for i in range(dofs.shape[0]):
        r_out[dofs[i]] += r_e[i]


# The helpers called per element take arrays and an index, never the NativeModel: a tuple
# of 24 arrays passed to a function that is not inlined is copied with a reference count
# increment and decrement of every array, which cost a third of the time of the strain
# kernels when the gravity helper took it.

@njit_inline
def _gravity_force(R, wq, g_ref, e, c, gravity, r_e):
    """r_e += the gradient of c times element e's gravity potential -int g . r ds
    (ds = wq sqrt(g*); c = lam rho A gravity_on), which is linear in x (no tangent)."""
    gx, gy = gravity[0], gravity[1]
    for q in range(R.shape[1]):
        w = c * wq[e, q] * np.sqrt(g_ref[e, q])
        for k in range(R.shape[2]):
            r_e[2 * k] -= w * R[e, q, k] * gx
            r_e[2 * k + 1] -= w * R[e, q, k] * gy


@njit_inline
def _gravity_energy(R, wq, g_ref, e, gravity, x_e):
    """-int g . r ds of element e at its control points x_e (times rho A gravity_on lam by
    the caller)."""
    s = 0.0
    for q in range(R.shape[1]):
        rx = ry = 0.0
        for k in range(R.shape[2]):
            rx += R[e, q, k] * x_e[k, 0]
            ry += R[e, q, k] * x_e[k, 1]
        s += wq[e, q] * np.sqrt(g_ref[e, q]) * (rx * gravity[0] + ry * gravity[1])
    return -s


@njit
def _potential(nm, x, lam, theta_n, t_n, r_el, r_out, k_out, tangent=True):
    """r_pot added to r_out and the potential's blocks into k_out[b] (the elements, then
    the loads; ``tangent`` False: the element blocks are left alone); r_el (n_el, m) is
    scratch. Returns the strain energy at x (the sum of :func:`energies`' E_strain, bit
    for bit: the same element energies in the same order)."""
    # k_out whole, not k_out[:n_el]: the kernel writes only rows e < n_el, and a slice
    # would be typed as a non-contiguous array and compile a slower element kernel
    e_strain = energy_native.block_strain_residual_tangent(
        x, nm.conn, nm.dR, nm.ddR, nm.wq, nm.g_ref, nm.K_ref, nm.eta, nm.w_eta, nm.E, r_el,
        k_out, tangent)
    _external_forces(nm, x, lam, theta_n, t_n, r_el, r_out, k_out)
    return e_strain


@njit_inline
def _external_forces(nm, x, lam, theta_n, t_n, r_el, r_out, k_out):
    """The rest of :func:`_potential` once the element strain forces are in r_el: gravity
    added to them, the elements' forces added to r_out in element order, then the point
    loads' forces and blocks (k_out[n_el + i]). Inlined: a call that takes the
    NativeModel counts a reference of each of its arrays."""
    n_el = nm.conn.shape[0]
    _add_gravity_elements(nm.R, nm.wq, nm.g_ref, nm.rho_area, nm.gravity_on, nm.gravity,
                          nm.block_dofs, lam, r_el, r_out)
    n = nm.load_conn.shape[1]
    x_l = np.empty((n, 2))
    r_l = np.empty(2 * n)
    for i in range(nm.load_conn.shape[0]):
        _gather(x, nm.load_conn[i], x_l)
        loads_native.point_load_residual_tangent(
            x_l, nm.load_R[i], nm.load_dR[i], nm.load_force[i], nm.load_moment[i],
            theta_n[i], t_n[i], lam, r_l, k_out[n_el + i])
        _scatter_add(nm.block_dofs[n_el + i], r_l, r_out)


@njit_uncounted
def _add_gravity_elements(R, wq, g_ref, rho_area, gravity_on, gravity, dofs, lam, r_el,
                          r_out):
    """Gravity added to each element's force r_el[e], then the elements' forces added to
    r_out in element order (no reference counts for the views of an element)."""
    for e in range(r_el.shape[0]):
        c = lam * rho_area[e] * gravity_on[e]
        if c != 0.0:  # gravity off: JAX adds exact zeros
            _gravity_force(R, wq, g_ref, e, c, gravity, r_el[e])
        _scatter_add(dofs[e], r_el[e], r_out)


@njit
def potential_residual_blocks(nm, u, lam, theta_n, t_n, r_out, k_out):
    """Gradient (residual) and element/load Hessian blocks of the static potential, as
    :func:`~beamcontact.assembly.system.potential_residual_tangent` (unconstrained).

    Arguments, in call order:
        nm: the NativeModel.
        u: displacement (n_dof,).
        lam: load factor (scales gravity and loads).
        theta_n, t_n: the load state (n_load,), (n_load, 2).
        r_out: residual (n_dof,), overwritten.
        k_out: blocks (n_blocks, m, m) in the dofs of nm.block_dofs, overwritten.
    """
    r_out[:] = 0.0
    r_el = np.empty((nm.conn.shape[0], nm.block_dofs.shape[1]))
    _potential(nm, _positions(nm.x_ref, u), lam, theta_n, t_n, r_el, r_out, k_out)


@njit
def energies(nm, u, lam, theta_n, t_n):
    """(E_strain, E_gravity, E_ext) at displacement u, as
    :func:`~beamcontact.assembly.system.energies` (E_gravity and E_ext include lam)."""
    x = _positions(nm.x_ref, u)
    n_el, n = nm.conn.shape
    x_e = np.empty((n, 2))
    e_strain = 0.0
    for e in range(n_el):
        _gather(x, nm.conn[e], x_e)
        e_strain += energy_native.element_strain_energy(x_e, nm.dR[e], nm.ddR[e], nm.wq[e],
                                                        nm.g_ref[e], nm.K_ref[e], nm.eta[e],
                                                        nm.w_eta[e], nm.E[e])
    e_grav, e_ext = external_energies(nm, x, lam, theta_n, t_n)
    return e_strain, e_grav, e_ext


@njit
def external_energies(nm, x, lam, theta_n, t_n):
    """(E_gravity, E_ext) of :func:`energies` alone, at the control points x (n_cp, 2): a
    time step takes E_strain from its last Newton evaluation (:func:`hht_residual_blocks`),
    at the same x."""
    x_e = np.empty((nm.conn.shape[1], 2))
    e_grav = _gravity_energies(nm.R, nm.wq, nm.g_ref, nm.rho_area, nm.gravity_on, nm.gravity,
                               nm.conn, x, x_e)
    e_ext = 0.0
    for i in range(nm.load_conn.shape[0]):
        _gather(x, nm.load_conn[i], x_e)
        e_ext += lam * loads_native.point_load_potential(
            x_e, nm.load_R[i], nm.load_dR[i], nm.load_force[i], nm.load_moment[i], theta_n[i],
            t_n[i])
    return lam * e_grav, e_ext


@njit_uncounted
def _gravity_energies(R, wq, g_ref, rho_area, gravity_on, gravity, conn, x, x_e):
    """The sum over the elements, in element order, of rho A gravity_on times
    :func:`_gravity_energy` at the control points x (x_e: scratch; no reference counts
    for the views of an element)."""
    e_grav = 0.0
    for e in range(conn.shape[0]):
        _gather(x, conn[e], x_e)
        e_grav += rho_area[e] * gravity_on[e] * _gravity_energy(R, wq, g_ref, e, gravity, x_e)
    return e_grav


@njit_inline
def _inertia_scratch(n_el, n):
    """The scratch of :func:`_element_inertia_at` for n_el elements of n control points,
    one row per element (w_e, m, jac, J): an allocation per element costs more than its
    sums."""
    return (np.empty((n_el, 5, n, 2)), np.empty((n_el, 2)), np.empty((n_el, 3, 2, 2)),
            np.empty((n_el, 2, 2)))


@njit_inline
def _element_inertia_at(e, conn, x_ref, u2, un2, vn2, an2, coeffs, R, dR, wq, g_ref, rho_area,
                        rho_inertia, w_e, m, jac, J, r_e, k_e, tangent):
    """Element e's inertia residual into r_e and (``tangent``) its block into k_e, its
    control-point values gathered into the scratch w_e (5, n, 2) (m, jac, J: the
    kernel's scratch)."""
    c = conn[e]
    _gather(u2, c, w_e[0])
    _gather(un2, c, w_e[1])
    _gather(vn2, c, w_e[2])
    _gather(an2, c, w_e[3])
    _gather(x_ref, c, w_e[4])
    inertia_native._element_inertia(w_e[0], w_e[1], w_e[2], w_e[3], w_e[4], coeffs, R[e],
                                    dR[e], wq[e], g_ref[e], rho_area[e], rho_inertia[e], r_e,
                                    k_e, m, jac, J, tangent)


@njit_parallel
def _inertia_elements(conn, x_ref, u2, un2, vn2, an2, coeffs, R, dR, wq, g_ref, rho_area,
                      rho_inertia, r_el, k_el):
    """Every element's inertia residual into r_el[e] and its block into k_el[e], the
    elements on the cores (each whole on one thread)."""
    n_el, n = conn.shape
    w_all, m_all, jac_all, J_all = _inertia_scratch(n_el, n)
    for e in prange(n_el):
        _element_inertia_at(e, conn, x_ref, u2, un2, vn2, an2, coeffs, R, dR, wq, g_ref,
                            rho_area, rho_inertia, w_all[e], m_all[e], jac_all[e], J_all[e],
                            r_el[e], k_el[e], True)


@njit
def inertia_residual_blocks(nm, u, u_n, v_n, a_n, coeffs, r_out, k_out):
    """Inertia force at u with Newmark's v(u), a(u) and its element blocks d/du, as
    :func:`~beamcontact.assembly.inertia.inertia_residual_tangent` (eqs. 29, 33-35).

    Arguments, in call order:
        u, u_n, v_n, a_n: displacement now and u, v, a of the last step (n_dof,).
        coeffs: (c_a, dt, c_1, gamma), dynamics/hht.py's ``hht_coefficients``.
        r_out: residual (n_dof,), overwritten.
        k_out: blocks (at least n_el, m, m); the first n_el are overwritten (the element
            blocks, dofs nm.block_dofs[:n_el]; the inertia has no load blocks).
    """
    r_out[:] = 0.0
    shape = nm.x_ref.shape
    n_el, n = nm.conn.shape
    r_el = np.empty((n_el, 2 * n))
    _inertia_elements(nm.conn, nm.x_ref, u.reshape(shape), u_n.reshape(shape),
                      v_n.reshape(shape), a_n.reshape(shape), coeffs, nm.R, nm.dR, nm.wq,
                      nm.g_ref, nm.rho_area, nm.rho_inertia, r_el, k_out)
    for e in range(n_el):
        _scatter_add(nm.block_dofs[e], r_el[e], r_out)


@njit
def hht_residual_blocks(nm, u, u_n, v_n, a_n, coeffs, alpha, f_pot_n, theta_n, t_n, r_out,
                        r_pot_out, k_out, tangent=True):
    """The HHT Newton residual and tangent blocks of dynamics/hht.py's ``hht_step``
    (eq. 36, lam = 1, before supports):
        r = r_inertia + (1 + alpha) r_pot - alpha f_pot_n,   K = K_i + (1 + alpha) K_p,
    into r_out (n_dof,) and k_out (n_blocks, m, m), with r_pot (the history f_pot of the
    next step once converged) into r_pot_out (n_dof,). Arguments as in
    :func:`inertia_residual_blocks` and :func:`potential_residual_blocks`. Returns the
    strain energy at u (:func:`energies`' E_strain, bit for bit). ``tangent`` False: the
    residuals and the energy alone, the same numbers bit for bit, k_out is scratch (the
    Newton check of an iterate expected to have converged, dynamics/native_step.py)."""
    c = 1.0 + alpha
    r_pot_out[:] = 0.0
    shape = nm.x_ref.shape
    n_el, n = nm.conn.shape
    x = _positions(nm.x_ref, u)
    r_el, r_in = np.empty((n_el, nm.block_dofs.shape[1])), np.empty((n_el, 2 * n))
    k_in = np.empty((n_el, 2 * n, 2 * n)) if tangent else k_out
    energies = np.empty(n_el)
    _hht_elements(x, nm.conn, nm.dR, nm.ddR, nm.wq, nm.g_ref, nm.K_ref, nm.eta, nm.w_eta,
                  nm.E, nm.x_ref, u.reshape(shape), u_n.reshape(shape), v_n.reshape(shape),
                  a_n.reshape(shape), coeffs, nm.R, nm.rho_area, nm.rho_inertia, r_el, k_out,
                  energies, r_in, k_in, tangent, c,
                  energy_native.element_scratch(n_el, n) + _inertia_scratch(n_el, n))
    e_strain = 0.0
    for e in range(n_el):  # in element order, as block_strain_residual_tangent sums
        e_strain += energies[e]
    _external_forces(nm, x, 1.0, theta_n, t_n, r_el, r_pot_out, k_out)
    for i in range(r_out.shape[0]):
        r_out[i] = c * r_pot_out[i] - alpha * f_pot_n[i]
    if tangent:
        _scale_blocks(k_out, n_el, c)  # the loads' (the elements' are scaled above)
    _add_inertia_forces(nm.block_dofs, r_in, r_out)
    return e_strain


@njit_uncounted
def _scale_blocks(k, first, c):
    """k[b] *= c for the blocks b >= first (element by element: ``k[b] *= c`` on a view
    compiles Numba's error message for mismatched shapes)."""
    for b in range(first, k.shape[0]):
        for i in range(k.shape[1]):
            for j in range(k.shape[2]):
                k[b, i, j] *= c


@njit_uncounted
def _add_inertia_forces(block_dofs, r_in, r_out):
    """The elements' inertia forces r_in[e] added to r_out, in element order (no
    reference counts for the views of an element)."""
    for e in range(r_in.shape[0]):
        _scatter_add(block_dofs[e], r_in[e], r_out)


@njit_parallel_uncounted
def _hht_elements(x, conn, dR, ddR, wq, g_ref, K_ref, eta, w_eta, E, x_ref, u2, un2, vn2, an2,
                  coeffs, R, rho_area, rho_inertia, r_strain, k_hht, energies, r_inertia,
                  k_inertia, tangent, c, scratch):
    """Each element's strain force and energy (as
    :func:`~beamcontact.beam.energy_native.block_strain_residual_tangent`) into
    r_strain[e], energies[e], its inertia force (as :func:`inertia_residual_blocks`) into
    r_inertia[e] and (``tangent``) its block of the HHT tangent, K_i + c K_p with
    c = 1 + alpha, into k_hht[e] (k_inertia[e] is scratch), in one pass over the elements
    on the cores: one parallel loop per evaluation of the HHT residual instead of two,
    each element whole on one thread. The block is formed where its two parts are in
    the cache: the numbers of scaling every block, then adding the inertia's, bit for
    bit. ``scratch``: :func:`~beamcontact.beam.energy_native.element_scratch` and
    :func:`_inertia_scratch` of the elements, the caller's (this loop allocates nothing:
    no reference counts)."""
    n_el = conn.shape[0]
    m = k_inertia.shape[1]
    x_all, grad_all, hess_all, w_all, m_all, jac_all, J_all = scratch
    for e in prange(n_el):
        energies[e] = energy_native.element_strain_at(
            e, x, conn, dR, ddR, wq, g_ref, K_ref, eta, w_eta, E, x_all[e], grad_all[e],
            hess_all[e], r_strain[e], k_hht[e], tangent)
        _element_inertia_at(e, conn, x_ref, u2, un2, vn2, an2, coeffs, R, dR, wq, g_ref,
                            rho_area, rho_inertia, w_all[e], m_all[e], jac_all[e], J_all[e],
                            r_inertia[e], k_inertia[e], tangent)
        if tangent:
            for i in range(m):
                for j in range(m):
                    k_hht[e, i, j] = c * k_hht[e, i, j] + k_inertia[e, i, j]


@njit
def inertia_force_mass_blocks(nm, u, v, f_out, m_out):
    """The inertia force at zero acceleration (its velocity terms, eq. 29) into f_out
    (n_dof,) and the mass matrix (translational and rotational) into the element blocks
    of m_out (n_blocks, m, m; the load blocks zero), both overwritten, at displacement u
    and velocity v: F_inertia(u, v, a) = f_out + M a, as
    :func:`~beamcontact.assembly.inertia.inertia_force_and_mass`."""
    x = _positions(nm.x_ref, u)
    v2 = v.reshape(nm.x_ref.shape)
    n_el, n = nm.conn.shape
    x_e, v_e, a_e = np.empty((n, 2)), np.empty((n, 2)), np.zeros((n, 2))
    f_e = np.empty(2 * n)
    jx, jv = np.empty((2 * n, 2 * n)), np.empty((2 * n, 2 * n))
    f_out[:] = 0.0
    m_out[:] = 0.0
    for e in range(n_el):
        _gather(x, nm.conn[e], x_e)
        _gather(v2, nm.conn[e], v_e)
        inertia_native.element_inertia_jacobians(x_e, v_e, a_e, nm.R[e], nm.dR[e], nm.wq[e],
                                                 nm.g_ref[e], nm.rho_area[e],
                                                 nm.rho_inertia[e], f_e, jx, jv, m_out[e])
        _scatter_add(nm.block_dofs[e], f_e, f_out)


@njit
def kinetic_energy_momentum(nm, u, v):
    """Kinetic energy (translation and rotation of the sections, eq. 18) and linear
    momentum (2,) at displacement u and velocity v (n_dof,), as
    :func:`~beamcontact.assembly.inertia.kinetic_energy_and_momentum`."""
    n = nm.conn.shape[1]
    p = np.zeros(2)
    T = _kinetic_elements(_positions(nm.x_ref, u), v.reshape(nm.x_ref.shape), nm.conn,
                          nm.R, nm.dR, nm.wq, nm.g_ref, nm.rho_area, nm.rho_inertia,
                          np.empty((n, 2)), np.empty((n, 2)), np.empty(2), p)
    return T, p


@njit_uncounted
def _kinetic_elements(x, v2, conn, R, dR, wq, g_ref, rho_area, rho_inertia, x_e, v_e, p_e,
                      p):
    """:func:`kinetic_energy_momentum`'s sums over the elements in element order: returns
    T, the momentum added to p (x_e, v_e, p_e: scratch; no reference counts for the views
    of an element)."""
    T = 0.0
    for e in range(conn.shape[0]):
        _gather(x, conn[e], x_e)
        _gather(v2, conn[e], v_e)
        T += inertia_native.element_kinetic_energy(x_e, v_e, R[e], dR[e], wq[e], g_ref[e],
                                                   rho_area[e], rho_inertia[e])
        inertia_native.element_momentum(v_e, R[e], wq[e], g_ref[e], rho_area[e], p_e)
        p[0] += p_e[0]
        p[1] += p_e[1]
    return T


@njit
def update_load_state(nm, u, theta_n, t_n, theta_out, t_out):
    """The load state (theta, tangent) at the converged displacement u, as
    :func:`~beamcontact.assembly.system.update_load_state`, into theta_out (n_load,) and
    t_out (n_load, 2) (they may be theta_n and t_n)."""
    loads_native.update_load_state(_positions(nm.x_ref, u), nm.load_conn, nm.load_dR,
                                   theta_n, t_n, theta_out, t_out)
