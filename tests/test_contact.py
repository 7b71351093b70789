"""Contact models (paper Sec. 2): laws, derivatives, broad phase, and mechanical checks."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from _builders import beam

from beamcontact.assembly.model import initial_load_state
from beamcontact.assembly.system import contact_residual_tangent
from beamcontact.contact.blocks import (
    FrozenContact,
    arc_length_weights,
    block_gaps,
    contact_energy,
)
from beamcontact.contact.broadphase import element_boxes
from beamcontact.contact.laws import cg_constant, cg_potential
from beamcontact.contact.select import closest_pair_weights
from beamcontact.dynamics.driver import solve_dynamic
from beamcontact.dynamics.hht import initial_state
from beamcontact.dynamics.step import JaxEngine
from beamcontact.io.case import CaseError, parse_case
from beamcontact.setup.contact import build_contact
from beamcontact.setup.model import build_model, point_sampler, uniform_velocities
from beamcontact.setup.start import step_control
from beamcontact.solvers.newton import NewtonOptions
from beamcontact.statics.driver import solve_static
from beamcontact.statics.native_step import NativeStatics
from beamcontact.statics.step import JaxStatics

# --- eq. (9) against brute-force integration of eq. (8) ----------------------------------

def _disk_disk_brute_force(R1, R2, q, m, n=24):
    """int_{disk1} int_{disk2} |x1 - x2|^-m dA1 dA2 for coplanar disks at gap q.

    Inner integral over disk 1 in polar coordinates around x2, radial part exact:
    int rho^(1-m) d rho = (rho_in^(2-m) - rho_out^(2-m)) / (m - 2); the remaining three
    dimensions by Gauss-Legendre on meshes graded geometrically towards the closest points.
    """
    d = R1 + R2 + q
    x, w = np.polynomial.legendre.leggauss(n)

    def graded(a, b, h):  # intervals a, a+h, a+2h, a+4h, ... b
        edges = [a]
        step = h
        while edges[-1] + step < b:
            edges.append(edges[-1] + step)
            step *= 2
        edges.append(b)
        e = np.array(edges)
        lo, hi = e[:-1, None], e[1:, None]
        return ((hi - lo) / 2 * x + (hi + lo) / 2).ravel(), ((hi - lo) / 2 * w).ravel()

    # disk 2 centred at (d, 0): points x2 = (d - R2 + s, y), s in [0, 2 R2]
    s, ws = graded(0.0, 2 * R2, q)
    total = 0.0
    for si, wsi in zip(s, ws, strict=True):
        half = np.sqrt(max(R2**2 - (R2 - si) ** 2, 0.0))
        yp, wy = graded(0.0, half, q)
        y = np.concatenate([-yp, yp])
        wy = np.concatenate([wy, wy])
        X, Y = d - R2 + si, y
        D = np.hypot(X, Y)
        amax = np.arcsin(np.minimum(R1 / D, 1.0))
        ph, wph = graded(0.0, 1.0, q / R1)  # fraction of amax, graded towards 0
        phi = ph[None, :] * amax[:, None]
        wphi = wph[None, :] * amax[:, None]
        disc = np.sqrt(np.maximum(R1**2 - (D[:, None] * np.sin(phi)) ** 2, 0.0))
        rin = D[:, None] * np.cos(phi) - disc
        rout = D[:, None] * np.cos(phi) + disc
        inner = 2 * np.sum(wphi * (rin ** (2 - m) - rout ** (2 - m)) / (m - 2), axis=1)
        total += wsi * np.sum(wy * inner)
    return total


@pytest.mark.parametrize(("R1", "R2"), [(0.1, 0.1), (0.05, 0.2)])
def test_section_section_potential_small_gap_asymptotics(R1, R2):
    """Eq. (9)'s integrand k b1 b2 C q^(7/2-m) is the small-gap limit of eq. (8) for two
    coplanar disks: the relative error shrinks like q/R."""
    m = 12.0
    errors = []
    for q_rel in (0.1, 0.03, 0.01):
        q = q_rel * min(R1, R2)
        exact = _disk_disk_brute_force(R1, R2, q, m)
        approx = float(cg_constant(m, R1, R2)) * q ** (3.5 - m)
        errors.append(abs(approx / exact - 1.0))
    assert errors[0] > errors[1] > errors[2]
    assert errors[2] < 0.02
    # first-order convergence in q/R
    assert 0.6 < np.log(errors[1] / errors[2]) / np.log(3.0) < 1.4


def test_regularised_potential_is_c2_and_finite():
    amp, m, q_reg = 2.0, 12.0, 1e-3
    f = lambda q: cg_potential(q, amp, m, q_reg)  # noqa: E731
    for k in range(3):
        g = f
        for _ in range(k):
            g = jax.grad(g)
        left, right = float(g(q_reg - 1e-12)), float(g(q_reg + 1e-12))
        assert abs(left - right) < 1e-6 * abs(right)
    for q in (0.0, -0.05, -1.0):
        for g in (f, jax.grad(f), jax.grad(jax.grad(f))):
            assert np.isfinite(float(g(q)))


# --- contact blocks: derivatives, no NaN -------------------------------------------------

def _two_beams(law, dy=-0.19, segments=5, **contact):
    raw = {"analysis": {"kind": "static"},
           "beams": [beam("a", line=([0, 0], [2, 0]), degree=4, elements=4, radius=0.1),
                     beam("b", line=([0.5, 0.3], [1.7, 0.15]), degree=3, elements=3,
                          radius=0.1)],
           "contact": {"model": law, "segments_per_element": segments, **contact}}
    case = parse_case(raw)
    model, disc = build_model(case)
    problem = build_contact(case, disc)
    x = np.asarray(model.x_ref).copy()
    x[disc.beam("b").offset:, 1] += dy
    return model, problem, jnp.asarray(x)


@pytest.mark.parametrize("law", ["cg", "ipip"])
def test_contact_residual_and_tangent_against_central_differences(law):
    model, problem, x = _two_beams(law, q_reg=0.02)
    cs, _ = problem.grown_set(x, 0.05, 8)
    assert int(jnp.sum(cs.pairs[:, 0] < problem.elements.n_elements)) > 0
    assert (cs.W is None) == (law == "cg")  # cg: arc-length weights formed in the kernel
    assert law == "cg" or float(jnp.max(cs.W)) > 0
    energy = jax.jit(lambda y: contact_energy(y.reshape(-1, 2), problem.elements, cs))
    r, K = jax.jit(contact_residual_tangent, static_argnums=(2,))(
        x, FrozenContact(problem.elements, cs), model.n_dof)
    y0 = np.asarray(x).ravel()
    h = 1e-6
    fd_r = np.array([(energy(y0 + h * e) - energy(y0 - h * e)) / (2 * h)
                     for e in np.eye(y0.size)])
    np.testing.assert_allclose(r, fd_r, atol=1e-6 * np.abs(fd_r).max())
    grad = jax.jit(jax.grad(energy))
    fd_K = np.array([(grad(y0 + h * e) - grad(y0 - h * e)) / (2 * h)
                     for e in np.eye(y0.size)])
    np.testing.assert_allclose(K, fd_K, atol=1e-5 * np.abs(fd_K).max())


@pytest.mark.parametrize("law", ["cg", "ipip"])
@pytest.mark.parametrize("dy", [-0.2, -0.25, -0.35])  # touching, penetrating, deep
def test_no_nan_at_zero_or_negative_gap(law, dy):
    model, problem, x = _two_beams(law, dy=dy)
    cs, _ = problem.grown_set(x, 0.05, 8)
    r, K = contact_residual_tangent(x, FrozenContact(problem.elements, cs), model.n_dof)
    e = contact_energy(x, problem.elements, cs)
    assert np.isfinite(float(e)) and np.all(np.isfinite(r)) and np.all(np.isfinite(K))
    assert float(jnp.min(block_gaps(x, problem.elements, cs.pairs))) <= 0.0 + 1e-12 or dy > -0.2


# --- broad phase against brute force ------------------------------------------------------

def _random_beams(rng, n_beams, spread):
    """Straight beams of random position, direction, length and element count."""
    beams = []
    for k in range(n_beams):
        a = rng.uniform(0, spread, 2)
        b = a + rng.uniform(-2, 2, 2)
        beams.append(beam(f"b{k}", line=(a.tolist(), b.tolist()), degree=3,
                          elements=int(rng.integers(1, 7)), radius=0.05))
    return beams


def _brute_force_pairs(x, ce, margin):
    """The candidates by plain loops over every pair of elements: boxes of the control
    points grown by margin overlap, and the pair may interact (different beams allowed
    to touch; one beam: different elements with two points at least the exclusion
    length apart along it)."""
    conn, valid, beam_of = map(np.asarray, (ce.conn, ce.loc_valid, ce.beam))
    allowed, s, excl = np.asarray(ce.allowed), np.asarray(ce.s), float(ce.exclusion)
    found = []
    E = len(beam_of)
    for i in range(E):
        for j in range(i + 1, E):
            bi, bj = beam_of[i], beam_of[j]
            if not allowed[bi, bj]:
                continue
            if bi == bj and np.max(np.abs(s[i][:, None] - s[j][None])) < excl:
                continue
            pi, pj = x[conn[i][valid[i]]], x[conn[j][valid[j]]]
            if np.all(pi.min(0) - margin <= pj.max(0) + margin) and np.all(
                    pj.min(0) - margin <= pi.max(0) + margin):
                found.append((i, j))
    return found


@pytest.mark.parametrize("seed, n_beams, spread, self_contact",
                         [(7, 4, 3.0, False), (8, 12, 4.0, False), (9, 30, 6.0, True),
                          (10, 40, 2.0, True), (11, 30, 3.0, False)])
def test_broad_phase_equals_brute_force(seed, n_beams, spread, self_contact):
    """The grid search finds exactly the pairs of the all-pairs box test, in the same
    (e1, e2) order, on random configurations (dense ones overflow the first cell
    capacity and grow it); so does the all-pairs path of small models."""
    from beamcontact.contact.broadphase import (
        ALL_PAIRS_LIMIT,
        SearchCapacity,
        all_candidates,
        all_pair_candidates,
        grid_candidates,
    )

    rng = np.random.default_rng(seed)
    case = parse_case({"analysis": {"kind": "static"},
                       "beams": _random_beams(rng, n_beams, spread),
                       "contact": {"model": "cg", "cutoff": 0.4, "segments_per_element": 6,
                                   "self_contact": self_contact}})
    model, disc = build_model(case)
    ce = build_contact(case, disc).elements
    x = np.asarray(model.x_ref) + rng.normal(0.0, 0.05, model.x_ref.shape)  # bent beams
    margin = 0.2
    brute = _brute_force_pairs(x, ce, margin)
    assert len(brute) > 0
    # the host check's list: all pairs up to ALL_PAIRS_LIMIT elements, its grid above
    assert n_beams < 30 or ce.n_elements > ALL_PAIRS_LIMIT
    assert [tuple(p) for p in all_candidates(x, ce, margin)] == brute
    roomy = SearchCapacity(len(brute) + 5, 512)
    for search in (grid_candidates, all_pair_candidates):
        pairs, count, _ = jax.jit(search, static_argnums=3)(jnp.asarray(x), ce, margin, roomy)
        assert int(count) == len(brute)
        assert [tuple(p) for p in np.asarray(pairs)[: len(brute)]] == brute
        assert np.all(np.asarray(pairs)[len(brute):] == ce.n_elements)
    # with capacities too small the count and the load say so
    pairs, count, load = jax.jit(grid_candidates, static_argnums=3)(
        jnp.asarray(x), ce, margin, SearchCapacity(4, 1))
    assert int(count) > 4 or int(load) > 1
    # every pair of contact points closer than 2 margin that may interact lies in a
    # candidate block
    conn, beam_of = np.asarray(ce.conn), np.asarray(ce.beam)
    pts = np.einsum("esk,ekd->esd", np.asarray(ce.R), x[conn])
    mask = np.asarray(ce.point_mask(*np.triu_indices(len(beam_of), 1)))
    i, j = np.triu_indices(len(beam_of), 1)
    d = np.linalg.norm(pts[i][:, :, None] - pts[j][:, None], axis=-1)
    close = np.any((d < 2 * margin) & mask, axis=(1, 2))
    assert set(zip(i[close], j[close], strict=True)) <= set(brute)
    lo, hi = element_boxes(jnp.asarray(x), ce, 0.0)
    assert np.all(np.asarray(lo) <= pts.min(axis=1) + 1e-12)  # convex hull property
    assert np.all(np.asarray(hi) >= pts.max(axis=1) - 1e-12)


def test_ipip_plateau_takes_the_middle_pairs():
    """Straight parallel beams: one contact zone; an even plateau gives its two middle
    pairs with weight 1/2 each (symmetric), an odd one its middle pair."""
    for n_upper, expected in ((4, [(0.5, 0.5)]), (5, [(1.0,)])):
        # plateau along the diagonal of a 1 x 1 block pair, n_upper points on the valley
        ns = n_upper
        q = np.full((1, ns, ns), 1.0)
        q[0, np.arange(ns), np.arange(ns)] = -0.01
        W = closest_pair_weights(q, np.array([[0, 1]]), np.array([0, 1]), np.array([0, 0]),
                                 q_active=0.1)
        weights = W[0][W[0] > 0]
        assert sorted(weights) == sorted(expected[0])
        idx = np.argwhere(W[0] > 0)
        assert np.all(idx[:, 0] == idx[:, 1])
        mid = (ns - 1) / 2
        assert np.isclose(np.mean(idx[:, 0]), mid)


def _pairing_energy(q, pairing, blocks=((0, 1),), n_elements=(1, 1)):
    """sum W eps q^2 / 2 (eps = 2) of the selection on gaps q (one block per entry of
    ``blocks``, elements numbered per beam)."""
    pairs = np.array(blocks)
    beam_of = np.array([0] * n_elements[0] + [1] * n_elements[1])
    local = np.array(list(range(n_elements[0])) + list(range(n_elements[1])))
    W = closest_pair_weights(q, pairs, beam_of, local, q_active=0.1, pairing=pairing)
    return np.sum(W * np.minimum(q, 0.0) ** 2), W


def test_ipip_points_pairs_every_point_with_its_closest():
    """pairing = "points": each row (a point of beam 1) and each column (beam 2) gives
    weight 1/2 to its closest cell, a tie shared; the energy is the independent sum
    1/2 sum_i Pi(min_j q_ij) + 1/2 sum_j Pi(min_i q_ij), over two blocks of one beam
    pair (the grid is assembled across element boundaries)."""
    rng = np.random.default_rng(3)
    q = rng.uniform(-0.05, 0.2, size=(2, 5, 5))
    energy, W = _pairing_energy(q, "points", blocks=((0, 2), (1, 2)), n_elements=(2, 1))
    grid = np.concatenate([q[0], q[1]], axis=0)  # beam 1 points (10) x beam 2 points (5)
    pen = lambda g: np.minimum(g, 0.0) ** 2  # noqa: E731
    expected = 0.5 * (np.sum(pen(grid.min(axis=1)) * (grid.min(axis=1) < 0.1))
                      + np.sum(pen(grid.min(axis=0)) * (grid.min(axis=0) < 0.1)))
    assert energy == pytest.approx(expected, rel=1e-14)
    Wg = np.concatenate([W[0], W[1]], axis=0)
    active_rows = grid.min(axis=1) < 0.1
    active_cols = grid.min(axis=0) < 0.1
    assert np.sum(Wg) == pytest.approx(0.5 * (active_rows.sum() + active_cols.sum()))
    # a tie: two equally close partners share the row's half
    q_tie = np.full((1, 3, 3), 1.0)
    q_tie[0, 1, 0] = q_tie[0, 1, 2] = -0.01
    _, W = _pairing_energy(q_tie, "points")
    assert W[0, 1, 0] == W[0, 1, 2] == pytest.approx(0.25 + 0.5)


def test_ipip_points_weights_on_the_device_equal_the_host_rule():
    """The device's "points" selection (segment minima) gives the host grid rule's
    weights exactly, with three beams (two grids per point of the middle beam), ties and
    padding blocks."""
    from types import SimpleNamespace

    from beamcontact.contact.select import point_weights_on_device

    rng = np.random.default_rng(7)
    beam_of = np.array([0, 0, 1, 1, 1, 2, 2])
    local = np.array([0, 1, 0, 1, 2, 0, 1])
    pairs = np.array([[0, 2], [0, 3], [1, 3], [1, 4], [2, 5], [3, 5], [4, 6], [0, 6],
                      [7, 7], [7, 7]])
    q = np.round(rng.uniform(-0.05, 0.3, size=(len(pairs), 4, 4)), 2)  # with ties
    q[pairs[:, 0] >= 7] = np.inf
    host = closest_pair_weights(q, pairs, beam_of, local, q_active=0.2, pairing="points")
    ce = SimpleNamespace(n_elements=7, n_beams=3, beam=jnp.asarray(beam_of))
    device = point_weights_on_device(jnp.asarray(q), jnp.asarray(pairs), ce, 0.2)
    np.testing.assert_array_equal(np.asarray(device), host)
    assert np.sum(host) > 0 and np.any((host > 0) & (host < 0.5))  # ties were shared


def test_ipip_points_energy_is_continuous_where_zones_jumps():
    """Along a path of gap fields on which a second contact zone appears while the beams
    overlap, the paper's "zones" energy jumps by the new zone's eps q^2 / 2 however finely
    the path is sampled; the largest change of the "points" energy between samples
    shrinks in proportion to the sampling step (continuous: a set change does no work)."""
    i = np.arange(9)
    diagonal = i[:, None] == i[None, :]
    valley = -0.02 + 0.1 * (i[:, None] - i[None, :]) ** 2  # point i faces point i
    slope = 0.02 * np.abs(i - 4.0) / 4.0  # one zone in the middle ...
    dip = np.exp(-((i - 6.0) / 1.2) ** 2)  # ... and a second one that appears at 6

    def largest_change(rule, samples):
        e = [_pairing_energy((valley + diagonal * (-slope + 0.01 * (1 - 2 * tau) * dip)
                              [:, None])[None], rule)[0]
             for tau in np.linspace(0.0, 1.0, samples)]
        return np.max(np.abs(np.diff(e)))

    coarse = {rule: largest_change(rule, 201) for rule in ("zones", "points")}
    fine = {rule: largest_change(rule, 1601) for rule in ("zones", "points")}
    assert fine["zones"] > 1e-5 and fine["zones"] > 0.9 * coarse["zones"]  # a jump
    assert fine["points"] == pytest.approx(coarse["points"] / 8, rel=0.05)  # continuous


# --- statics: IPIP closed form -----------------------------------------------------------

@pytest.mark.parametrize("engine", ["native", "jax"])
def test_ipip_static_reaction_and_penetration(engine):
    """A stiff straight beam pinned at its left end rests with its middle on the apex of a
    stiff clamped arc; a force F at that middle point: moment equilibrium about the pin
    gives the contact reaction F, hence a penetration F / eps."""
    R, eps, F = 0.05, 1.0e6, 800.0
    Rc, half = 5.0, 0.2
    arc = {"center": [0.0, -Rc], "radius": Rc, "start_angle": np.pi / 2 - half,
           "end_angle": np.pi / 2 + half}
    h = 2 * R - 1e-7  # a hair of initial overlap so the contact stiffness is there at once
    raw = {"analysis": {"kind": "static", "load_steps": 2},
           "beams": [{**beam("arc", degree=4, elements=1, radius=R, E=1e15,
                             supports=[{"at": "start", "type": "clamped"},
                                       {"at": "end", "type": "clamped"}]), "arc": arc},
                     beam("bar", line=([-1.0, h], [1.0, h]), degree=4, elements=1, radius=R,
                          E=1e15, supports=[{"at": "start", "type": "pinned"}])],
           "loads": [{"beam": "bar", "at": 0.5, "force": [0.0, -F]}],
           "contact": {"model": "ipip", "penalty": eps, "segments_per_element": 21}}
    case = parse_case(raw)
    model, disc = build_model(case)
    contact = build_contact(case, disc)
    steps = []
    statics = {"native": NativeStatics, "jax": JaxStatics}[engine]
    res = solve_static(statics(model, contact, NewtonOptions(), disc.length_scale), 2,
                       on_step=steps.append)
    assert res.status == "completed", res.message
    last = steps[-1].energies
    np.testing.assert_allclose(last["min_gap"], -F / eps, rtol=1e-4)
    np.testing.assert_allclose(last["E_contact"], F**2 / (2 * eps), rtol=2e-4)


# --- dynamics: collisions ----------------------------------------------------------------

def _collision_case(law, swap=False, q_reg=None):
    lower = beam("lower", line=([0.0, 0.0], [2.0, 0.0]), degree=4, elements=4, radius=0.05,
                 E=1e7, density=1000.0, continuity=1)
    upper = {**beam("upper", line=([0.6, 0.16], [1.6, 0.22]), degree=4, elements=2,
                    radius=0.05, E=1e7, density=1000.0, continuity=1),
             "initial_velocity": [0.3, -2.0]}
    beams = [upper, lower] if swap else [lower, upper]
    return parse_case({"analysis": {"kind": "dynamic", "t_end": 0.08, "dt": 1e-3,
                                    "alpha": -0.1},
                       "beams": beams,
                       "contact": {"model": law, "segments_per_element": 10,
                                   "penalty": 1e5, "cutoff": 0.15, "k": 1e-22,
                                   **({"q_reg": q_reg} if q_reg else {})}})


def _run_collision(case, capacity=8):
    model, disc = build_model(case)
    contact = build_contact(case, disc)
    v0 = jnp.asarray(uniform_velocities(disc, [b.initial_velocity for b in case.beams]))
    cs0, _ = contact.grown_set(model.x_ref, 0.0, capacity)
    s0 = initial_state(jnp.zeros(model.n_dof), v0, model, initial_load_state(model),
                       FrozenContact(contact.elements, cs0))
    rows = []
    engine = JaxEngine(model, contact, case.analysis.alpha, NewtonOptions(rtol=1e-11),
                       disc.length_scale, case.analysis.dt)
    res = solve_dynamic(engine, s0, case.analysis.t_end, disc.length_scale,
                        step_control(case), capacity=capacity, on_step=lambda s: rows.append(
                            (s.t, np.asarray(s.state.u), s.diagnostics)))
    assert res.status == "completed", res.message
    return model, disc, rows


@pytest.mark.parametrize("law", ["cg", "ipip"])
def test_free_collision_conserves_linear_momentum(law):
    model, disc, rows = _run_collision(_collision_case(law))
    m_upper = 1000.0 * np.pi * 0.05**2 * np.hypot(1.0, 0.06)
    p0 = m_upper * np.array([0.3, -2.0])
    gaps = np.array([d["min_gap"] for _, _, d in rows])
    assert gaps.min() < 0.01  # they did collide
    assert max(d["E_contact"] for _, _, d in rows) > 0
    for _, _, d in rows:
        np.testing.assert_allclose([d["p_x"], d["p_y"]], p0, atol=1e-8 * np.linalg.norm(p0))
    # the lower beam was set in motion: momentum went across the contact
    lower_p = rows[-1][2]
    assert lower_p is not None


@pytest.mark.parametrize("law", ["cg", "ipip"])
def test_swapping_beam_order_gives_the_same_motion(law):
    """Same motion to round-off. The coarse-grained case uses a larger q_reg so that no
    step is cut (a cut-back decided by round-off would change the step sequence)."""
    m1, d1, rows1 = _run_collision(_collision_case(law, q_reg=2e-3))
    m2, d2, rows2 = _run_collision(_collision_case(law, swap=True, q_reg=2e-3))
    assert len(rows1) == len(rows2)
    for (_, u1, _), (_, u2, _) in zip(rows1, rows2, strict=True):
        for name in ("lower", "upper"):
            for f in (0.0, 0.5, 1.0):
                p1 = _point(m1, d1, u1, name, f)
                p2 = _point(m2, d2, u2, name, f)
                np.testing.assert_allclose(p1, p2, atol=1e-9)


@pytest.mark.parametrize("law", ["cg", "ipip"])
def test_capacity_changes_the_cost_not_the_motion(law):
    """A candidate list of 2 blocks (grown on overflow, one chunk) and one of 64 (eight
    chunks of 8, most skipped as empty) give the same steps and motion to round-off."""
    case = _collision_case(law, q_reg=2e-3)
    _, _, small = _run_collision(case, capacity=2)
    _, _, large = _run_collision(case, capacity=64)
    assert [t for t, _, _ in small] == [t for t, _, _ in large]
    for (_, u1, d1), (_, u2, d2) in zip(small, large, strict=True):
        np.testing.assert_allclose(u1, u2, rtol=0, atol=1e-12)
        assert abs(d1["E_contact"] - d2["E_contact"]) <= 1e-9 * max(abs(d1["E_contact"]), 1)


def _point(model, disc, u, name, f):
    idx, R = point_sampler(disc, name, f)
    return R @ (np.asarray(model.x_ref) + u.reshape(-1, 2))[idx]


def test_weights_of_cg_blocks_are_reference_arc_lengths():
    model, problem, x = _two_beams("cg")
    ce = problem.elements
    w = np.asarray(ce.w)
    # every beam's weights add up to its length
    lengths = [np.sum(w[np.asarray(ce.beam) == b]) for b in range(2)]
    np.testing.assert_allclose(lengths, [2.0, np.hypot(1.2, 0.15)], rtol=1e-12)
    pairs = jnp.asarray([[0, 4], [ce.n_elements, ce.n_elements]])
    W = np.asarray(arc_length_weights(ce, pairs))
    np.testing.assert_allclose(W[0], np.outer(w[0], w[4]))
    assert np.all(W[1] == 0)


# --- contact.pairs: which beams interact ---------------------------------------------------

@pytest.mark.parametrize("law", ["cg", "ipip"])
def test_listed_pairs_only_interact(law):
    """contact.pairs = [["a", "b"]]: a third beam c lying across both adds nothing. The
    broad phase considers only element pairs of a and b, and the contact energy and
    force equal those of the model without c (an independent two-beam computation)."""
    a = beam("a", line=([0, 0], [2, 0]), degree=4, elements=4, radius=0.1)
    b = beam("b", line=([0.5, 0.3], [1.7, 0.15]), degree=3, elements=3, radius=0.1)
    c = beam("c", line=([1.0, -0.5], [1.1, 0.8]), degree=3, elements=2, radius=0.1)
    contact = {"model": law, "segments_per_element": 5, "q_reg": 0.02}

    def setup(beams, **extra):
        case = parse_case({"analysis": {"kind": "static"}, "beams": beams,
                           "contact": {**contact, **extra}})
        model, disc = build_model(case)
        problem = build_contact(case, disc)
        x = np.asarray(model.x_ref).copy()
        x[disc.beam("b").offset:disc.beam("b").offset + disc.beam("b").n_cp, 1] -= 0.19
        return model, disc, problem, jnp.asarray(x)

    model3, disc3, p3, x3 = setup([a, b, c], pairs=[["b", "a"]])
    model2, disc2, p2, x2 = setup([a, b])
    allowed = np.asarray(p3.elements.allowed)
    assert np.array_equal(allowed, [[0, 1, 0], [1, 0, 0], [0, 0, 0]])
    assert p3.elements.element_pair_count() == 4 * 3

    def energy_and_force(model, problem, x):
        cs, _ = problem.grown_set(x, 0.0, 64)
        e = contact_energy(x, problem.elements, cs)
        r, _ = contact_residual_tangent(x, FrozenContact(problem.elements, cs), model.n_dof)
        return float(e), np.asarray(r)

    e3, r3 = energy_and_force(model3, p3, x3)
    e2, r2 = energy_and_force(model2, p2, x2)
    assert e2 > 0
    np.testing.assert_allclose(e3, e2, rtol=1e-13)
    n2 = model2.n_dof
    np.testing.assert_allclose(r3[:n2], r2, rtol=0, atol=1e-13 * np.abs(r2).max())
    assert np.all(r3[n2:] == 0.0)
    # energies add up by pair of beams: all pairs = (a, b) + the two pairs with c
    e_all = energy_and_force(*setup([a, b, c])[::2], setup([a, b, c])[3])[0]
    e_c = energy_and_force(*setup([a, b, c], pairs=[["a", "c"], ["c", "b"]])[::2],
                           setup([a, b, c])[3])[0]
    assert e_c > 0
    np.testing.assert_allclose(e_all, e3 + e_c, rtol=1e-12)


@pytest.mark.parametrize("pairs, message", [
    ([["a", "z"]], "contact.pairs[0]: unknown beam 'z'"),
    ([["a", "a"]], "contact.pairs[0]: list pairs of different beams; for a beam touching "
                   "itself set contact.self_contact = true"),
    ([["a", "b"], ["b", "a"]], "contact.pairs[1]: the pair ['b', 'a'] is listed twice"),
    ([], "contact.pairs"),
    ([["a"]], "contact.pairs[0]"),
])
def test_bad_contact_pairs_are_named(pairs, message):
    raw = {"analysis": {"kind": "static"},
           "beams": [beam("a", line=([0, 0], [1, 0])), beam("b", line=([0, 1], [1, 1]))],
           "contact": {"model": "cg", "pairs": pairs}}
    with pytest.raises(CaseError) as err:
        parse_case(raw)
    assert message in str(err.value)
