"""Peer reference for the beam drop: Exudyn (2D ANCF cable elements, implicit, no damping).

What is modelled
----------------
Two elastic beams with circular sections (R = 0.1 m, density 1000 kg/m^3, E = 1e7 Pa:
EA = E pi R^2, EI = E pi R^4 / 4, mass per length rho pi R^2), in the x-y plane:

* lower beam: 10 m from (0, 0) to (10, 0), pinned at both ends (the two position
  coordinates of the end nodes are constrained, the slopes are free), no gravity;
* falling beam: 4 m, x from 3 to 7 m, axis at y = 2.96 m (surface gap 2.76 m), free, at rest,
  gravity (0, -9.81) m/s^2 on it only (``Gravity`` load on ``MarkerBodyMass``).

Output: the lower beam's midspan node vertical displacement ``A_uy`` (m), the total energy
``E_total`` (J; kinetic, axial + bending strain, gravity, contact penalty; evaluated in
post-processing from the written nodal coordinates and velocities with the element's
cubic Hermite shape functions and 5-point Gauss quadrature) and the falling beam's
centre-of-mass height ``yc_fall`` (m).

Discretisation
--------------
``ObjectANCFCable2D`` (Bernoulli-Euler ANCF cable: cubic Hermite interpolation of the
centre line, nodes ``NodePoint2DSlope1`` with position and slope, consistent mass, no shear
and no rotary inertia). Default element length 0.1 m: 100 elements on the lower beam, 40 on
the falling beam (``--dx``). Refinement on this machine (max |difference| of A_uy over
0..1.2 s): dx 0.1 -> 0.05: 0.3 cm; dt 1e-4 -> 5e-5: 0.8 cm.

Integrator
----------
``exudyn.SolveDynamic`` with the implicit generalized-alpha solver at spectralRadius = 1
(alpha_m = alpha_f = 1/2, Newmark beta = 1/4, gamma = 1/2: the trapezoidal rule, no
numerical damping), fixed step ``--dt`` (default 1e-4 s), Exudyn's modified Newton with its
default tolerances (``--full-newton`` gives the same history, 2-3x slower), contact
switching by Exudyn's discontinuous (post-Newton) iteration. No material damping
(bendingDamping = axialDamping = 0). dt = 2.5e-4 s is not enough for this contact
stiffness: it loses 260 J (7 %) at the first impact and moves A_uy by up to 13 cm.

Contact
-------
``mbs.AddGeneralContact()``: contact circles (``AddSphereWithMarker`` on
``MarkerBodyPosition`` markers, radius R) along the falling beam's axis at spacing
``--circle-spacing`` (default 0.05 m, element nodes included); the lower beam's cable
elements are added with ``AddANCFCable`` (half height R, exact cable geometry), so contact
starts when the centre-line distance reaches 2R. No damping, no friction (friction pairing
0), ``keepContactWhilePenetrating = True``. The contact is one-sided (falling-beam circles
against the lower beam's cable); with s = 0.05 m the scallops between circles are 3 mm deep.

Force law (measured here, not stated in the docs): GeneralContact integrates the
penetration along the cable, i.e. a force density k * pen(s) over the part of the cable
inside the circle of radius 2R, with k the series combination of the two entered
stiffnesses (both are entered as 2 k). For one circle on a straight cable this is
F = (4/3) sqrt(2 * 2R) k d^1.5 = 0.84 k d^1.5 (d the penetration) - a test with a
0.785 kg circle hitting a fixed cable at 7.36 m/s gave d = 3.32 mm against 3.31 mm from this
law and a restitution of 1.000 at dt = 2.5e-5 s (0.998 at 1e-4 s, 0.978 at 2.5e-4 s), so the
law is conservative with energy 0.5 k * integral pen(s)^2 ds, which is what ``E_total``
uses. The test also showed a loss of energy (restitution 0.61) when the penetration is as
deep as 3 cm, so the stiffness must keep penetrations small. Default k = 1e8 N/m^2: about
3.3 mm penetration at the first impact, the same as the PyElastica peer's linear
k_line = 1e8 N/m^2. Sensitivity: k = 1e7 (dt 2.5e-4) changes A_uy by up to 4.9 cm, a circle
spacing of 0.025 m (twice the circles, a stiffer line contact) by up to 2.0 cm, both only
near t = 1.19 s.

Energy
------
Evaluated in post-processing from the written nodal coordinates and velocities with the
element's Hermite shape functions and 5-point Gauss quadrature: kinetic (consistent mass),
axial 0.5 EA (|r'| - 1)^2, bending 0.5 EI kappa^2 with kappa = (r' x r'') / |r'|^2,
gravity, and the contact energy above (64 sampling points per lower element).

Usage
-----
    python benchmarks/peers/drop_exudyn.py --out benchmarks/peers/results/exudyn.csv
"""

