"""Native (Numba) beam kernels against JAX automatic differentiation of the energies and
forces they implement (beam/energy.py, beam/inertia.py) and against the JAX assembly.

Tolerance: RTOL = 1e-12 of the largest entry of the JAX result. Both sides evaluate the
same float64 formulas in different orders (hand-written chain rule against AD, loops
against XLA's reductions), so they differ by rounding only: a few ulps of the largest
terms that enter each entry. Observed: below 3e-15 against AD of an element, 3e-14 against
the assembly (y = D x sums a large rigid offset that cancels). The HHT inertia residual
has a higher floor that is no fault of either side: Newmark's a = c_a (u - u_n - dt v_n)
cancels, so rounding of |u| ~ 1 is amplified by c_a = 1/(beta dt^2) (eps |u| c_a rho A ds
against forces of rho A ds |a|): 1e-13 to 2e-13 for the states here. 1e-12 stays above
these floors, and an error in a formula shows far above it (a coefficient off by 1e-5
fails these tests).
"""

import dataclasses
import os
import subprocess
import sys
import time

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from _builders import beam, static_case

from beamcontact.assembly.inertia import inertia_residual_tangent, newmark_kinematics
from beamcontact.assembly.model import element_dofs
from beamcontact.assembly.system import _beam_residual_tangent
from beamcontact.beam import energy_native as en
from beamcontact.beam import inertia_native as ine
from beamcontact.beam.energy import element_strain_energy, point_strain_energy
from beamcontact.beam.inertia import element_inertia_force, element_kinetic_energy
from beamcontact.beam.inertia import element_momentum as jax_element_momentum
from beamcontact.beam.mesh import build_mesh, refine_axis
from beamcontact.beam.section import circle_section, rectangle_section
from beamcontact.dynamics.hht import hht_coefficients
from beamcontact.setup.model import build_model
from beamcontact.spline import arc

RTOL = 1e-12
SECTIONS = {"circle": lambda s: circle_section(0.1 * s),
            "rectangle": lambda s: rectangle_section(0.3 * s, 0.2 * s)}
CASES = [(shape, p) for shape in SECTIONS for p in (2, 4)]
N_STATES = 12


def _rel(native, ref):
    """max |native - ref| / max |ref|."""
    ref = np.asarray(ref)
    return float(np.max(np.abs(np.asarray(native) - ref)) / np.max(np.abs(ref)))


# ---------------------------------------------------------------- random elements and states

@dataclasses.dataclass
class Element:
    """One element of a refined arc: basis at the Gauss points, reference and section."""

    x_ref: np.ndarray
    R: np.ndarray
    dR: np.ndarray
    ddR: np.ndarray
    wq: np.ndarray
    g_ref: np.ndarray
    K_ref: np.ndarray
    eta: np.ndarray
    w_eta: np.ndarray
    half_depth: float


def _metric(x_e, dR, ddR):
    g1, g1d = dR @ x_e, ddR @ x_e
    g = np.sum(g1 * g1, axis=-1)
    return g, (g1[:, 0] * g1d[:, 1] - g1[:, 1] * g1d[:, 0]) / g**1.5


def _element(rng, shape, degree) -> Element:
    """A random element of a refined circular arc (rational basis, curved reference)."""
    radius = rng.uniform(0.5, 2.0)
    start = rng.uniform(-np.pi, np.pi)
    sweep = rng.choice([-1.0, 1.0]) * rng.uniform(1.0, 5.0)
    curve = refine_axis(arc(rng.normal(size=2), radius, start, start + sweep), degree,
                        int(rng.integers(2, 5)), degree - 1)
    mesh = build_mesh(curve)
    e = int(rng.integers(mesh.n_elements))
    x_ref = curve.points[mesh.conn[e]]
    g_ref, K_ref = _metric(x_ref, mesh.dR[e], mesh.ddR[e])
    sec = SECTIONS[shape](radius * rng.uniform(0.5, 2.0))
    return Element(x_ref, mesh.R[e], mesh.dR[e], mesh.ddR[e], mesh.wq[e], g_ref, K_ref,
                   sec.eta, sec.weights, sec.half_depth)


