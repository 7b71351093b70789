"""Resolution of the coarse-grained quadrature (eq. 9, ``contact/resolution.py``).

Two straight parallel beams (R = 0.1 m) at the fixed surface gap q = 2e-4 m; the upper one
slides along the lower one by fractions of the contact point spacing h. The package's
kernels give the double midpoint sum of eq. (9); the references are independent
quadratures (scipy) of the exact line integral: by Poisson summation, the sum over the
lower beam's points at offset a is ``F(0) + 2 sum_k F(2 pi k / h) cos(2 pi k a / h)``, F the
Fourier transform of Phi(q(s)), q(s) = sqrt(d^2 + s^2) - 2 R, computed by scipy.quad.
"""

import functools

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from _builders import beam
from scipy.integrate import quad

from beamcontact.contact.blocks import ContactSet, contact_energy
from beamcontact.contact.laws import CoarseGrained, cg_constant
from beamcontact.contact.points import contact_elements
from beamcontact.contact.resolution import (
    THRESHOLD,
    cg_resolution,
    log_kve,
    resolution_ratio,
    resolution_warning,
    washboard_variation,
)
from beamcontact.io.case import parse_case
from beamcontact.setup.model import build_model

R, Q, K_M = 0.1, 2.0e-4, 5.0e-25
D = 2 * R + Q  # centre-line distance
L_UPPER = 0.25
# both beams have 0.125 m elements: equal spacings h = 0.125 m / segments, and the upper
# beam's start (0.125 m) is a whole number of spacings, so a = 0 puts points face to face;
# the lower beam reaches 0.125 m (14 widths) beyond the upper one: an infinite line to
# 1e-19 for m = 12
SEGMENTS = (5, 10, 20, 30, 50)  # h = 25 (the benchmark's), 12.5, 6.25, 4.2, 2.5 mm
N_OFFSETS = 8


@functools.cache
def _model():
    raw = {"analysis": {"kind": "static"},
           "beams": [beam("lower", line=([0.0, 0.0], [0.5, 0.0]), degree=4, elements=4,
                          radius=R),
                     beam("upper", line=([0.125, D], [0.375, D]), degree=4, elements=2,
                          radius=R)]}
    return build_model(parse_case(raw))


@jax.jit
def _energy_and_force(x_ref, upper, ce, law, offsets):
    """Energy of the blocks of all element pairs, and the force (-dE/da, -dE/db) on the
    upper beam, at tangential offsets a (``offsets``) and normal offset b = 0."""
    lower, upper_el = jnp.nonzero(ce.beam == 0, size=4)[0], jnp.nonzero(ce.beam == 1, size=2)[0]
    every = jnp.stack(jnp.meshgrid(lower, upper_el, indexing="ij"), -1).reshape(-1, 2)
    cs = ContactSet(every, None, law)

    def energy(ab):
        return contact_energy(x_ref + upper[:, None] * ab, ce, cs)

    def energy_and_force(ab):
        # forward mode, one tangent per direction: half the compile time of a gradient
        e, de = jax.vmap(lambda t: jax.jvp(energy, (ab,), (t,)))(jnp.eye(2))
        return e[0], -de

    return jax.vmap(energy_and_force)(jnp.stack([offsets, jnp.zeros_like(offsets)], 1))


@functools.cache
def _slide(segments: int, m: float):
    """(h, offsets a, energies E(a), tangential forces T(a), normal forces N(a))."""
    model, disc = _model()
    ce = contact_elements(disc, segments, [1.0, 1.0])
    h = float(np.max(ce.w))
    assert np.allclose(ce.w, h, rtol=1e-12)  # straight lines: equal spacings
    upper = np.zeros(model.x_ref.shape[0])
    upper[disc.beam("upper").offset:] = 1.0
    # cutoff 1 m: every pair counts, as in the line integral; q_reg far below Q
    law = CoarseGrained(k=K_M, exponent=m, q_reg=1e-8, cutoff=1.0)
    a = h * np.arange(N_OFFSETS) / N_OFFSETS
    e, f = _energy_and_force(jnp.asarray(model.x_ref), jnp.asarray(upper), ce, law,
                             jnp.asarray(a))
    return h, a, np.asarray(e), np.asarray(f[:, 0]), np.asarray(f[:, 1])


def _phi(m):
    """Phi(q(s)) of eq. (9) along the beams, the exact gap of two parallel circles."""
    amplitude = K_M * float(cg_constant(m, R, R))
    return lambda s: amplitude * (np.sqrt(D * D + s * s) - 2 * R) ** (3.5 - m)


