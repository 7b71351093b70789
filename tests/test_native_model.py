"""The native (Numba) model assembly and point-load kernels against the JAX definitions
(assembly/system.py, assembly/inertia.py, beam/loads.py) on models built from cases.

Tolerance: RTOL = 1e-12 of the largest entry of the JAX result (of each vector, each
matrix, each energy). Both sides evaluate the same float64 formulas in different orders
(hand-written derivatives against AD, loops against XLA's reductions and scatters), so
they differ by rounding only, and an entry of a global vector or matrix is a sum of
element terms of both signs that may cancel to near zero: relative to itself it would
measure the cancellation, not the kernels. The floors: a few ulps of the largest terms
(y = D x sums a large rigid offset that cancels), and for the HHT inertia residual
Newmark's a = c_a (u - u_n - dt v_n), whose rounding of |u| is amplified by
c_a = 1 / (beta dt^2) (tests/test_native_beam.py); the states below keep both near 1e-13
or below, and a wrong coefficient, dof or sign shows far above 1e-12.
"""

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from _builders import beam, static_case

from beamcontact.assembly import native_model as nmod
from beamcontact.assembly.inertia import inertia_residual_tangent, kinetic_energy_and_momentum
from beamcontact.assembly.model import LoadState, element_dofs, initial_load_state
from beamcontact.assembly.system import energies, residual_tangent_with_contact
from beamcontact.assembly.system import update_load_state as jax_update_load_state
from beamcontact.beam import loads_native as lnat
from beamcontact.beam.loads import point_load_potential
from beamcontact.dynamics.hht import hht_coefficients
from beamcontact.setup.model import build_model
from beamcontact.solvers import linear

RTOL = 1e-12  # see the module docstring
N_STATES = 4

_residual_tangent = jax.jit(residual_tangent_with_contact)
_energies = jax.jit(energies)
_inertia = jax.jit(inertia_residual_tangent)
_kinetic = jax.jit(kinetic_energy_and_momentum)
_update = jax.jit(jax_update_load_state)


def _rel(native, ref):
    """max |native - ref| / max |ref| (the difference itself where ref is all zero)."""
    native, ref = np.asarray(native, float), np.asarray(ref, float)
    diff = float(np.max(np.abs(native - ref), initial=0.0))
    scale = float(np.max(np.abs(ref), initial=0.0))
    return diff / scale if scale > 0.0 else diff


def _rotation(angle):
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s], [s, c]])


# -------------------------------------------------------------------------------- models

def _two_beams():
    """Two degree-4 beams as in examples/free_fall/case_cg.toml, smaller: the lower one
    pinned at both ends without gravity, the upper one free under gravity."""
    lower = beam("lower", line=([0.0, 0.0], [4.0, 0.0]), degree=4, elements=6, continuity=1,
                 radius=0.1, E=0.98e6, supports=[{"at": "start", "type": "pinned"},
                                                 {"at": "end", "type": "pinned"}],
                 gravity=False)
    upper = beam("upper", line=([1.5, 1.0], [2.5, 1.0]), degree=4, elements=3, continuity=1,
                 radius=0.1, E=0.98e6, gravity=True)
    return static_case([lower, upper], gravity=(0.0, -9.81))


def _cantilever():
    """A clamped cantilever with an end force and an end moment, and a force with a
    moment at mid-length."""
    b = beam("b", line=([0.0, 0.0], [1.0, 0.0]), degree=3, elements=6, radius=0.01,
             E=2.0e11, density=7850.0, supports=[{"at": "start", "type": "clamped"}])
    loads = [{"beam": "b", "at": "end", "force": [3.0, -40.0], "moment": 25.0},
             {"beam": "b", "at": 0.5, "force": [-7.0, 2.0], "moment": -4.0}]
    return static_case([b], loads, gravity=(0.0, -9.81))


def _mixed():
    """Two beams of different degree, Gauss and section point counts (a rectangle
    section), with a load on the lower-degree one: the padded layout of native_model."""
    arc = {"center": [0.0, 0.0], "radius": 0.8, "start_angle": 0.3, "end_angle": 2.5}
    a = beam("a", arc=arc, degree=2, elements=5, radius=0.02, E=5e9,
             supports=[{"at": "start", "type": "clamped"}])
    a["section"] = {"shape": "rectangle", "width": 0.03, "height": 0.05}
    b = beam("b", line=([-0.5, 1.2], [0.6, 1.5]), degree=4, elements=3, radius=0.03, E=1e9)
    return static_case([a, b], [{"beam": "a", "at": "end", "force": [1.0, 2.0],
                                 "moment": 0.7}], gravity=(1.0, -9.81))


