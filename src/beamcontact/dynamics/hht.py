"""One HHT-alpha step (Hilber, Hughes & Taylor 1977; paper eqs. 31-37).

Paper convention: alpha in [-1/3, 0], beta = (1 - alpha)^2 / 4, gamma = 1/2 - alpha.
Equilibrium at t_{n+1} (eq. 36), with f_pot = f_int - f_ext (+ f_con) = grad Pi:

    F_inertia(u_{n+1}, v_{n+1}, a_{n+1}) + (1 + alpha) f_pot(u_{n+1}) - alpha f_pot(u_n) = 0,

v_{n+1} and a_{n+1} from Newmark (eqs. 33-35). Newton-Raphson runs inside one
``lax.while_loop``; the step returns a status instead of raising.
"""

from __future__ import annotations

from dataclasses import dataclass

from beamcontact._jax import jax, jnp, lazy_jit, pytree
from beamcontact._persistent import persistent_jit
from beamcontact.assembly.inertia import (
    inertia_force_and_mass,
    inertia_residual_tangent,
    newmark_kinematics,
)
from beamcontact.assembly.model import LoadState, Model
from beamcontact.assembly.system import (
    apply_supports,
    residual_tangent_with_contact,
    tie_dependent,
    update_load_state,
)
from beamcontact.contact.blocks import FrozenContact
from beamcontact.solvers import linear
from beamcontact.solvers.newton import NewtonResult, newton

# A time step whose Newton residual is still above the predictor's after this many
# iterations is given up and cut (the driver halves it): through impacts nearly all
# failed attempts diverge, and running them to max_iterations cost a quarter of the work.
DIVERGE_AFTER = 6


@pytree
@dataclass(frozen=True)
class DynState:
    """State after an accepted step: time, displacement, velocity, acceleration, the HHT
    history f_pot(u_n), and the rotations of the moment loads."""

    t: jax.Array
    u: jax.Array
    v: jax.Array
    a: jax.Array
    f_pot: jax.Array
    load_state: LoadState


def predictor(state: DynState, h):
    """The Newmark predictor of the displacement after a step h (constant acceleration):
    the start of Newton and of the contact search."""
    return state.u + h * state.v + 0.5 * h * h * state.a


def hht_coefficients(alpha, dt):
    """(c_a, dt, c_1, gamma) of the Newmark kinematics for HHT parameter alpha."""
    beta = 0.25 * (1.0 - alpha) ** 2
    gamma = 0.5 - alpha
    return jnp.stack([1.0 / (beta * dt**2), dt, (1.0 - 2.0 * beta) / (2.0 * beta), gamma])


@persistent_jit
def initial_state(u0, v0, model: Model, load_state: LoadState,
                  contact: FrozenContact | None = None) -> DynState:
    """Consistent initial acceleration: F_inertia(u0, v0, a0) = -f_pot(u0) on free dofs."""
    free = model.free
    v0 = tie_dependent(v0 * free, model)
    f_pot, _ = residual_tangent_with_contact(u0, model, 1.0, load_state, contact)
    f0, M = inertia_force_and_mass(u0, v0, jnp.zeros_like(u0), model)
    r, M = apply_supports(f0 + f_pot, M, free)
    a0 = tie_dependent(linear.solve(M, -r), model)
    return DynState(jnp.asarray(0.0), u0, v0, a0, f_pot, load_state)


@lazy_jit(static_argnames=("max_iterations",))
def hht_step(state: DynState, model: Model, dt, alpha, rtol, utol_abs, max_iterations: int,
             contact: FrozenContact | None = None, etol_abs=None
             ) -> tuple[DynState, NewtonResult]:
    """Advance by dt; returns the new state (meaningful only if converged) and Newton info.

    ``contact``: the contact elements and the blocks frozen for this step (None without
    contact); contact forces enter f_pot (eq. 36). ``etol_abs``: the bound of the error
    left in an iterate (:func:`~beamcontact.solvers.newton.newton`; None: no such test,
    and no second solve per iteration).
    """
    coeffs = hht_coefficients(alpha, dt)

    def residual_tangent(u):
        r_p, K_p = residual_tangent_with_contact(u, model, 1.0, state.load_state, contact)
        r_i, K_i = inertia_residual_tangent(u, state.u, state.v, state.a, coeffs, model)
        r = r_i + (1.0 + alpha) * r_p - alpha * state.f_pot
        return (*apply_supports(r, linear.add(K_i, K_p, 1.0 + alpha), model.free), r_p)

    u_pred = predictor(state, dt)
    tol = jnp.stack([rtol, rtol * jnp.linalg.norm(state.f_pot * model.free), utol_abs]
                    + ([] if etol_abs is None else [etol_abs]))
    res = newton(residual_tangent, u_pred, max_iterations, tol, diverge_after=DIVERGE_AFTER)
    # the free ends' tied dofs follow their masters (v and a too: their Newmark values
    # agree only to round-off, which the acceleration's 1 / (beta h^2) amplifies)
    u = tie_dependent(res.u, model)
    v, a = newmark_kinematics(u, state.u, state.v, state.a, coeffs)
    new = DynState(state.t + dt, u, tie_dependent(v, model), tie_dependent(a, model), res.aux,
                   update_load_state(model, u, state.load_state))
    return new, res
