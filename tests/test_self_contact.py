"""Self-contact (contact.self_contact): the exclusion rule, the energy against a brute-force
sum over the point pairs, the "points" selection on the device against the host rule, a
free beam folding onto itself (linear momentum), and load stepping that does not let a
large increment carry a beam through another."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from _builders import beam, bending_stiffness, static_case

import beamcontact as bc
from beamcontact.contact.blocks import contact_energy
from beamcontact.contact.points import self_exclusion
from beamcontact.contact.problem import candidate_gaps
from beamcontact.contact.select import closest_pair_weights, point_weights_on_device
from beamcontact.io.case import CaseError, parse_case
from beamcontact.setup.contact import build_contact
from beamcontact.setup.model import build_model

R = 0.01


def _ring(contact, gap_angle):
    """One free beam along a circular arc of radius 0.1 m that leaves out ``gap_angle``
    (rad) of the circle: its two ends face each other across a chord of
    0.2 sin(gap_angle / 2)."""
    arc = {"center": [0.0, 0.0], "radius": 0.1, "start_angle": 0.0,
           "end_angle": 2 * np.pi - gap_angle}
    case = parse_case({"analysis": {"kind": "static"},
                       "beams": [beam("ring", arc=arc, degree=3, elements=24, radius=R)],
                       "contact": {"segments_per_element": 4, "self_contact": True,
                                   **contact}})
    model, disc = build_model(case)
    return case, model, build_contact(case, disc)


def _points(model, ce):
    x = np.asarray(model.x_ref)
    pts = np.einsum("esk,ekd->esd", np.asarray(ce.R), x[np.asarray(ce.conn)])
    return pts.reshape(-1, 2), np.asarray(ce.s).ravel(), np.asarray(ce.w).ravel()


def test_exclusion_rule():
    """Default exclusion: 4 R_max, at least the cutoff; two points of one beam interact
    iff they are at least that far apart along it; elements of one beam may touch iff
    they hold such a pair; a beam with itself only under self-contact."""
    assert self_exclusion(0.01, np.inf) == 0.04
    assert self_exclusion(0.01, 0.06) == 0.06
    _, _, problem = _ring({"model": "ipip"}, 0.3)
    ce = problem.elements
    assert float(ce.exclusion) == pytest.approx(4 * R)
    s = np.asarray(ce.s)
    E = s.shape[0]
    e1, e2 = np.meshgrid(np.arange(E), np.arange(E), indexing="ij")
    mask = np.asarray(ce.point_mask(e1, e2))
    far = np.abs(s[e1][..., :, None] - s[e2][..., None, :]) >= 4 * R
    assert np.array_equal(mask, far)
    assert np.array_equal(np.asarray(ce.may_touch(e1, e2)), far.any(axis=(2, 3)) & (e1 != e2))
    # the positions are the middles of the segments along the reference arc
    length = 0.1 * (2 * np.pi - 0.3)
    assert np.isclose(np.sum(ce.w), length, rtol=1e-12)
    assert np.isclose(s.ravel()[0], 0.5 * float(ce.w[0, 0]), rtol=1e-12)
    assert s.ravel()[-1] == pytest.approx(length - 0.5 * float(ce.w[-1, -1]), rel=1e-12)
    with pytest.raises(CaseError, match="contact.self_exclusion: applies only with"):
        parse_case({"analysis": {"kind": "static"}, "beams": [beam("a", line=([0, 0], [1, 0]))],
                    "contact": {"model": "cg", "self_exclusion": 0.1}})


def test_coarse_grained_self_energy_equals_brute_force():
    """The energy of a ring whose ends face each other 0.024 m apart (cutoff 0.06 m)
    through the broad phase, the blocks and the mask equals the plain double sum over
    every pair of contact points at least the exclusion length apart along the beam."""
    _, model, problem = _ring({"model": "cg", "cutoff": 0.06, "k": 1.0e-20}, 0.24)
    ce = problem.elements
    assert float(ce.exclusion) == pytest.approx(0.06)
    cs, _ = problem.grown_set(model.x_ref, 0.0, 8)
    energy = float(contact_energy(model.x_ref, ce, cs))
    pts, s, w = _points(model, ce)
    i, j = np.triu_indices(len(s), 1)
    keep = np.abs(s[i] - s[j]) >= float(ce.exclusion)
    d = np.linalg.norm(pts[i[keep]] - pts[j[keep]], axis=1)
    amp = problem.law.amplitude(R, R, 1.0)
    phi = jax.vmap(lambda r: problem.law.pair_energy(r, 2 * R, amp))(jnp.asarray(d))
    brute = float(np.sum(w[i[keep]] * w[j[keep]] * np.asarray(phi)))
    assert np.sum(d < 0.06) > 10  # the ends interact
    assert energy > 0.0
    np.testing.assert_allclose(energy, brute, rtol=1e-12)


def test_points_selection_on_one_beam_device_equals_host():
    """IPIP "points" on a ring whose ends overlap: the weights chosen inside the step
    equal the host rule's, and every point with a partner in reach carries 1/2 in all."""
    _, model, problem = _ring({"model": "ipip", "pairing": "points"}, 0.05)
    ce = problem.elements
    capacity = problem.first_capacity(256)
    pairs, q, count, load = candidate_gaps(model.x_ref, ce, problem.reach, capacity)
    assert capacity.fits(int(count), int(load))
    q_active = 0.01
    host = closest_pair_weights(np.asarray(q), np.asarray(pairs), problem.beam_of,
                                problem.local_element, q_active, pairing="points")
    device = np.asarray(point_weights_on_device(q, pairs, ce, q_active))
    assert host.sum() > 0
    np.testing.assert_array_equal(device, host)
    # each point's nearest allowed partner on the beam, by brute force
    pts, s, _ = _points(model, ce)
    d = np.linalg.norm(pts[:, None] - pts[None], axis=-1) - 2 * R
    d[np.abs(s[:, None] - s[None]) < float(ce.exclusion)] = np.inf
    assert host.sum() == pytest.approx(0.5 * np.sum(d.min(axis=1) < q_active), rel=1e-12)


