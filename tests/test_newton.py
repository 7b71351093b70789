"""Newton-Raphson: quadratic convergence and the divergence test, on scalar closed forms."""

import jax.numpy as jnp
import numpy as np

from beamcontact.solvers.newton import newton


def _atan(u):
    """r(u) = atan(u): Newton converges from |u0| < 1.3917 and diverges beyond (the
    iterates alternate in sign and grow), a classic closed-form example."""
    return jnp.arctan(u), (1.0 / (1.0 + u * u))[:, None] * jnp.eye(1), None


TOL = jnp.asarray([1e-12, 0.0, 0.0])


def test_converges_from_inside_the_basin():
    res = newton(_atan, jnp.asarray([1.0]), 25, TOL)
    assert bool(res.converged) and abs(float(res.u[0])) < 1e-12
    assert int(res.iterations) <= 6


def test_divergence_is_detected_early_only_when_asked():
    u0 = jnp.asarray([1.5])
    plain = newton(_atan, u0, 25, TOL)
    assert not bool(plain.converged) and int(plain.iterations) > 6  # NaN or limit
    early = newton(_atan, u0, 25, TOL, diverge_after=4)
    assert not bool(early.converged) and int(early.iterations) == 4
    # |u| grows monotonically from 1.5: after 4 iterations the residual is above r(u0)
    assert float(early.residual_norm) > np.arctan(1.5)
