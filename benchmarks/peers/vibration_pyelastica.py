"""Contact-free peer test, PyElastica: free vibration of the pinned 10 m beam.

The lower beam of the peer drop alone (built as in ``drop_pyelastica.py``: Cosserat rod
from (0, 0) to (10, 0), end node positions fixed, directors free; R = 0.1 m,
rho = 1000 kg/m^3, E = 1e7 Pa, G = E/3; no gravity, no contact), starting straight with
the node velocities

    v(x) = (0, -V sin(pi x / L)),  L = 10 m   (default V = 7 m/s)

and, by default, the element angular velocities of the same motion (the rotation rate of
the tangent, d v_y / dx = -V pi / L cos(pi x / L) at the element centres, about the
binormal z), so that the rod starts without shear rate (``--omega zero`` starts the
directors at rest instead). Integrator ``PositionVerlet`` (explicit, symplectic), fixed
step ``--dt``. Output: the midspan node's vertical displacement A_uy (m) and PyElastica's
energy diagnostic E_total (J; kinetic translational + rotational, bending, shear +
stretch: not the exact potential of its internal forces at finite stretch, see
README.md).

Output CSV ``t, A_uy, E_total``. Usage (from the repository root; about 10 s for 1.2 s):

    python benchmarks/peers/vibration_pyelastica.py \
        --out benchmarks/peers/results/vib_pyelastica_V7.csv
    python benchmarks/peers/vibration_pyelastica.py --V 0.07 --t-end 14 --max-rows 14001 \
        --out benchmarks/peers/results/vib_pyelastica_V0.07.csv
"""

from __future__ import annotations

import _common as common
import elastica as ea
import numpy as np
from _common import L_LOWER, RHO, E, R

L = L_LOWER


class Vibration(ea.BaseSystemCollection, ea.Constraints):
    pass


def build(n: int, V: float, omega: str, shear_factor: float = 1.0):
    sim = Vibration()
    rod = ea.CosseratRod.straight_rod(
        n, np.array([0.0, 0.0, 0.0]), np.array([1.0, 0.0, 0.0]), np.array([0.0, 0.0, 1.0]),
        L, R, RHO, youngs_modulus=E, shear_modulus=shear_factor * E / 3.0,
    )
    sim.append(rod)
    sim.constrain(rod).using(  # pinned ends, as in drop_pyelastica.build
        ea.GeneralConstraint,
        constrained_position_idx=(0, -1),
        translational_constraint_selector=np.array([True, True, True]),
        rotational_constraint_selector=np.array([False, False, False]),
    )
    sim.finalize()
    x = rod.position_collection[0].copy()
    vy = -V * np.sin(np.pi * x / L)
    vy[0] = vy[-1] = 0.0
    rod.velocity_collection[1, :] = vy
    if omega == "consistent":
        xc = 0.5 * (x[1:] + x[:-1])
        w_lab = np.zeros((3, n))
        w_lab[2] = -V * np.pi / L * np.cos(np.pi * xc / L)  # rotation rate of the tangent
        # omega_collection is in the material frame: Q (rows = directors) times w_lab
        rod.omega_collection[:] = np.einsum("ijk,jk->ik", rod.director_collection, w_lab)
    return sim, rod


def energy(rod, t):
    rod.compute_internal_forces_and_torques(t)
    return float(rod.compute_translational_energy() + rod.compute_rotational_energy()
                 + rod.compute_bending_energy() + rod.compute_shear_energy())


def main(argv=None) -> None:
    ap = common.parser(__doc__, "vib_pyelastica.csv", dt=1.0e-4, dx=0.025, V=True)
    ap.add_argument("--omega", choices=["consistent", "zero"], default="consistent",
                    help="initial angular velocities of the elements")
    ap.add_argument("--shear-factor", type=float, default=1.0,
                    help="study: shear modulus = factor * E / 3")
    common.add_max_rows(ap)
    a = ap.parse_args(argv)

    n = common.even_elements(L, a.dx)
    sim, rod = build(n, a.V, a.omega, a.shear_factor)
    mid = n // 2
    nsteps, every = common.sampling(a.t_end, a.dt, a.max_rows)
    stepper = ea.PositionVerlet()
    print(f"PyElastica vibration: V = {a.V} m/s, {n} elements (dx = {L / n} m), dt = {a.dt}, "
          f"steps = {nsteps}, t_end = {a.t_end}, omega0 = {a.omega}, "
          f"G = {a.shear_factor:g} * E/3")
    rows = []

    def record(t):
        rows.append((float(t), float(rod.position_collection[1, mid]), energy(rod, t)))

    record(np.float64(0.0))
    wall, t_all = common.step_loop(lambda t: stepper.step(sim, t, a.dt), np.float64(0.0),
                                   nsteps, every, record)
    arr = np.array(rows)
    common.check_stable(arr, 50.0)
    common.write_csv(a.out, ["t", "A_uy", "E_total"], rows, [".9g", ".10g", ".10g"])
    i = int(np.argmin(arr[:, 1]))
    print(f"wall time: step loop {wall:.2f} s; with energy/output sampling {t_all:.2f} s")
    print(f"min A_uy = {arr[i, 1]:.5g} m at t = {arr[i, 0]:.4f} s; A_uy(t_end) = "
          f"{arr[-1, 1]:.5g} m; E_total: initial {arr[0, 2]:.6g} J, max |E - E0| = "
          f"{np.abs(arr[:, 2] - arr[0, 2]).max():.3g} J")
    print(f"wrote {a.out} ({len(rows)} rows)")


if __name__ == "__main__":
    main()
