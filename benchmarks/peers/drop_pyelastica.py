"""Peer reference for the beam drop: PyElastica (Cosserat rods, explicit, symplectic).

What is modelled
----------------
Two elastic rods with circular sections (R = 0.1 m, density 1000 kg/m^3, E = 1e7 Pa),
planar motion in the x-y plane (the 3-D code stays exactly planar: every load lies in the
plane and the initial state is planar):

* lower beam: 10 m from (0, 0) to (10, 0), pinned at both ends (end node positions fixed,
  directors free, i.e. rotations free), no gravity;
* falling beam: 4 m, x from 3 to 7 m, axis at y = 2.96 m (surface gap 2.76 m), free, at rest,
  gravity (0, -9.81) m/s^2 on it only.

Output: the lower beam's midspan node vertical displacement ``A_uy`` (m), the total energy
``E_total`` (J; kinetic translational + rotational, bending, shear + stretch, gravity, contact)
and the falling beam's centre-of-mass height ``yc_fall`` (m).

Discretisation
--------------
``elastica.CosseratRod.straight_rod`` (Gazzola et al. 2018 discrete Cosserat rod: nodes carry
positions and lumped masses, elements carry directors and rotary inertia; shear- and
extension-deformable). Shear modulus G = E / 3 (PyElastica's default, Poisson 0.5).
Default element length 0.025 m: 400 elements on the lower beam, 160 on the falling beam
(``--dx``). Refinement on this machine (max |difference| of A_uy over 0..1.2 s, all at
t ~ 1.18-1.2 s): dx 0.05 -> 0.025: 1.3 cm; dx 0.025 -> 0.0125 (dt 5e-5): 0.5 cm;
dt 1e-4 -> 5e-5: 0.7 cm (dx 0.025) and 0.2 cm (dx 0.05).

Integrator
----------
``elastica.PositionVerlet``: second-order, explicit, symplectic, no numerical damping; no
damper modules are added. Fixed step ``--dt`` (default 1e-4 s). At dx = 0.05 m the run is
stable at dt = 4e-4 s and blows up at 7e-4 s.

Contact
-------
Frictionless penalty, written here as a PyElastica contact class (subclass of
``elastica.NoContact``, applied through ``detect_contact_between``), because PyElastica's own
``RodRodContact`` is not conservative: besides the penalty k*gap and the damping nu it adds
a force that cancels the rods' compressive internal/external forces (marked "FIX ME" in
its source) and applies each element pair's force to both element nodes, so it has no
energy and its stiffness is not a line stiffness. ``--contact builtin`` runs it anyway
(``RodRodContact(k, nu=0)``) for comparison.

The default ``--contact penalty`` is a two-pass node-to-segment line penalty with an
energy: for every node i of one rod, q_i = (distance from the node to the other rod's
centre-line polyline) - (R1 + R2); energy ``0.5 * k_line * w_i * q_i**2`` for q_i < 0, where
w_i is the node's tributary reference length (dx, dx/2 at the ends). Both rods act as the
slave in turn with half weight each, so the stiffness per unit contact length is
``k_line`` (N/m^2). The forces are the exact gradient of this energy (closest-point
projection, envelope theorem), so the contact is conservative and its energy is part of
``E_total``. Default k_line = 1e8 N/m^2: penetration at the first impact of the two beams
(relative velocity 7.4 m/s, 15.7 kg/m effective mass per length) is about
v * sqrt(m_eff / k_line) = 3 mm; the contact frequency sqrt(k_line / m_eff) = 2.5e3 rad/s
gives omega*dt = 0.25 at dt = 1e-4 s (Verlet limit 2). Sensitivity (dx = 0.05 / 0.1):
k_line 1e8 -> 1e9 (dt 5e-5) changes A_uy by at most 1.1 cm, 1e8 -> 1e7 by 2.8 cm.

Energy
------
``E_total`` uses PyElastica's own ``compute_*_energy`` functions plus gravity and contact.
Those energies are not the exact potential of PyElastica's discrete internal forces at
finite stretch (the forces carry extra 1/dilatation factors): a contact-free test (the
pinned lower beam given a 7 m/s sine velocity) shows the same 3 % wander of E_total,
independent of dt. Here E_total is conserved to 1e-11 J in free fall and wanders by +17 to
+111 J (<= 3 %) after the impact for the same reason, the same at dt = 1e-4 and 5e-5 s;
it is a diagnostic, not a proof of conservation.

Usage
-----
    python benchmarks/peers/drop_pyelastica.py --out benchmarks/peers/results/pyelastica.csv
"""

from __future__ import annotations

import _common as common
import elastica as ea
import numpy as np
from _common import L_FALL, RHO, X_FALL, Y_FALL, E, G, R
from numba import njit


