"""The native contact set of a step (contact/step_set_native.py) against its JAX twins.

The JAX functions (broadphase.candidate_pairs, problem.near_candidates,
step_set.step_set for IPIP "points", advance.approach_ratio, problem.missed_blocks,
broadphase.box_gap_lower_bound, blocks.arc_length_weights) are the definition; they run
under jit with a list long enough for every element pair that may touch, so that their
real rows are the native lists. Cases: two beams of different degrees (padded local
control points), two parallel beams whose points face each other exactly or half a
spacing apart (ties: a point with two equally close partners), three beams (all pairs,
and only a listed pair), in configurations that cross, overlap, lie parallel or are far
apart, the same bent by a smooth random field, and a ring closing on itself
(self-contact: the exclusion masks part of the point pairs), for the coarse-grained law
and IPIP with pairing = "points".

Selections (lists, culling, IPIP weights, missed-block flags, counts) must be equal;
numbers (gaps, approach ratios) equal to 1e-12 relative. Both sides evaluate the same
expressions in float64; XLA contracts some a * b + c into fused multiply-adds (the
squared distances, the basis sums), which Numba without fastmath does not, so the gaps
differ in the last bits (measured: at most 7e-16, relative to the largest gap 5e-16),
and an approach ratio approach / (q + s) by eps d / (q + s) relative (measured 3e-13).
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from _builders import beam

from beamcontact.contact import blocks, broadphase, problem, step_set
from beamcontact.contact import step_set_native as ssn
from beamcontact.contact.advance import approach_ratio
from beamcontact.contact.broadphase import SearchCapacity
from beamcontact.io.case import parse_case
from beamcontact.setup.contact import build_contact
from beamcontact.setup.model import build_model

RTOL = 1e-12  # see the module docstring
MOTION = 0.02

jax_candidates = jax.jit(broadphase.candidate_pairs, static_argnames=("capacity",))
jax_near = jax.jit(problem.near_candidates, static_argnames=("capacity",))
jax_gaps = jax.jit(problem.candidate_gaps, static_argnames=("capacity",))
jax_step_set = jax.jit(step_set.step_set, static_argnames=("capacity",))
jax_missed = jax.jit(problem.missed_blocks, static_argnames=("capacity",))
jax_bound = jax.jit(broadphase.box_gap_lower_bound)
jax_weights = jax.jit(blocks.arc_length_weights)
jax_near_blocks = jax.jit(blocks.near_blocks)


@jax.jit
def jax_predictor_ratio(x0, v, a, h, ce, pairs, slack):
    """The ratio of step_set.advanced_step: the predictor's h v and h^2 a / 2."""
    return approach_ratio(x0, (h * v, 0.5 * h * h * a), ce, pairs, slack)


@jax.jit
def jax_step_ratio(x0, x_new, ce, pairs, slack):
    """The approach of step_set.after_step: the actual displacement."""
    return approach_ratio(x0, (x_new - x0,), ce, pairs, slack)


def _contact(law):
    return ({"model": "cg", "segments_per_element": 6} if law == "cg" else
            {"model": "ipip", "pairing": "points", "segments_per_element": 10,
             "penalty": 1e5})


def _setup(beams, law, **contact):
    """(problem, native elements, reference control points, beam offsets by name)."""
    case = parse_case({"analysis": {"kind": "static"}, "beams": beams,
                       "contact": {**_contact(law), **contact}})
    model, disc = build_model(case)
    cp = build_contact(case, disc)
    spans = {b.name: slice(info.offset, info.offset + info.n_cp)
             for b, info in zip(case.beams, disc.beams, strict=True)}
    return cp, ssn.native_contact_elements(cp.elements), np.asarray(model.x_ref), spans


def _two_beams(law):
    """Degree 4 (5 control points) and degree 3 (4, padded to 5): the second beam falls
    from 0.3 (left end) and 0.15 (right end) above the first."""
    return _setup([beam("a", line=([0, 0], [2, 0]), degree=4, elements=4, radius=0.1),
                   beam("b", line=([0.5, 0.3], [1.7, 0.15]), degree=3, elements=3,
                        radius=0.1)], law)


def _parallel(law, start):
    """Two straight parallel beams with points 0.05 apart along both; the upper one
    starting at ``start``: 0.5 puts its points right above the lower one's, 0.525 half a
    spacing off (every point has two equally close partners)."""
    return _setup([beam("lower", line=([0, 0], [2, 0]), degree=4, elements=4, radius=0.05),
                   beam("upper", line=([start, 0.0], [start + 1.0, 0.0]), degree=4,
                        elements=2, radius=0.05)],
                  law, segments_per_element=10)


