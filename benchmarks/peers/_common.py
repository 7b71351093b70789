"""Shared helpers of the peer scripts in benchmarks/peers (not a script of its own).

Only the pieces that the drop and the vibration scripts of every code share: the
problem's parameters, the command-line options common to all runs, the element count of a
mesh, the output sampling, the step loop with its timing, and the CSV writer. They import
nothing beyond NumPy, so every script (beamcontact's, PyElastica's, Exudyn's) can use
them.
"""

from __future__ import annotations

import argparse
import csv
import os
import time
from collections.abc import Callable, Iterable, Sequence

import numpy as np

# The problem of every peer script (benchmarks/peers/README.md): circular section, material
G = 9.81  # gravity on the falling beam [m/s^2]
R = 0.1  # radius of both beams [m]
RHO = 1000.0  # density [kg/m^3]
# The problem: "drop" (the peer drop: a 4 m beam from x = 3 to 7, E = 1e7 Pa, surface gap
# 2.76 m) or, with PEER_PROBLEM=bundled, the bundled benchmark examples/free_fall/case_cg.toml
# (a 3 m beam from x = 3.5 to 6.5, E = 0.98e6 Pa, surface gap 2.759 m: Fig. 7 of the paper).
# Environment variables, because every script reads them when it is imported.
PROBLEM = os.environ.get("PEER_PROBLEM", "drop")
if PROBLEM not in ("drop", "bundled"):
    raise SystemExit(f"PEER_PROBLEM={PROBLEM!r}: 'drop' or 'bundled'")
_BUNDLED = PROBLEM == "bundled"
# Young's modulus [Pa]; PEER_E overrides it (the stiff case of benchmarks/peers.py)
E = float(os.environ.get("PEER_E", "0.98e6" if _BUNDLED else "1.0e7"))
AREA = np.pi * R**2
INERTIA = np.pi * R**4 / 4
MU = RHO * AREA  # mass per length [kg/m]
L_LOWER = 10.0  # length of the pinned lower beam (and of the vibration tests) [m]
GAP = 2.759 if _BUNDLED else 2.76  # initial surface gap of the drop [m]
Y_FALL = GAP + 2 * R  # axis of the falling beam [m]
X_FALL = (3.5, 6.5) if _BUNDLED else (3.0, 7.0)  # ends of the falling beam [m]
L_FALL = X_FALL[1] - X_FALL[0]  # its length [m]


def parser(doc: str, out: str, *, dt: float, dx: float | None = None, V: bool = False,
           dt_help: str = "time step [s]") -> argparse.ArgumentParser:
    """An argument parser with the options every run shares: ``--out``, (``--V`` for the
    vibration tests), ``--dt``, ``--t-end`` (default 1.2 s) and (``--dx``)."""
    ap = argparse.ArgumentParser(description=doc.split("\n")[0])
    ap.add_argument("--out", default=out, help="output CSV")
    if V:
        ap.add_argument("--V", type=float, default=7.0,
                        help="amplitude of the sine velocity [m/s]")
    ap.add_argument("--dt", type=float, default=dt, help=dt_help)
    ap.add_argument("--t-end", type=float, default=1.2, help="end time [s]")
    if dx is not None:
        ap.add_argument("--dx", type=float, default=dx, help="element length [m]")
    return ap


def add_max_rows(ap: argparse.ArgumentParser) -> None:
    ap.add_argument("--max-rows", type=int, default=2000, help="rows written at most")


def even_elements(length: float, dx: float) -> int:
    """Number of elements of length about dx on a beam, rounded up to an even number (so
    that the midspan is a node)."""
    n = int(round(length / dx))
    return n + n % 2


def sampling(t_end: float, dt: float, max_rows: int) -> tuple[int, int]:
    """(number of steps, one output row every so many steps) for at most max_rows rows."""
    nsteps = int(round(t_end / dt))
    return nsteps, max(1, int(np.ceil((nsteps + 1) / max_rows)))


def step_loop(step: Callable[[object], object], t, nsteps: int, every: int,
              record: Callable[[object], None]) -> tuple[float, float]:
    """Calls ``t = step(t)`` nsteps times and ``record(t)`` every ``every`` steps and after
    the last; returns (seconds in ``step``, seconds of the whole loop)."""
    wall = 0.0  # time spent stepping, without the (slow, Python) sampling
    t_all = time.perf_counter()
    for k in range(1, nsteps + 1):
        t0 = time.perf_counter()
        t = step(t)
        wall += time.perf_counter() - t0
        if k % every == 0 or k == nsteps:
            record(t)
    return wall, time.perf_counter() - t_all


def check_stable(arr: np.ndarray, limit: float) -> None:
    """Stops with a message if the sampled rows hold a non-finite value or |A_uy| > limit."""
    if not np.all(np.isfinite(arr)) or np.abs(arr[:, 1]).max() > limit:
        raise SystemExit("unstable run (non-finite or exploding state): the step is too large")


def write_csv(path, header: Sequence[str], rows: Iterable[Sequence[float]],
              formats: Sequence[str]) -> None:
    """Writes the rows with one format spec per column (e.g. ``".9g"``)."""
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(header)
        for r in rows:
            w.writerow([format(x, f) for x, f in zip(r, formats, strict=True)])
