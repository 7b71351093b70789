"""Resolution of the coarse-grained quadrature (paper Sec. 2.2, eq. 9), host side.

The coarse-grained energy of two beams is the double sum ``sum_ij w1_i w2_j Phi(q_ij)``
over their contact points (segment midpoints, weights the segment arc lengths): a
product midpoint rule for the double line integral of eq. (9). Near a contact with
surface gap q, two sections offset by s along nearly parallel beams have the gap
``q(s) = sqrt(d^2 + s^2) - R1 - R2 ~ q + s^2 / (2 d)``, ``d = R1 + R2 + q``, so

    Phi(q(s)) ~ Phi(q) (1 + s^2 / (n w^2))^-n,   n = m - 7/2,
    w = sqrt(2 d q / n)                          (the interaction width),

a bell that has fallen by ``(1 + 1/n)^n`` at ``s = w`` (2.57 for m = 12, e for large m).
By Poisson summation, the sum over one beam's points (spacing h) seen from a point of the
other beam (offset a against that lattice) equals the line integral times
``1 + 2 sum_k c_k cos(2 pi k a / h)``, ``c_k`` the Fourier transform of the bell at
``2 pi k / h`` over its integral (for equal spacings every point has the same offset, and
the double sum carries the same factor):

    c_1 = 2^(1-nu) / Gamma(nu) z^nu K_nu(z),   nu = m - 4,   z = 2 pi sqrt(n) w / h.

So the quadrature error depends on ``rho = h / w`` alone, and, with this choice of w,
hardly on m (for large m the bell is the Gaussian exp(-s^2/w^2) and c_1 = exp(-(pi/rho)^2)):
the energy varies by ``(max - min) / mean ~ 4 c_1`` as the points of the two beams slide
past each other (a washboard, with tangential forces like friction). That is 1 % at
rho = 1.05 (m = 4.5), 1.15 (m = 8), 1.20 (m = 12), 1.27 (m = 100): below the threshold
rho = 1 it is under 1 % for every m >= 4.5 (0.75 % for m = 4.5, 0.14 % for m = 12). The
energy averaged over the offset is exact at any spacing; the washboard is the error.

For a pair of beams the larger of the two spacings counts: each point of the finer beam
sees the coarser beam's lattice, so its force oscillates along the beam with the coarser
period even where the total energy averages out.
"""

import math
from dataclasses import asdict, dataclass

import numpy as np

from beamcontact.contact.laws import CoarseGrained

# rho = h / w above which the quadrature counts as under-resolved: at or below it the
# energy washboard is under 1 % for every m >= 4.5, 0.14 % for m = 12 (module docstring;
# measured in tests/test_cg_resolution.py)
THRESHOLD = 1.0


def interaction_width(q, R1, R2, m):
    """Width ``w = sqrt(2 (R1 + R2 + q) q / (m - 7/2))`` of the section-section
    interaction (eq. 9) along two parallel beams at surface gap q."""
    q = np.asarray(q, dtype=float)
    d = R1 + R2 + q
    return np.sqrt(2.0 * d * np.maximum(q, 0.0) / (m - 3.5))


def resolution_ratio(h1, h2, R1, R2, q_min, m, q_reg=0.0):
    """``rho = max(h1, h2) / w(max(q_min, q_reg))`` for beams with contact point spacings
    h1, h2 (segment arc lengths) and radii R1, R2; broadcasts over arrays.

    Below ``q_reg`` the potential is a quadratic continuation (see ``laws.py``) that is no
    narrower than the bell at ``q_reg``, so the gap is taken as at least ``q_reg``. A
    non-finite q_min (no contact in reach) gives rho = 0; a gap <= 0 with q_reg = 0, inf.
    """
    q = np.maximum(np.asarray(q_min, dtype=float), q_reg)
    w = interaction_width(np.where(np.isfinite(q), q, 1.0), R1, R2, m)
    with np.errstate(divide="ignore"):
        rho = np.maximum(h1, h2) / w
    return np.where(np.isfinite(q), rho, 0.0)


