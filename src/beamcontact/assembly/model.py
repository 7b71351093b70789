"""The discrete model as JAX pytrees: beams' element data, point loads, supports.

This is the only place that knows the global numbering: control point c of the whole
model owns dofs 2c (x) and 2c+1 (y); beam b's points follow those of beams 0..b-1.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from beamcontact._jax import jax, jnp, pytree


def _pytree(cls):
    """Frozen dataclass (compared by identity) registered as a pytree
    (:func:`beamcontact._jax.pytree`)."""
    return pytree(dataclass(frozen=True, eq=False)(cls))


@_pytree
class ElementBlock:
    """All elements of one beam (one degree, number of Gauss points and of section points):
    the kernels run over them in one ``vmap``.

    Shapes: conn (n_el, n_loc) global control-point indices; R, dR, ddR (n_el, n_qp, n_loc);
    wq, g_ref, K_ref (n_el, n_qp); eta, w_eta (n_el, n_eta); per element: E, rho_area (mass
    per reference length), rho_inertia (rho I, rotational inertia per reference length),
    gravity_on (1.0 or 0.0), shape (n_el,).
    """

    conn: jax.Array
    R: jax.Array
    dR: jax.Array
    ddR: jax.Array
    wq: jax.Array
    g_ref: jax.Array
    K_ref: jax.Array
    eta: jax.Array
    w_eta: jax.Array
    E: jax.Array
    rho_area: jax.Array
    rho_inertia: jax.Array
    gravity_on: jax.Array


@_pytree
class PointLoads:
    """Point forces and moments, padded to a common n_loc (padding has R = dR = 0).

    Shapes: conn (n_load, n_loc); R, dR (n_load, n_loc); force (n_load, 2); moment (n_load,).
    """

    conn: jax.Array
    R: jax.Array
    dR: jax.Array
    force: jax.Array
    moment: jax.Array


@_pytree
class LoadState:
    """Rotation and tangent of each load point at the last converged state."""

    theta: jax.Array
    tangent: jax.Array


@_pytree
class Model:
    """Everything the kernels need; varying numbers are array data (one compile per shape).

    Attributes:
        beams: one ElementBlock per beam.
        loads: point loads (n_load may be 0).
        x_ref: reference control points of the whole model, shape (n_cp, 2).
        free: 1.0 for free dofs, 0.0 for supported and tied ones, shape (2 n_cp,).
        gravity: acceleration of gravity, shape (2,).
        tied, tie_masters, tie_weights: the dofs that free ends' outlier removal ties to
            others (beam/free_ends.py): u[tied[t]] = sum_k tie_weights[t, k]
            u[tie_masters[t, k]], shapes (n_t,), (n_t, 3), (n_t, 3); n_t = 0 without it.
        sparse: static; the tangent is kept as local blocks and solved by a sparse or
            banded LU (:mod:`~beamcontact.solvers.linear`) instead of a dense matrix.
    """

    beams: tuple
    loads: PointLoads
    x_ref: jax.Array
    free: jax.Array
    gravity: jax.Array
    tied: jax.Array
    tie_masters: jax.Array
    tie_weights: jax.Array
    sparse: bool = field(default=False, metadata=dict(static=True))

    @property
    def n_dof(self) -> int:
        """Number of dofs, 2 per control point."""
        return 2 * self.x_ref.shape[0]


def element_dofs(conn: jax.Array) -> jax.Array:
    """Dofs of each element in the order of x_e.ravel(): (.., n_loc) -> (.., 2 n_loc)."""
    return jnp.stack([2 * conn, 2 * conn + 1], axis=-1).reshape(*conn.shape[:-1], -1)


def initial_load_state(model: Model) -> LoadState:
    """Zero rotation and the reference tangent at every load point (arrays of the
    model's kind: :func:`beamcontact._jax.model_array`)."""
    loads = model.loads
    if isinstance(model.x_ref, np.ndarray):
        t = np.einsum("lk,lkd->ld", loads.dR, model.x_ref[loads.conn])
        return LoadState(theta=np.zeros(t.shape[0]), tangent=t)
    t = jnp.einsum("lk,lkd->ld", loads.dR, model.x_ref[loads.conn])
    return LoadState(theta=jnp.zeros(t.shape[0]), tangent=t)


