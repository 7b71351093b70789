"""Compare the contact-free vibration runs of beamcontact, PyElastica and Exudyn.

Reads the CSVs (columns t, A_uy, ...) written by vibration_beamcontact.py,
vibration_pyelastica.py and vibration_exudyn.py, interpolates A_uy onto a common grid
(0.25 ms) and prints, for every pair of runs, the largest |difference| of A_uy over
0..0.9, 0..1.0, 0..1.1 and 0..1.2 s (and 0..t_end when the runs are longer), the signed
difference at 1.2 s; for every run the first minimum of A_uy, the zero crossings of A_uy
(A starts at 0 going down: crossings at T/2, T, ... for a periodic motion) and the period
estimates; and the closed forms: the linear first-mode period
T1 = 2 L^2 / pi * sqrt(rho A / (E I)) and the single-mode (Galerkin, immovable ends)
Duffing estimate q'' + w0^2 q + beta q^3 = 0, beta = (E / rho) (pi / L)^4 / 4.

Usage (from the repository root; reads benchmarks/peers/results/ by default):

    python benchmarks/peers/vibration_compare.py --tag V7
    python benchmarks/peers/vibration_compare.py --V 7 \
        bc_eng=benchmarks/peers/results/vib_bc-engineering_V7.csv \
        Exudyn=benchmarks/peers/results/vib_exudyn_V7.csv
"""

from __future__ import annotations

import argparse
from itertools import combinations
from pathlib import Path

import numpy as np
from _common import AREA, INERTIA, L_LOWER, RHO, E, R
from scipy.integrate import quad
from scipy.special import ellipk

HERE = Path(__file__).resolve().parent
L = L_LOWER
CODES = {"beamcontact": "vib_bc_{tag}.csv", "PyElastica": "vib_pyelastica_{tag}.csv",
         "Exudyn": "vib_exudyn_{tag}.csv"}


def load(path: Path):
    d = np.genfromtxt(path, delimiter=",", names=True)
    return d["t"], d["A_uy"]


def zero_crossings(t, a):
    """Times where A_uy changes sign (linear interpolation), t = 0 excluded."""
    s = np.sign(a)
    k = np.nonzero((s[:-1] * s[1:] < 0) & (t[:-1] > 0))[0]
    return t[k] - a[k] * (t[k + 1] - t[k]) / (a[k + 1] - a[k])


def first_minimum(t, a):
    """First local minimum of A_uy (parabola through the sampled minimum)."""
    for i in range(1, len(a) - 1):
        if a[i] <= a[i - 1] and a[i] < a[i + 1]:
            y0, y1, y2 = a[i - 1:i + 2]
            h = 0.5 * (t[i + 1] - t[i - 1])
            den = y0 - 2 * y1 + y2
            dx = 0.5 * (y0 - y2) / den if den != 0 else 0.0
            return t[i] + dx * h, y1 - 0.25 * (y0 - y2) * dx
    return np.nan, np.nan