def log_kve(nu: float, z) -> np.ndarray:
    """ln(K_nu(z) e^z) for real nu and z > 0 (``log(scipy.special.kve(nu, z))``), from
    K_nu(z) = int_0^inf exp(-z cosh t) cosh(nu t) dt (DLMF 10.32.9) by the trapezoidal
    rule, summed in logarithms: the integrand is even in t and analytic, so the rule
    converges faster than any power of the node spacing (tests/test_cg_resolution.py
    compares it with SciPy: the logarithm to 1e-12 plus 1e-13 of itself, and finite where
    SciPy's K overflows). 4001 nodes per value of z (memory len(z) x 4001). Here rather
    than SciPy's because scipy.special's import took 0.1 s of every coarse-grained run
    (session 27)."""
    z = np.asarray(z, dtype=float)
    nu = abs(float(nu))
    # the integrand has fallen by e^-60 from its largest value where
    # z (cosh t - 1) >= nu t + 60 (its log is at most nu t - z (cosh t - 1), at least 0)
    end = np.full(z.shape, 50.0 + nu)
    for _ in range(60):
        d = (nu * end + 60.0) / z
        end = np.log1p(d + np.sqrt(d * (2.0 + d)))  # arccosh(1 + d), also for tiny d
    t = end[..., None] * np.linspace(0.0, 1.0, 4001)
    # cosh t - 1 = 2 sinh^2(t/2), without cancellation where z is large and t tiny
    log_f = (-2.0 * z[..., None] * np.sinh(0.5 * t) ** 2 + nu * t
             + np.log1p(np.exp(-2.0 * nu * t)) - np.log(2.0))
    top = log_f.max(axis=-1, keepdims=True)
    terms = np.exp(log_f - top)
    terms[..., 0] *= 0.5
    return top[..., 0] + np.log(terms.sum(axis=-1) * (t[..., 1] - t[..., 0]))


def washboard_variation(rho, m):
    """Predicted relative variation ``(max - min) / mean`` of the coarse-grained energy of
    two parallel beams as one slides along the other, ``4 c_1`` of the first Poisson mode
    (module docstring); accurate to a few per cent for rho <= 4, an under-estimate
    beyond (the higher modes add up). NaN for m <= 4, where the line integral of eq. (9)
    diverges and no width exists."""
    rho = np.asarray(rho, dtype=float)
    if m <= 4.0:
        return np.full(rho.shape, np.nan)
    nu = m - 4.0
    finite = np.isfinite(rho) & (rho > 0.0)
    z = 2.0 * np.pi * np.sqrt(m - 3.5) / np.where(finite, rho, 1.0)
    # in logarithms: z^nu K_nu(z) is a ratio of huge and tiny numbers for small rho
    log_c1 = ((1.0 - nu) * np.log(2.0) - math.lgamma(nu) + nu * np.log(z) - z
              + log_kve(nu, z))
    # rho = inf (no width at all): c_1 -> 1, the bell is a single point pair
    return np.where(rho > 0.0, np.where(np.isinf(rho), 4.0, 4.0 * np.exp(log_c1)), 0.0)


@dataclass(frozen=True)
class Resolution:
    """The worst-resolved beam pair of a coarse-grained run.

    Attributes:
        ratio: rho = spacing / width.
        spacing: the larger contact point spacing of the pair [m].
        width: interaction width at ``gap`` [m].
        gap: the gap used, max(q_min, q_reg) [m].
        beams: indices of the two beams.
        segments: ``segments_per_element`` of the run.
        exponent: m of eq. (9).
    """

    ratio: float
    spacing: float
    width: float
    gap: float
    beams: tuple[int, int]
    segments: int
    exponent: float

    @property
    def under_resolved(self) -> bool:
        """rho above :data:`THRESHOLD`."""
        return self.ratio > THRESHOLD

    @property
    def recommended_segments(self) -> int:
        """The smallest ``segments_per_element`` with rho <= THRESHOLD (spacings scale
        like 1 / segments)."""
        return max(self.segments, math.ceil(self.segments * self.ratio / THRESHOLD - 1e-9))

    @property
    def variation(self) -> float:
        """Predicted energy washboard (max - min) / mean, :func:`washboard_variation`."""
        return float(washboard_variation(self.ratio, self.exponent))

    def as_dict(self) -> dict:
        """JSON-ready summary (non-finite numbers as None: strict JSON has no inf)."""
        out = asdict(self)
        out.update(beams=list(self.beams), threshold=THRESHOLD,
                   under_resolved=self.under_resolved,
                   recommended_segments=self.recommended_segments,
                   predicted_energy_variation=self.variation)
        return {k: None if isinstance(v, float) and not math.isfinite(v) else v
                for k, v in out.items()}