CASES = {"two_beams": _two_beams, "cantilever": _cantilever, "mixed": _mixed}


def _model(name, sparse):
    model, _ = build_model(CASES[name]())
    return dataclasses.replace(model, sparse=sparse)


def _state(model, rng, angle):
    """Displacement of a rigid rotation by ``angle`` about the first control point and a
    translation, plus a distortion of 5 % of a mean element length."""
    x_ref = np.asarray(model.x_ref)
    n_el = sum(b.conn.shape[0] for b in model.beams)
    size = 0.05 * np.ptp(x_ref, axis=0).max() / n_el
    x = (x_ref - x_ref[0]) @ _rotation(angle).T + x_ref[0] + rng.normal(size=2)
    return (x + size * rng.normal(size=x.shape) - x_ref).ravel()


def _large_rotations(model, rng):
    """N_STATES displacements of :func:`_state`, each a rotation by 0.6-0.95 pi (the
    caller may draw from rng between them)."""
    for _ in range(N_STATES):
        yield _state(model, rng, rng.uniform(0.6, 0.95) * np.pi)


def _load_state(model, u, rng):
    """A load state a step behind u: the tangents of u turned back by up to 0.8 rad and
    their rotations continued by whole turns (theta far from the angle of the tangent)."""
    x = np.asarray(model.x_ref) + u.reshape(-1, 2)
    ld = model.loads
    t = np.einsum("lk,lkd->ld", np.asarray(ld.dR), x[np.asarray(ld.conn)])
    if len(t) == 0:
        return np.zeros(0), np.zeros((0, 2))
    back = rng.uniform(-0.8, 0.8, len(t))
    t_n = np.stack([_rotation(-b) @ ti for b, ti in zip(back, t, strict=True)])
    angle = np.arctan2(t[:, 1], t[:, 0])
    theta_n = angle - back + 2.0 * np.pi * rng.integers(-3, 4, len(t))
    return theta_n, t_n


def _dense(nm, block_k, n_blocks=None):
    """The global matrix of the blocks (the scatter a linear solver would do)."""
    n_blocks = nm.n_blocks if n_blocks is None else n_blocks
    dofs = nm.block_dofs[:n_blocks]
    K = np.zeros((nm.n_dof, nm.n_dof))
    np.add.at(K, (dofs[:, :, None], dofs[:, None, :]), block_k[:n_blocks])
    return K


def _with_zero_modulus(model):
    return dataclasses.replace(model, beams=tuple(dataclasses.replace(b, E=0.0 * b.E)
                                                  for b in model.beams))


MODEL_PARAMS = [("two_beams", False), ("two_beams", True), ("cantilever", False),
                ("mixed", True)]


# ---------------------------------------------------------------------------- the layout

def test_layout_of_the_native_arrays():
    """Elements in block order, padded (mixed degrees) with exact zeros and weight-0 copies
    of a Gauss point; the block dofs are element_dofs of the connectivity, then the
    loads'."""
    model = _model("mixed", False)
    nm = nmod.native_arrays(model)
    blocks = model.beams
    assert nm.n_elements == sum(b.conn.shape[0] for b in blocks)
    assert nm.n_blocks == nm.n_elements + model.loads.conn.shape[0]
    assert nm.n_dof == model.n_dof
    start = 0
    for i, b in enumerate(blocks):
        n_el, n_qp, n_loc = b.R.shape
        rows = slice(start, start + n_el)
        assert np.all(nm.block_index[rows] == i) and np.all(nm.elem_n_loc[rows] == n_loc)
        np.testing.assert_array_equal(nm.R[rows, :n_qp, :n_loc], b.R)
        np.testing.assert_array_equal(nm.wq[rows, :n_qp], b.wq)
        assert np.all(nm.R[rows, :, n_loc:] == 0.0) and np.all(nm.wq[rows, n_qp:] == 0.0)
        np.testing.assert_array_equal(nm.block_dofs[rows, :2 * n_loc], element_dofs(b.conn))
        start += n_el
    assert nm.R.shape[1:] == (5, 5) and nm.eta.shape[1] == max(b.eta.shape[1] for b in blocks)
    np.testing.assert_array_equal(nm.block_dofs[nm.n_elements:],
                                  element_dofs(model.loads.conn))


