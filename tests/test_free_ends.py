"""Outlier removal at free ends (beam/free_ends.py): the constraint u'''(end) = 0, the
folded basis, the spectra it leaves, its dynamics, and the cases it refuses."""

import numpy as np
import pytest
import scipy.linalg as sla
from _builders import beam

from beamcontact.assembly.inertia import inertia_force_and_mass
from beamcontact.assembly.model import initial_load_state
from beamcontact.assembly.system import potential_residual_tangent
from beamcontact.beam.free_ends import free_end
from beamcontact.beam.mesh import build_mesh, refine_axis
from beamcontact.dynamics.driver import solve_dynamic
from beamcontact.io.case import CaseError, ignored_keys, parse_case
from beamcontact.setup.start import dynamic_start, prepare
from beamcontact.solvers import linear
from beamcontact.spline import line
from beamcontact.spline.basis import basis_derivatives, find_span

RNG = np.random.default_rng(7)


def _axis(degree, elements, continuity, length=1.0):
    return refine_axis(line([0.0, 0.0], [length, 0.0]), degree, elements, continuity)


@pytest.mark.parametrize("degree", [4, 5, 6])
def test_the_tied_point_makes_the_third_derivative_vanish(degree):
    """For every continuity, at either end: masters anywhere, the dependent point from the
    weights, and the curve's third derivative at that end is zero (to round-off of the
    derivative's scale); the weights sum to 1 (rigid translations keep the constraint)."""
    for continuity in range(1, degree):
        curve = _axis(degree, 5, continuity)
        for at in ("start", "end"):
            end = free_end(curve, at)
            assert sum(end.weights) == pytest.approx(1.0, abs=1e-13)
            x = RNG.normal(size=(curve.n_points, 2))
            x[end.dependent] = sum(w * x[m] for w, m in zip(end.weights, end.masters,
                                                             strict=True))
            xi = curve.knots[0] if at == "start" else curve.knots[-1]
            span = find_span(curve.knots, degree, xi)
            third = basis_derivatives(curve.knots, degree, span, xi, 3)[3]
            d3 = third @ x[span - degree: span + 1]
            scale = np.abs(third) @ np.abs(x[span - degree: span + 1])
            assert np.max(np.abs(d3)) <= 1e-13 * np.max(scale), (continuity, at)


def test_quartic_c1_uniform_weights_are_3_minus_3_1():
    """The closed form for the paper's splines: u_0 = 3 u_1 - 3 u_2 + u_3 (the third
    difference of the uniform interior control points), mirrored at the other end."""
    curve = _axis(4, 6, 1)
    start, end = free_end(curve, "start"), free_end(curve, "end")
    n = curve.n_points
    assert (start.dependent, start.masters) == (0, (1, 2, 3))
    assert (end.dependent, end.masters) == (n - 1, (n - 2, n - 3, n - 4))
    np.testing.assert_allclose(start.weights, [3.0, -3.0, 1.0], rtol=1e-13)
    np.testing.assert_allclose(end.weights, [3.0, -3.0, 1.0], rtol=1e-13)


def test_folded_basis_is_the_tied_curve():
    """The folded rows at the Gauss points give, for any masters, the curve (and its first
    two derivatives) of the original basis with the tied end points; they still sum to
    one (partition of unity)."""
    curve = _axis(4, 6, 1)
    ends = (free_end(curve, "start"), free_end(curve, "end"))
    plain, folded = build_mesh(curve), build_mesh(curve, free_ends=ends)
    x = RNG.normal(size=(curve.n_points, 2))
    tied = x.copy()
    for e in ends:
        tied[e.dependent] = sum(w * x[m] for w, m in zip(e.weights, e.masters, strict=True))
    for name in ("R", "dR", "ddR"):
        want = np.einsum("eqk,ekd->eqd", getattr(plain, name), tied[plain.conn])
        got = np.einsum("eqk,ekd->eqd", getattr(folded, name), x[folded.conn])
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-12 * np.max(np.abs(want)))
    np.testing.assert_allclose(folded.R.sum(axis=-1), 1.0, rtol=0, atol=1e-14)
    assert np.all(folded.R[0, :, 0] == 0.0) and np.all(folded.R[-1, :, -1] == 0.0)
    assert np.array_equal(folded.R[1:-1], plain.R[1:-1])  # inner elements untouched


def _case(remove_outliers, elements=8, radius=1e-4, supports=(), kind="dynamic", **extra):
    b = beam("b", line=([0.0, 0.0], [1.0, 0.0]), degree=4, elements=elements, continuity=1,
             radius=radius, E=1e9, density=1000.0, supports=supports)
    b["remove_outliers"] = remove_outliers
    return {"analysis": {"kind": kind, "t_end": 1.0, "dt": 1e-3, "gravity": [0.0, 0.0]},
           "beams": [b], **extra}


