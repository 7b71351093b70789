"""The fibre-pile generator (examples/fibre_pile/pile.py) and a small pile in free fall:
many beams through the broad phase against the closed form of free fall."""

import sys
from pathlib import Path

import numpy as np
import pytest

import beamcontact as bc
from beamcontact.io.case import parse_case

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "examples" / "fibre_pile"))
from pile import RADIUS, WALL_RADIUS, pile_case  # noqa: E402

G = 9.81


def _points(case):
    """Contact points (n, 2), radius and whether each belongs to a fibre, at t = 0."""
    from beamcontact.setup.contact import build_contact
    from beamcontact.setup.model import build_model

    model, disc = build_model(case)
    ce = build_contact(case, disc).elements
    x = np.asarray(model.x_ref)
    pts = np.einsum("esk,ekd->esd", np.asarray(ce.R), x[np.asarray(ce.conn)])
    n_s = pts.shape[1]
    names = [b.name for b in case.beams]
    fibre = np.repeat([names[b].startswith("fibre") for b in np.asarray(ce.beam)], n_s)
    radius = np.repeat(np.asarray(ce.radius), n_s)
    beam = np.repeat(np.asarray(ce.beam), n_s)
    return pts.reshape(-1, 2), radius, fibre, beam


def _free_fall_gaps(case, t):
    """The smallest gap between contact points of different beams at times t when the
    fibres fall freely from rest and the container stands still: fibre-fibre gaps stay
    as they are, a fibre point and a container point approach by g t^2 / 2."""
    pts, radius, fibre, beam = _points(case)
    f, c = np.nonzero(fibre)[0], np.nonzero(~fibre)[0]
    d = np.linalg.norm(pts[f][:, None] - pts[f][None], axis=-1) - radius[f][:, None] - radius[f]
    d[beam[f][:, None] == beam[f][None]] = np.inf
    ff = d.min()
    rel = pts[f][:, None] - pts[c][None]  # fibre point - container point
    drop = 0.5 * G * np.asarray(t) ** 2
    fc = [np.min(np.hypot(rel[..., 0], rel[..., 1] - s) - radius[f][:, None] - radius[c])
          for s in drop]
    return np.minimum(ff, fc), ff


def test_generated_pile_is_valid_and_seeded():
    """The generator gives a valid case, the same for the same seed, with no fibre
    touching another or the container."""
    a, b = (pile_case(40, seed=3, rows=4, container="rods"),
            pile_case(40, seed=3, rows=4, container="rods"))
    assert a == b and pile_case(40, seed=4, rows=4, container="rods") != a
    case = parse_case(a)
    assert sum(b.name.startswith("fibre") for b in case.beams) == 40
    assert _free_fall_gaps(case, [0.0])[0][0] > 0


@pytest.mark.parametrize("model", ["ipip", "cg"])
def test_small_pile_falls_freely_until_the_first_contact(model):
    """Six fibres and the container, until just before the first contact: every fibre
    falls freely, so the smallest gap of the run is the closed form of
    :func:`_free_fall_gaps` (to 1e-9 m) once it is within the law's reach (every pair
    closer than twice the search reach is a candidate); the coarse-grained repulsion,
    which acts before contact, only makes it larger."""
    raw = pile_case(6, seed=2, model=model, rows=2, container="rods")
    case = parse_case(raw)
    t = np.linspace(0.0, 0.2, 2001)
    t_hit = t[np.argmax(_free_fall_gaps(case, t)[0] <= 0.0)]
    raw["analysis"].update(t_end=round(0.995 * t_hit, 4), dt=2.0e-4)
    case = parse_case(raw)
    res = bc.simulate(case)
    h = res.history
    assert res.status == "completed"
    expected, ff = _free_fall_gaps(case, h["t"].to_numpy())
    assert expected[-1] < ff  # the floor is the nearest by the end
    from beamcontact.setup.contact import build_contact
    from beamcontact.setup.model import build_model

    reach = build_contact(case, build_model(case)[1]).reach
    exact = expected < 2 * reach - RADIUS - WALL_RADIUS
    if model == "cg":
        # the potential acts within the cutoff and slows the approach: the gap is never
        # below free fall, and equal to it while the repulsion is still negligible
        assert (h["min_gap"][exact] >= expected[exact] - 1e-12).all()
        assert h["min_gap"].iloc[-1] > expected[-1] + 1e-6
        exact &= expected > RADIUS
    assert exact.sum() > 3
    np.testing.assert_allclose(h["min_gap"][exact], expected[exact], rtol=0, atol=1e-9)


def test_pile_in_a_container_of_walls_falls_freely_until_the_floor():
    """The default container: three rigid walls ([[obstacles]]). Every obstacle gap is
    evaluated at every step (no search reach), so once the floor is the nearest, the
    smallest gap of the run is the closed form of free fall, the lowest fibre point's
    height less R, to 1e-9 m, until just before the first fibre lands. Before that it
    is the fibres' box bound (docs/theory.md, "Diagnostics"), which must stay below the
    exact fibre-fibre and side-wall gaps and, as the fibres fall together, constant."""
    raw = pile_case(6, seed=2, model="ipip", rows=2)
    assert raw == pile_case(6, seed=2, model="ipip", rows=2)
    case = parse_case(raw)
    assert [o.name for o in case.obstacles] == ["floor", "left", "right"]
    assert all(b.name.startswith("fibre") for b in case.beams)
    from beamcontact.setup.contact import build_contact
    from beamcontact.setup.model import build_model

    model, disc = build_model(case)
    ce = build_contact(case, disc).elements
    x = np.asarray(model.x_ref)
    pts = np.einsum("esk,ekd->esd", np.asarray(ce.R), x[np.asarray(ce.conn)]).reshape(-1, 2)
    beam = np.repeat(np.asarray(ce.beam), np.asarray(ce.R).shape[1])
    d = np.linalg.norm(pts[:, None] - pts[None], axis=-1) - 2 * RADIUS
    d[beam[:, None] == beam[None]] = np.inf
    left, right = (o.wall.point[0] for o in case.obstacles[1:])
    sides = min(pts[:, 0].min() - left, right - pts[:, 0].max()) - RADIUS
    t_hit = np.sqrt(2 * (pts[:, 1].min() - RADIUS) / G)
    raw["analysis"].update(t_end=round(0.99 * t_hit, 4), dt=2.0e-3)
    res = bc.simulate(parse_case(raw))
    assert res.status == "completed"
    h = res.history
    t = h["t"].to_numpy()
    floor = pts[:, 1].min() - 0.5 * G * t**2 - RADIUS
    bound = h["min_gap"].iloc[0]
    assert bound <= min(d.min(), sides)
    nearest = floor < bound
    assert nearest.sum() > 10 and nearest[-1]
    np.testing.assert_allclose(h["min_gap"][nearest], floor[nearest], rtol=0, atol=1e-9)
    np.testing.assert_allclose(h["min_gap"][~nearest], bound, rtol=0, atol=1e-9)