# -------------------------------------------------------------------------- the potential

@pytest.mark.parametrize(("name", "sparse"), MODEL_PARAMS)
def test_potential_residual_tangent_and_energies_equal_jax(name, sparse):
    """r_pot and the tangent assembled from the blocks against residual_tangent_with_contact
    (no contact, no supports), the energies against energies(), at states rotated by more
    than 90 degrees with a load state of whole turns."""
    model = _model(name, sparse)
    nm = nmod.native_arrays(model)
    rng = np.random.default_rng(3)
    r, k = np.empty(nm.n_dof), nmod.new_blocks(nm)
    worst = {"r": 0.0, "K": 0.0, "E": 0.0}
    for _ in range(N_STATES):
        u = _state(model, rng, rng.uniform(0.6, 0.95) * np.pi * rng.choice([-1, 1]))
        theta_n, t_n = _load_state(model, u, rng)
        lam = rng.uniform(0.3, 1.5)
        ls = LoadState(theta=jnp.asarray(theta_n), tangent=jnp.asarray(t_n))
        r_ad, K_ad = _residual_tangent(jnp.asarray(u), model, lam, ls, None)
        nmod.potential_residual_blocks(nm, u, lam, theta_n, t_n, r, k)
        worst["r"] = max(worst["r"], _rel(r, r_ad))
        worst["K"] = max(worst["K"], _rel(_dense(nm, k), linear.to_dense(K_ad)))
        e_ad = _energies(jnp.asarray(u), model, lam, ls)
        e = nmod.energies(nm, u, lam, theta_n, t_n)
        for value, key in zip(e, ("E_strain", "E_gravity", "E_ext"), strict=True):
            worst["E"] = max(worst["E"], _rel(value, e_ad[key]))
    assert max(worst.values()) <= RTOL, worst


@pytest.mark.parametrize("name", ["two_beams", "cantilever", "mixed"])
def test_external_forces_alone_equal_jax(name):
    """With E = 0 the potential is gravity and the loads alone (strain would hide them
    far below its rounding): residual, load blocks and energies."""
    model = _with_zero_modulus(_model(name, False))
    nm = nmod.native_arrays(model)
    rng = np.random.default_rng(5)
    r, k = np.empty(nm.n_dof), nmod.new_blocks(nm)
    worst = 0.0
    for _ in range(N_STATES):
        u = _state(model, rng, rng.uniform(-2.0 * np.pi, 2.0 * np.pi))
        theta_n, t_n = _load_state(model, u, rng)
        lam = rng.uniform(0.3, 1.5)
        ls = LoadState(theta=jnp.asarray(theta_n), tangent=jnp.asarray(t_n))
        r_ad, K_ad = _residual_tangent(jnp.asarray(u), model, lam, ls, None)
        nmod.potential_residual_blocks(nm, u, lam, theta_n, t_n, r, k)
        assert np.all(k[:nm.n_elements] == 0.0)
        e_ad = _energies(jnp.asarray(u), model, lam, ls)
        e = nmod.energies(nm, u, lam, theta_n, t_n)
        worst = max(worst, _rel(r, r_ad), _rel(_dense(nm, k), linear.to_dense(K_ad)),
                    _rel(e[1], e_ad["E_gravity"]), _rel(e[2], e_ad["E_ext"]))
        assert e[0] == 0.0
    assert np.max(np.abs(r)) > 1.0  # the forces really act
    assert worst <= RTOL


@pytest.mark.parametrize("name", ["cantilever", "mixed"])
def test_load_state_update_equals_jax(name):
    model = _model(name, False)
    nm = nmod.native_arrays(model)
    rng = np.random.default_rng(7)
    worst = 0.0
    for u in _large_rotations(model, rng):
        theta_n, t_n = _load_state(model, u, rng)
        ref = _update(model, jnp.asarray(u), LoadState(jnp.asarray(theta_n),
                                                       jnp.asarray(t_n)))
        theta, t = np.empty_like(theta_n), np.empty_like(t_n)
        nmod.update_load_state(nm, u, theta_n, t_n, theta, t)
        worst = max(worst, _rel(theta, ref.theta), _rel(t, ref.tangent))
        nmod.update_load_state(nm, u, theta_n, t_n, theta_n, t_n)  # in place
        np.testing.assert_array_equal(theta_n, theta)
        np.testing.assert_array_equal(t_n, t)
    assert worst <= RTOL


