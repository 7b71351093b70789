"""Contact-free peer test, beamcontact: free vibration of the pinned 10 m beam.

The lower beam of the peer drop alone (10 m from (0, 0) to (10, 0), pinned at both ends,
circle R = 0.1 m, rho = 1000 kg/m^3, E = 1e7 Pa, no gravity, no contact) starts from its
straight reference configuration with the velocity field

    v(x) = (0, -V sin(pi x / L)),  L = 10 m   (default V = 7 m/s),

and vibrates freely. Output (CSV ``t, A_uy, E_total, dt``): the midspan vertical
displacement A_uy (m) at every accepted step, the total energy E_total (J, kinetic +
strain) and the step taken (s).

The case file supports only a uniform initial velocity per beam, so this script uses the
library's lower layers: the case is built with ``parse_case`` (one beam, 20 quartic
C^1 elements as in compare.py's drop case, contact model "none", HHT alpha = 0 = the
trapezoidal rule, adaptive steps with ``solver.error_tol``), the control-point velocities
are the L2 projection of the sine field onto the spline space (end control points fixed
at zero: they are the pinned dofs), and the run is ``solve_dynamic`` (the same call as
``runner._run_dynamic``) from the consistent initial state of
``dynamics.hht.initial_state``.

``--strain-law engineering | pyelastica`` is a diagnostic: it swaps beamcontact's fibre
law (St. Venant-Kirchhoff in the Green-Lagrange strain) for the axial laws of the peers
at run time (``patch_strain_law``; nothing under src/ is changed), to isolate the effect
of the constitutive law at finite stretch.

Usage (from the repository root; about 10 s for 1.2 s):

    python benchmarks/peers/vibration_beamcontact.py --out benchmarks/peers/results/vib_bc_V7.csv
    python benchmarks/peers/vibration_beamcontact.py --strain-law engineering \
        --out benchmarks/peers/results/vib_bc-engineering_V7.csv
    python benchmarks/peers/vibration_beamcontact.py --V 0.07 --t-end 14 \
        --out benchmarks/peers/results/vib_bc_V0.07.csv
"""

from __future__ import annotations

import time

import _common as common
import numpy as np
from _common import L_LOWER, RHO, E, R

import beamcontact

L = L_LOWER


def patch_strain_law(law: str) -> None:
    """Diagnostic only: replace beamcontact's fibre law at run time (nothing in src/ is
    changed). The library's law is St. Venant-Kirchhoff in the Green-Lagrange strain of
    the equidistant fibre, W = E/2 eps_GL^2 with eps_GL = (lam^2 - 1)/2, lam^2 =
    g_bar / g_bar_ref (``law = "svk"``, no patch). ``"engineering"``: W = E/2 (lam - 1)^2,
    the fibre-wise form of the ANCF cable's EA (|r'| - 1) (Exudyn). ``"pyelastica"``:
    W = E (lam - 1 - ln lam), whose force E (lam - 1)/lam is PyElastica's axial law
    n = EA (e - 1)/e (its internal stress divided by the dilatation e). Each is applied
    fibre by fibre, so the bending part changes only at higher order."""
    if law == "svk":
        return
    import jax.numpy as jnp

    import beamcontact.beam.energy as energy

    def density(g, K, g_ref, K_ref, eta, w_eta, E):
        g0_ref = 1.0 - eta[None, :] * K_ref[:, None]
        gbar_ref = g0_ref**2 * g_ref[:, None]
        gbar = (1.0 - eta[None, :] * K[:, None]) ** 2 * g[:, None]
        lam = jnp.sqrt(gbar / gbar_ref)
        w = (0.5 * E * (lam - 1.0) ** 2 if law == "engineering"
             else E * (lam - 1.0 - jnp.log(lam)))
        return (w * g0_ref * jnp.sqrt(g_ref)[:, None]) @ w_eta

    energy.fibre_strain_energy_density = density


def vibration_case(elements: int, t_end: float, dt: float, error_tol: float | None,
                   energy_tol: float | None, continuity: int = 1) -> dict:
    solver = {}
    if error_tol is not None:
        solver["error_tol"] = error_tol
    if energy_tol is not None:
        solver["energy_tol"] = energy_tol
    case = {
        "title": "Contact-free vibration of the pinned 10 m beam (sine initial velocity)",
        "analysis": {"kind": "dynamic", "t_end": t_end, "dt": dt, "alpha": 0.0,
                     "gravity": [0.0, 0.0]},
        "beams": [
            {"name": "lower", "line": {"start": [0.0, 0.0], "end": [L, 0.0]},
             "degree": 4, "elements": elements, "continuity": continuity,
             "section": {"shape": "circle", "radius": R},
             "material": {"E": E, "density": RHO}, "gravity": False,
             "supports": [{"at": "start", "type": "pinned"}, {"at": "end", "type": "pinned"}]},
        ],
        "contact": {"model": "none"},
        "output": {"points": [{"name": "A", "beam": "lower", "at": 0.5}]},
    }
    if solver:
        case["solver"] = solver
    return case


