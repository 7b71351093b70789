"""Initial interpenetration of beams (contact/overlap.py) against closed forms."""

import numpy as np
import pytest
from _builders import beam, static_case

import beamcontact.contact.overlap as overlap
from beamcontact.contact.overlap import describe, initial_overlaps
from beamcontact.contact.points import contact_elements
from beamcontact.setup.model import build_model


def _overlaps(beams, segments=3):
    case = static_case(beams)
    model, disc = build_model(case)
    ce = contact_elements(disc, segments, [1.0] * len(beams))
    return initial_overlaps(np.asarray(model.x_ref), ce, [b.name for b in disc.beams])


def test_crossing_beams_overlap_by_both_radii_at_the_crossing():
    """Two diagonals of a square cross at its centre: with 5 elements of 3 segments each
    (15 points), the middle point of both beams is the crossing, d = 0, q = -(R1 + R2)."""
    found = _overlaps([beam("a", line=([-1, -1], [1, 1]), elements=5, radius=0.05),
                       beam("b", line=([-1, 1], [1, -1]), elements=5, radius=0.03)])
    assert len(found) == 1
    f = found[0]
    assert f.beams == ("a", "b")
    assert f.gap == pytest.approx(-0.08, abs=1e-12)
    np.testing.assert_allclose(f.point, [0.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(f.fractions, [0.5, 0.5], atol=1e-12)
    assert f.elements == (2, 2)
    assert f.point_pairs >= 1


def test_overlapping_parallel_beams_report_the_middle_of_the_plateau():
    """Upper beam x in [2, 7] at y = 0.15 over a lower one x in [0, 10], both R = 0.1:
    q = 0.15 - 0.2 = -0.05 at the 15 aligned point pairs (spacing 1/3); the middle one
    is at x = 4.5, half-way along the upper beam and 0.45 along the lower one."""
    found = _overlaps([beam("lower", line=([0, 0], [10, 0]), elements=10, radius=0.1),
                       beam("upper", line=([2, 0.15], [7, 0.15]), elements=5, radius=0.1)])
    assert len(found) == 1
    f = found[0]
    assert f.beams == ("lower", "upper")
    assert f.gap == pytest.approx(-0.05, abs=1e-12)
    np.testing.assert_allclose(f.point, [4.5, 0.075], atol=1e-12)
    np.testing.assert_allclose(f.fractions, [0.45, 0.5], atol=1e-12)
    assert f.elements == (4, 2) and f.point_pairs == 15
    assert describe(found) == f.message == (
        "beams 'lower' and 'upper' interpenetrate in the initial configuration: gap -0.05 m "
        "at (4.5, 0.075) (lower at 0.45 of its length, upper at 0.5)")


def test_separated_beams_give_no_finding():
    found = _overlaps([beam("lower", line=([0, 0], [10, 0]), elements=10, radius=0.1),
                       beam("upper", line=([2, 0.21], [7, 0.21]), elements=5, radius=0.1),
                       beam("far", line=([20, 0], [20, 5]), elements=3, radius=0.1)])
    assert found == [] and describe(found) is None


def test_chunks_give_the_same_findings_and_pairs_are_ranked(monkeypatch):
    """Chunks of one element pair of points (memory bound for big models) change nothing; several
    interpenetrating pairs of beams are reported deepest first. The post's points (spacing
    1/6) nearest to y = 0 and y = 0.15 are at y = 1/12 and 1/12 + 1/6: its smallest
    distances are 1/12 to the lower beam and 1/15 to the upper one."""
    beams = [beam("lower", line=([0, 0], [10, 0]), elements=10, radius=0.1),
             beam("upper", line=([2, 0.15], [7, 0.15]), elements=5, radius=0.1),
             beam("post", line=([5.5, -1], [5.5, 1]), elements=4, radius=0.02)]
    whole = _overlaps(beams)
    monkeypatch.setattr(overlap, "POINT_CHUNK", 9)
    assert _overlaps(beams) == whole
    assert [f.beams for f in whole] == [("upper", "post"), ("lower", "upper"),
                                        ("lower", "post")]
    np.testing.assert_allclose([f.gap for f in whole], [1 / 15 - 0.12, -0.05, 1 / 12 - 0.12],
                               atol=1e-12)
    assert describe(whole).endswith("(and 2 more pair(s) of beams)")