def _fourier(m, omega):
    """int Phi(q(s)) cos(omega s) ds over the whole line, by scipy.quad on intervals
    graded from the bell's width to 40 widths (beyond, Phi is below 1e-27 of its peak)."""
    w = np.sqrt(2 * D * Q)
    edges = np.concatenate([[0.0], w * np.geomspace(0.25, 40.0, 12)])
    f = _phi(m)
    scale = f(0.0) * w
    if omega == 0.0:
        parts = [quad(f, a, b, epsabs=1e-14 * scale, epsrel=1e-11, limit=200)[0]
                 for a, b in zip(edges[:-1], edges[1:], strict=True)]
    else:
        parts = [quad(f, a, b, weight="cos", wvar=omega, epsabs=1e-15 * scale,
                      epsrel=1e-11, limit=200)[0]
                 for a, b in zip(edges[:-1], edges[1:], strict=True)]
    return 2.0 * sum(parts)


def _poisson_reference(m, h, a):
    """Energy E(a) / (L_upper F(0)) and tangential force T(a) = -dE/da of the double
    midpoint sum for an infinite lower beam, from the Fourier transform F (module doc)."""
    f0 = _fourier(m, 0.0)
    e, t = np.ones_like(a), np.zeros_like(a)
    for k in range(1, 60):
        ck = _fourier(m, 2 * np.pi * k / h) / f0
        e += 2 * ck * np.cos(2 * np.pi * k * a / h)
        t += 2 * ck * (2 * np.pi * k / h) * np.sin(2 * np.pi * k * a / h) * L_UPPER * f0
        if abs(ck) < 1e-14:
            break
    return f0, e, t


def _normal_force_per_length(m):
    """-d/dd of the line integral of Phi(q(s)), q(s) = sqrt(d^2 + s^2) - 2 R, by quad."""
    amplitude = K_M * float(cg_constant(m, R, R))
    w = np.sqrt(2 * D * Q)

    def minus_dphi_dd(s):
        r = np.sqrt(D * D + s * s)
        return amplitude * (m - 3.5) * (r - 2 * R) ** (2.5 - m) * D / r

    return 2 * quad(minus_dphi_dd, 0.0, 40 * w, points=[w, 4 * w], epsabs=0.0,
                    epsrel=1e-12, limit=200)[0]


def _width(m):
    """The interaction width of the docs, written out: sqrt(2 (R1 + R2 + q) q / (m - 7/2))."""
    return np.sqrt(2 * (2 * R + Q) * Q / (m - 3.5))


@pytest.mark.parametrize("segments", SEGMENTS)
def test_sliding_energy_and_force_match_the_poisson_sum_of_the_line_integral(segments):
    """At every offset, energy and tangential force of the kernels equal the Poisson
    reconstruction from the exact line integral's Fourier transform (to round-off and
    the lower beam's finite length), at every resolution: the washboard is exactly the
    aliasing of the bell's Fourier transform at 2 pi k / h."""
    m = 12.0
    h, a, e, t, n = _slide(segments, m)
    f0, e_ref, t_ref = _poisson_reference(m, h, a)
    np.testing.assert_allclose(e / (L_UPPER * f0), e_ref, rtol=0, atol=1e-8)
    np.testing.assert_allclose(t, t_ref, rtol=0, atol=1e-8 * np.mean(n))
    # the average over the offsets is the line integral, whatever h: only the washboard
    # (modes k = 1 .. N_OFFSETS - 1, cancelled by the average) is the quadrature's error
    np.testing.assert_allclose(np.mean(n), L_UPPER * _normal_force_per_length(m),
                               rtol=5e-3 if segments == SEGMENTS[0] else 1e-8)


def test_aligned_energy_converges_to_the_line_integral():
    """Points face to face (a = 0, the worst offset): the energy per unit length of the
    upper beam over the line integral of Phi(q(s)) (scipy.quad) goes to 1, fast once the
    spacing is below the interaction width."""
    m = 12.0
    f0 = _fourier(m, 0.0)
    errors = np.array([abs(_slide(s, m)[2][0] / (L_UPPER * f0) - 1.0) for s in SEGMENTS])
    ratios = [_slide(s, m)[0] / _width(m) for s in SEGMENTS]
    assert np.all(np.diff(errors) < 0)
    assert errors[0] > 3.0  # 25 mm spacing, rho = 8: more than four times the energy
    assert ratios[-1] < THRESHOLD and errors[-1] < 1e-4


@pytest.mark.parametrize("m", [12.0, 6.0])
def test_washboard_is_large_when_coarse_and_vanishes_below_the_threshold(m):
    """(max - min) / mean of the energy over the slide, and the largest tangential force
    over the mean normal force (a pinning force, like static friction): large for rho > 2
    (the energy over 100 % for rho > 4), the energy below 1 % once rho < THRESHOLD, for
    m = 12 (steric) and m = 6 alike; the first-mode prediction of resolution.py follows
    the kernels (rho <= 4)."""
    ratios = []
    for segments in SEGMENTS:
        h, _, e, t, n = _slide(segments, m)
        rho = float(resolution_ratio(h, h, R, R, Q, m))
        assert np.isclose(rho, h / _width(m), rtol=1e-12)
        ratios.append(rho)
        variation = (e.max() - e.min()) / e.mean()
        friction = np.max(np.abs(t)) / np.mean(n)
        if rho > 2.0:
            assert variation > 0.3 and friction > 1e-3
        if rho > 4.0:
            assert variation > 1.0
        if rho < THRESHOLD:
            assert variation < 0.01 and friction < 2e-4
        if rho <= 4.0:
            np.testing.assert_allclose(washboard_variation(rho, m), variation, rtol=0.1)
    assert max(ratios) > 4.0 and min(ratios) < THRESHOLD  # both regimes were seen