def _rotation(angle):
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s], [s, c]])


def _state(rng, el: Element):
    """Control points after a large rotation, a shrink (up to 4x the reference curvature)
    and a random distortion of 10 % of the element size, with |eta K| <= 0.95."""
    size = np.ptp(el.x_ref, axis=0).max()
    for _ in range(100):
        centre = el.x_ref.mean(axis=0)
        scale = rng.uniform(0.25, 1.5)
        x = (scale * (el.x_ref - centre)) @ _rotation(rng.uniform(0, 2 * np.pi)).T
        x = x + rng.normal(size=2) + 0.1 * size * rng.normal(size=x.shape)
        _, K = _metric(x, el.dR, el.ddR)
        if np.max(np.abs(K)) * el.half_depth <= 0.95:
            return x
    raise AssertionError("no admissible state drawn")


# ------------------------------------------------------------------------------ strain

_jax_point_grad = jax.jit(jax.vmap(jax.grad(point_strain_energy), (0, 0, 0, None, None, None)))
_jax_point_hess = jax.jit(jax.vmap(jax.hessian(point_strain_energy),
                                   (0, 0, 0, None, None, None)))


@pytest.mark.parametrize(("shape", "degree"), CASES)
def test_point_strain_derivatives_equal_jax_ad(shape, degree):
    rng = np.random.default_rng(11 + degree)
    worst = 0.0
    for _ in range(N_STATES):
        el = _element(rng, shape, degree)
        x = _state(rng, el)
        y = np.concatenate([el.dR @ x, el.ddR @ x], axis=1)  # (n_qp, 4)
        E = rng.uniform(1e6, 1e11)
        args = (el.eta, el.w_eta, E)
        g_ad = _jax_point_grad(y, el.g_ref, el.K_ref, *args)
        h_ad = _jax_point_hess(y, el.g_ref, el.K_ref, *args)
        grad, hess = np.empty(4), np.empty((4, 4))
        for q in range(len(y)):
            psi = en.point_strain_derivatives(y[q], el.g_ref[q], el.K_ref[q], *args, grad, hess)
            ref = point_strain_energy(y[q], jnp.asarray(el.g_ref[q]), jnp.asarray(el.K_ref[q]),
                                      *args)
            worst = max(worst, _rel(psi, ref), _rel(grad, g_ad[q]), _rel(hess, h_ad[q]))
    assert worst <= RTOL


def _jax_element_strain(x_flat, *data):
    return element_strain_energy(x_flat.reshape(-1, 2), *data)


_jax_element_grad = jax.jit(jax.grad(_jax_element_strain))
_jax_element_hess = jax.jit(jax.hessian(_jax_element_strain))


@pytest.mark.parametrize(("shape", "degree"), CASES)
def test_element_strain_residual_tangent_equals_jax_ad(shape, degree):
    """Gradient and Hessian of the whole element energy, AD over all control points."""
    rng = np.random.default_rng(23 + degree)
    n = 2 * (degree + 1)
    worst = 0.0
    for _ in range(N_STATES):
        el = _element(rng, shape, degree)
        x = _state(rng, el)
        E = rng.uniform(1e6, 1e11)
        r, k = np.empty(n), np.empty((n, n))
        data = (el.dR, el.ddR, el.wq, el.g_ref, el.K_ref, el.eta, el.w_eta, E)
        energy = en.element_strain_residual_tangent(x, *data, r, k)
        xf = jnp.asarray(x.ravel())
        ref_e = _jax_element_strain(xf, *data)
        worst = max(worst, _rel(energy, ref_e), _rel(en.element_strain_energy(x, *data), ref_e),
                    _rel(r, _jax_element_grad(xf, *data)), _rel(k, _jax_element_hess(xf, *data)))
    assert worst <= RTOL