from __future__ import annotations

import os
import shutil
import tempfile
import time

import _common as common
import exudyn as exu
import numpy as np
from _common import AREA, INERTIA, L_FALL, MU, X_FALL, Y_FALL, E, G, R
from exudyn.beams import GenerateBeamElementsAlongLine
from exudyn.itemInterface import (
    MarkerBodyPosition,
    ObjectANCFCable2D,
)


def cable_template() -> ObjectANCFCable2D:
    """The ANCF cable element of both beams (the section and material above, no damping)."""
    return ObjectANCFCable2D(
        massPerLength=MU, bendingStiffness=E * INERTIA, axialStiffness=E * AREA,
        bendingDamping=0.0, axialDamping=0.0,
    )


def add_lower_beam(mbs, n: int) -> dict:
    """The lower beam: n cable elements from (0, 0) to (10, 0), end positions fixed (pinned:
    the slopes are free), no gravity. Returns GenerateBeamElementsAlongLine's dict."""
    return GenerateBeamElementsAlongLine(
        mbs, [0.0, 0.0, 0.0], [10.0, 0.0, 0.0], n, cable_template(),
        groundConstraintsStart=[1, 1, 0, 0], groundConstraintsEnd=[1, 1, 0, 0],
    )


def build(n_lower: int, n_fall: int, circles_per_element: int, k: float):
    SC = exu.SystemContainer()
    mbs = SC.AddSystem()
    lower = add_lower_beam(mbs, n_lower)
    fall = GenerateBeamElementsAlongLine(
        mbs, [X_FALL[0], Y_FALL, 0.0], [X_FALL[1], Y_FALL, 0.0], n_fall, cable_template(),
        gravity=[0.0, -G, 0.0],
    )

    gc = mbs.AddGeneralContact()
    gc.verboseMode = 0
    gc.sphereSphereContact = False
    gc.keepContactWhilePenetrating = True
    gc.ancfCableUseExactMethod = True
    gc.SetFrictionPairings(np.zeros((1, 1)))
    gc.SetSearchTreeCellSize(numberOfCells=[40, 8, 1])
    gc.SetSearchTreeBox(pMin=np.array([-1.0, -4.0, -1.0]), pMax=np.array([11.0, 4.0, 1.0]))

    le_fall = L_FALL / n_fall
    s = le_fall / circles_per_element
    n_circles = 0
    for i, el in enumerate(fall["elements"]):
        for c in range(circles_per_element + (1 if i == n_fall - 1 else 0)):
            m = mbs.AddMarker(MarkerBodyPosition(bodyNumber=el, localPosition=[c * s, 0.0, 0.0]))
            gc.AddSphereWithMarker(m, radius=R, contactStiffness=2 * k, contactDamping=0.0,
                                   frictionMaterialIndex=0)
            n_circles += 1
    for el in lower["elements"]:
        gc.AddANCFCable(objectIndex=el, halfHeight=R, contactStiffness=2 * k,
                        contactDamping=0.0, frictionMaterialIndex=0)
    mbs.Assemble()
    return SC, mbs, lower, fall, n_circles, s


# ---------------------------------------------------------------- post-processing (energy)
_GP, _GW = np.polynomial.legendre.leggauss(5)


def _hermite(xi, L):
    """Cubic Hermite shapes (position, slope*L) and derivatives w.r.t. x at xi in [0, 1]."""
    s = np.array([1 - 3 * xi**2 + 2 * xi**3, L * (xi - 2 * xi**2 + xi**3),
                  3 * xi**2 - 2 * xi**3, L * (-xi**2 + xi**3)])
    ds = np.array([-6 * xi + 6 * xi**2, L * (1 - 4 * xi + 3 * xi**2),
                   6 * xi - 6 * xi**2, L * (-2 * xi + 3 * xi**2)]) / L
    dds = np.array([-6 + 12 * xi, L * (-4 + 6 * xi), 6 - 12 * xi, L * (-2 + 6 * xi)]) / L**2
    return s, ds, dds


def _element_arrays(q, L):
    """q: (n_el, 4, 2) = [r0, r0', r1, r1'] per element; returns r, r', r'' at Gauss points."""
    xi = 0.5 * (_GP + 1)
    S, dS, ddS = _hermite(xi, L)  # (4, ng)
    r = np.einsum("kg,ekd->egd", S, q)
    dr = np.einsum("kg,ekd->egd", dS, q)
    ddr = np.einsum("kg,ekd->egd", ddS, q)
    return r, dr, ddr