def sine_velocities(info, V: float, free_mask: np.ndarray) -> np.ndarray:
    """Control-point velocities (n_cp, 2): L2 projection of (0, -V sin(pi x / L)) onto the
    spline space, with the supported (pinned) control points held at zero."""
    curve = info.curve
    breaks = info.mesh.breaks
    gx, gw = np.polynomial.legendre.leggauss(curve.degree + 4)
    us, ws = [], []
    for a, b in zip(breaks[:-1], breaks[1:], strict=True):
        us.append(0.5 * (b - a) * gx + 0.5 * (a + b))
        ws.append(0.5 * (b - a) * gw)
    u = np.concatenate(us)
    w = np.concatenate(ws)
    N, dN = curve.basis_matrix(u, 1)
    X = N @ curve.points
    jac = np.linalg.norm(dN @ curve.points, axis=1)  # dx/du (arc length per parameter)
    wx = w * jac
    target = -V * np.sin(np.pi * X[:, 0] / L)
    free = free_mask.reshape(-1, 2)[info.offset:info.offset + info.n_cp, 1].astype(bool)
    M = (N[:, free] * wx[:, None]).T @ N[:, free]
    rhs = (N[:, free] * wx[:, None]).T @ target
    vy = np.zeros(info.n_cp)
    vy[free] = np.linalg.solve(M, rhs)
    err = np.sqrt(np.sum(wx * (N @ vy - target) ** 2) / np.sum(wx * target**2)) \
        if V != 0 else 0.0
    v = np.zeros((info.n_cp, 2))
    v[:, 1] = vy
    return v, err


def main(argv=None) -> None:
    ap = common.parser(__doc__, "vib_beamcontact.csv", dt=1.0e-3, V=True,
                       dt_help="first and largest step [s]")
    ap.add_argument("--elements", type=int, default=20, help="quartic elements")
    ap.add_argument("--continuity", type=int, default=1,
                    help="inter-element continuity (1: as in compare.py's drop case)")
    ap.add_argument("--error-tol", type=float, default=None,
                    help="solver.error_tol (default: the library's default)")
    ap.add_argument("--strain-law", choices=["svk", "engineering", "pyelastica"],
                    default="svk", help="diagnostic: the fibre law (svk = beamcontact's own; "
                    "the others patch it at run time, see patch_strain_law)")
    ap.add_argument("--energy-tol", type=float, default=None,
                    help="solver.energy_tol (default: the library's default)")
    a = ap.parse_args(argv)

    beamcontact.enable_x64()
    patch_strain_law(a.strain_law)
    import jax.numpy as jnp
    from threadpoolctl import threadpool_limits

    from beamcontact.assembly.model import initial_load_state
    from beamcontact.dynamics.driver import solve_dynamic
    from beamcontact.dynamics.hht import initial_state
    from beamcontact.io.case import parse_case
    from beamcontact.setup.model import point_sampler
    from beamcontact.setup.start import dynamic_start, prepare
    from beamcontact.summary import effective_settings

    case = parse_case(vibration_case(a.elements, a.t_end, a.dt, a.error_tol, a.energy_tol,
                                     a.continuity))
    # the engine and the step control of a run, the initial state made here from the
    # projected sine velocities
    start = dynamic_start(prepare(case), initial=False)
    model, disc, control = start.prepared.model, start.prepared.disc, start.control
    info = disc.beam("lower")
    v_cp, proj_err = sine_velocities(info, a.V, np.asarray(model.free))
    idx, Nmid = point_sampler(disc, "lower", 0.5)
    settings = effective_settings(case)
    print(f"beamcontact vibration: V = {a.V} m/s, {a.elements} quartic C^{a.continuity} elements "
          f"({info.n_cp} control points), alpha = 0, dt (max) = {a.dt}, "
          f"error_tol = {control.error_tol:g}, energy_tol = {control.energy_tol:g}, "
          f"t_end = {a.t_end}, fibre law {a.strain_law}; L2 projection of the sine: "
          f"relative error {proj_err:.2e}")
    print(f"effective solver settings: {settings}")

    rows = []

    def a_uy(u):
        return float(Nmid @ np.asarray(u).reshape(-1, 2)[idx, 1])

    def on_step(s):
        rows.append((s.t, a_uy(s.state.u), s.diagnostics["E_total"], s.dt))

    with threadpool_limits(limits=1, user_api="blas"):
        u0 = jnp.zeros(model.n_dof)
        state = initial_state(u0, jnp.asarray(v_cp.ravel()), model,
                              initial_load_state(model))
        from beamcontact.dynamics.control import total_energy
        from beamcontact.dynamics.step import diagnostics
        d0 = {k: float(v) for k, v in diagnostics(state, model).items()}
        rows.append((0.0, 0.0, total_energy(d0), 0.0))
        t0 = time.perf_counter()
        res = solve_dynamic(start.engine, state, a.t_end, disc.length_scale, control,
                            on_step=on_step)
        wall = time.perf_counter() - t0
    arr = np.array(rows)
    print(f"{res.status}: {res.message}; {res.iterations} Newton iterations, "
          f"{res.cutbacks} cutbacks, rejections {res.rejections}")
    print(f"wall time: solve_dynamic {wall:.2f} s (compilation {res.compile_time:.2f} s)")
    steps = arr[1:, 3]
    print(f"steps: {len(steps)}, min {steps.min():.3g} s, max {steps.max():.3g} s; "
          f"E_total: initial {arr[0, 2]:.6g} J (0.5 rho A V^2 L/2 = "
          f"{0.5 * RHO * np.pi * R**2 * a.V**2 * L / 2:.6g} J), "
          f"max |E - E0| = {np.abs(arr[:, 2] - arr[0, 2]).max():.3g} J")
    i = int(np.argmin(arr[:, 1]))
    print(f"min A_uy = {arr[i, 1]:.5g} m at t = {arr[i, 0]:.4f} s; "
          f"A_uy(t_end) = {arr[-1, 1]:.5g} m")
    common.write_csv(a.out, ["t", "A_uy", "E_total", "dt"], rows, [".9g", ".10g", ".10g", ".6g"])
    print(f"wrote {a.out} ({len(rows)} rows)")


if __name__ == "__main__":
    main()