def test_rigid_motion_has_no_strain_force():
    """Round-off zero residual in any rotated position of the reference (eqs. 23-25)."""
    rng = np.random.default_rng(5)
    el = _element(rng, "circle", 4)
    x = el.x_ref @ _rotation(2.1).T + np.array([0.4, -1.0])
    n = x.size
    r, k = np.empty(n), np.empty((n, n))
    data = (el.dR, el.ddR, el.wq, el.g_ref, el.K_ref, el.eta, el.w_eta, 1e9)
    assert abs(en.element_strain_residual_tangent(x, *data, r, k)) < 1e-20
    assert np.max(np.abs(r)) < 1e-12 * np.max(np.abs(k)) * np.max(np.abs(x))


# ------------------------------------------------------------------------------ inertia

def _inertia_data(el, rng):
    rho_area, rho_inertia = rng.uniform(1.0, 1e3), rng.uniform(1e-6, 1e-2)
    return (el.R, el.dR, el.wq, el.g_ref, rho_area, rho_inertia)


def _jax_inertia(x_f, v_f, a_f, data):
    return element_inertia_force(x_f.reshape(-1, 2), v_f.reshape(-1, 2), a_f.reshape(-1, 2),
                                 *data).ravel()


@pytest.mark.parametrize("degree", [2, 4])
def test_element_inertia_force_and_jacobians_equal_jax_ad(degree):
    """Force of eq. (29) and jax.jacfwd of it in x_e, v_e and a_e; the kinetic energy
    and momentum besides."""
    rng = np.random.default_rng(31 + degree)
    n = 2 * (degree + 1)
    worst = 0.0
    for _ in range(N_STATES):
        el = _element(rng, "circle", degree)
        x = _state(rng, el)
        v, a = rng.normal(size=x.shape), 100.0 * rng.normal(size=x.shape)
        data = _inertia_data(el, rng)
        f, jx, jv, ja = np.empty(n), np.empty((n, n)), np.empty((n, n)), np.empty((n, n))
        ine.element_inertia_jacobians(x, v, a, *data, f, jx, jv, ja)
        f_only = np.empty(n)
        ine.element_inertia_force(x, v, a, *data, f_only)
        args = tuple(jnp.asarray(w.ravel()) for w in (x, v, a))
        f_ad = _jax_inertia(*args, data)
        jacs = jax.jacfwd(_jax_inertia, argnums=(0, 1, 2))(*args, data)
        T = element_kinetic_energy(x, v, *data)
        p, p_ref = np.empty(2), jax_element_momentum(v, el.R, el.wq, el.g_ref, data[4])
        ine.element_momentum(v, el.R, el.wq, el.g_ref, data[4], p)
        worst = max(worst, _rel(f, f_ad), _rel(f_only, f_ad), _rel(jx, jacs[0]),
                    _rel(jv, jacs[1]), _rel(ja, jacs[2]),
                    _rel(ine.element_kinetic_energy(x, v, *data), T), _rel(p, p_ref))
    assert worst <= RTOL


def _jax_hht_element(u_f, un, vn, an, x_ref, coeffs, data):
    """The element's inertia force at the Newmark v(u), a(u) (control-point kinematics)."""
    v, a = newmark_kinematics(u_f, un, vn, an, coeffs)
    return _jax_inertia(x_ref + u_f, v, a, data)


