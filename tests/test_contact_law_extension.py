"""A third contact law added as docs/contact_laws.md shows: the law of the how-to, defined
here, and the case schema's ``Contact.law`` pointed at it (the only other place a new law
touches). Nothing else is changed, yet a dynamic run with it works: two free parallel
beams attract each other (the law has an attractive part, which neither shipped law has),
linear momentum stays zero to round-off, and with alpha = 0 the total energy, contact
energy included, is conserved."""

from dataclasses import dataclass
from typing import ClassVar

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from _builders import beam

from beamcontact.contact.laws import taylor_below
from beamcontact.io.case import Contact, parse_case
from beamcontact.runner import run_case


@jax.tree_util.register_dataclass
@dataclass(frozen=True)
class LennardJones:
    """The how-to's law: Phi(q) = eps beta1 beta2 [(sigma/q)^12 - 2 (sigma/q)^6]."""

    eps: float
    sigma: float
    q_reg: float
    cutoff: float

    closest_pairs: ClassVar[bool] = False

    def amplitude(self, R1, R2, beta12):
        del R1, R2
        return self.eps * beta12

    def pair_energy(self, d, R12, amplitude):
        def phi(q):
            s6 = (self.sigma / q) ** 6
            return amplitude * (s6 * s6 - 2.0 * s6)

        return jnp.where(d < self.cutoff, taylor_below(phi, d - R12, self.q_reg), 0.0)

    def interaction_distance(self):
        return self.cutoff

    def search_reach(self, r_max):
        del r_max
        return 0.5 * self.cutoff

    def advance_slack(self):
        return self.q_reg


R, SIGMA, GAP0 = 0.01, 0.004, 0.008


def test_taylor_continuation_matches_the_law_to_second_order():
    f = lambda q: (SIGMA / q) ** 12 - 2.0 * (SIGMA / q) ** 6  # noqa: E731
    q_reg = 0.003
    for q in (0.0031, 0.005):  # above q_reg: the law itself
        assert float(taylor_below(f, jnp.asarray(q), q_reg)) == pytest.approx(f(q), rel=1e-14)
    g = jax.grad(lambda q: taylor_below(f, q, q_reg))
    f2 = float(jax.grad(jax.grad(f))(q_reg))
    h = 1e-7  # across q_reg the force changes like a C^2 function's: by 2 h f''
    assert float(g(q_reg + h)) - float(g(q_reg - h)) == pytest.approx(2 * h * f2, rel=1e-3)
    slope = (float(g(0.0)) - float(g(-0.001))) / 0.001  # below: a linear force
    assert slope == pytest.approx(f2, rel=1e-9)


def test_a_new_law_runs_through_the_whole_solver(tmp_path, monkeypatch):
    law = LennardJones(eps=2e-2, sigma=SIGMA, q_reg=0.5 * SIGMA, cutoff=2 * R + 0.03)
    monkeypatch.setattr(Contact, "law", lambda self, radii: law)
    d = 2 * R + GAP0
    raw = {"analysis": {"kind": "dynamic", "t_end": 0.4, "dt": 5e-3, "alpha": 0.0},
           "beams": [beam("a", line=([0.0, 0.0], [0.2, 0.0]), degree=3, elements=4,
                          radius=R, E=1e7, gravity=False),
                     beam("b", line=([0.0, d], [0.2, d]), degree=3, elements=4, radius=R,
                          E=1e7, gravity=False)],
           "contact": {"model": "cg", "segments_per_element": 10, "cutoff": 2 * R + 0.03},
           "output": {"points": [{"name": "A", "beam": "a", "at": 0.5},
                                 {"name": "B", "beam": "b", "at": 0.5}]}}
    summary = run_case(parse_case(raw), "", tmp_path)
    assert summary["status"] == "completed", summary["message"]
    # a law without a native kernel runs on the JAX engine, and the summary says why
    assert summary["solver"]["engine_used"] == "jax"
    assert "LennardJones" in summary["solver"]["engine_reason"]
    h = np.genfromtxt(tmp_path / "history.csv", delimiter=",", names=True)
    gap = h["B_y"] - h["A_y"] - 2 * R
    assert gap[0] == pytest.approx(GAP0)
    # attracted from 2 sigma into the repulsive core below sigma, and pushed back out
    assert gap.min() < SIGMA < gap[-1]
    assert h["E_contact"][0] < 0.0  # an attractive well: no shipped law is negative
    mass = 1000.0 * np.pi * R**2 * 0.2  # of one beam
    assert np.max(np.abs(h["p_y"])) < 1e-9 * np.sqrt(2.0 * mass * h["E_kin"].max())
    e0 = h["E_total"][0]
    assert np.max(np.abs(h["E_total"] - e0)) < 5e-3 * np.max(np.abs(h["E_contact"]))