def test_initial_load_state_continues_without_jump():
    """From the initial load state at u = 0, theta after a rotation by 3 pi / 4 is 3 pi / 4
    (up to the distortion of the tangent): the updates carry the rotation on."""
    model = _model("cantilever", False)
    nm = nmod.native_arrays(model)
    ls = initial_load_state(model)
    theta, t = np.array(ls.theta), np.array(ls.tangent)
    x_ref = np.asarray(model.x_ref)
    for step in range(1, 5):  # four steps of 3 pi / 4: 3 pi in total
        x = x_ref @ _rotation(0.75 * np.pi * step).T
        nmod.update_load_state(nm, (x - x_ref).ravel(), theta, t, theta, t)
    np.testing.assert_allclose(theta, 3.0 * np.pi, rtol=1e-14)


# ----------------------------------------------------------------------------- dynamics

def _dynamic_state(model, rng):
    u = _state(model, rng, rng.uniform(0.6, 0.95) * np.pi)
    u_n = u - 0.05 * rng.normal(size=u.size)
    return u, u_n, rng.normal(size=u.size), 10.0 * rng.normal(size=u.size)


@pytest.mark.parametrize(("name", "sparse"), MODEL_PARAMS)
def test_inertia_residual_tangent_equals_jax(name, sparse):
    model = _model(name, sparse)
    nm = nmod.native_arrays(model)
    rng = np.random.default_rng(11)
    r, k = np.empty(nm.n_dof), nmod.new_blocks(nm)
    worst = 0.0
    for _ in range(N_STATES):
        state = _dynamic_state(model, rng)
        coeffs = np.asarray(hht_coefficients(rng.uniform(-1 / 3, 0), rng.uniform(1e-4, 1e-2)))
        r_ad, K_ad = _inertia(*(jnp.asarray(w) for w in state), jnp.asarray(coeffs), model)
        nmod.inertia_residual_blocks(nm, *state, coeffs, r, k)
        worst = max(worst, _rel(r, r_ad),
                    _rel(_dense(nm, k, nm.n_elements), linear.to_dense(K_ad)))
    assert worst <= RTOL


@pytest.mark.parametrize(("name", "sparse"), MODEL_PARAMS)
def test_hht_residual_tangent_equals_jax(name, sparse):
    """The combination of dynamics/hht.py's hht_step (before supports): r_i + (1 + alpha)
    r_pot - alpha f_pot_n and K_i + (1 + alpha) K_p, with r_pot and the strain energy
    besides; the evaluation without the tangent gives the same numbers bit for bit."""
    model = _model(name, sparse)
    nm = nmod.native_arrays(model)
    rng = np.random.default_rng(13)
    r, r_pot, k = np.empty(nm.n_dof), np.empty(nm.n_dof), nmod.new_blocks(nm)
    worst = 0.0
    for _ in range(N_STATES):
        state = _dynamic_state(model, rng)
        theta_n, t_n = _load_state(model, state[0], rng)
        ls = LoadState(theta=jnp.asarray(theta_n), tangent=jnp.asarray(t_n))
        alpha, dt = rng.uniform(-1 / 3, 0), rng.uniform(1e-4, 1e-2)
        coeffs = np.asarray(hht_coefficients(alpha, dt))
        f_pot_n = np.asarray(_residual_tangent(jnp.asarray(state[1]), model, 1.0, ls, None)[0])
        r_p, K_p = _residual_tangent(jnp.asarray(state[0]), model, 1.0, ls, None)
        r_i, K_i = _inertia(*(jnp.asarray(w) for w in state), jnp.asarray(coeffs), model)
        r_ref = r_i + (1.0 + alpha) * r_p - alpha * f_pot_n
        K_ref = linear.to_dense(linear.add(K_i, K_p, 1.0 + alpha))
        e_strain = nmod.hht_residual_blocks(nm, *state, coeffs, alpha, f_pot_n, theta_n, t_n,
                                            r, r_pot, k)
        # without the tangent: the same residuals and energy, bit for bit
        r_alone, r_pot_alone = np.empty(nm.n_dof), np.empty(nm.n_dof)
        assert e_strain == nmod.hht_residual_blocks(nm, *state, coeffs, alpha, f_pot_n,
                                                    theta_n, t_n, r_alone, r_pot_alone,
                                                    nmod.new_blocks(nm), False)
        assert np.array_equal(r_alone, r) and np.array_equal(r_pot_alone, r_pot)
        # the strain energy it returns (a time step's E_strain) against JAX's energy
        e_ad = _energies(jnp.asarray(state[0]), model, 1.0, ls)["E_strain"]
        worst = max(worst, _rel(r, r_ref), _rel(r_pot, r_p), _rel(_dense(nm, k), K_ref),
                    _rel(e_strain, e_ad))
    assert worst <= RTOL