def _spectra(remove_outliers, elements):
    """Axial and bending circular frequencies of the linearised free-free beam (x and y
    dofs decouple at the straight reference), over the dofs left to the solve."""
    model = prepare(parse_case(_case(remove_outliers, elements))).model
    n = model.n_dof
    u = np.zeros(n)
    K = linear.to_dense(potential_residual_tangent(u, model, 1.0,
                                                   initial_load_state(model))[1])
    M = linear.to_dense(inertia_force_and_mass(u, u, u, model)[1])
    free = np.asarray(model.free) > 0.5
    out = []
    for component in (0, 1):
        idx = np.flatnonzero(free & (np.arange(n) % 2 == component))
        w2 = sla.eigvals(K[np.ix_(idx, idx)], M[np.ix_(idx, idx)]).real
        out.append(np.sqrt(np.sort(np.abs(w2))))
    return out


def test_the_outliers_go_and_the_low_modes_stay():
    """Free-free bar and beam, quartic C1, 1 m, slender (R = 0.1 mm): the axial spectrum
    against the continuum's n pi c / L, the bending one against Euler-Bernoulli's
    (beta_n L)^2 sqrt(EI / rho A) / L^2 (rotary inertia changes these by < 1e-6 here).
    Without the constraint the top of the axial spectrum is 1.57x the continuum's; with
    it no mode is 1.15x above, the low modes keep their accuracy (axial 2e-5, bending
    0.3 % for the first five at 8 elements), and bending converges at the rate of the
    space, h^(2(p-1)) = h^6 for the eigenvalue (the ratio of errors at 8 and 16 elements
    at least 2^5 for the modes above the rotary-inertia floor)."""
    c = np.sqrt(1e9 / 1000.0)
    beam_c = np.sqrt(1e9 * (1e-4) ** 2 / 4.0 / 1000.0)
    beta_l = np.array([4.7300407448627, 7.8532046240958, 10.995607838002, 14.137165491257,
                       17.278759657399])
    bending_c = beta_l**2 * beam_c
    errors = {}
    for elements in (8, 16):
        plain_ax, plain_be = _spectra(False, elements)
        ax, be = _spectra(True, elements)
        assert len(ax) == len(plain_ax) - 2 and len(be) == len(plain_be) - 2
        assert plain_ax[-1] > 1.5 * (len(plain_ax) - 1) * np.pi * c  # the outliers
        assert np.max(ax[1:] / (np.arange(1, len(ax)) * np.pi * c)) < 1.15
        assert be[-1] < 0.85 * plain_be[-1]
        np.testing.assert_allclose(ax[1:6], np.arange(1, 6) * np.pi * c, rtol=2e-5)
        assert be[1] < 1e-4 * bending_c[0]  # translation and rotation stay rigid modes
        errors[elements] = np.abs(be[2:7] / bending_c - 1.0)
    assert np.all(errors[8] < 3e-3)
    assert np.all(errors[8][2:] / errors[16][2:] > 2.0**5)


def _swing(remove_outliers, engine="native", t_end=0.6):
    """A 1 m beam pinned at its start, released horizontally under gravity (alpha = 0):
    it swings down and bends, its free end unloaded."""
    b = beam("b", line=([0.0, 0.0], [1.0, 0.0]), degree=4, elements=8, continuity=1,
             radius=0.01, E=1e7, density=1000.0, supports=[{"at": "start", "type": "pinned"}])
    b["remove_outliers"] = remove_outliers
    raw = {"analysis": {"kind": "dynamic", "t_end": t_end, "dt": 1e-2, "alpha": 0.0,
                        "gravity": [0.0, -9.81]},
           "beams": [b], "solver": {"engine": engine}}
    start = dynamic_start(prepare(parse_case(raw)))
    rows = []
    res = solve_dynamic(start.engine, start.state, t_end, start.prepared.length,
                        start.control, on_step=lambda s: rows.append(
                            (s.t, np.array(s.state.u), np.array(s.state.v),
                             np.array(s.state.a), s.diagnostics)))
    assert res.status == "completed", res.message
    return rows, start.prepared.model


