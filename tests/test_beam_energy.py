"""Local beam energies: rigid motions, closed forms, and AD tangents vs central differences."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from _builders import beam, static_case

from beamcontact.assembly.model import initial_load_state
from beamcontact.assembly.system import energies as _energies
from beamcontact.assembly.system import potential_residual_tangent as _prt
from beamcontact.setup.model import build_model

energies = jax.jit(_energies)
potential_residual_tangent = jax.jit(_prt)


def _curved_model(loads=()):
    arc = {"center": [0.3, -0.2], "radius": 1.2, "start_angle": 0.2, "end_angle": 4.2}
    case = static_case([beam(arc=arc, degree=4, elements=6, continuity=1, radius=0.03)], loads)
    return build_model(case)


def _rigidly_moved(x_ref, angle, shift):
    c, s = np.cos(angle), np.sin(angle)
    return x_ref @ np.array([[c, s], [-s, c]]) + shift  # rows rotated by +angle


@pytest.mark.parametrize("angle", [0.0, 1.1, -2.9])
def test_rigid_motion_gives_zero_strain_energy_and_residual(angle):
    model, _ = _curved_model()
    x_ref = np.asarray(model.x_ref)
    u = (_rigidly_moved(x_ref, angle, [3.0, -1.0]) - x_ref).ravel()
    state = initial_load_state(model)
    e = energies(jnp.asarray(u), model, 1.0, state)
    r, _ = potential_residual_tangent(jnp.asarray(u), model, 1.0, state)
    EA = 1.0e9 * np.pi * 0.03**2
    # round-off level: strains of 1e-13 would give E A L 1e-26 / 2
    assert abs(float(e["E_strain"])) < 1e-24 * EA
    assert float(jnp.max(jnp.abs(r))) < 1e-11 * EA


def test_uniform_stretch_energy_closed_form():
    """A straight beam scaled by lam: Green-Lagrange strain (lam^2 - 1)/2 in every fibre."""
    L, r, E, lam = 2.0, 0.01, 2.0e8, 1.07
    case = static_case([beam(line=([0, 0], [L, 0]), degree=3, elements=5, radius=r, E=E)])
    model, _ = build_model(case)
    x_ref = np.asarray(model.x_ref)
    u = jnp.asarray(((lam - 1.0) * x_ref).ravel())
    e = energies(u, model, 1.0, initial_load_state(model))
    exact = 0.5 * E * np.pi * r**2 * L * (0.5 * (lam**2 - 1.0)) ** 2
    assert abs(float(e["E_strain"]) - exact) < 1e-12 * exact


def test_gravity_potential_closed_form():
    """-rho A L g.r_centroid for an arc (reference arc-length measure)."""
    R, sweep, rho, rad = 1.5, 2.0, 800.0, 0.02
    arc = {"center": [0.0, 0.0], "radius": R, "start_angle": 0.0, "end_angle": sweep}
    case = static_case([beam(arc=arc, degree=4, elements=8, radius=rad, density=rho)],
                       gravity=(0.0, -9.81))
    model, _ = build_model(case)
    e = energies(jnp.zeros(model.n_dof), model, 1.0, initial_load_state(model))
    y_centroid = R * (1.0 - np.cos(sweep)) / sweep  # of the arc from angle 0 to sweep
    exact = rho * np.pi * rad**2 * (R * sweep) * 9.81 * y_centroid
    assert abs(float(e["E_gravity"]) - exact) < 1e-10 * exact


def test_ad_tangent_matches_central_differences():
    loads = [{"beam": "b", "at": "end", "force": [0.3, -0.7], "moment": 0.4},
             {"beam": "b", "at": 0.35, "force": [-1.0, 0.2], "moment": -0.25}]
    model, _ = _curved_model(loads)
    state = initial_load_state(model)
    u = jnp.asarray(np.random.default_rng(3).normal(scale=0.02, size=model.n_dof))
    f = jax.jit(lambda u: _prt(u, model, 0.8, state))
    r, K = f(u)
    h = 1e-6
    fd = np.zeros_like(np.asarray(K))
    for j in range(model.n_dof):
        e = jnp.zeros(model.n_dof).at[j].set(h)
        fd[:, j] = (np.asarray(f(u + e)[0]) - np.asarray(f(u - e)[0])) / (2 * h)
    scale = np.abs(np.asarray(K)).max()
    assert np.abs(np.asarray(K) - fd).max() < 1e-6 * scale
    np.testing.assert_allclose(np.asarray(K), np.asarray(K).T, atol=1e-10 * scale)
