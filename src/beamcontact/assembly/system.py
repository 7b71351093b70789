"""Global residual and tangent from local energies (docs/architecture.md,
"Energies and assembly").

Each term is a scalar energy of local unknowns (the axis derivatives at one Gauss point,
one load point's control points); ``jax.grad`` and ``jax.hessian`` act locally,
``vmap`` runs over points and elements, and the results are scattered into the global
vector and matrix. No global Hessian is formed by AD.

Static total potential (load factor lam scales all external actions):
    Pi(u) = sum_e Pi_int,e + lam (sum_e Pi_grav,e + sum_l Pi_load,l).
"""

from __future__ import annotations

from beamcontact._jax import jax, jnp
from beamcontact.assembly.model import ElementBlock, LoadState, Model, element_dofs
from beamcontact.beam.energy import (
    element_gravity_potential,
    element_strain_energy,
    point_strain_energy,
)
from beamcontact.beam.loads import point_load_potential, tangent_rotation
from beamcontact.contact.blocks import (
    FrozenContact,
    block_forces,
    contact_energy,
    fold_block_forces,
)
from beamcontact.contact.obstacles import obstacle_energy, obstacle_forces
from beamcontact.solvers import linear


def _beam_residual_tangent(x, blk: ElementBlock, lam, gravity):
    """Residual and tangent of every element of one beam, (E, 2n) and (E, 2n, 2n).

    Strain: AD at the Gauss point (:func:`point_strain_energy` of y = (g1, g1'), 4 numbers)
    and the chain rule through y_q = D_q x_e, linear in the control points:
    r_e = sum_q D_q^T dpsi/dy, k_e = sum_q D_q^T d2psi/dy2 D_q. Gravity is linear in x,
    so its gradient (AD of the element potential) is all and its Hessian is zero.
    """
    n_el, n_qp = blk.wq.shape
    xe = x[blk.conn]  # (E, n, 2)
    D = jnp.stack([blk.dR, blk.ddR], axis=2)  # (E, Q, 2, n): the rows giving g1 and g1'
    y = jnp.einsum("eqsk,ekd->eqsd", D, xe).reshape(n_el, n_qp, 4)

    def density(y_q, g_ref, K_ref, wq, eta, w_eta, E):
        return wq * point_strain_energy(y_q, g_ref, K_ref, eta, w_eta, E)

    def at_points(f):
        per_point = jax.vmap(f, (0, 0, 0, 0, None, None, None))
        return jax.vmap(per_point)(y, blk.g_ref, blk.K_ref, blk.wq, blk.eta, blk.w_eta, blk.E)

    dpsi = at_points(jax.grad(density)).reshape(n_el, n_qp, 2, 2)
    d2psi = at_points(jax.hessian(density)).reshape(n_el, n_qp, 2, 2, 2, 2)
    r_e = jnp.einsum("eqsk,eqsa->eka", D, dpsi)
    k_e = jnp.einsum("eqsk,eqsatb,eqtl->ekalb", D, d2psi, D)
    r_grav = jax.vmap(jax.grad(element_gravity_potential), (0, 0, 0, 0, 0, None))(
        xe, blk.R, blk.wq, blk.g_ref, blk.rho_area * blk.gravity_on, gravity)
    m = 2 * xe.shape[1]
    return (r_e + lam * r_grav).reshape(n_el, m), k_e.reshape(n_el, m, m)


def _load_energy(x_l, R, dR, force, moment, theta, tangent, lam):
    return lam * point_load_potential(x_l, R, dR, force, moment, theta, tangent)


def energies(u: jax.Array, model: Model, lam, load_state: LoadState) -> dict:
    """Strain energy, gravity potential and load potential at displacement u (flat)."""
    x = model.x_ref + u.reshape(-1, 2)
    e_strain = 0.0
    e_grav = 0.0
    for blk in model.beams:
        xe = x[blk.conn]
        e_strain += jnp.sum(jax.vmap(element_strain_energy)(
            xe, blk.dR, blk.ddR, blk.wq, blk.g_ref, blk.K_ref, blk.eta, blk.w_eta, blk.E))
        e_grav += lam * jnp.sum(jax.vmap(element_gravity_potential, (0, 0, 0, 0, 0, None))(
            xe, blk.R, blk.wq, blk.g_ref, blk.rho_area * blk.gravity_on, model.gravity))
    ld = model.loads
    e_ext = jnp.sum(jax.vmap(_load_energy, (0, 0, 0, 0, 0, 0, 0, None))(
        x[ld.conn], ld.R, ld.dR, ld.force, ld.moment, load_state.theta, load_state.tangent, lam))
    return {"E_strain": e_strain, "E_gravity": e_grav, "E_ext": e_ext}


def _scatter(r, K, dofs, r_e, k_e):
    return r.at[dofs].add(r_e), linear.scatter(K, dofs, k_e)


