"""Single-mode estimate of how the axial law changes the period of the vibration test.

The pinned 10 m beam of vibration_*.py reduced to one degree of freedom: w(x, t) =
q(t) sin(pi x / L), uniform stretch lam(q) = (arc length of the sine) / L (axial inertia
neglected, i.e. axial equilibrium is quasi-static), linear bending energy
EI/2 (pi/L)^4 L/2 q^2, kinetic energy rho A L/4 q_t^2, and one of three axial laws per
unit length:

* ``svk``        EA/2 ((lam^2 - 1)/2)^2   (beamcontact: St. Venant-Kirchhoff, Green-Lagrange)
* ``engineering`` EA/2 (lam - 1)^2         (Exudyn's ANCF cable, axial force EA (|r'| - 1))
* ``pyelastica`` EA (lam - 1 - ln lam)     (PyElastica, axial force EA (e - 1)/e)

It integrates q from q = 0, q_t = -V and prints the period (twice the first upward zero
crossing), the first minimum and q(1.2 s) for each law, and the period ratios to the
engineering law. The absolute periods are only estimates (about 1 % long at V = 7 m/s,
since the axial inertia and the change of the mode shape are neglected); the ratios are
what the test compares with the full codes.

Usage (about 40 s per velocity):

    python benchmarks/peers/vibration_galerkin.py [--V 7 0.07 0.0007]
"""

from __future__ import annotations

import argparse

import numpy as np
from _common import AREA, INERTIA, L_LOWER, RHO, E
from scipy.integrate import solve_ivp

L = L_LOWER
MASS = RHO * AREA * L / 2  # modal mass of sin(pi x / L)
LAWS = {
    "svk": lambda lam: 0.5 * E * AREA * ((lam * lam - 1) / 2) ** 2,
    "engineering": lambda lam: 0.5 * E * AREA * (lam - 1) ** 2,
    "pyelastica": lambda lam: E * AREA * (lam - 1 - np.log(lam)),
}
_X, _W = np.polynomial.legendre.leggauss(64)
_X, _W = 0.5 * L * (_X + 1), 0.5 * L * _W


def stretch(q: float) -> float:
    return float(np.sum(_W * np.sqrt(1 + (q * np.pi / L * np.cos(np.pi * _X / L)) ** 2)) / L)


def run(V: float, law: str, t_end: float):
    W = LAWS[law]

    def U(q):
        return L * W(stretch(q)) + 0.5 * E * INERTIA * (np.pi / L) ** 4 * L / 2 * q * q

    def rhs(t, y, h=1e-7):
        hq = h * max(1.0, abs(y[0]))
        return [y[1], -(U(y[0] + hq) - U(y[0] - hq)) / (2 * hq) / MASS]

    def up(t, y):
        return y[0] if t > 1e-3 else -1.0

    up.direction = 1
    sol = solve_ivp(rhs, [0, t_end], [0.0, -V], rtol=1e-11, atol=1e-13 * max(V, 1e-3),
                    events=up, dense_output=True)
    half = sol.t_events[0][0]
    return 2 * half, sol.sol(0.5 * half)[0], sol.sol(min(1.2, t_end))[0]


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--V", type=float, nargs="+", default=[7.0, 0.07, 0.0007])
    a = ap.parse_args(argv)
    print("| V [m/s] | law | period [s] | ratio to engineering | first min q [m] | q(1.2) [m] |")
    print("|---|---|---|---|---|---|")
    for V in a.V:
        res = {law: run(V, law, 40.0) for law in LAWS}
        for law, (T, qmin, q12) in res.items():
            print(f"| {V:g} | {law} | {T:.5f} | {T / res['engineering'][0] - 1:+.3%} | "
                  f"{qmin:.4f} | {q12:.4f} |")


if __name__ == "__main__":
    main()