def cg_resolution(w, radius, beam, q_min, m, q_reg=0.0, allowed=None) -> Resolution:
    """The worst rho over the interacting beam pairs, from the contact point data.

    Args:
        w: point weights (segment arc lengths) per element, (E, segments).
        radius: contact radius per element, (E,).
        beam: beam index per element, (E,).
        q_min: the smallest surface gap reached (one number for all pairs: conservative).
            A gap measured between contact points, like the runs' ``min_gap``, exceeds the
            surface gap by up to h^2 / (8 (R1 + R2)) when the points are staggered: rho is
            then a lower bound, tight near the threshold (to q / (4 (m - 7/2))).
        m: exponent of the law.
        q_reg: regularisation gap of the law.
        allowed: (B, B) which beams interact (the diagonal: self-contact). None: every
            two different beams.
    """
    w, radius, beam = np.asarray(w, float), np.asarray(radius, float), np.asarray(beam)
    n_beams = int(beam.max()) + 1
    # the coarsest segment and the thinnest section of each beam: the contact can be
    # anywhere, and a smaller radius means a narrower interaction
    h = np.array([w[beam == b].max() for b in range(n_beams)])
    R = np.array([radius[beam == b].min() for b in range(n_beams)])
    if allowed is None:
        b1, b2 = np.triu_indices(n_beams, k=1)
    else:
        b1, b2 = np.nonzero(np.triu(np.asarray(allowed, dtype=bool)))
    gap = max(float(q_min), float(q_reg))
    if not b1.size:  # no interacting pair
        return Resolution(0.0, 0.0, np.inf, gap, (0, 0), w.shape[1], float(m))
    rho = resolution_ratio(h[b1], h[b2], R[b1], R[b2], q_min, m, q_reg)
    k = int(np.argmax(rho))
    return Resolution(ratio=float(rho[k]), spacing=float(max(h[b1[k]], h[b2[k]])),
                      width=float(interaction_width(gap, R[b1[k]], R[b2[k]], m)),
                      gap=gap, beams=(int(b1[k]), int(b2[k])), segments=w.shape[1],
                      exponent=float(m))


def contact_resolution(ce, law: CoarseGrained, q_min) -> Resolution:
    """:func:`cg_resolution` for ``ContactElements`` ce and a coarse-grained law."""
    return cg_resolution(np.asarray(ce.w), np.asarray(ce.radius), np.asarray(ce.beam),
                         q_min, m=float(law.exponent), q_reg=float(law.q_reg),
                         allowed=np.asarray(ce.allowed))


def _mm(x: float) -> str:
    """A length in millimetres, two significant digits."""
    return f"{1e3 * x:.2g} mm"


def resolution_warning(res: Resolution, names=None) -> str:
    """One-line warning for an under-resolved pair (see :func:`cg_resolution`)."""
    between = ("" if names is None else
               f" between '{names[res.beams[0]]}' and '{names[res.beams[1]]}'")
    variation = res.variation
    effect = ("" if not np.isfinite(variation) else
              f" (the energy varies by about {100 * variation:.0f} % as one beam slides along"
              " the other)" if variation < 1.0 else
              " (the energy varies by more than 100 % as one beam slides along the other)")
    return (f"coarse-grained quadrature under-resolved{between}: contact points "
            f"{_mm(res.spacing)} apart, interaction width {_mm(res.width)} at the smallest "
            f"gap {res.gap:.1e} m (ratio {res.ratio:.3g} > {THRESHOLD:g}); the contact "
            f"energy and tangential forces depend on how the points line up{effect}; "
            f"use segments_per_element >= {res.recommended_segments}")