@njit(cache=True)
def _penalty_pass(xs, ws, xm, k, rsum, fs, fm, apply):
    """One slave pass: nodes xs (3, ns) with weights ws against the polyline xm (3, nm).

    Adds forces to fs, fm when apply is True; returns the penalty energy.
    """
    ns = xs.shape[1]
    nm = xm.shape[1]
    energy = 0.0
    for i in range(ns):
        best_d = 1e300
        best_j = -1
        best_s = 0.0
        for j in range(nm - 1):
            a0 = xm[0, j]
            a1 = xm[1, j]
            a2 = xm[2, j]
            e0 = xm[0, j + 1] - a0
            e1 = xm[1, j + 1] - a1
            e2 = xm[2, j + 1] - a2
            ee = e0 * e0 + e1 * e1 + e2 * e2
            s = ((xs[0, i] - a0) * e0 + (xs[1, i] - a1) * e1 + (xs[2, i] - a2) * e2) / ee
            s = min(max(s, 0.0), 1.0)
            d0 = xs[0, i] - a0 - s * e0
            d1 = xs[1, i] - a1 - s * e1
            d2 = xs[2, i] - a2 - s * e2
            d = np.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
            if d < best_d:
                best_d = d
                best_j = j
                best_s = s
        q = best_d - rsum
        if q >= 0.0 or best_j < 0:
            continue
        kk = k * ws[i]
        energy += 0.5 * kk * q * q
        if apply:
            j = best_j
            s = best_s
            for c in range(3):
                cp = xm[c, j] + s * (xm[c, j + 1] - xm[c, j])
                n = (xs[c, i] - cp) / best_d
                f = -kk * q * n  # repulsive, on the slave node
                fs[c, i] += f
                fm[c, j] -= (1.0 - s) * f
                fm[c, j + 1] -= s * f
    return energy


def _weights(n_nodes, length):
    dx = length / (n_nodes - 1)
    w = np.full(n_nodes, dx)
    w[0] = w[-1] = 0.5 * dx
    return w


class LinePenaltyContact(ea.NoContact):
    """Conservative frictionless two-pass node-to-segment line penalty (see module doc)."""

    def __init__(self, k_line: float, w_one: np.ndarray, w_two: np.ndarray) -> None:
        super().__init__()
        self.k_line = float(k_line)
        self.w_one = 0.5 * np.asarray(w_one, dtype=np.float64)
        self.w_two = 0.5 * np.asarray(w_two, dtype=np.float64)

    def energy_and_forces(self, one, two, apply: bool) -> float:
        # the reference radii, not rod.radius: PyElastica shrinks an element's radius as it
        # stretches (constant volume), which made this energy depend on the stretch of
        # the end elements and the contact non-conservative (+4 % of E_total at the
        # first impact of the bundled problem)
        rsum = 2.0 * R
        x1 = one.position_collection
        x2 = two.position_collection
        f1 = one.external_forces
        f2 = two.external_forces
        e = _penalty_pass(x1, self.w_one, x2, self.k_line, rsum, f1, f2, apply)
        e += _penalty_pass(x2, self.w_two, x1, self.k_line, rsum, f2, f1, apply)
        return e

    def apply_contact(self, system_one, system_two, time=0.0) -> None:
        # cheap pre-check: skip while rod one lies entirely above rod two (plus R1 + R2)
        y1 = system_one.position_collection[1]
        y2 = system_two.position_collection[1]
        if y1.min() - y2.max() > 2.0 * R:
            return
        self.energy_and_forces(system_one, system_two, True)


class Drop(ea.BaseSystemCollection, ea.Constraints, ea.Forcing, ea.Contact):
    pass


def build(n_lower: int, n_fall: int, contact: str, k_line: float, k_builtin: float,
          shear_factor: float = 1.0, rotary_factor: float = 1.0):
    sim = Drop()
    normal = np.array([0.0, 0.0, 1.0])
    lower = ea.CosseratRod.straight_rod(
        n_lower, np.array([0.0, 0.0, 0.0]), np.array([1.0, 0.0, 0.0]), normal,
        10.0, R, RHO, youngs_modulus=E, shear_modulus=shear_factor * E / 3.0,
    )
    fall = ea.CosseratRod.straight_rod(
        n_fall, np.array([X_FALL[0], Y_FALL, 0.0]), np.array([1.0, 0.0, 0.0]), normal,
        L_FALL, R, RHO, youngs_modulus=E, shear_modulus=shear_factor * E / 3.0,
    )
    for rod in (lower, fall):  # optional study: scale the rotary inertia
        rod.mass_second_moment_of_inertia *= rotary_factor
        rod.inv_mass_second_moment_of_inertia /= rotary_factor
    sim.append(lower)
    sim.append(fall)
    # pinned ends: positions fixed, directors (rotations) free
    sim.constrain(lower).using(
        ea.GeneralConstraint,
        constrained_position_idx=(0, -1),
        translational_constraint_selector=np.array([True, True, True]),
        rotational_constraint_selector=np.array([False, False, False]),
    )
    sim.add_forcing_to(fall).using(ea.GravityForces, acc_gravity=np.array([0.0, -G, 0.0]))
    if contact == "penalty":
        w_fall, w_lower = _weights(n_fall + 1, L_FALL), _weights(n_lower + 1, 10.0)
        sim.detect_contact_between(fall, lower).using(LinePenaltyContact, k_line, w_fall, w_lower)
        cont = LinePenaltyContact(k_line, w_fall, w_lower)  # twin, used for the energy only
    else:
        cont = None
        sim.detect_contact_between(fall, lower).using(ea.RodRodContact, k=k_builtin, nu=0.0)
    sim.finalize()
    return sim, lower, fall, cont