def test_ratio_on_the_benchmark_numbers():
    """Free-fall benchmark: 0.5 m elements with 20 segments (25 mm), R = 0.1 m, m = 12,
    gaps reached 1e-4 .. 5e-4 m: rho = 11.5 .. 5.1, under-resolved; the recommended
    segments bring it to the threshold."""
    h, m, q_reg = 0.5 / 20, 12.0, 1e-4
    for q, expected in ((1e-4, 11.52), (5e-4, 5.147)):
        written_out = h / np.sqrt(2 * (0.2 + q) * q / (m - 3.5))
        rho = float(resolution_ratio(h, h, 0.1, 0.1, q, m, q_reg))
        assert np.isclose(rho, written_out, rtol=1e-12)
        assert np.isclose(rho, expected, rtol=1e-3)
    # the benchmark's contact data: lower beam 20 elements, upper 6, 20 segments each
    w = np.full((26, 20), h)
    radius = np.full(26, 0.1)
    beam_of = np.repeat([0, 1], [20, 6])
    allowed = ~np.eye(2, dtype=bool)
    res = cg_resolution(w, radius, beam_of, 1.2e-4, m, q_reg, allowed=allowed)
    assert res.under_resolved and res.beams == (0, 1)
    assert np.isclose(res.width, np.sqrt(2 * (0.2 + 1.2e-4) * 1.2e-4 / 8.5), rtol=1e-12)
    n_rec = int(np.ceil(20 * res.ratio))
    assert res.recommended_segments == n_rec == 211
    message = resolution_warning(res, ["lower", "upper"])
    for part in ("'lower' and 'upper'", "25 mm apart", "width 2.4 mm", "1.2e-04 m",
                 "ratio 10.5 > 1", "more than 100 %", "segments_per_element >= 211"):
        assert part in message
    finer = cg_resolution(np.full((26, n_rec), 0.5 / n_rec), radius, beam_of, 1.2e-4, m,
                          q_reg, allowed=allowed)
    assert not finer.under_resolved and finer.ratio <= THRESHOLD
    # a gap below q_reg (or a penetration) counts as q_reg; no contact in reach, as 0
    assert np.isclose(float(resolution_ratio(h, h, 0.1, 0.1, -1e-3, m, q_reg)), 11.52,
                      rtol=1e-3)
    assert float(resolution_ratio(h, h, 0.1, 0.1, np.inf, m, q_reg)) == 0.0


@pytest.mark.parametrize("nu", [0.5, 1.0, 4.5, 8.0, 12.0, 46.0, 96.0])
def test_log_kve_is_scipys(nu):
    """ln(K_nu(z) e^z) by the trapezoidal rule of its integral (resolution.log_kve)
    against SciPy's Bessel function, over the range the washboard formula meets (z from
    rho = 20 000 to rho = 2e-4 at m = 12), to a relative 1e-12."""
    from scipy.special import kve

    z = np.logspace(-3, 4, 300)
    with np.errstate(over="ignore"):
        scipys = kve(nu, z)
    finite = np.isfinite(scipys)  # SciPy's overflows for large nu and small z
    assert finite.sum() > 200
    # an absolute error of the logarithm is a relative one of K_nu
    np.testing.assert_allclose(log_kve(nu, z[finite]), np.log(scipys[finite]), rtol=1e-13,
                               atol=1e-12)
    assert np.all(np.isfinite(log_kve(nu, z)))
    # far beyond, the asymptotic series (DLMF 10.40.2) K_nu(z) e^z = sqrt(pi / (2 z))
    # (1 + a1 / z + a2 / z^2 + ...), a_k = prod_j (4 nu^2 - (2 j - 1)^2) / (k! 8^k)
    far = np.array([1e8, 1e12, 1e18])
    mu = 4.0 * nu**2
    series = 1.0 + (mu - 1.0) / (8.0 * far) + (mu - 1.0) * (mu - 9.0) / (2.0 * (8.0 * far)**2) \
        + (mu - 1.0) * (mu - 9.0) * (mu - 25.0) / (6.0 * (8.0 * far)**3)
    np.testing.assert_allclose(log_kve(nu, far),
                               0.5 * np.log(np.pi / (2.0 * far)) + np.log(series), rtol=0,
                               atol=1e-12)