@pytest.mark.parametrize("degree", [2, 4])
def test_element_inertia_residual_tangent_equals_jax_ad(degree):
    """The HHT residual and d/du against jax.jacfwd of the force at Newmark's v(u), a(u)
    (linear, so Newmark at control points equals Newmark at Gauss points)."""
    rng = np.random.default_rng(41 + degree)
    n = 2 * (degree + 1)
    worst = 0.0
    for _ in range(N_STATES):
        el = _element(rng, "rectangle", degree)
        x = _state(rng, el)
        u = x - el.x_ref
        un = u - 0.01 * rng.normal(size=u.shape)
        vn, an = rng.normal(size=u.shape), 10.0 * rng.normal(size=u.shape)
        coeffs = np.asarray(hht_coefficients(rng.uniform(-1 / 3, 0), rng.uniform(1e-4, 1e-2)))
        data = _inertia_data(el, rng)
        r, k = np.empty(n), np.empty((n, n))
        ine.element_inertia_residual_tangent(u, un, vn, an, el.x_ref, coeffs, *data, r, k)
        args = (jnp.asarray(u.ravel()), *(jnp.asarray(w.ravel()) for w in (un, vn, an,
                                                                           el.x_ref)), coeffs)
        worst = max(worst, _rel(r, _jax_hht_element(*args, data)),
                    _rel(k, jax.jacfwd(_jax_hht_element)(*args, data)))
    assert worst <= RTOL


# ------------------------------------------------------ element by element against assembly

def _model(shape, degree):
    arc_ = {"center": [0.3, -0.2], "radius": 0.8, "start_angle": 0.2, "end_angle": 4.0}
    b = beam(arc=arc_, degree=degree, elements=5, radius=0.05, E=2e9, density=900.0)
    if shape == "rectangle":
        b["section"] = {"shape": "rectangle", "width": 0.02, "height": 0.08}
    model, _ = build_model(static_case([b]))
    return dataclasses.replace(model, sparse=False)


def _moved(model, rng):
    """Displacement of a large rotation and translation plus a distortion of 2 % of the
    beam size (strongly bent between neighbouring control points)."""
    x_ref = np.asarray(model.x_ref)
    x = x_ref @ _rotation(rng.uniform(0, 2 * np.pi)).T + rng.normal(size=2)
    return (x + 0.02 * np.ptp(x_ref) * rng.normal(size=x.shape) - x_ref).ravel()


def _numpy_block(blk):
    return {f.name: np.asarray(getattr(blk, f.name)) for f in dataclasses.fields(blk)}


@pytest.mark.parametrize(("shape", "degree"), CASES)
def test_strain_matches_assembly_element_by_element(shape, degree):
    """Per-element output of assembly/system.py's _beam_residual_tangent (lam = 0: the
    strain part only) equals the element kernel and the block kernel."""
    model = _model(shape, degree)
    rng = np.random.default_rng(53 + degree)
    blk = model.beams[0]
    b = _numpy_block(blk)
    n_el, n_loc = b["conn"].shape
    m = 2 * n_loc
    worst = 0.0
    for _ in range(3):
        x = np.asarray(model.x_ref) + _moved(model, rng).reshape(-1, 2)
        r_ad, k_ad = jax.jit(_beam_residual_tangent)(jnp.asarray(x), blk, 0.0, model.gravity)
        r_blk, k_blk = np.empty((n_el, m)), np.empty((n_el, m, m))
        en.block_strain_residual_tangent(x, b["conn"], b["dR"], b["ddR"], b["wq"], b["g_ref"],
                                         b["K_ref"], b["eta"], b["w_eta"], b["E"], r_blk,
                                         k_blk)
        r, k = np.empty(m), np.empty((m, m))
        for e in range(n_el):
            en.element_strain_residual_tangent(
                x[b["conn"][e]], b["dR"][e], b["ddR"][e], b["wq"][e], b["g_ref"][e],
                b["K_ref"][e], b["eta"][e], b["w_eta"][e], b["E"][e], r, k)
            worst = max(worst, _rel(r, r_ad[e]), _rel(k, k_ad[e]), _rel(r_blk[e], r_ad[e]),
                        _rel(k_blk[e], k_ad[e]))
    assert worst <= RTOL


_jax_inertia_assembly = jax.jit(inertia_residual_tangent)