def energy(lower, fall, cont, t):
    e = 0.0
    for rod in (lower, fall):
        rod.compute_internal_forces_and_torques(t)  # refreshes sigma, kappa at current state
        e += rod.compute_translational_energy() + rod.compute_rotational_energy()
        e += rod.compute_bending_energy() + rod.compute_shear_energy()
    e += G * float(np.dot(fall.mass, fall.position_collection[1]))
    if cont is not None:
        e += cont.energy_and_forces(fall, lower, False)
    return float(e)


def main(argv=None) -> None:
    ap = common.parser(__doc__, "pyelastica.csv", dt=1.0e-4, dx=0.025)
    ap.add_argument("--contact", choices=["penalty", "builtin"], default="penalty",
                    help="penalty: the conservative line penalty of this script; builtin: "
                         "PyElastica's RodRodContact (see the module docstring)")
    ap.add_argument("--k-line", type=float, default=1.0e8,
                    help="penalty stiffness per unit contact length [N/m^2]")
    ap.add_argument("--k-builtin", type=float, default=1.0e6,
                    help="RodRodContact k for --contact builtin [N/m] (E_total then omits "
                         "the contact, which has no energy)")
    ap.add_argument("--shear-factor", type=float, default=1.0,
                    help="study: shear modulus = factor * E / 3 (large: shear-rigid, needs a "
                         "smaller dt)")
    ap.add_argument("--rotary-factor", type=float, default=1.0,
                    help="study: scale the rotary inertia (small -> none; needs smaller dt)")
    common.add_max_rows(ap)
    a = ap.parse_args(argv)

    n_lower = common.even_elements(10.0, a.dx)
    n_fall = int(round(L_FALL / a.dx))
    sim, lower, fall, cont = build(n_lower, n_fall, a.contact, a.k_line, a.k_builtin,
                                   a.shear_factor, a.rotary_factor)
    mid = n_lower // 2
    nsteps, every = common.sampling(a.t_end, a.dt, a.max_rows)
    stepper = ea.PositionVerlet()

    print(f"PyElastica drop: elements lower/fall = {n_lower}/{n_fall} (dx = {a.dx} m), "
          f"dt = {a.dt}, steps = {nsteps}, t_end = {a.t_end}, contact = {a.contact}, "
          + (f"k_line = {a.k_line:g} N/m^2" if a.contact == "penalty"
             else f"k = {a.k_builtin:g} N/m, nu = 0")
          + f", G = {a.shear_factor:g} * E/3, rotary inertia x {a.rotary_factor:g}")
    rows = []

    def record(t):
        rows.append((float(t), float(lower.position_collection[1, mid]),
                     energy(lower, fall, cont, t),
                     float(np.dot(fall.mass, fall.position_collection[1]) / fall.mass.sum())))

    # warm-up compile of the numba kernels outside the timing
    if cont is not None:
        cont.energy_and_forces(fall, lower, False)
    record(np.float64(0.0))
    wall, t_all = common.step_loop(lambda t: stepper.step(sim, t, a.dt), np.float64(0.0),
                                   nsteps, every, record)
    arr = np.array(rows)
    common.check_stable(arr, 10.0)
    common.write_csv(a.out, ["t", "A_uy", "E_total", "yc_fall"], rows, [".6g", ".9g", ".9g", ".9g"])
    print(f"wall time: step loop {wall:.2f} s; with energy/output sampling {t_all:.2f} s")
    print(f"min A_uy = {arr[:, 1].min():.4f} m at t = {arr[arr[:, 1].argmin(), 0]:.4f} s; "
          f"E_total drift max|E-E0| = {np.abs(arr[:, 2] - arr[0, 2]).max():.3g} J "
          f"(E0 = {arr[0, 2]:.6g} J)")
    print(f"wrote {a.out} ({len(rows)} rows)")


if __name__ == "__main__":
    main()