def potential_residual_tangent(u: jax.Array, model: Model, lam, load_state: LoadState):
    """Gradient (residual) and Hessian (tangent) of the static potential, unconstrained;
    the tangent dense or sparse as ``model.sparse`` says."""
    n = model.n_dof
    x = model.x_ref + u.reshape(-1, 2)
    r = jnp.zeros(n)
    K = linear.zeros(n, model.sparse)
    for blk in model.beams:
        r_e, k_e = _beam_residual_tangent(x, blk, lam, model.gravity)
        r, K = _scatter(r, K, element_dofs(blk.conn), r_e, k_e)
    ld = model.loads
    if ld.conn.shape[0] > 0:
        def load_local(xl_flat, R, dR, force, moment, theta, tangent):
            return _load_energy(xl_flat.reshape(-1, 2), R, dR, force, moment, theta, tangent, lam)

        xl = x[ld.conn].reshape(ld.conn.shape[0], -1)
        args = (xl, ld.R, ld.dR, ld.force, ld.moment, load_state.theta, load_state.tangent)
        r_l = jax.vmap(jax.grad(load_local))(*args)
        k_l = jax.vmap(jax.hessian(load_local))(*args)
        r, K = _scatter(r, K, element_dofs(ld.conn), r_l, k_l)
    return r, K


def residual_tangent_with_contact(u, model: Model, lam, load_state: LoadState,
                                  contact: FrozenContact | None):
    """:func:`potential_residual_tangent` plus the frozen contact blocks (None: none)."""
    r, K = potential_residual_tangent(u, model, lam, load_state)
    if contact is None:
        return r, K
    r_c, K_c = contact_residual_tangent(model.x_ref + u.reshape(-1, 2), contact, model.n_dof,
                                        model.sparse)
    return r + r_c, linear.add(K, K_c)


def contact_residual_tangent(x, contact: FrozenContact, n_dof: int, sparse: bool = False):
    """Global contact force (gradient of the contact energy) and tangent (its Hessian) of
    the frozen blocks at control points x.

    Dense: scattered chunk by chunk as the blocks are computed. Sparse: every block's
    (dofs, gradient, Hessian) at once (zeros for skipped chunks: exact zeros that the
    host solve drops), appended as triplets."""
    if sparse:
        conn, f, k = block_forces(x, contact.elements, contact.blocks)
        r, K = _scatter(jnp.zeros(n_dof, x.dtype), linear.zeros(n_dof, True),
                        element_dofs(conn), f, k)
    else:
        zero = (jnp.zeros(n_dof, x.dtype), linear.zeros(n_dof, False))
        r, K = fold_block_forces(x, contact.elements, contact.blocks, _scatter_blocks, zero)
    if contact.obstacles is not None:
        r, K = _scatter(r, K, *_element_obstacle_forces(x, contact))
    return r, K


def _element_obstacle_forces(x, contact: FrozenContact):
    """(dofs, gradient, Hessian) of every element's energy against the obstacles."""
    conn, f, k = obstacle_forces(x, contact.elements, contact.obstacles, contact.blocks.law)
    return element_dofs(conn), f, k


def _scatter_blocks(carry, conn, f, k):
    """Add contact blocks (control points conn of both elements) to carry = (r, K)."""
    return _scatter(*carry, element_dofs(conn), f, k)


def contact_energy_of(u, model: Model, contact: FrozenContact | None):
    """Contact energy of the frozen blocks at displacement u (0 without contact)."""
    if contact is None:
        return jnp.asarray(0.0)
    x = model.x_ref + u.reshape(-1, 2)
    e = contact_energy(x, contact.elements, contact.blocks)
    if contact.obstacles is not None:
        e = e + obstacle_energy(x, contact.elements, contact.obstacles, contact.blocks.law)
    return e


def apply_supports(r: jax.Array, K, free: jax.Array):
    """Zero the residual of supported dofs and replace their rows/columns by the identity.

    Supported dofs keep their (zero) displacement because their Newton increment is zero.
    """
    return r * free, linear.apply_supports(K, free)


def tie_dependent(w: jax.Array, model: Model) -> jax.Array:
    """w with its tied dofs set from their masters, w[tied] = sum_k tie_weights[:, k]
    w[tie_masters[:, k]], for a displacement, velocity or acceleration (beam/free_ends.py:
    the free ends' constraints; the solve leaves those dofs alone, as supported ones)."""
    if model.tied.shape[0] == 0:
        return w
    # summed left to right, as the native twin does
    total = jnp.zeros(model.tied.shape[0])
    for k in range(model.tie_masters.shape[1]):
        total = total + model.tie_weights[:, k] * w[model.tie_masters[:, k]]
    return w.at[model.tied].set(total)


def update_load_state(model: Model, u: jax.Array, state: LoadState) -> LoadState:
    """Rotations and tangents of the load points at the converged displacement u."""
    x = model.x_ref + u.reshape(-1, 2)
    t = jnp.einsum("lk,lkd->ld", model.loads.dR, x[model.loads.conn])
    theta = jax.vmap(tangent_rotation)(t, state.theta, state.tangent)
    return LoadState(theta=theta, tangent=t)