def _folding(self_contact, tmp_path):
    """A free beam (no supports, no gravity) under unequal opposite end moments: it curls
    up and its ends strike each other about 0.045 s later."""
    M = 2.2 * np.pi * bending_stiffness(1.0e8, R)
    raw = {"analysis": {"kind": "dynamic", "t_end": 0.07, "dt": 2.0e-3, "alpha": -0.1},
           "beams": [beam("free", line=([0, 0], [1, 0]), degree=3, elements=12, radius=R,
                          E=1.0e8, gravity=False)],
           "loads": [{"beam": "free", "at": "end", "moment": M},
                     {"beam": "free", "at": "start", "moment": -0.7 * M}],
           "contact": {"model": "ipip", "penalty": 1.0e7, "segments_per_element": 6,
                       "pairing": "points", "self_contact": self_contact},
           "output": {"points": [{"name": "tip", "beam": "free", "at": "end"}]}}
    return bc.simulate(parse_case(raw), tmp_path / f"fold_{self_contact}")


def test_free_beam_folding_onto_itself_conserves_momentum(tmp_path):
    """Contact and elastic forces come in equal and opposite pairs and the moments are
    force-free, so the linear momentum stays zero through the strikes (to round-off of
    the momentum scale sqrt(2 m E_kin)); the ends never penetrate deeper than allowed."""
    res = _folding(True, tmp_path)
    h = res.history
    assert res.status == "completed"
    assert (h["E_contact"] > 0).sum() > 5  # the ends struck
    mass = 1000.0 * np.pi * R**2
    scale = np.sqrt(2 * mass * h["E_kin"].max())
    assert np.abs(h[["p_x", "p_y"]].to_numpy()).max() < 1e-9 * scale
    assert h["min_gap"].min() > -R


