"""Native (Numba) contact kernels against JAX AD of the JAX laws and blocks.

The JAX energies are the definition (contact/laws, contact/blocks.py,
contact/obstacles.py); the native kernels are closed-form derivatives of the same
energies. Tolerance 1e-12 relative: both sides evaluate the same formulas in float64 with
different operation orders and different exp/log implementations (XLA's vs libm's), whose
rounding differences, amplified by the exponent of q^(7/2-m) (|n log q| up to ~60 here) and by the
sums over a block, stay near 1e-14; anything of 1e-12 or more is a wrong formula, not
rounding. Block results are compared relative to the largest entry of the JAX result,
since individual entries are sums of terms of both signs and may be near zero.
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from beamcontact.contact import blocks, obstacles
from beamcontact.contact import blocks_native as bn
from beamcontact.contact.blocks import ContactSet
from beamcontact.contact.laws import CoarseGrained, Penalty, cg_constant
from beamcontact.contact.laws import coarse_grained_native as cgn
from beamcontact.contact.laws import penalty_native as pn
from beamcontact.contact.laws.coarse_grained import cg_wall_constant
from beamcontact.contact.obstacles import obstacles_from
from beamcontact.contact.points import ContactElements
from beamcontact.spline import nurbs_basis_derivatives

jax.config.update("jax_enable_x64", True)

# the JAX paths under jit: compiled once per shape (the laws are data), where eager AD of
# the obstacle Hessian takes seconds per call
block_forces = jax.jit(blocks.block_forces)
contact_energy = jax.jit(blocks.contact_energy)
obstacle_forces = jax.jit(obstacles.obstacle_forces)
obstacle_energy = jax.jit(obstacles.obstacle_energy)

RTOL = 1e-12  # see the module docstring
R1, R2 = 0.01, 0.012
R12 = R1 + R2
Q_REG = 1e-3
CUTOFF = R12 + 0.02
K_M, BETA12 = 3.0e-20, 1.0e28


def _cg(m):
    return CoarseGrained(k=K_M, exponent=m, q_reg=Q_REG, cutoff=CUTOFF)


def _gaps(rng, q_reg, q_far):
    """Gaps q of every regime: near 0 on both sides, in the regularisation zone (below
    q_reg, negative), at and around q_reg, random up to q_far, and just below and above
    q_far (the cutoff's gap)."""
    special = [0.0, 1e-14, -1e-14, 1e-9, -1e-9, 0.5 * q_reg, -0.3 * q_reg, -2.0 * q_reg,
               q_reg, q_reg * (1 - 1e-9), q_reg * (1 + 1e-9),
               q_far * (1 - 1e-12), q_far * (1 - 1e-6), q_far, q_far * (1 + 1e-12),
               q_far * 1.5]
    return np.concatenate([special, rng.uniform(-q_reg, 1.2 * q_far, 40)])


def _jax_derivatives(energy, x):
    """(e, e', e'') of a scalar JAX energy at each entry of x, by AD, shape (len(x), 3)."""
    d1 = jax.grad(energy)
    d2 = jax.grad(d1)
    return np.stack([np.asarray(jax.vmap(g)(jnp.asarray(x))) for g in (energy, d1, d2)], 1)


def _native_derivatives(kernel, x, *args):
    return np.array([kernel(float(v), *args) for v in x])


def test_constants_match_jax():
    for m in (6.0, 8.0, 12.0, 20.0):
        assert cgn.cg_constant(m, R1, R2) == pytest.approx(
            float(cg_constant(m, R1, R2)), rel=RTOL)
        assert cgn.cg_wall_constant(m, R1) == pytest.approx(
            float(cg_wall_constant(m, R1)), rel=RTOL)


@pytest.mark.parametrize("m", [6.0, 12.0, 7.3])
def test_cg_pair_law_matches_jax_ad(m):
    """Phi, dPhi/dd, d2Phi/dd2 (eq. 9) and the s-derivatives f', f'' the blocks lift
    (m = 6, 12: the power by repeated squaring; 7.3: through exp and log)."""
    law = _cg(m)
    amp = float(law.amplitude(R1, R2, BETA12))
    d = R12 + _gaps(np.random.default_rng(1), Q_REG, CUTOFF - R12)
    want = _jax_derivatives(lambda d: law.pair_energy(d, R12, amp), d)
    got = _native_derivatives(cgn.cg_pair, d, R12, amp, m, Q_REG, CUTOFF)
    np.testing.assert_allclose(got, want, rtol=RTOL, atol=0.0)
    assert np.all(got[d >= CUTOFF] == 0.0) and np.all(got[d < CUTOFF, 1] < 0.0)
    s = np.r_[d * d, 0.0, 1e-301, 1e-299]  # and around the floor of s (coincident points)
    want = _jax_derivatives(lambda s: blocks._pair_law(law)(s, R12, amp), s)
    got = _native_derivatives(cgn.cg_pair_s, s, R12, amp, m, Q_REG, CUTOFF)
    np.testing.assert_allclose(got, want, rtol=RTOL, atol=0.0)


@pytest.mark.parametrize("m", [6.0, 12.0, 20.0, 7.3, 80.0])
def test_cg_pair_law_over_arrays_is_the_scalar_law(m):
    """cg_pair_s_many (the law pass by pass, for SIMD) gives bitwise the numbers of
    cg_pair_s in every regime: whole and half exponents by repeated squaring (6, 12, 20),
    through exp and log (7.3; 80: 2 n above 64), the regularisation zone, the cutoff and
    the floor of s. The JAX comparison of cg_pair_s above then covers both."""
    amp = float(_cg(m).amplitude(R1, R2, BETA12))
    d = R12 + _gaps(np.random.default_rng(5), Q_REG, CUTOFF - R12)
    s = np.r_[d * d, 0.0, 1e-301, 1e-299, (R12 + Q_REG) ** 2, CUTOFF**2, R12**2]
    f, f1, f2 = (np.full(s.size + 3, 7.0) for _ in range(3))
    work = np.full((3, s.size + 3), np.nan)  # longer than count, stale: as in a block
    cgn.cg_pair_s_many(s, s.size, R12, amp, m, Q_REG, CUTOFF, f, f1, f2, *work)
    want = _native_derivatives(cgn.cg_pair_s, s, R12, amp, m, Q_REG, CUTOFF)
    assert np.array_equal(np.stack([f, f1, f2], 1)[:s.size], want)
    assert np.all(f[s.size:] == 7.0)  # nothing written past count


@pytest.mark.parametrize("m", [8.0, 12.0, 9.7])
def test_cg_obstacle_law_matches_jax_ad(m):
    """w Phi_w(q) of a point against a half-space and its q-derivatives, cut off at the
    gap cutoff - 2 R."""
    law, w = _cg(m), 0.0037
    amp = float(law.obstacle_amplitude(R1, BETA12))
    q = _gaps(np.random.default_rng(2), Q_REG, CUTOFF - 2.0 * R1)
    want = _jax_derivatives(lambda q: law.obstacle_energy(q, R1, amp, w), q)
    got = _native_derivatives(cgn.cg_obstacle, q, R1, amp, w, m, Q_REG, CUTOFF)
    np.testing.assert_allclose(got, want, rtol=RTOL, atol=0.0)
    assert np.count_nonzero(got[:, 0]) == np.count_nonzero(q < CUTOFF - 2.0 * R1)


def test_penalty_laws_match_jax_ad():
    """eps q^2 / 2 for q < 0 (eq. 3), of a pair (in d and in s) and of an obstacle point;
    at q = 0 exactly, Pi'' = eps / 4 from JAX's tie rule of minimum (asserted)."""
    law = Penalty(penalty=2.5e5, max_penetration=1e-3)
    eps = float(law.amplitude(R1, R2, BETA12))
    q = _gaps(np.random.default_rng(3), 0.3 * R12, 0.5 * R12)
    q = np.concatenate([q, -q])
    d = R12 + q
    want = _jax_derivatives(lambda d: law.pair_energy(d, R12, eps), d)
    np.testing.assert_allclose(_native_derivatives(pn.penalty_pair, d, R12, eps), want,
                               rtol=RTOL, atol=0.0)
    assert pn.penalty_pair(R12, R12, eps) == (0.0, 0.0, 0.25 * eps)
    s = np.r_[d * d, 0.0, 1e-301, 1e-299]
    want = _jax_derivatives(lambda s: blocks._pair_law(law)(s, R12, eps), s)
    np.testing.assert_allclose(_native_derivatives(pn.penalty_pair_s, s, R12, eps), want,
                               rtol=RTOL, atol=0.0)
    eps_o = float(law.obstacle_amplitude(R1, BETA12))
    want = _jax_derivatives(lambda q: law.obstacle_energy(q, R1, eps_o, 0.0037), q)
    np.testing.assert_allclose(_native_derivatives(pn.penalty_obstacle, q, eps_o), want,
                               rtol=RTOL, atol=0.0)


# --- blocks -------------------------------------------------------------------------------

DEGREE = 4
N_LOC = DEGREE + 1


def _element_rows(rng, n_s):
    """Basis rows (n_s, 5) at the segment middles of one rational quartic element (a
    Bezier span with random weights: the package's NURBS basis, eq. 40)."""
    knots = np.r_[np.zeros(N_LOC), np.ones(N_LOC)]
    weights = rng.uniform(0.7, 1.3, N_LOC)
    u = (np.arange(n_s) + 0.5) / n_s
    first, ders = nurbs_basis_derivatives(knots, DEGREE, weights, u)
    assert np.all(first == 0)
    return ders[:, 0]


def _elements(rng, n_s, radii=(R1, R2), betas=(1.0e14, 1.0e14)):
    """ContactElements of two quartic elements, one per beam (global dofs 0-4, 5-9)."""
    return ContactElements(
        conn=jnp.arange(2 * N_LOC).reshape(2, N_LOC), loc_valid=jnp.ones((2, N_LOC), bool),
        R=jnp.asarray(np.stack([_element_rows(rng, n_s), _element_rows(rng, n_s)])),
        w=jnp.asarray(rng.uniform(0.5, 1.5, (2, n_s)) * 0.1 / n_s),
        s=jnp.asarray(np.tile((np.arange(n_s) + 0.5) / n_s, (2, 1))),
        radius=jnp.asarray(radii), beta=jnp.asarray(betas), beam=jnp.array([0, 1]),
        allowed=jnp.asarray(~np.eye(2, dtype=bool)), exclusion=jnp.asarray(np.inf),
        n_beams=2)


def _control_points(rng, offset, tilt):
    """Two wavy quartic elements of length 0.1: one along y = 0, the other at height
    ``offset`` at its middle, tilted by ``tilt`` (so that their gaps span a range)."""
    t = np.linspace(0.0, 0.1, N_LOC)
    lower = np.c_[t, 0.0003 * rng.standard_normal(N_LOC)]
    upper = np.c_[t + 0.005 * rng.standard_normal(), offset + tilt * (t - 0.05)
                  + 0.0003 * rng.standard_normal(N_LOC)]
    return np.concatenate([lower, upper])


def _compare_block(x, ce, W, law, law_code, amp, m=0.0, q_reg=0.0, cutoff=0.0):
    """Native block vs blocks.block_forces / contact_energy; returns the largest relative
    difference (energy, gradient, Hessian), each relative to the JAX result's largest
    entry."""
    cs = ContactSet(jnp.array([[0, 1]]), None if W is None else jnp.asarray(W)[None], law)
    conn, f_jax, k_jax = (np.asarray(a)[0] for a in block_forces(jnp.asarray(x), ce, cs))
    e_jax = float(contact_energy(jnp.asarray(x), ce, cs))
    assert np.array_equal(conn, np.arange(2 * N_LOC))
    R = np.asarray(ce.R)
    W_native = (np.outer(np.asarray(ce.w)[0], np.asarray(ce.w)[1]) if W is None
                else np.asarray(W))
    args = (law_code, x[:N_LOC], x[N_LOC:], R[0], R[1], W_native,
            float(ce.radius[0] + ce.radius[1]), amp, m, q_reg, cutoff)
    e, f, k = bn.block_forces(*args)
    assert np.abs(k_jax).max() > 0.0 and np.array_equal(k, k.T)
    # the energy alone (the energy account's evaluations) is the same sum, bit for bit
    assert bn.block_energy(*args) == e
    return (abs(e - e_jax) / abs(e_jax), np.abs(f - f_jax).max() / np.abs(f_jax).max(),
            np.abs(k - k_jax).max() / np.abs(k_jax).max())


def _gap_spread(x, ce):
    """The gaps of all point pairs of the block (to check that a case covers its regimes)."""
    R = np.asarray(ce.R)
    p1, p2 = R[0] @ x[:N_LOC], R[1] @ x[N_LOC:]
    d = np.linalg.norm(p1[:, None] - p2[None], axis=-1)
    return d - float(ce.radius[0] + ce.radius[1])


@pytest.mark.parametrize("m", [6.0, 12.0])
@pytest.mark.parametrize("n_s,offset,tilt", [(7, R12 + 0.004, 0.2), (12, R12 + 0.0005, 0.1),
                                             (20, R12 + 0.01, 0.0)])
def test_cg_block_matches_jax(m, n_s, offset, tilt):
    """Arc-length weights w1_i w2_j (W None in the JAX set): pairs overlapping, in the
    regularisation zone, in the power law and beyond the cutoff."""
    rng = np.random.default_rng(n_s)
    ce = _elements(rng, n_s)
    x = _control_points(rng, offset, tilt)
    law = _cg(m)
    amp = float(law.amplitude(ce.radius[0], ce.radius[1], ce.beta[0] * ce.beta[1]))
    q = _gap_spread(x, ce)
    assert (q < CUTOFF - R12).any()
    errors = _compare_block(x, ce, None, law, bn.LAW_CG, amp, m, Q_REG, CUTOFF)
    assert max(errors) < RTOL, errors


def test_cg_block_regimes_are_covered():
    """The steep case of test_cg_block_matches_jax holds pairs of every regime."""
    rng = np.random.default_rng(12)
    ce = _elements(rng, 12)
    q = _gap_spread(_control_points(rng, R12 + 0.0005, 0.1), ce)
    assert (q < 0).any() and ((q > 0) & (q < Q_REG)).any()
    assert ((q > Q_REG) & (q < CUTOFF - R12)).any() and (q > CUTOFF - R12).any()


def test_cg_block_all_beyond_cutoff_is_zero():
    rng = np.random.default_rng(5)
    ce = _elements(rng, 8)
    x = _control_points(rng, CUTOFF + 0.01, 0.0)
    R = np.asarray(ce.R)
    e, f, k = bn.block_forces(bn.LAW_CG, x[:N_LOC], x[N_LOC:], R[0], R[1], np.ones((8, 8)),
                              R12, 1.0, 12.0, Q_REG, CUTOFF)
    assert e == 0.0 and not f.any() and not k.any()


@pytest.mark.parametrize("law_code", [bn.LAW_CG, bn.LAW_PENALTY])
@pytest.mark.parametrize("n_pairs", [0, 1, 7, bn.BLOCK_RUNS, bn.BLOCK_RUNS + 1, 41])
def test_blocks_of_a_set_are_each_block_alone(n_pairs, law_code):
    """blocks_into (the blocks shared out in runs over the cores, each run reusing one
    row of work arrays) gives each block's numbers as block_into gives them alone, bit
    for bit, and blocks_energy the same energies (block_energy alone is checked against
    block_into above): no stale work array leaks into the next block of a run, whatever
    the count of blocks against the count of runs."""
    rng = np.random.default_rng(n_pairs)
    n_el, n_s, m = 12, 9, 12.0
    conn = rng.permutation(n_el * N_LOC).reshape(n_el, N_LOC)
    R = np.stack([_element_rows(rng, n_s) for _ in range(n_el)])
    x = np.empty((n_el * N_LOC, 2))
    for e in range(n_el):  # small elements in a row: neighbours overlap, 6 apart are far
        x[conn[e]] = (0.015 * e, 0.0) + rng.uniform(0.0, 0.02, (N_LOC, 2))
    first = rng.integers(0, n_el, n_pairs)  # with a neighbour, or one far beyond the cutoff
    pairs = np.c_[first, (first + np.where(np.arange(n_pairs) % 2, 1, 6)) % n_el]
    W = rng.uniform(0.0, 1e-2, (n_pairs, n_s, n_s)) * (rng.random((n_pairs, n_s, n_s)) < 0.7)
    R12s = rng.uniform(0.8, 1.2, n_pairs) * R12
    amps = rng.uniform(0.5, 2.0, n_pairs) * (float(_cg(m).amplitude(R1, R2, BETA12))
                                             if law_code == bn.LAW_CG else 1e6)
    size = 4 * N_LOC
    F, K = np.full((n_pairs, size), np.nan), np.full((n_pairs, size, size), np.nan)
    energies, energies_only = np.full(n_pairs, np.nan), np.full(n_pairs, np.nan)
    ws = bn.blocks_scratch(conn, R, n_pairs)
    bn.blocks_into(x, conn, R, pairs, W, R12s, amps, law_code, m, Q_REG, CUTOFF, F, K,
                   energies, True, ws)
    bn.blocks_energy(x, conn, R, pairs, W, R12s, amps, law_code, m, Q_REG, CUTOFF,
                     energies_only, ws)
    assert np.array_equal(energies_only, energies)
    for p, (e1, e2) in enumerate(pairs):
        e, f, k = bn.block_forces(law_code, x[conn[e1]], x[conn[e2]], R[e1], R[e2], W[p],
                                  R12s[p], amps[p], m, Q_REG, CUTOFF)
        assert e == energies[p] and np.array_equal(f, F[p]) and np.array_equal(k, K[p])
    assert n_pairs < 7 or ((energies > 0.0).any() and (energies == 0.0).any())


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_ipip_block_matches_jax(seed):
    """Selection weights 1, 1/2 and 0 over crossing elements that overlap (eq. 3)."""
    rng = np.random.default_rng(100 + seed)
    n_s = 10
    ce = _elements(rng, n_s)
    x = _control_points(rng, R12 - 0.004, 0.15 * (seed - 1))
    W = rng.choice([0.0, 0.5, 1.0], size=(n_s, n_s), p=[0.6, 0.2, 0.2])
    q = _gap_spread(x, ce)
    assert ((W > 0) & (q < 0)).any() and ((W > 0) & (q > 0)).any()
    law = Penalty(penalty=1.0e6, max_penetration=1e-3)
    errors = _compare_block(x, ce, W, law, bn.LAW_PENALTY, law.penalty)
    assert max(errors) < RTOL, errors


def _jax_signed_distance(p, obs):
    """(s, ds/dx, ds/dy, d2s/dx2, d2s/dxdy, d2s/dy2) of obstacle 0 at p, by AD."""
    def s(p):
        return obstacles.signed_distance(p, obs)[0]

    p = jnp.asarray(p)
    g, H = jax.grad(s)(p), jax.hessian(s)(p)
    return np.array([s(p), g[0], g[1], H[0, 0], H[0, 1], H[1, 1]])


def test_signed_distance_matches_jax_ad():
    """s(p), its gradient and Hessian for a wall and a circle, at random points and at the
    circle's centre (the floor of |p - c|: no derivatives there, in both)."""
    rng = np.random.default_rng(11)
    wall = obstacles_from([((0.1, -0.2), (0.3, 1.0), 1.0)], [])
    circle = obstacles_from([], [((0.05, -0.08), 0.08, 1.0)])
    for obs in (wall, circle):
        centre = np.asarray(obs.point[0])
        args = (bool(obs.circle[0]), centre, np.asarray(obs.normal[0]), float(obs.radius[0]))
        for p in np.r_[centre[None] + rng.normal(0.0, 0.1, (20, 2)), centre[None]]:
            want = _jax_signed_distance(p, obs)
            got = np.array(bn.signed_distance(p[0], p[1], *args))
            assert np.abs(got - want).max() <= RTOL * np.abs(want).max(), (p, got, want)


def _compare_obstacle(x, ce, obs, law, law_code, amp, m=0.0, q_reg=0.0, cutoff=0.0):
    """Native element-obstacle kernel vs obstacles.obstacle_forces / obstacle_energy for
    element 0 (element 1 is placed far away); largest relative differences."""
    _, f_jax, k_jax = (np.asarray(a)[0] for a in obstacle_forces(jnp.asarray(x), ce, obs, law))
    R = np.asarray(ce.R)[0]
    w = np.asarray(ce.w)[0]
    e, f, k = bn.obstacle_forces(law_code, x[:N_LOC], R, w, float(ce.radius[0]),
                                 bool(obs.circle[0]), np.asarray(obs.point[0]),
                                 np.asarray(obs.normal[0]), float(obs.radius[0]), amp, m,
                                 q_reg, cutoff)
    e_jax = float(obstacle_energy(jnp.asarray(x), ce, obs, law))
    assert np.abs(k_jax).max() > 0.0
    return (abs(e - e_jax) / abs(e_jax), np.abs(f - f_jax).max() / np.abs(f_jax).max(),
            np.abs(k - k_jax).max() / np.abs(k_jax).max())


def _obstacle_cases():
    """(obstacles, control points of element 0): a tilted wall and a circle, the element
    placed at gaps about -0.001 + 3 t^2 (t in [0, 0.1] along it), so that its points span
    overlap, the regularisation zone, the power law and beyond the gap cutoff."""
    t = np.linspace(0.0, 0.1, N_LOC)
    q = -0.001 + 3.0 * t * t
    n = np.array([0.2, 1.0]) / np.hypot(0.2, 1.0)
    wall = obstacles_from([((0.0, 0.0), tuple(n), 1.0e14)], [])
    on_wall = np.c_[t, np.zeros(N_LOC)] - np.outer(np.c_[t, np.zeros(N_LOC)] @ n, n)
    circle = obstacles_from([], [((0.0, 0.0), 0.08, 2.0e14)])
    theta = 1.0 + t / 0.08
    return [(wall, on_wall + np.outer(R1 + q, n)),
            (circle, (0.08 + R1 + q)[:, None] * np.c_[np.cos(theta), np.sin(theta)])]


def _far_element(x0):
    return np.concatenate([x0, x0 + [0.0, 10.0]])


@pytest.mark.parametrize("m", [8.0, 12.0])
@pytest.mark.parametrize("case", [0, 1])
def test_cg_obstacle_matches_jax(m, case):
    obs, x0 = _obstacle_cases()[case]
    rng = np.random.default_rng(7)
    ce = _elements(rng, 15, radii=(R1, R1))
    law = _cg(m)
    amp = K_M * float(ce.beta[0] * obs.beta[0]) * cgn.cg_wall_constant(m, R1)
    assert amp == pytest.approx(float(law.obstacle_amplitude(R1, ce.beta[0] * obs.beta[0])),
                                rel=RTOL)
    errors = _compare_obstacle(_far_element(x0), ce, obs, law, bn.LAW_CG, amp, m, Q_REG, CUTOFF)
    assert max(errors) < RTOL, errors


@pytest.mark.parametrize("case", [0, 1])
def test_penalty_obstacle_matches_jax(case):
    obs, x0 = _obstacle_cases()[case]
    rng = np.random.default_rng(7)
    ce = _elements(rng, 15, radii=(R1, R1))
    law = Penalty(penalty=1.0e6, max_penetration=1e-3)
    errors = _compare_obstacle(_far_element(x0), ce, obs, law, bn.LAW_PENALTY, law.penalty)
    assert max(errors) < RTOL, errors


def test_obstacle_regimes_are_covered():
    """Both obstacle cases hold points overlapping, in the regularisation zone, in the
    power law and beyond the gap cutoff (the element rows of the obstacle tests)."""
    R = np.asarray(_elements(np.random.default_rng(7), 15).R)[0]
    for obs, x0 in _obstacle_cases():
        p = R @ x0
        rel = p - np.asarray(obs.point[0])
        s = (np.linalg.norm(rel, axis=1) - float(obs.radius[0]) if bool(obs.circle[0])
             else rel @ np.asarray(obs.normal[0]))
        q = s - R1
        assert (q < 0).any() and ((q > 0) & (q < Q_REG)).any()
        assert ((q > Q_REG) & (q < CUTOFF - 2 * R1)).any() and (q > CUTOFF - 2 * R1).any()