def theory(V: float) -> None:
    w0 = (np.pi / L) ** 2 * np.sqrt(E * INERTIA / (RHO * AREA))
    T1 = 2 * L**2 / np.pi * np.sqrt(RHO * AREA / (E * INERTIA))
    beta = (E / RHO) * (np.pi / L) ** 4 / 4
    # amplitude from the energy 0.5 V^2 = 0.5 w0^2 a^2 + 0.25 beta a^4
    a2 = (-w0**2 + np.sqrt(w0**4 + 2 * beta * V**2)) / beta
    amp = np.sqrt(a2)

    def integrand(theta):  # period of q'' + w0^2 q + beta q^3 = 0, amplitude amp
        x = amp * np.sin(theta)
        pot = lambda y: 0.5 * w0**2 * y**2 + 0.25 * beta * y**4  # noqa: E731
        return amp * np.cos(theta) / np.sqrt(2 * (pot(amp) - pot(x)))

    T_duff = 4 * quad(integrand, 0, np.pi / 2, limit=200)[0]
    T_cubic = 4 * ellipk(0.5) / (amp * np.sqrt(beta))
    print(f"closed forms (L = {L} m, R = {R} m, rho = {RHO}, E = {E:g}): linear first mode "
          f"T1 = 2 L^2/pi sqrt(rho A/(E I)) = {T1:.5f} s (w0 = {w0:.5f} rad/s, linear "
          f"amplitude V/w0 = {V / w0:.4g} m); radius of gyration r = R/2 = {R / 2} m")
    print(f"single-mode Duffing estimate (immovable ends, axial inertia neglected, "
          f"beta = {beta:.4g} 1/(m^2 s^2)): amplitude {amp:.4g} m (a/r = {amp / (R / 2):.3g}),"
          f" period {T_duff:.5f} s (pure cubic: {T_cubic:.5f} s), mean stretch at the "
          f"amplitude {(np.pi * amp / L) ** 2 / 4:.3%}")


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("runs", nargs="*", help="label=path (default: the three codes of --tag)")
    ap.add_argument("--tag", default="V7", help="file tag, e.g. V7, V0.07, V0.0007")
    ap.add_argument("--dir", type=Path, default=HERE / "results")
    ap.add_argument("--windows", type=float, nargs="+", default=[0.9, 1.0, 1.1, 1.2],
                    help="ends T of the windows 0..T [s]")
    ap.add_argument("--at", type=float, nargs="+", default=[1.2],
                    help="times of the signed differences [s]")
    ap.add_argument("--V", type=float, default=None, help="velocity amplitude (default: "
                    "from the tag)")
    a = ap.parse_args(argv)
    if a.runs:
        runs = {r.split("=", 1)[0]: Path(r.split("=", 1)[1]) for r in a.runs}
    else:
        runs = {k: a.dir / v.format(tag=a.tag) for k, v in CODES.items()}
    V = a.V if a.V is not None else float(a.tag.lstrip("V"))
    curves = {k: load(p) for k, p in runs.items()}
    t_end = min(c[0][-1] for c in curves.values())
    grid = np.arange(0.0, t_end + 1e-12, 2.5e-4)
    on = {k: np.interp(grid, t, y) for k, (t, y) in curves.items()}
    windows = [w for w in a.windows if w <= t_end + 1e-9]
    if t_end > max(a.windows) + 1e-9:
        windows.append(t_end)
    at = [x for x in a.at if x <= t_end + 1e-9]
    print(f"V = {V} m/s; runs: " + ", ".join(f"{k} = {p}" for k, p in runs.items()))
    print(f"max |difference| of A_uy [cm] over 0..T (T in s); signed difference first - "
          f"second [cm] at the times given, and where the maximum over 0..{windows[-1]:g} s "
          f"occurs")
    print("| pair | " + " | ".join(f"0..{w:g}" for w in windows)
          + " | " + " | ".join(f"d({x:g})" for x in at) + " | t of max |")
    print("|---" * (len(windows) + len(at) + 2) + "|")
    for x, y in combinations(on, 2):
        d = on[x] - on[y]
        cells = [f"{100 * np.abs(d[grid <= w + 1e-9]).max():.3f}" for w in windows]
        signed = [f"{100 * d[np.argmin(np.abs(grid - s))]:+.3f}" for s in at]
        w_end = grid <= windows[-1] + 1e-9
        print(f"| {x} - {y} | " + " | ".join(cells + signed)
              + f" | {grid[w_end][np.argmax(np.abs(d[w_end]))]:.3f} |")
    print()
    print("| run | first min A_uy [m] | at t [s] | A_uy(1.2) [m] | zero crossings [s] "
          "| period: 2 x first crossing, second crossing, 4 x first-min time [s] |")
    print("|---|---|---|---|---|---|")
    for k, (t, y) in curves.items():
        tm, ym = first_minimum(t, y)
        zc = zero_crossings(t, y)
        i12 = np.argmin(np.abs(grid - 1.2))
        per = [f"{2 * zc[0]:.5f}" if len(zc) > 0 else "-",
               f"{zc[1]:.5f}" if len(zc) > 1 else "-", f"{4 * tm:.5f}"]
        print(f"| {k} | {ym:.5g} | {tm:.5f} | {on[k][i12]:.5g} | "
              + ", ".join(f"{z:.5f}" for z in zc[:6]) + " | " + ", ".join(per) + " |")
    print()
    theory(V)


if __name__ == "__main__":
    main()