@pytest.mark.parametrize(("shape", "degree"), CASES)
def test_inertia_matches_assembly_element_by_element(shape, degree):
    """assembly/inertia.py's inertia_residual_tangent of a model holding one element at a
    time (its dofs are that element's contribution) equals the element kernel."""
    model = _model(shape, degree)
    rng = np.random.default_rng(61 + degree)
    blk = model.beams[0]
    b = _numpy_block(blk)
    n_el, n_loc = b["conn"].shape
    u = _moved(model, rng)
    un = u - 0.01 * rng.normal(size=u.size)
    vn, an = rng.normal(size=u.size), 10.0 * rng.normal(size=u.size)
    coeffs = hht_coefficients(-0.2, 1e-3)
    m = 2 * n_loc
    r, k = np.empty(m), np.empty((m, m))
    worst = 0.0
    for e in range(n_el):
        one = jax.tree_util.tree_map(lambda w, e=e: w[e:e + 1], blk)
        r_ad, k_ad = _jax_inertia_assembly(*(jnp.asarray(w) for w in (u, un, vn, an)), coeffs,
                                           dataclasses.replace(model, beams=(one,)))
        dofs = np.asarray(element_dofs(b["conn"][e]))
        c = b["conn"][e]
        ine.element_inertia_residual_tangent(
            u.reshape(-1, 2)[c], un.reshape(-1, 2)[c], vn.reshape(-1, 2)[c],
            an.reshape(-1, 2)[c], np.asarray(model.x_ref)[c], np.asarray(coeffs), b["R"][e],
            b["dR"][e], b["wq"][e], b["g_ref"][e], b["rho_area"][e], b["rho_inertia"][e], r, k)
        worst = max(worst, _rel(r, np.asarray(r_ad)[dofs]),
                    _rel(k, np.asarray(k_ad)[np.ix_(dofs, dofs)]))
    assert worst <= RTOL


# ------------------------------------------------------------------------- the numba cache

def _run(code, cache_value):
    env = {**os.environ, "BEAMCONTACT_CACHE_DIR": cache_value}
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True,
                         check=True)
    return out.stdout.strip()


def test_native_import_loads_no_jax():
    assert _run("import sys, beamcontact._native; "
                "print(sorted({'jax', 'matplotlib'} & set(sys.modules)))", "") == "[]"


def test_numba_cache_beside_the_jax_cache(tmp_path):
    """Compiled kernels go to <cache>/numba/<hash>, and nowhere when the cache is off."""
    code = ("import numpy as np; from beamcontact.beam.energy_native import "
            "fibre_density_derivatives as f; "
            "print(f(1.0, 0.5, 1.0, 0.4, np.ones(2), np.ones(2), 1.0)[0], "
            "type(f._cache).__name__)")
    on = _run(code, str(tmp_path / "jax")).split()
    assert on[1] == "FunctionCache"
    assert any(p.suffix == ".nbi" for p in (tmp_path / "jax" / "numba").rglob("*"))
    off = _run(code, "").split()
    assert off == [on[0], "NullCache"]


def test_numba_cache_removes_folders_of_old_sources(tmp_path):
    """A folder of compiled kernels that no version used for STALE_AFTER_S goes; a
    recently used one of another version stays."""
    numba_dir = tmp_path / "jax" / "numba"
    old, recent = numba_dir / "0000000000000000", numba_dir / "1111111111111111"
    for folder in (old, recent):
        folder.mkdir(parents=True)
        (folder / "kernel.nbi").write_bytes(b"")
    long_ago = time.time() - 31 * 24 * 3600.0
    os.utime(old, (long_ago, long_ago))
    current = _run("from beamcontact import _native; print(_native._CACHE_DIR.name)",
                   str(tmp_path / "jax"))
    assert sorted(p.name for p in numba_dir.iterdir()) == sorted([recent.name, current])