def _beam_energy(q, qd, L, gravity: bool):
    w = 0.5 * L * _GW
    r, dr, ddr = _element_arrays(q, L)
    v = _element_arrays(qd, L)[0]
    ekin = 0.5 * MU * np.einsum("g,egd->", w, v * v)
    nrm2 = np.einsum("egd,egd->eg", dr, dr)
    eps = np.sqrt(nrm2) - 1.0
    kappa = (dr[..., 0] * ddr[..., 1] - dr[..., 1] * ddr[..., 0]) / nrm2
    estr = 0.5 * E * AREA * np.einsum("g,eg->", w, eps**2)
    estr += 0.5 * E * INERTIA * np.einsum("g,eg->", w, kappa**2)
    egrav = MU * G * np.einsum("g,eg->", w, r[..., 1]) if gravity else 0.0
    ymean = np.einsum("g,eg->", w, r[..., 1]) / (L * q.shape[0])
    return ekin + estr + egrav, ymean


def _curve_points(q, L, n=64):
    """Points and midpoint-rule arc-length weights (ds) along the cable, n per element."""
    xi = (np.arange(n) + 0.5) / n
    S, dS, _ = _hermite(xi, L)
    pts = np.einsum("kg,ekd->egd", S, q).reshape(-1, 2)
    ds = (L / n) * np.sqrt((np.einsum("kg,ekd->egd", dS, q) ** 2).sum(-1)).reshape(-1)
    return pts, ds


def _contact_energy(circles, pts, ds, k):
    """GeneralContact circle-cable law: force density k * pen(s) along the cable, where
    pen(s) = R + R - |c - r(s)| > 0; its potential is k/2 * integral pen(s)^2 ds."""
    lo, hi = circles.min(0) - 2 * R, circles.max(0) + 2 * R
    near = np.all((pts > lo) & (pts < hi), axis=1)  # bounding-box pre-filter
    if not near.any():
        return 0.0
    pts, ds = pts[near], ds[near]
    d = np.sqrt(((circles[:, None, :] - pts[None, :, :]) ** 2).sum(-1))
    pen = np.clip(2 * R - d, 0.0, None)
    return 0.5 * k * float((pen**2 * ds[None, :]).sum())


def _to_elements(nodes_q):
    """(n_nodes, 4) nodal [x, y, x', y'] -> (n_el, 4, 2)."""
    a = nodes_q.reshape(-1, 2, 2)  # node, (pos, slope), xy
    return np.concatenate([a[:-1], a[1:]], axis=1)


# ---------------------------------------------------------------- solving, reading back
def solve(mbs, t_end: float, dt: float, nsteps: int, every: int, prefix: str, *,
          spectral_radius: float = 1.0, full_newton: bool = False,
          abs_tol: float | None = None, discontinuous_iterations: int | None = None):
    """Runs ``exu.SolveDynamic`` (generalized-alpha at ``spectral_radius``, fixed step dt,
    modified Newton unless ``full_newton``, Exudyn's default Newton tolerances unless
    ``abs_tol``, one solution row every ``every`` steps), prints its wall time and returns
    the written times, coordinates and velocities (t, q, v; q and v: (rows, ODE2 size))."""
    tmp = tempfile.mkdtemp(prefix=prefix)
    sol_file = os.path.join(tmp, "solution.txt")
    st = exu.SimulationSettings()
    ti = st.timeIntegration
    ti.endTime = t_end
    ti.numberOfSteps = nsteps
    ti.generalizedAlpha.spectralRadius = spectral_radius
    ti.generalizedAlpha.computeInitialAccelerations = True
    ti.newton.useModifiedNewton = not full_newton
    if abs_tol is not None:
        ti.newton.absoluteTolerance = abs_tol
    if discontinuous_iterations is not None:
        ti.discontinuous.maxIterations = discontinuous_iterations
    ti.adaptiveStep = False
    ti.verboseMode = 0
    st.linearSolver.solverType = exu.LinearSolverType.EigenSparse
    st.parallel.numberOfThreads = 1
    f = st.solution.file
    f.write = True
    f.name = sol_file
    f.writePeriod = every * dt * (1 - 1e-6)  # one row every `every` steps
    st.solution.precision = 12
    f.export.velocities = True
    f.export.accelerations = False
    f.export.algebraicCoordinates = False
    f.export.dataCoordinates = False
    f.export.ODE1Velocities = False
    st.solution.sensors.active = False
    st.show.statistics = False

    t0 = time.perf_counter()
    ok = exu.SolveDynamic(mbs, st, solverType=exu.DynamicSolverType.GeneralizedAlpha,
                          showHints=True)
    wall = time.perf_counter() - t0
    print(f"wall time (SolveDynamic incl. solution-file output): {wall:.2f} s, success = {ok}")

    data = np.loadtxt(sol_file, comments="#", delimiter=",")
    shutil.rmtree(tmp, ignore_errors=True)
    n2 = mbs.systemData.ODE2Size()
    return data[:, 0], data[:, 1:1 + n2], data[:, 1 + n2:1 + 2 * n2]