def _three_beams(law, **contact):
    """The two beams above and a third lying across both."""
    return _setup([beam("a", line=([0, 0], [2, 0]), degree=4, elements=4, radius=0.1),
                   beam("b", line=([0.5, 0.3], [1.7, 0.15]), degree=3, elements=3,
                        radius=0.1),
                   beam("c", line=([1.0, -0.5], [1.1, 0.8]), degree=3, elements=2,
                        radius=0.1)], law, **contact)


def _ring(law):
    """Self-contact (beyond the brief of the native engine, but the same formulas): one
    beam along a circle of radius 0.1 leaving out 0.3 rad, so that its ends face each
    other across a chord of 0.03 (tests/test_self_contact.py); neighbours along the beam
    are candidates whose point pairs are partly masked by the exclusion."""
    arc = {"center": [0.0, 0.0], "radius": 0.1, "start_angle": 0.0,
           "end_angle": 2 * np.pi - 0.3}
    extra = {"cutoff": 0.03} if law == "cg" else {}
    return _setup([beam("ring", arc=arc, degree=3, elements=24, radius=0.01)], law,
                  self_contact=True, segments_per_element=4, **extra)


def _bent(x, seed, amplitude=0.01):
    """x bent by a smooth random field (a generic, curved configuration)."""
    rng = np.random.default_rng(seed)
    k = rng.normal(size=(3, 2))
    return x + amplitude * np.stack([np.sin(k[0, d] * x[:, 0] + k[1, d] * x[:, 1] + k[2, d])
                                     for d in range(2)], axis=1)


def _moved(x, spans, name, dy):
    x = x.copy()
    x[spans[name], 1] += dy
    return x


def _configurations():
    """(id, builder, list of configurations) per law: crossing, overlapping, near,
    parallel with and without ties, far apart, bent."""
    cases = []
    for law in ("cg", "ipip"):
        cp, ne, x, spans = _two_beams(law)
        cases += [(f"{law}-two-{dy}", cp, ne, _moved(x, spans, "b", dy))
                  for dy in (-0.19, -0.12, -0.02, 0.08, 2.0)]
        cases.append((f"{law}-two-bent", cp, ne, _bent(_moved(x, spans, "b", -0.15), 1)))
        for start in (0.5, 0.525):
            cp, ne, x, spans = _parallel(law, start)
            cases += [(f"{law}-parallel-{start}-{h}", cp, ne, _moved(x, spans, "upper", h))
                      for h in (0.095, 0.1, 0.104, 0.13)]
        cp, ne, x, spans = _three_beams(law)
        cases += [(f"{law}-three", cp, ne, _moved(x, spans, "b", -0.19)),
                  (f"{law}-three-bent", cp, ne, _bent(_moved(x, spans, "b", -0.19), 2, 0.02))]
        cp, ne, x, spans = _three_beams(law, pairs=[["b", "a"]])
        cases.append((f"{law}-three-listed", cp, ne, _moved(x, spans, "b", -0.19)))
        cp, ne, x, _ = _ring(law)
        cases += [(f"{law}-ring", cp, ne, x), (f"{law}-ring-bent", cp, ne, _bent(x, 5, 0.005))]
    return cases


# the self-contact ring goes beyond what the native engine runs today (no self-contact): a
# long study, kept for `pytest -m slow`
CASES = [pytest.param(*c, id=c[0], marks=[pytest.mark.slow] if "ring" in c[0] else [])
         for c in _configurations()]


def _capacity(cp):
    return SearchCapacity(cp.all_pairs, 16)


def _real(pairs, n_elements):
    """The real rows of a JAX list (writable int64), checked to come first."""
    pairs = np.array(pairs, dtype=np.int64)
    real = pairs[:, 0] < n_elements
    n = int(real.sum())
    assert np.all(real[:n]) and np.all(pairs[n:] == n_elements)  # then only the sentinel
    return pairs[:n]


def _padded(pairs, cp):
    """A JAX list of the real rows ``pairs`` and sentinel rows, of one length per model (one
    compile per model)."""
    E = cp.elements.n_elements
    out = np.full((cp.all_pairs + 4, 2), E, dtype=np.int64)
    out[: pairs.shape[0]] = pairs
    return out