@pytest.mark.parametrize("name", ["two_beams", "mixed"])
def test_kinetic_energy_and_momentum_equal_jax(name):
    model = _model(name, False)
    nm = nmod.native_arrays(model)
    rng = np.random.default_rng(17)
    worst = 0.0
    for u in _large_rotations(model, rng):
        v = rng.normal(size=u.size)
        T_ad, p_ad = _kinetic(jnp.asarray(u), jnp.asarray(v), model)
        T, p = nmod.kinetic_energy_momentum(nm, u, v)
        worst = max(worst, _rel(T, T_ad), _rel(p, p_ad))
    assert worst <= RTOL


# ------------------------------------------------------------------------ the load kernel

def _jax_load(x_flat, R, dR, force, moment, theta_n, t_n):
    return point_load_potential(x_flat.reshape(-1, 2), R, dR, force, moment, theta_n, t_n)


_jax_load_value = jax.jit(_jax_load)
_jax_load_grad = jax.jit(jax.grad(_jax_load))
_jax_load_hess = jax.jit(jax.hessian(_jax_load))


@pytest.mark.parametrize("n_loc", [3, 5])
def test_point_load_kernel_equals_jax_ad(n_loc):
    """Value, jax.grad and jax.hessian of point_load_potential at random states: tangents
    of any direction and length, steps of up to 0.95 pi from t_n, theta_n up to ten
    turns either way, zero basis padding."""
    rng = np.random.default_rng(19 + n_loc)
    m = 2 * n_loc
    worst = 0.0
    for i in range(24):
        x_e = rng.normal(size=(n_loc, 2)) * rng.uniform(0.1, 10.0)
        R, dR = rng.uniform(0.0, 1.0, n_loc), rng.normal(size=n_loc) * rng.uniform(0.5, 20.0)
        if i % 4 == 0:
            R[-1] = dR[-1] = 0.0  # a padding column
        t = dR @ x_e
        step = rng.uniform(-0.95, 0.95) * np.pi
        t_n = _rotation(-step) @ t * rng.uniform(0.2, 5.0)
        theta_n = rng.uniform(-20.0, 20.0) * np.pi
        force, moment = rng.normal(size=2) * 100.0, rng.normal() * 10.0
        scale = rng.uniform(0.1, 2.0)
        r, k = np.empty(m), np.empty((m, m))
        value = lnat.point_load_residual_tangent(x_e, R, dR, force, moment, theta_n, t_n,
                                                 scale, r, k)
        args = (jnp.asarray(x_e.ravel()), R, dR, force, moment, theta_n, t_n)
        ref = _jax_load_value(*args)
        theta = lnat.tangent_rotation(t[0], t[1], theta_n, t_n[0], t_n[1])
        worst = max(worst, _rel(value, scale * ref),
                    _rel(lnat.point_load_potential(x_e, R, dR, force, moment, theta_n, t_n),
                         ref),
                    _rel(r, scale * _jax_load_grad(*args)),
                    _rel(k, scale * _jax_load_hess(*args)),
                    _rel(theta, theta_n + step))
        if i % 4 == 0:
            assert np.all(r[-2:] == 0.0) and np.all(k[-2:] == 0.0) and np.all(k[:, -2:] == 0.0)
    assert worst <= RTOL
