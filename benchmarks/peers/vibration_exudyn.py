"""Contact-free peer test, Exudyn: free vibration of the pinned 10 m beam.

The lower beam of the peer drop alone (built as in ``drop_exudyn.py``: 2D ANCF cable
``ObjectANCFCable2D`` from (0, 0) to (10, 0), end positions constrained, slopes free;
EA = E pi R^2, EI = E pi R^4 / 4, R = 0.1 m, rho = 1000 kg/m^3, E = 1e7 Pa; no gravity,
no contact), starting straight with the velocity field

    v(x) = (0, -V sin(pi x / L)),  L = 10 m   (default V = 7 m/s).

The nodal coordinates of the planar ANCF cable are the position r and the slope r' =
dr/dx, so the initial velocities are r_t = v(x_i) and r'_t = dv/dx(x_i) =
(0, -V pi / L cos(pi x_i / L)) at every node x_i (the cubic Hermite interpolant of the
sine field). Implicit generalized-alpha with spectralRadius = 1 (trapezoidal rule),
fixed step ``--dt``, modified Newton, consistent initial accelerations, as in
``drop_exudyn.py``, except Newton's absolute tolerance (``--abs-tol``, default 1e-6
instead of Exudyn's 1e-10: without gravity and contact the residual of the first steps
is small and its round-off floor, 2e-9 to 2e-8, lies above 1e-10, so Newton stalls;
at 1e-6 every step still takes at least one Newton iteration, also at V = 7e-4 m/s, and
full Newton at 1e-7 gives the same A_uy to 1e-10 m). Output: the midspan node's vertical
displacement A_uy (m) and the total energy E_total (J: kinetic + 0.5 EA (|r'| - 1)^2 +
0.5 EI kappa^2, from the written coordinates and velocities with ``drop_exudyn._beam_energy``).

Output CSV ``t, A_uy, E_total``. Usage (from the repository root; a few seconds):

    python benchmarks/peers/vibration_exudyn.py --out benchmarks/peers/results/vib_exudyn_V7.csv
    python benchmarks/peers/vibration_exudyn.py --V 0.07 --t-end 14 --max-rows 14001 \
        --out benchmarks/peers/results/vib_exudyn_V0.07.csv
"""

from __future__ import annotations

import _common as common
import exudyn as exu
import numpy as np
from _common import L_LOWER
from drop_exudyn import _beam_energy, _to_elements, add_lower_beam, node_dofs, solve

L = L_LOWER  # the lower beam of drop_exudyn.add_lower_beam


def build(n: int, V: float):
    SC = exu.SystemContainer()
    mbs = SC.AddSystem()
    beam = add_lower_beam(mbs, n)
    mbs.Assemble()
    v0 = np.zeros(mbs.systemData.ODE2Size())
    for node in beam["nodes"]:
        x = mbs.GetNodeParameter(node, "referenceCoordinates")[0]
        i = mbs.GetNodeODE2Index(node)
        v0[i + 1] = 0.0 if x in (0.0, L) else -V * np.sin(np.pi * x / L)  # y velocity
        v0[i + 3] = -V * np.pi / L * np.cos(np.pi * x / L)  # d/dt of the slope's y component
    mbs.systemData.SetODE2Coordinates_t(v0, configuration=exu.ConfigurationType.Initial)
    return SC, mbs, beam


def main(argv=None) -> None:
    ap = common.parser(__doc__, "vib_exudyn.csv", dt=1.0e-4, dx=0.1, V=True)
    ap.add_argument("--full-newton", action="store_true", help="full instead of modified Newton")
    ap.add_argument("--abs-tol", type=float, default=1e-6,
                    help="newton.absoluteTolerance (Exudyn's default 1e-10 lies below the "
                         "round-off floor of this contact-free residual, ~1e-8, and Newton "
                         "stalls at the first steps)")
    common.add_max_rows(ap)
    a = ap.parse_args(argv)

    n = common.even_elements(L, a.dx)
    SC, mbs, beam = build(n, a.V)
    nsteps, every = common.sampling(a.t_end, a.dt, a.max_rows)
    print(f"Exudyn {exu.__version__} vibration: V = {a.V} m/s, ANCFCable2D elements = {n} "
          f"(dx = {L / n} m), dt = {a.dt}, steps = {nsteps}, t_end = {a.t_end}, "
          f"generalized-alpha spectralRadius = 1, "
          f"{'full' if a.full_newton else 'modified'} Newton, absoluteTolerance = {a.abs_tol:g}")
    t, q_all, v_all = solve(mbs, a.t_end, a.dt, nsteps, every, "exudyn_vib_",
                            full_newton=a.full_newton, abs_tol=a.abs_tol)
    il, ref = node_dofs(mbs, beam["nodes"])
    mid = n // 2
    assert abs(ref[mid, 0] - 0.5 * L) < 1e-12
    a_uy = q_all[:, il].reshape(len(t), -1, 4)[:, mid, 1]
    e_tot = np.array([
        _beam_energy(_to_elements(ref + q_all[j, il].reshape(-1, 4)),
                     _to_elements(v_all[j, il].reshape(-1, 4)), L / n, False)[0]
        for j in range(len(t))])
    common.write_csv(a.out, ["t", "A_uy", "E_total"], zip(t, a_uy, e_tot, strict=True),
                     [".9g", ".10g", ".10g"])
    i = int(np.argmin(a_uy))
    print(f"min A_uy = {a_uy[i]:.5g} m at t = {t[i]:.4f} s; A_uy(t_end) = {a_uy[-1]:.5g} m; "
          f"E_total: initial {e_tot[0]:.6g} J, max |E - E0| = "
          f"{np.abs(e_tot - e_tot[0]).max():.3g} J")
    print(f"wrote {a.out} ({len(t)} rows)")


if __name__ == "__main__":
    main()