def test_a_swinging_beam_keeps_its_ties_its_energy_and_its_motion():
    """Every accepted state satisfies the ties exactly (u, v and a); the total energy is
    conserved (alpha = 0) to 1e-4 of the kinetic energy it reaches, as without the
    constraint; and the tip moves as without it (the continuum satisfies the
    constraint): to 1e-4 of the length, the order of the time integration's own error
    (the two runs take different steps; compared by linear interpolation)."""
    rows, model = _swing(True)
    plain, _ = _swing(False)
    dep, masters = np.asarray(model.tied), np.asarray(model.tie_masters)
    weights = np.asarray(model.tie_weights)
    assert dep.shape == (2,)  # the free end only, x and y
    for k in (1, 2, 3):
        w = np.array([r[k] for r in rows])
        assert np.array_equal(w[:, dep], np.einsum("tk,rtk->rt", weights, w[:, masters]))
    e_total = np.array([r[4]["E_total"] for r in rows])
    e_kin = max(r[4]["E_kin"] for r in rows)
    assert e_kin > 1.0 and np.ptp(e_total) < 1e-4 * e_kin
    t = np.array([r[0] for r in rows])
    tip = np.array([r[1][-2:] for r in rows])
    t_plain = np.array([r[0] for r in plain])
    tip_plain = np.array([r[1][-2:] for r in plain])
    for a in (0, 1):
        assert np.max(np.abs(np.interp(t_plain, t, tip[:, a]) - tip_plain[:, a])) < 1e-4
    assert abs(tip[-1, 1]) > 0.5  # it swung


def test_both_engines_swing_the_same():
    """The JAX engine's ties (assembly/system.py) and the native ones give one trajectory
    (tolerance as in tests/test_engine_parity.py)."""
    native, _ = _swing(True, "native", t_end=0.2)
    jax_rows, _ = _swing(True, "jax", t_end=0.2)
    assert len(native) == len(jax_rows)
    u_n = np.array([r[1] for r in native])
    u_j = np.array([r[1] for r in jax_rows])
    np.testing.assert_allclose(u_n, u_j, rtol=0, atol=1e-9)
    assert np.max(np.abs(u_n)) > 0.1


@pytest.mark.parametrize("change, key", [
    (lambda r: r["beams"][0].update(degree=3), "degree >= 4"),
    (lambda r: r["beams"][0].update(elements=1), "at least 2 elements"),
    (lambda r: r["beams"][0].update(supports=[{"at": "start", "type": "pinned"},
                                              {"at": "end", "type": "clamped"}]),
     "both ends of this beam are supported"),
    (lambda r: r.update(loads=[{"beam": "b", "at": 1.0, "force": [0.0, -1.0]}]),
     "loads[0].at"),
])
def test_cases_it_cannot_serve_are_refused(change, key):
    raw = _case(True)
    change(raw)
    with pytest.raises(CaseError, match=key.replace("[", r"\[").replace("]", r"\]")):
        parse_case(raw)


@pytest.mark.parametrize("geometry, why", [
    ({"arc": {"center": [0.0, 0.0], "radius": 1.0, "start_angle": 0.0, "end_angle": 1.5}},
     "equal NURBS weights"),
    # a parabola: its third derivative is zero, but a curved free end does not have
    # r''' = 0 once its stretch varies
    ({"nurbs": {"degree": 2, "knots": [0, 0, 0, 1, 1, 1],
                "points": [[0.0, 0.0], [0.5, 0.3], [1.0, 0.0]]}},
     "straight end element"),
    # straight, but not uniformly parametrised: the reference is not in the space
    ({"nurbs": {"degree": 3, "knots": [0, 0, 0, 0, 1, 1, 1, 1],
                "points": [[0.0, 0.0], [0.1, 0.0], [0.2, 0.0], [1.0, 0.0]]}},
     "parametrised uniformly"),
])
def test_an_end_it_cannot_serve_is_refused(geometry, why):
    """A rational, curved or non-uniformly parametrised end element: a CaseError that
    names the beam and why, not a silently different model."""
    b = beam("hook", degree=4, elements=6, continuity=1, radius=0.01)
    b.update(geometry, remove_outliers=True)
    raw = {"analysis": {"kind": "dynamic", "t_end": 1.0, "dt": 1e-3}, "beams": [b]}
    with pytest.raises(CaseError, match=f"'hook'.*{why}"):
        prepare(parse_case(raw))


def test_statics_ignores_it_with_a_warning():
    """As other dynamics-only keys: one case file serves a static and a dynamic run, so
    statics warns and builds the beam as discretised (no tie, the end point free)."""
    case = parse_case(_case(True, kind="static", supports=[{"at": "start",
                                                            "type": "clamped"}]))
    assert any(w.startswith("beams[0].remove_outliers: ignored") for w in ignored_keys(case))
    model = prepare(case).model
    assert model.tied.shape == (0,) and np.asarray(model.free)[-2:].tolist() == [1.0, 1.0]


def test_a_load_inside_the_end_element_is_folded():
    """A point load inside the free end element acts in the constrained space: its basis
    row no longer touches the tied point, and still sums to one."""
    raw = _case(True, loads=[{"beam": "b", "at": 0.05, "force": [0.0, -1.0]}])
    model = prepare(parse_case(raw)).model
    conn, R = np.asarray(model.loads.conn[0]), np.asarray(model.loads.R[0])
    assert conn[0] == 0 and R[0] == 0.0 and R.sum() == pytest.approx(1.0, abs=1e-14)