def test_large_load_increment_does_not_carry_a_beam_through_another():
    """A cantilever pressed by its tip force onto a beam below in one load increment:
    without contact the tip would end 0.18 m lower, 0.15 m past the other beam. The
    contact set is frozen at the start of an increment, where the beams are apart, so
    the increment is halved until the solution does not penetrate deeper than
    max_penetration, and the tip ends resting on the lower beam."""
    lower = beam("lower", line=([0, 0], [1, 0]), elements=8, radius=R, E=1.0e8,
                 supports=[{"at": "start", "type": "pinned"}, {"at": "end", "type": "pinned"}])
    upper = beam("upper", line=([0.2, 0.05], [0.8, 0.05]), elements=8, radius=R, E=1.0e8,
                 supports=[{"at": "start", "type": "clamped"}])
    case = static_case([lower, upper], loads=[{"beam": "upper", "at": "end", "force": [0, -2.0]}],
                       load_steps=1, points=[{"name": "tip", "beam": "upper", "at": "end"},
                                             {"name": "below", "beam": "lower", "at": 0.8}])
    raw = case.model_dump()
    raw["contact"] = {"model": "ipip", "penalty": 1.0e6, "max_penetration": 1e-4}
    res = bc.simulate(parse_case(raw))
    h = res.history
    assert res.status == "completed"
    assert h["min_gap"].min() >= -1e-4
    assert res.summary["steps"] > 1  # the increment was cut
    end = h.iloc[-1]
    assert end["tip_y"] > end["below_y"] + R  # on the lower beam, not through it
    assert end["tip_y"] < end["below_y"] + 2 * R + 2e-3  # and resting on it
    assert end["tip_uy"] < -0.03  # it went down the whole gap


def _rolled_cantilever(self_contact: bool):
    """A clamped cantilever (L = 1 m, R = 5 mm, 40 cubic C^2 elements) under an end moment
    of 2.2 pi EI / L in 22 load steps: without contact it rolls into 1.1 turns of a
    circle of radius L / (2.2 pi). Contact: a soft coarse-grained repulsion (m = 6,
    smooth, so that load control can follow the tip as it comes to rest)."""
    E, L = 1.0e9, 1.0
    M = 2.2 * np.pi * bending_stiffness(E, 0.005) / L
    raw = {"analysis": {"kind": "static", "load_steps": 22},
           "beams": [beam("cantilever", line=((0, 0), (L, 0)), degree=3, elements=40,
                          continuity=2, radius=0.005, E=E,
                          supports=[{"at": "start", "type": "clamped"}])],
           "loads": [{"beam": "cantilever", "at": "end", "moment": M}],
           "contact": {"model": "cg", "exponent": 6.0, "k": 1.4e-6, "cutoff": 0.02,
                       "segments_per_element": 8, "self_contact": self_contact},
           "output": {"points": [{"name": "tip", "beam": "cantilever", "at": "end"}]}}
    return bc.simulate(parse_case(raw))


def test_cantilever_rolled_past_a_full_circle_rests_on_itself():
    """Issue 13's static test. With self-contact the free end comes to rest against the
    beam where it began a full turn earlier: the run reaches the full moment, the tip
    stays short of the clamp (x < 0) and within one diameter of it, the contact carries
    load, and the smallest gap stays above -1 % of R (the repulsion keeps it positive).
    Without self-contact the tip rolls on through the beam: at the full moment it lies
    inside the beam's own material near its start."""
    R = 0.005
    res = _rolled_cantilever(True)
    assert res.status == "completed"
    h = res.history
    assert h["load_factor"].iloc[-1] == pytest.approx(1.0)
    tip = np.array([h["tip_x"].iloc[-1], h["tip_y"].iloc[-1]])
    assert tip[0] < 0.0 and np.hypot(*tip) < 2 * R
    assert h["E_contact"].iloc[-1] > 0.0
    assert h["min_gap"].min() > -0.01 * R
    free = _rolled_cantilever(False)
    assert free.status == "completed"
    tip = np.array([free.history["tip_x"].iloc[-1], free.history["tip_y"].iloc[-1]])
    assert tip[0] > 0.05  # past the clamp, 0.1 of a turn further on
    axis = free.states.centrelines["cantilever"][-1]
    start = axis[: len(axis) // 2]  # the first half turn
    assert np.min(np.linalg.norm(start - tip, axis=1)) < R
