"""Rigid obstacles: walls (half-planes) and circles (disks) that every beam touches.

An obstacle is described by the signed distance s(p) of a point p of the plane from its
surface (positive outside the solid):

    wall:   s(p) = n . (p - p0)          (the half-plane behind the unit normal n is solid)
    circle: s(p) = |p - c| - r           (the disk of radius r around c is solid)

Each contact integration point of each element (:mod:`beamcontact.contact.points`, the
points of the beam-to-beam laws) has the gap q = s(p) - R to each obstacle, R its beam's
radius, and the energy of its law (:meth:`ContactLaw.obstacle_energy`):

* IPIP penalty (eq. 3): eps q^2 / 2 for q < 0, weight 1 per point: a beam point against
  a rigid surface carries what a point of the "points" pairing carries in total (1/2
  from each side of a beam pair), see docs/theory.md, "Rigid obstacles".
* coarse-grained: the section-to-half-space potential per unit reference length,
  integrated with the points' arc-length weights. It is eq. (8) with the obstacle as a
  half-space of particle density beta_o, pre-integrated over the half-space (point to
  half-space: 2 pi k beta_o h^(3-m) / ((m-2)(m-3))) and over the circular section in the
  small-gap limit (Derjaguin):

      Phi_w(q) = k beta beta_o (2 pi)^(3/2) sqrt(R) Gamma(m - 9/2) / Gamma(m - 1) q^(9/2-m),

  for m > 9/2; exact to first order in q / R for a straight beam parallel to a wall
  (tests/test_obstacles.py against the quadrature of eq. 8), and the leading order for
  a circle (a curved surface seen from a section is locally flat). Like eq. (9) it is
  continued by its quadratic Taylor polynomial below q_reg; a point interacts when its
  gap is below cutoff - 2 R, the gap at which two sections of its beam stop interacting.

Obstacles are few: every element meets every obstacle, as one (E, O) evaluation, linear
in the number of elements without a search. The energy of one point is differentiated by
AD in the point's position (a 2-vector) and taken to the element's control points by its
basis row, like the beam-to-beam blocks (:mod:`beamcontact.contact.blocks`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from beamcontact._jax import jax, jnp, model_array, pytree
from beamcontact._x64 import as_float
from beamcontact.contact.points import ContactElements


@pytree
@dataclass(frozen=True)
class Obstacles:
    """O rigid obstacles as arrays: point (O, 2) a point of a wall's surface or a
    circle's centre; normal (O, 2) a wall's unit normal (0 for circles); radius (O,) a
    circle's radius (0 for walls); circle (O,) True for circles; beta (O,) particle
    densities (coarse-grained law)."""

    point: jax.Array
    normal: jax.Array
    radius: jax.Array
    circle: jax.Array
    beta: jax.Array


def obstacles_from(walls: list[tuple], circles: list[tuple]) -> Obstacles:
    """Obstacles from ``walls`` [(point, normal, beta)] then ``circles`` [(center, radius,
    beta)] (host, once); normals are made unit length."""
    point = [w[0] for w in walls] + [c[0] for c in circles]
    normal = [np.asarray(w[1], float) / np.linalg.norm(w[1]) for w in walls]
    normal += [np.zeros(2)] * len(circles)
    radius = [0.0] * len(walls) + [c[1] for c in circles]
    beta = [w[2] for w in walls] + [c[2] for c in circles]
    return Obstacles(point=as_float(np.reshape(point, (-1, 2))),
                     normal=as_float(np.reshape(normal, (-1, 2))), radius=as_float(radius),
                     circle=model_array(np.arange(len(point)) >= len(walls)),
                     beta=as_float(beta))


def signed_distance(p, obs: Obstacles):
    """s(p) for a point p (2,) to every obstacle, shape (O,) (see the module docstring)."""
    rel = p - obs.point
    r2 = jnp.sum(rel * rel, axis=-1)
    # sqrt of a positive floor: a point at a circle's centre is deep inside anyway
    centre = jnp.sqrt(jnp.where(obs.circle, jnp.maximum(r2, 1e-300), 1.0))
    return jnp.where(obs.circle, centre - obs.radius, jnp.sum(rel * obs.normal, axis=-1))


def _points(x, ce: ContactElements):
    """Contact point positions of every element, (E, n_s, 2)."""
    return jnp.einsum("esk,ekd->esd", ce.R, x[ce.conn])


def _point_energy(law, obs: Obstacles):
    """Energy of one contact point p (2,) against all obstacles, f(p, R, beta, w)."""

    def f(p, R, beta, w):
        q = signed_distance(p, obs) - R
        return jnp.sum(law.obstacle_energy(q, R, law.obstacle_amplitude(R, beta * obs.beta), w))

    return f


def _over_points(f):
    """vmap f(p, R, beta, w) over elements (R, beta per element) and their points."""
    return jax.vmap(jax.vmap(f, (0, None, None, 0)), (0, 0, 0, 0))


def obstacle_energy(x, ce: ContactElements, obs: Obstacles, law):
    """Total energy of every contact point against every obstacle at control points x."""
    e = _over_points(_point_energy(law, obs))(_points(x, ce), ce.radius, ce.beta, ce.w)
    return jnp.sum(e)


def obstacle_forces(x, ce: ContactElements, obs: Obstacles, law):
    """(conn (E, n_loc), gradient (E, 2 n_loc), Hessian (E, 2 n_loc, 2 n_loc)) of each
    element's obstacle energy, in the order of ``x[conn].ravel()``: AD of the point energy
    in the point position (g, H), then f_e = sum_i R_i g_i and k_e = sum_i R_i R_i^T H_i
    (padding basis rows are zero, so padding dofs get nothing)."""
    f = _point_energy(law, obs)
    p = _points(x, ce)
    args = (p, ce.radius, ce.beta, ce.w)
    g = _over_points(jax.grad(f))(*args)  # (E, s, 2)
    H = _over_points(jax.hessian(f))(*args)  # (E, s, 2, 2)
    E, n_loc = ce.conn.shape
    grad = jnp.einsum("esk,esa->eka", ce.R, g).reshape(E, 2 * n_loc)
    hess = jnp.einsum("esk,esab,esl->ekalb", ce.R, H, ce.R).reshape(E, 2 * n_loc, 2 * n_loc)
    return ce.conn, grad, hess


def obstacle_gaps(x, ce: ContactElements, obs: Obstacles):
    """Gaps q = s - R of every contact point to every obstacle, (E, n_s, O)."""
    s = jax.vmap(jax.vmap(signed_distance, (0, None)), (0, None))(_points(x, ce), obs)
    return s - ce.radius[:, None, None]


def obstacle_approach_ratio(x0, displacements, ce: ContactElements, obs: Obstacles, slack):
    """The conservative advancement (:mod:`beamcontact.contact.advance`) against the
    obstacles: the largest approach / (q + slack) of a contact point towards an obstacle
    along the obstacle's normal at the start of the step, approach = max(0, -n . dp)
    summed over the displacement fields; points within slack / 100 of the depth of the
    law are left to the law. 0 when nothing approaches."""
    p0 = _points(x0, ce)

    def normals(p):  # the outward unit normal of every obstacle at p, (O, 2)
        rel = p - obs.point
        away = rel / jnp.maximum(jnp.linalg.norm(rel, axis=-1, keepdims=True), 1e-300)
        return jnp.where(obs.circle[:, None], away, obs.normal)

    n = jax.vmap(jax.vmap(normals))(p0)  # (E, s, O, 2)
    approach = 0.0
    for field in displacements:
        dp = _points(field, ce)[:, :, None, :]
        approach = approach + jnp.maximum(-jnp.sum(n * dp, axis=-1), 0.0)
    room = obstacle_gaps(x0, ce, obs) + slack
    real = room > 1e-2 * slack
    return jnp.max(jnp.where(real, approach / jnp.where(real, room, 1.0), 0.0), initial=0.0)
