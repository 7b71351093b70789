"""The scripts behind the paper's figures (issue 24): the continuum model's section and
geometry (benchmarks/peers/drop_solid.py), the peers' two problems
(benchmarks/peers/_common.py), the Fig. 7 overlay's measurements (benchmarks/peers/fig7.py)
and the potential at the coarse-grained cutoff (examples/studies/study_tables.py). The runs
themselves are benchmarks, not tests."""

import json
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
PEERS = ROOT / "benchmarks" / "peers"
sys.path.insert(0, str(PEERS))
sys.path.insert(0, str(ROOT / "examples" / "studies"))

import drop_solid  # noqa: E402
import fig7  # noqa: E402
import study_tables  # noqa: E402


def test_solid_section_has_the_beams_area_inertia_and_mass():
    """The rectangle of height sqrt(12 I / A) and thickness A / height has the circle's A
    and I (so EA, EI and rho A of the beam model), and the gap closes in free fall at the
    beam model's first impact, 0.750 s."""
    R = 0.1
    area, inertia = math.pi * R**2, math.pi * R**4 / 4
    assert pytest.approx(area, rel=1e-14) == drop_solid.H * drop_solid.THICK
    assert pytest.approx(inertia, rel=1e-14) == drop_solid.THICK * drop_solid.H**3 / 12
    assert pytest.approx(math.sqrt(3.0) * R, rel=1e-14) == drop_solid.H
    t_fall = math.sqrt(2 * drop_solid.GAP0 / drop_solid.G)
    assert t_fall == pytest.approx(0.750, abs=1e-4)
    # the bevel reaches the reference mesh's first element (3 m / 30) on every mesh
    assert pytest.approx((drop_solid.X_UP1 - drop_solid.X_UP0) / 30) == drop_solid.CHAMFER_LENGTH


def test_solid_first_amplitude_and_contact_episodes():
    t = np.linspace(0.0, 3.0, 3001)
    uy = np.where(t < 1.0, 0.0, -np.sin(np.pi * (t - 1.0)))  # one dip of depth 1 at 1.5 s
    amp, when, ended = drop_solid.first_amplitude(t, uy, 1.0)
    assert amp == pytest.approx(-1.0, abs=1e-6) and when == pytest.approx(1.5, abs=1e-3)
    assert ended
    gap = np.ones_like(t)
    h = 0.5e-3  # half the row spacing: the intervals' ends are rows
    gap[(t > 0.75 - h) & (t < 0.80 + h)] = 0.0
    gap[(t > 0.82 - h) & (t < 0.83 + h)] = 0.0  # within 0.05 s: the same collision
    gap[(t > 1.25 - h) & (t < 1.30 + h)] = 0.0
    episodes = drop_solid.contact_episodes(t, gap, 1e-3)
    assert [(round(a, 3), round(b, 3)) for a, b in episodes] == [(0.75, 0.83), (1.25, 1.3)]


@pytest.mark.parametrize("problem, x_fall, young, gap", [
    ("drop", (3.0, 7.0), 1.0e7, 2.76), ("bundled", (3.5, 6.5), 0.98e6, 2.759)])
def test_peer_problems(problem, x_fall, young, gap):
    """PEER_PROBLEM chooses the peer drop or the bundled benchmark (case_cg.toml)."""
    code = ("import json, _common as c; print(json.dumps([c.X_FALL, c.L_FALL, c.E, c.GAP, "
            "c.Y_FALL]))")
    env = {k: v for k, v in os.environ.items() if k != "PEER_E"}
    out = subprocess.run([sys.executable, "-c", code], cwd=PEERS, capture_output=True,
                         text=True, env={**env, "PEER_PROBLEM": problem}, check=True)
    xs, length, e, g, y = json.loads(out.stdout)
    assert tuple(xs) == x_fall and length == pytest.approx(x_fall[1] - x_fall[0])
    assert e == young and g == gap and y == pytest.approx(gap + 0.2)
    bad = subprocess.run([sys.executable, "-c", "import _common"], cwd=PEERS,
                         capture_output=True, text=True, env={**env, "PEER_PROBLEM": "x"})
    assert bad.returncode != 0 and "PEER_PROBLEM" in bad.stderr


def test_fig7_measures_every_curve_alike(tmp_path):
    """A peer's CSV: the first impact where A moves, the first amplitude of its first
    excursion, the curve ended where its energy leaves +-10 %; a solid's CSV: the impact
    from its gap, the second collision from its JSON."""
    t = np.linspace(0.0, 3.0, 3001)
    uy = np.where(t < 0.75, 0.0, -2.0 * np.sin(np.pi * (t - 0.75) / 1.5))
    energy = np.where(t < 2.0, 100.0, 120.0)  # +20 % from t = 2
    peer = tmp_path / "peer.csv"
    np.savetxt(peer, np.c_[t, uy, energy], delimiter=",", header="t,A_uy,E_total",
               comments="")
    c = fig7.load(peer)
    assert c["impact"] == pytest.approx(0.75 + 1.5 / np.pi * np.arcsin(5e-4), abs=2e-3)
    assert c["how"] == "A moves"
    assert c["cut"] == pytest.approx(2.0, abs=1e-3) and c["t"][-1] <= 2.0
    assert c["amplitude"]["uy"] == pytest.approx(-2.0, abs=1e-5)
    assert c["amplitude"]["t"] == pytest.approx(1.5, abs=1e-3)
    assert not c["amplitude"]["ended"]  # the excursion ends at 2.25 s, after the cut

    gap = np.where(t < 0.8, 1.0 - t / 0.8, 0.0)
    solid = tmp_path / "solid.csv"
    solid.write_text("# a comment line, as drop_solid.py writes\n" + "t,A_uy,min_gap\n"
                     + "".join(f"{a},{b},{g}\n" for a, b, g in zip(t, uy, gap,
                                                                             strict=True))
                     + "# valid_until = 3.0 s\n")
    (tmp_path / "solid.json").write_text(json.dumps({"second_collision_t": 1.25,
                                                     "valid_until": 3.0}))
    s = fig7.load(solid)
    assert s["how"] == "gap" and s["impact"] == pytest.approx(0.8 * (1 - 1e-3), abs=1e-3)
    assert s["second"] == 1.25 and s["cut"] is None
    assert s["amplitude"]["ended"]
    table = fig7.table([("peer", c), ("solid", s)])
    assert "| peer |" in table and "(A moves)" in table and "| 1.250 |" in table


def test_cg_potential_at_the_cutoff(tmp_path):
    """eq. (9) at the gap of the cutoff, against the closed form with math.lgamma."""
    case = tmp_path / "case.toml"
    case.write_text((ROOT / "examples" / "free_fall" / "case_cg_paper.toml").read_text())
    q, phi, force = study_tables.cutoff_potential(case, 0.3)
    m, k, R = 12.0, 5.0e-25, 0.1
    c = math.exp((2.5 - m) * math.log(2) + 1.5 * math.log(math.pi) + math.lgamma(m - 3.5)
                 - 2 * math.lgamma(m / 2)) * math.sqrt(R * R / (2 * R))
    assert q == pytest.approx(0.1)
    assert phi == pytest.approx(k * c * 0.1 ** (3.5 - m), rel=1e-12)
    assert force == pytest.approx((m - 3.5) * phi / 0.1, rel=1e-12)