def node_dofs(mbs, nodes):
    """ODE2 indices of the nodes' 4 coordinates (x, y, x', y') and their reference values
    (n_nodes, 4)."""
    idx = np.array([mbs.GetNodeODE2Index(n) + k for n in nodes for k in range(4)])
    ref = np.array([mbs.GetNodeParameter(n, "referenceCoordinates") for n in nodes])
    return idx, ref


def main(argv=None) -> None:
    ap = common.parser(__doc__, "exudyn.csv", dt=1.0e-4, dx=0.1)
    ap.add_argument("--circle-spacing", type=float, default=0.05,
                    help="spacing of the contact circles along the falling beam [m]")
    ap.add_argument("--k", type=float, default=1.0e8,
                    help="GeneralContact stiffness (force per length per penetration) [N/m^2]")
    ap.add_argument("--spectral-radius", type=float, default=1.0,
                    help="generalized-alpha rho_inf (1: trapezoidal rule, no damping)")
    ap.add_argument("--full-newton", action="store_true",
                    help="full Newton (Jacobian every iteration); default: Exudyn's modified "
                         "Newton (Jacobian reused while it converges; same tolerances)")
    common.add_max_rows(ap)
    ap.add_argument("--no-energy", action="store_true", help="skip the energy post-processing")
    a = ap.parse_args(argv)

    n_lower = common.even_elements(10.0, a.dx)
    n_fall = int(round(L_FALL / a.dx))
    cpe = max(1, int(round(L_FALL / n_fall / a.circle_spacing)))
    SC, mbs, lower, fall, n_circles, s = build(n_lower, n_fall, cpe, a.k)
    nsteps, every = common.sampling(a.t_end, a.dt, a.max_rows)

    print(f"Exudyn {exu.__version__} drop: ANCFCable2D elements lower/fall = "
          f"{n_lower}/{n_fall} (dx = {a.dx} m), dt = {a.dt}, steps = {nsteps}, "
          f"t_end = {a.t_end}, generalized-alpha spectralRadius = {a.spectral_radius}, "
          f"GeneralContact: {n_circles} circles (spacing {s:g} m) vs lower cable, "
          f"k = {a.k:g} N/m^2, no damping, no friction")
    t, q_all, v_all = solve(mbs, a.t_end, a.dt, nsteps, every, "exudyn_drop_",
                            spectral_radius=a.spectral_radius, full_newton=a.full_newton,
                            discontinuous_iterations=8)
    il, ref_l = node_dofs(mbs, lower["nodes"])
    iff, ref_f = node_dofs(mbs, fall["nodes"])
    mid = n_lower // 2
    a_uy = q_all[:, il].reshape(len(t), -1, 4)[:, mid, 1]  # displacement coordinates

    e_tot = np.full(len(t), np.nan)
    yc = np.full(len(t), np.nan)
    le_l, le_f = 10.0 / n_lower, L_FALL / n_fall
    for j in range(len(t)):
        ql = ref_l + q_all[j, il].reshape(-1, 4)
        qf = ref_f + q_all[j, iff].reshape(-1, 4)
        ef, yc[j] = _beam_energy(_to_elements(qf), _to_elements(v_all[j, iff].reshape(-1, 4)),
                                 le_f, True)
        if a.no_energy:
            continue
        el, _ = _beam_energy(_to_elements(ql), _to_elements(v_all[j, il].reshape(-1, 4)),
                             le_l, False)
        xi = np.arange(cpe) / cpe
        S, _, _ = _hermite(xi, le_f)
        circ = np.einsum("kg,ekd->egd", S, _to_elements(qf)).reshape(-1, 2)
        circ = np.vstack([circ, qf[-1, :2]])
        pts, ds = _curve_points(_to_elements(ql), le_l)
        ec = _contact_energy(circ, pts, ds, a.k)
        e_tot[j] = el + ef + ec

    common.write_csv(a.out, ["t", "A_uy", "E_total", "yc_fall"],
                     zip(t, a_uy, e_tot, yc, strict=True), [".6g", ".9g", ".9g", ".9g"])
    i = int(np.argmin(a_uy))
    print(f"min A_uy = {a_uy[i]:.4f} m at t = {t[i]:.4f} s", end="")
    if not a.no_energy:
        print(f"; E_total drift max|E-E0| = {np.nanmax(np.abs(e_tot - e_tot[0])):.3g} J "
              f"(E0 = {e_tot[0]:.6g} J)")
    else:
        print()
    print(f"wrote {a.out} ({len(t)} rows)")


if __name__ == "__main__":
    main()