def _rel(a, b):
    """Largest |a - b| relative to max(|b|) (0 for two empty arrays)."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    assert a.shape == b.shape
    finite = np.isfinite(b)
    np.testing.assert_array_equal(np.isfinite(a), finite)
    np.testing.assert_array_equal(a[~finite], b[~finite])
    if not finite.any():
        return 0.0
    return float(np.max(np.abs(a[finite] - b[finite])) / max(np.max(np.abs(b[finite])),
                                                             1e-300))


@pytest.mark.parametrize(("name", "cp", "ne", "x"), CASES)
def test_candidates_boxes_and_arc_length_weights(name, cp, ne, x):
    """The same element pairs in the same (e1, e2) order, for several margins; the boxes
    and the lower bound of the gap bitwise; W = w1 w2 of every candidate bitwise."""
    ce, xj = cp.elements, jnp.asarray(x)
    found = 0
    for margin in (0.0, cp.reach, cp.reach + MOTION, 0.5):
        pairs, count, load = jax_candidates(xj, ce, jnp.asarray(margin), _capacity(cp))
        native = ssn.candidate_pairs(x, ne, margin)
        assert native.dtype == np.int64 and native.shape == (int(count), 2)
        np.testing.assert_array_equal(native, _real(pairs, ce.n_elements))
        assert int(load) == 0
        found += native.shape[0]
        lo, hi = broadphase.element_boxes(xj, ce, margin)
        nlo, nhi = ssn.element_boxes(x, ne, margin)
        np.testing.assert_array_equal(nlo, np.asarray(lo))
        np.testing.assert_array_equal(nhi, np.asarray(hi))
        assert ssn.box_gap_lower_bound(x, ne, margin) == float(jax_bound(xj, ce, margin))
        if native.shape[0]:
            W = jax_weights(ce, jnp.asarray(native))
            for c, (e1, e2) in enumerate(native):
                np.testing.assert_array_equal(ssn.arc_length_weights(ne, e1, e2),
                                              np.asarray(W[c]))
    if "2.0" not in name:
        assert found > 0  # the near configurations have candidates
    else:
        assert ssn.candidate_pairs(x, ne, 0.5).shape[0] == 0


@pytest.mark.parametrize(("name", "cp", "ne", "x"), CASES)
def test_step_set(name, cp, ne, x):
    """The frozen set of a step: coarse-grained, the candidates culled to the blocks within
    interaction + 2 motion (the same kept list); IPIP "points", the same gaps (1e-12), the
    same weights bit for bit, the same order (weighted blocks first)."""
    ce, xj = cp.elements, jnp.asarray(x)
    capacity = _capacity(cp)
    cs, count, _ = jax_step_set(xj, jnp.asarray(MOTION), cp.search, capacity)
    if cp.law.closest_pairs:
        pairs, q, count_q, _ = jax_gaps(xj, ce, jnp.asarray(cp.reach + MOTION), capacity)
        native_pairs = ssn.candidate_pairs(x, ne, cp.reach + MOTION)
        q = np.asarray(q)[: int(count_q)]
        assert _rel(ssn.block_gaps(x, ne, native_pairs), q) <= RTOL
        from_jax_gaps = ssn.point_weights(q, native_pairs, ne, 2.0 * MOTION)
        p, W, n = ssn.closest_points(x, ne, cp.reach, MOTION)
        assert n == int(count)
        np.testing.assert_array_equal(p, _real(cs.pairs, ce.n_elements))
        W_jax = np.asarray(cs.W)[: int(count)]
        np.testing.assert_array_equal(W, W_jax)
        # the weights from the JAX gaps too (the selection alone)
        order = [np.flatnonzero((native_pairs == row).all(1))[0] for row in p]
        np.testing.assert_array_equal(from_jax_gaps[order], W_jax)
        if "parallel-0.525" in name and "0.13" not in name:
            # ties: every point has two equally close partners, 1/4 each from its side, so
            # a cell gets 1/4 + 1/4, or 1/2 + 1/4 where the lower beam's point beyond the
            # upper's end takes the end point alone
            assert set(np.unique(W)) == {0.0, 0.5, 0.75}
        elif "ring" in name:
            # self-contact: neighbours along the beam are candidates with masked pairs
            assert np.isinf(q).any() and np.any(W > 0)
        elif "parallel-0.5-" in name and "0.13" not in name:
            # points face each other: no tie; inside the overlap both sides choose the same
            # pair (1), the lower beam's points beyond its ends the upper's end point (1/2)
            assert set(np.unique(W)) == {0.0, 0.5, 1.0}
    else:
        p, n = ssn.near_candidates(x, ne, cp.reach, cp.interaction, MOTION)
        near, box_count, _ = jax_near(xj, ce, cp.reach, cp.interaction, MOTION, capacity)
        assert n == int(count) == int(box_count)
        np.testing.assert_array_equal(p, _real(cs.pairs, ce.n_elements))
        np.testing.assert_array_equal(p, _real(near, ce.n_elements))
        # near_blocks alone, at limits that cull more (the wide candidates: some far blocks)
        wide = ssn.candidate_pairs(x, ne, 0.5)
        for limit in (0.21, 0.3, 0.5):
            culled = jax_near_blocks(xj, ce, jnp.asarray(_padded(wide, cp)), limit)
            kept = ssn.near_blocks(x, ne, wide, limit)
            np.testing.assert_array_equal(kept, _real(culled, ce.n_elements))
        if "2.0" not in name:
            assert 0 < p.shape[0] < n  # the step's culling kept some blocks, not all


@pytest.mark.parametrize(("name", "cp", "ne", "x"),
                         [c for c in CASES if c.values[0].startswith("ipip")])
def test_zone_weights_are_the_host_rule(name, cp, ne, x):
    """IPIP "zones" (the paper's rule: the middle of each plateau of local minima) chosen
    in compiled code: the same weights bit for bit as the host rule
    (select.closest_pair_weights) from the same gaps, at several activation gaps; the
    parallel beams give plateaus (a middle pair, or two with 1/2 each)."""
    from beamcontact.contact.select import closest_pair_weights

    pairs = ssn.candidate_pairs(x, ne, cp.reach + MOTION)
    q = ssn.block_gaps(x, ne, pairs)
    local = np.asarray(cp.local_element, dtype=np.int64)
    chosen = 0.0
    for q_active in (0.0, 2.0 * MOTION, 0.1):
        host = closest_pair_weights(q, pairs, cp.beam_of, local, q_active, pairing="zones")
        native = ssn.zone_weights(q, pairs, ne.beam, local, q_active)
        np.testing.assert_array_equal(native, host)
        chosen += native.sum()
    if "2.0" not in name:
        assert chosen > 0  # some zone was chosen
    if "parallel-0.525" in name and "0.13" not in name:
        assert 0.5 in native  # a plateau of an even number of cells


@pytest.mark.parametrize(("name", "cp", "ne", "x"), CASES)
def test_approach_ratios(name, cp, ne, x):
    """Conservative advancement over the frozen set: the predictor's (h v, h^2 a / 2) and
    the actual displacement, to 1e-12 relative, with motions that approach and recede."""
    ce, xj = cp.elements, jnp.asarray(x)
    cs, count, _ = jax_step_set(xj, jnp.asarray(MOTION), cp.search, _capacity(cp))
    pairs = _real(cs.pairs, ce.n_elements)
    # also the box candidates at a wide margin: many more pairs, some receding
    wide = ssn.candidate_pairs(x, ne, 0.5)
    slack = float(cp.law.advance_slack())
    rng = np.random.default_rng(len(name))
    ratios = []
    for blocks_ in (pairs, wide):
        padded = jnp.asarray(_padded(blocks_, cp))
        for _ in range(3):
            v = rng.normal(size=x.shape)
            a = 20.0 * rng.normal(size=x.shape)
            h = float(rng.uniform(1e-3, 1e-2))
            native = ssn.predictor_approach_ratio(x, v, a, h, ne, blocks_, slack)
            jax_value = float(jax_predictor_ratio(xj, jnp.asarray(v), jnp.asarray(a), h, ce,
                                                  padded, slack))
            assert native == pytest.approx(jax_value, rel=RTOL, abs=0.0)
            # the JAX padding rows may be passed as they are
            assert ssn.predictor_approach_ratio(x, v, a, h, ne, np.asarray(padded), slack) \
                == native
            x_new = x + h * v + 0.5 * h * h * a
            native = ssn.step_approach_ratio(x, x_new, ne, blocks_, slack)
            jax_value = float(jax_step_ratio(xj, jnp.asarray(x_new), ce, padded, slack))
            assert native == pytest.approx(jax_value, rel=RTOL, abs=0.0)
            ratios.append(native)
            # the general form: the two fields given directly
            fields = np.stack([h * v, 0.5 * h * h * a])
            assert ssn.approach_ratio(x, fields, ne, blocks_, slack) == pytest.approx(
                ssn.predictor_approach_ratio(x, v, a, h, ne, blocks_, slack), rel=RTOL)
    if "2.0" not in name:
        assert max(ratios) > 0.0
    else:
        assert max(ratios) == 0.0  # no pair at all


def _every_pair_ratio(x0, fields, ne, pairs, slack, at_least):
    """approach / room over every point pair of the blocks ``pairs`` (no pair skipped by a
    bound), with the pair arithmetic of :func:`ssn.approach_ratio`, from the same contact
    points: the largest, or ``at_least``."""
    X = ssn._pair_points(x0, ne.conn, ne.R, pairs)
    D = [ssn._pair_points(f, ne.conn, ne.R, pairs) for f in fields]
    ns = X.shape[1]
    ratio = at_least
    for e1, e2 in pairs:
        r12 = ne.radius[e1] + ne.radius[e2]
        rx = X[e1, :, None, 0] - X[e2, None, :, 0]
        ry = X[e1, :, None, 1] - X[e2, None, :, 1]
        d = np.sqrt(rx * rx + ry * ry)
        room = d - r12 + slack
        dd = np.maximum(d, 1e-300)
        nx, ny = rx / dd, ry / dd
        approach = np.zeros_like(d)
        for f in D:
            dx = f[e1, :, None, 0] - f[e2, None, :, 0]
            dy = f[e1, :, None, 1] - f[e2, None, :, 1]
            approach = approach + np.maximum(-(nx * dx + ny * dy), 0.0)
        touch = np.array([[ssn.point_may_touch(ne, e1, e2, i, j) for j in range(ns)]
                          for i in range(ns)])
        counted = touch & (room > 1e-2 * slack)
        if counted.any():
            ratio = max(ratio, float(np.max((approach / room)[counted])))
    return ratio


def _sliding_pair():
    """Two parallel beams 1 mm apart with 60 points per element (the bundled benchmark's
    resolution): most pairs of a block lie far along the beams."""
    return _setup([beam("lower", line=([0, 0], [2, 0]), degree=4, elements=4, radius=0.05),
                   beam("upper", line=([0.3, 0.101], [1.3, 0.101]), degree=4, elements=2,
                        radius=0.05)], "cg", segments_per_element=60)


# the cases above and the sliding pair, built once at collection
CASES_AND_SLIDING = CASES + [pytest.param("sliding", *_sliding_pair()[:3], id="sliding-60")]


@pytest.mark.parametrize(("name", "cp", "ne", "x"), CASES_AND_SLIDING)
def test_approach_ratio_skips_only_pairs_that_cannot_count(name, cp, ne, x):
    """The bounds by which :func:`ssn.approach_ratio` skips blocks, rows and chunks of
    points leave its value that of every pair, bit for bit: beams moving together (large
    motions, small approaches: the bounds by motion are loose), apart, and towards each
    other, with and without a threshold ``at_least``."""
    pairs = ssn.candidate_pairs(x, ne, 0.5)
    slack = float(cp.law.advance_slack())
    rng = np.random.default_rng(7)
    seen = []
    for common, relative in ((1e-2, 1e-4), (1e-3, 1e-3), (0.0, 2e-2)):
        for _ in range(2):
            fields = np.stack([common * rng.normal(size=2) + relative * rng.normal(size=x.shape),
                               relative * rng.normal(size=x.shape)])
            for at_least in (0.0, 0.05, ssn.ADVANCE_FRACTION):
                native = ssn.approach_ratio(x, fields, ne, pairs, slack, at_least)
                assert native == _every_pair_ratio(x, fields, ne, pairs, slack, at_least)
                if at_least == 0.0:
                    seen.append(native)
    if "2.0" not in name:
        assert max(seen) > 0.0  # some pair approached


@pytest.mark.parametrize(("name", "cp", "ne", "x"), CASES)
def test_missed_blocks(name, cp, ne, x):
    """The post-step check at a configuration moved from the predictor: the same flag, the
    same number of box candidates, the same smallest gap (the box bound when there is no
    candidate), for the full frozen set, for it less one block, and for an empty one."""
    ce, xj = cp.elements, jnp.asarray(x)
    capacity = _capacity(cp)
    cs, count, _ = jax_step_set(xj, jnp.asarray(MOTION), cp.search, capacity)
    frozen = _real(cs.pairs, ce.n_elements)
    flags = []
    for step, seed in ((0.0, 0), (0.01, 3), (0.05, 4)):
        x_new = _bent(x, seed, step) if step else x
        xn = jnp.asarray(x_new)
        sets = [frozen, frozen[1:], np.zeros((0, 2), np.int64)]
        for frozen_set in sets:
            padded = _padded(frozen_set, cp)
            missing, n, _, gap = jax_missed(xn, ce, jnp.asarray(padded), cp.reach,
                                            cp.interaction, capacity)
            native = ssn.missed_blocks(x_new, ne, frozen_set, cp.reach, cp.interaction)
            assert native[0] == bool(missing)
            assert native[1] == int(n)
            assert native[2] == pytest.approx(float(gap), rel=RTOL, abs=0.0)
            # the JAX padding rows may be passed as they are
            assert ssn.missed_blocks(x_new, ne, padded, cp.reach, cp.interaction) == native
            flags.append(native[0])
    if "2.0" in name:
        assert not any(flags)
    elif "-0.19" in name or ("parallel" in name and "0.13" not in name):
        assert any(flags) and not flags[0]  # the full set at the predictor misses nothing


@pytest.mark.parametrize(("name", "cp", "ne", "x"), CASES_AND_SLIDING)
def test_smallest_gap_is_that_of_every_pair(name, cp, ne, x):
    """The nearest-pair search after a step skips rows and chunks of points by their
    boxes: its smallest gap is still the smallest over every point pair of the
    candidate blocks that may interact, bit for bit (one square root of the smallest
    squared distance, less R1 + R2), at configurations bent from the case's."""
    for seed, step in ((0, 0.0), (3, 0.01), (4, 0.05)):
        x_new = _bent(x, seed, step) if step else x
        pairs = ssn.candidate_pairs(x_new, ne, cp.reach)
        if pairs.shape[0] == 0:
            continue
        P = ssn._pair_points(x_new, ne.conn, ne.R, pairs)
        ns = P.shape[1]
        smallest = np.inf
        for e1, e2 in pairs:
            sq = ((P[e1, :, None, 0] - P[e2, None, :, 0]) ** 2
                  + (P[e1, :, None, 1] - P[e2, None, :, 1]) ** 2)
            touch = np.array([[ssn.point_may_touch(ne, e1, e2, i, j) for j in range(ns)]
                              for i in range(ns)])
            if touch.any():
                smallest = min(smallest, float(np.sqrt(sq[touch].min()))
                               - (ne.radius[e1] + ne.radius[e2]))
        assert ssn.missed_blocks(x_new, ne, pairs, cp.reach, cp.interaction)[2] == smallest


def test_far_apart_gap_is_the_box_bound():
    """No candidate: the smallest gap is the lower bound from the boxes, which for two
    straight beams 2 apart is their distance less both radii."""
    cp, ne, x, spans = _two_beams("ipip")
    x = _moved(x, spans, "b", 2.0)
    missing, n, gap = ssn.missed_blocks(x, ne, np.zeros((0, 2), np.int64), cp.reach,
                                        cp.interaction)
    assert not missing and n == 0
    assert gap == pytest.approx(2.15 - 0.2, rel=1e-12)  # b's lower end at y = 2.15


def test_weights_sum_to_a_half_per_active_point():
    """Each point of either beam with a partner closer than q_active carries 1/2 in total
    (shared among ties), so W sums to half the number of such points; on two parallel beams
    in contact every point of the upper beam is one, ties or not."""
    for start in (0.5, 0.525):
        cp, ne, x, spans = _parallel("ipip", start)
        x = _moved(x, spans, "upper", 0.1)
        pairs, W, _ = ssn.closest_points(x, ne, cp.reach, MOTION)
        q = ssn.block_gaps(x, ne, pairs)
        ns = ne.R.shape[1]
        nearest = np.full((ne.conn.shape[0], ns), np.inf)
        for c, (e1, e2) in enumerate(pairs):
            nearest[e1] = np.minimum(nearest[e1], q[c].min(axis=1))
            nearest[e2] = np.minimum(nearest[e2], q[c].min(axis=0))
        active = nearest < 2.0 * MOTION
        assert np.sum(W) == pytest.approx(0.5 * active.sum(), rel=1e-14)
        upper = ne.beam == 1
        assert np.all(active[upper]) and active[upper].size == 2 * ns
        assert np.all(q[W > 0] < 2.0 * MOTION)
