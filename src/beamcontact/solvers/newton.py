"""Newton-Raphson with the consistent (AD) tangent, as one ``lax.while_loop``.

Convergence (all measured on free dofs):
    ||r_k|| <= rtol * ||r_0|| + atol     or     ||du_k||_inf <= utol * length
    or     ||K_(k-1)^-1 r_k||_inf <= etol * length   (when etol > 0),
where r_0 is the residual at the predictor. The third test bounds the error left in the
iterate u_k by the next increment, computed with the tangent that gave u_k (the factors
a solver has in hand), as implicit integrators stop their Newton iterations once that
error is a small fraction of the local error tolerance (Hairer & Wanner, Solving ODEs
II, Sec. IV.8): time steps set etol = newton_error_fraction * error_tol; statics do not
use it. A NaN, the iteration limit, or (when asked
for with ``diverge_after``) divergence ends the loop with ``converged = False``; the
caller (load stepping, time stepping) decides what to do.
"""

from __future__ import annotations

from dataclasses import dataclass

from beamcontact._jax import jax, jnp, pytree
from beamcontact.solvers.linear import solve


@dataclass(frozen=True)
class NewtonOptions:
    """Newton settings; ``max_iterations`` is static, the tolerances are plain floats
    (utol and etol fractions of the length scale L; etol 0: no error test)."""

    max_iterations: int = 25
    rtol: float = 1e-9
    utol: float = 1e-11
    etol: float = 0.0


@pytree
@dataclass(frozen=True)
class NewtonResult:
    """Solution, iterations, convergence flag, final norms and the caller's auxiliary
    output of the last residual evaluation (JAX arrays)."""

    u: jax.Array
    iterations: jax.Array
    converged: jax.Array
    residual_norm: jax.Array
    initial_residual_norm: jax.Array
    aux: object = None


def newton(residual_tangent, u0, max_iterations: int, tolerances,
           diverge_after: int = 0) -> NewtonResult:
    """Solve residual(u) = 0 from u0.

    Args:
        residual_tangent: u -> (r, K, aux) with supports already applied (K dense or
            sparse, :mod:`~beamcontact.solvers.linear`); aux (any pytree,
            e.g. a force needed after convergence) of the final u is returned.
        u0: predictor.
        max_iterations: the static iteration limit.
        tolerances: array (rtol, atol, utol * length[, etol * length]), traced so no
            recompilation; without the fourth entry no error test (and no second solve
            per iteration).
        diverge_after: if > 0, the solve fails as soon as the residual is still above
            ||r_0|| after this many iterations, so a hopeless attempt is given up early
            (time steps: at impacts most failed attempts diverge, and the step is cut).
    """
    rtol, atol, utol_abs = tolerances[0], tolerances[1], tolerances[2]
    error_test = tolerances.shape[0] > 3
    r0, K0, aux0 = residual_tangent(u0)
    norm0 = jnp.linalg.norm(r0)

    def cond(state):
        _, _, _, _, k, done, failed, _ = state
        return (~done) & (~failed) & (k < max_iterations)

    def body(state):
        u, r, K, _, k, _, _, _ = state
        du = solve(K, -r)
        u = u + du
        r, K_new, aux = residual_tangent(u)
        rn = jnp.linalg.norm(r)
        done = (rn <= rtol * norm0 + atol) | (jnp.max(jnp.abs(du)) <= utol_abs)
        if error_test:
            etol_abs = tolerances[3]
            done = done | ((etol_abs > 0.0) & (jnp.max(jnp.abs(solve(K, -r))) <= etol_abs))
        K = K_new
        diverged = (diverge_after > 0) & (k + 1 >= diverge_after) & (rn > norm0)
        failed = ~jnp.isfinite(rn) | ~jnp.all(jnp.isfinite(du)) | diverged
        return u, r, K, aux, k + 1, done & ~failed, failed, rn

    done0 = norm0 <= atol
    state = (u0, r0, K0, aux0, jnp.asarray(0), done0, ~jnp.isfinite(norm0), norm0)
    u, _, _, aux, k, done, _, rn = jax.lax.while_loop(cond, body, state)
    return NewtonResult(u, k, done, rn, norm0, aux)
