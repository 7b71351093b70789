"""Cross sections: quadrature in the in-plane coordinate eta across the section.

The strain energy (paper eq. 30) is integrated over the cross section as
int_A f(eta) dA ~= sum_k w_k f(eta_k); eta is measured along the in-plane normal g2.
"""

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True, eq=False)
class Section:
    """Cross-section quadrature and properties.

    Attributes:
        eta: in-plane fibre coordinates, shape (n_eta,).
        weights: area weights, shape (n_eta,); sum(weights) = area.
        area: A.
        inertia: I = int eta^2 dA (bending in the plane).
        half_depth: largest |eta|: the contact radius and the curvature limit 1/half_depth.
    """

    eta: np.ndarray
    weights: np.ndarray
    area: float
    inertia: float
    half_depth: float


def circle_section(radius: float, n_eta: int = 6) -> Section:
    """Solid circle of radius a: int_A f dA = int_{-a}^{a} f(eta) 2 sqrt(a^2 - eta^2) d eta.

    Gauss-Chebyshev quadrature of the second kind (weight sqrt(1 - x^2)), exact for
    polynomials in eta up to degree 2 n_eta - 1.
    """
    i = np.arange(1, n_eta + 1)
    x = np.cos(i * np.pi / (n_eta + 1))
    w = np.pi / (n_eta + 1) * np.sin(i * np.pi / (n_eta + 1)) ** 2
    a = float(radius)
    return Section(eta=a * x, weights=2.0 * a * a * w, area=np.pi * a * a,
                   inertia=np.pi * a**4 / 4.0, half_depth=a)


def rectangle_section(width: float, height: float, n_eta: int = 6) -> Section:
    """Rectangle b x h (h in the plane of bending): Gauss-Legendre over the height."""
    x, w = np.polynomial.legendre.leggauss(n_eta)
    h2 = 0.5 * float(height)
    return Section(eta=h2 * x, weights=float(width) * h2 * w, area=width * height,
                   inertia=width * height**3 / 12.0, half_depth=h2)
