#!/usr/bin/env python
"""Continuum (2D plane-stress solid) reference for the beam-drop contact benchmark, in Kratos.

The problem is the bundled benchmark examples/free_fall/case_cg.toml of the beam code
(an elastic beam falls onto a second beam pinned at both ends), rebuilt here with
KratosMultiphysics 10.4 (StructuralMechanics + ContactStructuralMechanics applications).

Defaults: implicit Newmark, dt 5e-4, mortar penalty contact 1e8 Pa/m, 100 x 4 (lower) and
30 x 4 (upper) Q4 elements, upper body's bottom corners bevelled (--chamfer 0.5), nu = 0.
Run with OMP_NUM_THREADS=1 (with 2 threads the ALM contact search has hung).

Modelling choices (all of them; values in SI units)
---------------------------------------------------
Geometry and section
  * The beam model's circular section R = 0.1 (A = pi R^2, I = pi R^4 / 4) is replaced by a
    rectangle of height H = sqrt(12 I / A) = sqrt(3) R = 0.173205 and out-of-plane thickness
    A / H = 0.181380, so that A, I and the mass per length match the beam model.
  * Lower body: 10 long, axis from (0, 0) to (10, 0), occupies y in [-H/2, H/2].
  * Upper body: 3 long, x in [3.5, 6.5], at rest at t = 0.  Its bottom is 2.759 above the
    lower body's top (the beam model's surface gap: axes 2.959 apart minus 2 R), so free
    fall closes the gap at t = sqrt(2 * 2.759 / 9.81) = 0.750 s.
  * Bevelled bottom corners of the upper body (--chamfer, default 0.5): the two bottom corner
    nodes are raised by chamfer * H (= 0.0866, over CHAMFER_LENGTH = 0.1 along the bottom,
    the reference mesh's first element, on every mesh: a 41 degree bevel), the nodes above
    and beside them linearly; with --chamfer-keep-mass 1 (default)
    the upper body's density is raised (to 1016.9 for 0.5) so that its mass is still
    rho A L = 94.248.  Reason: with square ends (--chamfer 0) the upper body's end corners dig
    into the lower body's top at about 1.5 s (relative angle 45-55 degrees between the two
    surfaces) and Kratos' mortar contact does not activate the corner node (checked: nodes
    penetrated by 1-8 cm with ACTIVE false), so the bodies interpenetrate and every square-end
    variant tried was invalid from 1.49-1.54 s.  (Arguably a bevel is also nearer the beam
    model, whose contact acts on the axis and so has no sharp edge at a beam end.)
Material and kinematics
  * E = 0.98e6, density 1000, Poisson ratio 0 by default (--poisson), plane stress
    (LinearElasticPlaneStress2DLaw, THICKNESS = A / H), out-of-plane displacement nil.
  * TotalLagrangianElement2D4N (bilinear quadrilaterals, 2x2 Gauss, geometrically
    nonlinear: Green-Lagrange strain, linear St. Venant-Kirchhoff PK2 law), consistent mass
    in the implicit schemes (Kratos default), lumped (row-sum) nodal mass in the explicit one.
  * Structured mesh per body: --nx-lower / --nx-upper elements along the length and --ny
    through the height (even numbers: a node sits at mid-height of the end faces and at
    point A = (5, 0)).
Supports and loads
  * Lower body "pinned": both displacement components of the single node at mid-height
    (y = 0) of each end face are fixed; all other nodes free (rotation of the end faces free).
  * Gravity (0, -9.81) as VOLUME_ACCELERATION on the upper body only (no gravity on the lower).
Contact
  * Frictionless.  The upper body's bottom edge ("UpperBottom", slave; --upper-surface
    bottom+ends adds both end faces) against the lower body's top edge ("LowerTop", master;
    --slave lower swaps the roles), both as LineCondition2D2N oriented counter-clockwise
    around their body (outward normals).  No other surfaces are in contact.
  * implicit + alm     : mortar augmented Lagrangian (ALMContactFrictionless, exact "hard"
                         enforcement of the non-penetration, Lagrange multipliers as dofs),
                         contact_residual_criterion.
  * implicit + penalty : mortar penalty (PenaltyContactFrictionless): contact pressure =
                         penalty * weighted gap, i.e. a linear overclosure-pressure law
                         (the default formulation).
  * explicit           : central differences with explicit_penalty_contact_process (mortar
                         penalty), contact search "in_radius_with_obb" (the default
                         "octree_with_obb" formed no pairs in a trial).
  * Penalty stiffness --penalty (Pa/m, the slope of the pressure-overclosure law; the Abaqus
    study of the paper used 1e7 and "hard" contact): default 1e8 for the penalty
    formulations.  --penalty 0 leaves it to Kratos (stiffness_factor * E / h, scaled
    internally: it gave 2.3e11 here and the implicit penalty run blew up at the first impact).
    1e7 lets the bodies overlap by 8.7 cm (half of H) at the first impact.  For ALM the
    number is the augmentation parameter (Kratos' automatic value by default).
Time integration
  * implicit: Newmark (beta 0.25, gamma 0.5; no numerical dissipation) by default, or Bossak
    (--time-scheme bossak --alpha-m ...), fixed step --dt, full Newton (--max-iter).
    Kratos' own step splitting on non-convergence is --adaptive (off by default).
  * explicit: central differences, step --dt (Kratos halves it while contact is active).
Output and checks (computed by this script from the nodal values, not by Kratos)
  * CSV rows: t, A_uy, E_total, yc_fall, min_gap
      A_uy    vertical displacement of the node at (5, 0) (midspan, mid-height, lower body);
      E_total kinetic + strain + gravity potential energy.  Kinetic energy with the
              consistent mass (implicit) or the row-sum lumped mass (explicit); strain energy
              of the St. Venant-Kirchhoff law with 2x2 Gauss points; gravity potential
              m_upper * g * yc_fall.  Contact (penalty) energy is not included;
      yc_fall centre-of-mass height of the upper body;
      min_gap smallest signed distance of the upper body's bottom nodes to the lower body's
              deformed top edge (polyline), negative = penetration.
    A sidecar <out>.diag.csv adds kinetic, strain and potential energy, number of active
    slave nodes, Newton iterations and the convergence flag of every step.
  * <out>.json: wall time, steps, Newton iterations, non-converged steps, first impact time,
    contact episodes, second collision time, first amplitude of A and its time, valid_until.
  * valid_until: the first time at which the penetration exceeds --pen-limit * H (default
    10 %) or a bottom node of the upper body lies below the lower body's bottom edge
    (pass-through), or the last completed step if Kratos aborts (e.g. an inverted element);
    the end time if none of these happens.  The same value ends the CSV as a comment line.
  * Both CSVs are written as the run goes (a row per step, flushed at every progress line),
    so that a run that is stopped keeps what it computed; Ctrl-C (SIGINT) ends the time
    loop and still writes the JSON, with "interrupted" true.
  * first impact: first step with min_gap <= --contact-tol (1 mm); also the zero of the gap
    extrapolated from the two last free steps.  Contact episodes: intervals with
    min_gap <= --contact-tol, merged when less than 0.05 s apart; the second collision is the
    start of the second episode.  First amplitude of A: most negative A_uy in its first
    excursion after the first impact (from where |A_uy| first exceeds 1 % of its largest
    value until it comes back above zero by that much).
Known limits (Kratos 10.4.4, this set-up)
  * ALM + Newmark gains energy at the impact (2711 J -> about 7100 J at 0.76 s) through
    active-set chatter; ALM + Bossak (alpha_m -0.3) loses about 110 J at the first impact.
  * The energy balance is only approximate with the penalty formulation: the penalty energy
    is not in E_total, and the long contact episodes (1.5-1.75 s) add or remove about 100 J.
  * The mortar penalty's stiffness depends on the mesh: on a mesh twice as fine the same
    --penalty let the bodies overlap twice as deep at the first impact (1e8, Bossak -0.1:
    0.90 cm with 100 x 4 / 30 x 4 elements, 1.77 cm with 200 x 8 / 60 x 8). A mesh study
    scales the penalty with the elements per length (benchmarks/peers.py, SOLID_STUDIES).
  * Undamped Newmark went unstable in free flight after the first impact on the 200 x 8 /
    60 x 8 mesh (the energy grew without bound from about 1.0 s); a little Bossak damping
    (--time-scheme bossak --alpha-m -0.1) keeps it stable.
"""
import argparse
import contextlib
import json
import math
import os
import sys
import time

import numpy as np

# geometry and material of the benchmark
R = 0.1
AREA = math.pi * R ** 2
INERTIA = math.pi * R ** 4 / 4.0
H = math.sqrt(12.0 * INERTIA / AREA)
THICK = AREA / H
E_MOD = 0.98e6
RHO = 1000.0
G = 9.81
L_LOW = 10.0
X_UP0, X_UP1 = 3.5, 6.5
GAP0 = 2.759
XA = 5.0
# horizontal extent of the upper body's bevelled corners (--chamfer): the reference mesh's
# first element, kept on every mesh so that a mesh study compares one geometry
CHAMFER_LENGTH = 0.1


def parse_args(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", default="drop_solid.csv", help="CSV output file")
    p.add_argument("--t-end", type=float, default=3.0)
    p.add_argument("--dt", type=float, default=None,
                   help="time step (default 5e-4 implicit, 1e-4 explicit)")
    p.add_argument("--scheme", choices=["implicit", "explicit"], default="implicit")
    p.add_argument("--contact", choices=["alm", "penalty"], default="penalty",
                   help="implicit contact formulation (explicit always uses penalty)")
    p.add_argument("--penalty", type=float, default=None,
                   help="penalty stiffness in Pa/m (slope of the linear pressure-overclosure "
                        "law; the paper's Abaqus study used 1e7).  Default 1e8 for the penalty "
                        "formulations and Kratos' automatic value for ALM; 0 = Kratos' "
                        "automatic value (stiffness_factor * E / h) in all cases")
    p.add_argument("--stiffness-factor", type=float, default=1.0,
                   help="factor of Kratos' automatic penalty E / h")
    p.add_argument("--upper-surface", choices=["bottom", "bottom+ends"], default="bottom",
                   help="contact surface of the upper body: its bottom edge, or the bottom "
                        "edge and both end faces")
    p.add_argument("--chamfer", type=float, default=0.5,
                   help="bevel the upper body's two bottom corners: the corner node is raised "
                        "by CHAMFER * H (end-face nodes linearly); 0 = square ends")
    p.add_argument("--chamfer-keep-mass", type=int, choices=[0, 1], default=1,
                   help="with --chamfer: scale the upper body's density so that its mass is "
                        "unchanged (default 1)")
    p.add_argument("--slave", choices=["upper", "lower"], default="upper",
                   help="which surface is the mortar slave (the other is the master)")
    p.add_argument("--time-scheme", choices=["newmark", "bossak"], default="newmark")
    p.add_argument("--alpha-m", type=float, default=-0.3, help="Bossak alpha_m")
    p.add_argument("--nx-lower", type=int, default=100)
    p.add_argument("--nx-upper", type=int, default=30)
    p.add_argument("--ny", type=int, default=4, help="elements through the height (even)")
    p.add_argument("--poisson", type=float, default=0.0)
    p.add_argument("--max-iter", type=int, default=30)
    p.add_argument("--adaptive", action="store_true",
                   help="Kratos' step splitting on non-convergence (adaptative_strategy)")
    p.add_argument("--pen-limit", type=float, default=0.10,
                   help="penetration (fraction of H) beyond which the result is invalid")
    p.add_argument("--contact-tol", type=float, default=1.0e-3,
                   help="gap [m] below which the bodies count as touching (impact detection)")
    p.add_argument("--stop-invalid", type=float, default=None,
                   help="stop this many seconds after the result became invalid")
    p.add_argument("--snapshots", type=float, default=None,
                   help="save all nodal positions every this many seconds to <out>.npz")
    p.add_argument("--progress", type=float, default=0.1, help="progress print interval [s]")
    p.add_argument("--kratos-stdout", dest="quiet_kratos", action="store_false",
                   help="keep Kratos' per-step stdout (hidden by default)")
    a = p.parse_args(argv)
    if a.dt is None:
        a.dt = 5.0e-4 if a.scheme == "implicit" else 1.0e-4
    if a.penalty is None:
        a.penalty = 0.0 if (a.scheme == "implicit" and a.contact == "alm") else 1.0e8
    for name in ("nx_lower", "ny"):
        if getattr(a, name) % 2:
            p.error("--{} must be even".format(name.replace("_", "-")))
    return a


def build_parameters(a):
    implicit = a.scheme == "implicit"
    mortar = ("ALMContactFrictionless" if (implicit and a.contact == "alm")
              else "PenaltyContactFrictionless")
    solver = {
        "solver_type": "Dynamic",
        "model_part_name": "Structure",
        "domain_size": 2,
        "echo_level": 0,
        "analysis_type": "non_linear",
        "time_integration_method": "implicit" if implicit else "explicit",
        "model_import_settings": {"input_type": "use_input_model_part"},
        "material_import_settings": {"materials_filename": ""},
        "time_stepping": {"time_step": a.dt},
        "rotation_dofs": False,
        "contact_settings": {"mortar_type": mortar},
    }
    if implicit:
        solver.update({
            "scheme_type": a.time_scheme,
            "damp_factor_m": a.alpha_m if a.time_scheme == "bossak" else 0.0,
            "convergence_criterion": "contact_residual_criterion",
            "max_iteration": a.max_iter,
            "linear_solver_settings": {"solver_type": "LinearSolversApplication.sparse_lu"},
        })
        solver["contact_settings"].update({
            "fancy_convergence_criterion": False,
            "print_convergence_criterion": False,
            "silent_strategy": True,
            "adaptative_strategy": bool(a.adaptive),
        })
    else:
        solver.update({
            "scheme_type": "central_differences",
            "time_step_prediction_level": 0,
        })
        solver["contact_settings"].update({"silent_strategy": True})

    alm = {"stiffness_factor": a.stiffness_factor}
    if a.penalty > 0.0:
        alm.update({"manual_ALM": True, "penalty": a.penalty, "scale_factor": 1.0})
    contact = {
        "model_part_name": "Structure",
        "contact_model_part": {"0": ["UpperBottom", "LowerTop"]},
        "assume_master_slave": {"0": ["UpperBottom" if a.slave == "upper" else "LowerTop"]},
        "contact_type": "Frictionless",
        "search_parameters": {"type_search": "in_radius_with_obb"},
        "advance_ALM_parameters": alm,
    }
    if implicit and a.contact == "alm":
        cproc = "alm_contact_process"
    elif implicit:
        cproc = "penalty_contact_process"
    else:
        cproc = "explicit_penalty_contact_process"
    processes = {
        "constraints_process_list": [{
            "python_module": "assign_vector_variable_process",
            "kratos_module": "KratosMultiphysics",
            "Parameters": {"model_part_name": "Structure.Pinned", "variable_name": "DISPLACEMENT",
                           "interval": [0.0, "End"], "constrained": [True, True, True],
                           "value": [0.0, 0.0, 0.0]}}],
        "loads_process_list": [{
            "python_module": "assign_vector_by_direction_process",
            "kratos_module": "KratosMultiphysics",
            "Parameters": {"model_part_name": "Structure.Upper",
                           "variable_name": "VOLUME_ACCELERATION", "interval": [0.0, "End"],
                           "constrained": False, "modulus": G, "direction": [0.0, -1.0, 0.0]}}],
        "contact_process_list": [{
            "python_module": cproc,
            "kratos_module": "KratosMultiphysics.ContactStructuralMechanicsApplication",
            "Parameters": contact}],
    }
    return {
        "problem_data": {"problem_name": "drop_solid", "parallel_type": "OpenMP",
                         "echo_level": 0, "start_time": 0.0, "end_time": a.t_end},
        "solver_settings": solver,
        "processes": processes,
        "output_processes": {},
    }


class Mesh:
    """Structured Q4 meshes of the two bodies, built into the Kratos model part."""

    def __init__(self, mp, a, KM, SMA):
        self.nodes = []          # Kratos node objects, index = id - 1
        self.X0 = []             # reference coordinates
        nid = [0]
        eid = [0]
        cid = [0]
        self.elems = []          # (body, [4 node indices])

        def grid(x0, x1, nx, y0, y1, ny, chamfer=0.0):
            ids = np.zeros((nx + 1, ny + 1), dtype=int)
            for j in range(ny + 1):
                for i in range(nx + 1):
                    nid[0] += 1
                    x = x0 + (x1 - x0) * i / nx
                    y = y0 + (y1 - y0) * j / ny
                    # bevel the bottom corners: the corner raised by `chamfer`, the
                    # bevel reaching CHAMFER_LENGTH along the bottom on every mesh
                    d = min(i, nx - i) * (x1 - x0) / nx
                    y += chamfer * (1.0 - j / ny) * max(0.0, 1.0 - d / CHAMFER_LENGTH)
                    self.nodes.append(mp.CreateNewNode(nid[0], x, y, 0.0))
                    self.X0.append((x, y))
                    ids[i, j] = nid[0]
            return ids

        props = []
        for pid in (1, 2):
            pr = mp.CreateNewProperties(pid) if hasattr(mp, "CreateNewProperties") \
                else mp.GetProperties()[pid]
            pr.SetValue(KM.YOUNG_MODULUS, E_MOD)
            pr.SetValue(KM.POISSON_RATIO, a.poisson)
            pr.SetValue(KM.DENSITY, RHO)
            pr.SetValue(KM.THICKNESS, THICK)
            pr.SetValue(KM.CONSTITUTIVE_LAW, SMA.LinearElasticPlaneStress2DLaw())
            props.append(pr)

        ny = a.ny
        y_up0 = H / 2 + GAP0
        self.low = grid(0.0, L_LOW, a.nx_lower, -H / 2, H / 2, ny)
        self.up = grid(X_UP0, X_UP1, a.nx_upper, y_up0, y_up0 + H, ny, a.chamfer * H)

        def elements(ids, pr):
            out = []
            nx, nyy = ids.shape[0] - 1, ids.shape[1] - 1
            for j in range(nyy):
                for i in range(nx):
                    eid[0] += 1
                    conn = [ids[i, j], ids[i + 1, j], ids[i + 1, j + 1], ids[i, j + 1]]
                    mp.CreateNewElement("TotalLagrangianElement2D4N", eid[0], conn, pr)
                    self.elems.append(conn)
                    out.append(eid[0])
            return out

        el_low = elements(self.low, props[0])
        el_up = elements(self.up, props[1])

        def lines(node_seq, pr):
            out = []
            for k in range(len(node_seq) - 1):
                cid[0] += 1
                mp.CreateNewCondition("LineCondition2D2N", cid[0],
                                      [int(node_seq[k]), int(node_seq[k + 1])], pr)
                out.append(cid[0])
            return out

        # counter-clockwise around each body: lower top runs right -> left,
        # upper bottom runs left -> right
        low_top = self.low[::-1, ny]
        up_bot = self.up[:, 0]
        if a.upper_surface == "bottom+ends":
            # left end face top -> bottom, bottom left -> right, right end face bottom -> top
            up_surf = np.concatenate([self.up[0, :0:-1], up_bot, self.up[-1, 1:]])
        else:
            up_surf = up_bot
        c_low = lines(low_top, props[0])
        c_up = lines(up_surf, props[1])

        def sub(name, nodes, elems=(), conds=()):
            s = mp.CreateSubModelPart(name)
            s.AddNodes([int(n) for n in np.ravel(nodes)])
            if elems:
                s.AddElements(list(elems))
            if conds:
                s.AddConditions(list(conds))
            return s

        sub("Lower", self.low, el_low)
        sub("Upper", self.up, el_up)
        sub("LowerTop", low_top, (), c_low)
        sub("UpperBottom", up_surf, (), c_up)
        sub("Pinned", [self.low[0, ny // 2], self.low[-1, ny // 2]])

        self.X0 = np.array(self.X0)
        self.nn = len(self.nodes)
        self.conn = np.array(self.elems) - 1
        self.n_el_low = len(el_low)
        self.rho_e = np.full(len(self.elems), RHO)
        self.rho_up = RHO
        if a.chamfer > 0.0 and a.chamfer_keep_mass:
            # scale the upper body's density so that its mass stays rho * A * L
            xe = self.X0[self.conn[self.n_el_low:]]
            area = 0.5 * np.abs(np.sum(xe[:, :, 0] * np.roll(xe[:, :, 1], -1, axis=1)
                                       - np.roll(xe[:, :, 0], -1, axis=1) * xe[:, :, 1], axis=1))
            self.rho_up = RHO * H * (X_UP1 - X_UP0) / float(np.sum(area))
            props[1].SetValue(KM.DENSITY, self.rho_up)
            self.rho_e[self.n_el_low:] = self.rho_up
        self.node_A = int(self.low[a.nx_lower // 2, ny // 2]) - 1
        assert abs(self.X0[self.node_A, 0] - XA) < 1e-12 and abs(self.X0[self.node_A, 1]) < 1e-12
        self.low_top = self.low[:, ny] - 1          # left -> right
        self.low_bot = self.low[:, 0] - 1
        self.up_bot = up_bot - 1
        self.up_nodes = np.ravel(self.up) - 1
        self._prepare_quadrature(a.poisson)

    def _prepare_quadrature(self, nu):
        gp = 1.0 / math.sqrt(3.0)
        pts = [(-gp, -gp), (gp, -gp), (gp, gp), (-gp, gp)]
        Xe = self.X0[self.conn]                                   # (ne, 4, 2)
        N, dN = [], []
        for (xi, eta) in pts:
            N.append([(1 - xi) * (1 - eta) / 4, (1 + xi) * (1 - eta) / 4,
                      (1 + xi) * (1 + eta) / 4, (1 - xi) * (1 + eta) / 4])
            dN.append([[-(1 - eta) / 4, -(1 - xi) / 4], [(1 - eta) / 4, -(1 + xi) / 4],
                       [(1 + eta) / 4, (1 + xi) / 4], [-(1 + eta) / 4, (1 - xi) / 4]])
        self.N = np.array(N)                                      # (4gp, 4)
        dN = np.array(dN)                                         # (4gp, 4, 2)
        J = np.einsum("eai,gaj->egij", Xe, dN)                    # (ne, gp, 2, 2)
        detJ = np.linalg.det(J)
        Jinv = np.linalg.inv(J)
        self.dNdX = np.einsum("gak,egkj->egaj", dN, Jinv)         # (ne, gp, 4, 2)
        self.wdet = detJ                                          # Gauss weights are 1
        self.C = E_MOD / (1 - nu ** 2)
        self.nu = nu
        # row-sum lumped nodal masses
        me = THICK * self.rho_e[:, None] * np.einsum("eg,ga->ea", self.wdet, self.N)
        self.mass = np.zeros(self.nn)
        np.add.at(self.mass, self.conn, me)
        self.m_up = self.mass[self.up_nodes].sum()

    def energies(self, U, V, lumped):
        Ue = U[self.conn]                                         # (ne, 4, 2)
        Fm = np.einsum("eai,egaj->egij", Ue, self.dNdX)
        Fm[..., 0, 0] += 1.0
        Fm[..., 1, 1] += 1.0
        Cg = np.einsum("egki,egkj->egij", Fm, Fm)
        E11 = 0.5 * (Cg[..., 0, 0] - 1.0)
        E22 = 0.5 * (Cg[..., 1, 1] - 1.0)
        E12 = 0.5 * Cg[..., 0, 1]
        w = 0.5 * self.C * (E11 ** 2 + E22 ** 2 + 2 * self.nu * E11 * E22
                            + 2 * (1 - self.nu) * E12 ** 2)
        strain = THICK * float(np.sum(w * self.wdet))
        if lumped:
            kin = 0.5 * float(np.sum(self.mass * np.sum(V * V, axis=1)))
        else:
            Vg = np.einsum("ga,eai->egi", self.N, V[self.conn])
            kin = 0.5 * THICK * float(np.sum(self.rho_e[:, None] * np.sum(Vg * Vg, axis=2)
                                             * self.wdet))
        return kin, strain


def signed_gaps(P, top):
    """Signed distances of the points P (n, 2) to the polyline top (m, 2), ordered left to
    right; positive above (on the side of the left-hand normal of the direction of travel).
    The sign uses the segment normal, or at a vertex the mean of the two adjacent normals."""
    a = top[:-1]
    b = top[1:]
    d = b - a
    L = np.sqrt(np.sum(d * d, axis=1))
    nrm = np.stack([-d[:, 1], d[:, 0]], axis=1) / L[:, None]      # left normals (up)
    vn = np.zeros_like(top)                                        # vertex pseudo-normals
    vn[:-1] += nrm
    vn[1:] += nrm
    rel = P[:, None, :] - a[None, :, :]
    t = np.clip(np.sum(rel * d[None], axis=2) / (L * L)[None], 0.0, 1.0)
    q = a[None] + t[..., None] * d[None]
    dist = np.linalg.norm(P[:, None, :] - q, axis=2)
    k = np.argmin(dist, axis=1)
    idx = np.arange(P.shape[0])
    tk = t[idx, k]
    n_use = np.where((tk <= 0.0)[:, None], vn[k], np.where((tk >= 1.0)[:, None], vn[k + 1],
                                                            nrm[k]))
    side = np.sum((P - q[idx, k]) * n_use, axis=1)
    return np.where(side >= 0.0, 1.0, -1.0) * dist[idx, k]


def first_amplitude(t, uy, t_imp):
    """Most negative uy in the first excursion of A after the first impact (from where |uy|
    first exceeds 1 % of its largest value until it comes back above zero by that much)."""
    if t_imp is None:
        return None, None, False
    m = t >= t_imp
    tt, uu = t[m], uy[m]
    if len(uu) == 0:
        return None, None, False
    thr = 0.01 * np.max(np.abs(uu))
    start = np.argmax(uu < -thr) if np.any(uu < -thr) else None
    if start is None:
        return None, None, False
    after = np.nonzero(uu[start:] > thr)[0]
    end = start + after[0] if len(after) else len(uu)
    k = start + int(np.argmin(uu[start:end]))
    return float(uu[k]), float(tt[k]), len(after) > 0


def contact_episodes(t, gap, tol, merge=0.05):
    """Time intervals with gap <= tol; intervals separated by less than `merge` s are
    merged (chattering sequence = one collision)."""
    eps = []
    touching = gap <= tol
    i = 0
    n = len(t)
    while i < n:
        if touching[i]:
            j = i
            while j + 1 < n and touching[j + 1]:
                j += 1
            eps.append([float(t[i]), float(t[j])])
            i = j + 1
        else:
            i += 1
    merged = []
    for e in eps:
        if merged and e[0] - merged[-1][1] < merge:
            merged[-1][1] = e[1]
        else:
            merged.append(e)
    return merged


def main(argv=None):
    a = parse_args(argv)
    t_wall0 = time.time()
    import KratosMultiphysics as KM
    import KratosMultiphysics.ContactStructuralMechanicsApplication  # noqa: F401
    import KratosMultiphysics.LinearSolversApplication  # noqa: F401
    import KratosMultiphysics.StructuralMechanicsApplication as SMA
    from KratosMultiphysics.StructuralMechanicsApplication.structural_mechanics_analysis import (
        StructuralMechanicsAnalysis,
    )
    if a.quiet_kratos:
        KM.Logger.GetDefaultOutput().SetSeverity(KM.Logger.Severity.WARNING)

    params = build_parameters(a)
    model = KM.Model()
    analysis = StructuralMechanicsAnalysis(model, KM.Parameters(json.dumps(params)))
    mp = model["Structure"]
    mesh = Mesh(mp, a, KM, SMA)
    analysis.Initialize()
    t_init = time.time() - t_wall0
    analysis._GetSolver()
    # The mortar convergence criterion writes a "CONVERGENCE CHECK" banner per step to the C++
    # std::cout whatever the echo levels; silence file descriptor 1 during the time loop and
    # print the progress lines to a duplicate of it.
    sys.stdout.flush()
    out_fd = os.dup(1)
    con = os.fdopen(out_fd, "w")
    if a.quiet_kratos:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, 1)
    pinfo = mp.ProcessInfo
    vu = KM.VariableUtils()
    nodes = mp.Nodes
    # node order of the vector getters = model-part order = id order
    ids = np.array([n.Id for n in nodes])
    assert np.all(ids == np.arange(1, mesh.nn + 1))
    lumped = a.scheme == "explicit"
    penalty_used = pinfo[KM.INITIAL_PENALTY]
    scale_used = pinfo[KM.SCALE_FACTOR]
    slave_nodes = [mesh.nodes[i] for i in mesh.up_bot]

    def state():
        U = np.array(vu.GetSolutionStepValuesVector(nodes, KM.DISPLACEMENT, 0, 2)).reshape(-1, 2)
        V = np.array(vu.GetSolutionStepValuesVector(nodes, KM.VELOCITY, 0, 2)).reshape(-1, 2)
        return U, V

    rows, diag = [], []
    csv_file = open(a.out, "w")  # noqa: SIM115 (closed after the loop)
    diag_file = open(os.path.splitext(a.out)[0] + ".diag.csv", "w")  # noqa: SIM115
    csv_file.write("# Kratos plane-stress continuum drop: {}\n".format(" ".join(sys.argv[1:])))
    csv_file.write("t,A_uy,E_total,yc_fall,min_gap\n")
    diag_file.write("t,E_kin,E_strain,E_pot,n_active_slave,nl_iter,converged\n")
    snaps, next_snap = [], [0.0]
    t_valid = None
    reason = None
    nonconv = []
    aborted = None
    total_it = 0
    step = 0
    next_print = 0.0

    def record(t, conv, nit):
        nonlocal t_valid, reason
        U, V = state()
        x = mesh.X0 + U
        kin, strain = mesh.energies(U, V, lumped)
        yc = float(np.sum(mesh.mass[mesh.up_nodes] * x[mesh.up_nodes, 1]) / mesh.m_up)
        pot = mesh.m_up * G * yc
        top = x[mesh.low_top]
        P = x[mesh.up_bot]
        gaps = signed_gaps(P, top)
        inside = (P[:, 0] >= top[0, 0]) & (P[:, 0] <= top[-1, 0])
        mg = float(np.min(gaps[inside])) if np.any(inside) else float("nan")
        bot = x[mesh.low_bot]
        below = np.any(inside & (P[:, 1] < np.interp(P[:, 0], bot[:, 0], bot[:, 1])))
        if t_valid is None:
            if mg < -a.pen_limit * H:
                t_valid, reason = t, f"penetration {-mg:.4f} m > {100 * a.pen_limit:.0f} % of H"
            elif below:
                t_valid, reason = t, "upper body's bottom below the lower body's bottom"
        n_act = sum(1 for n in slave_nodes if n.Is(KM.ACTIVE))
        rows.append((t, float(U[mesh.node_A, 1]), kin + strain + pot, yc, mg))
        if a.snapshots is not None and t >= next_snap[0] - 1e-12:
            snaps.append((t, x.copy(), np.array([n.Is(KM.ACTIVE) for n in slave_nodes])))
            next_snap[0] += a.snapshots
        diag.append((t, kin, strain, pot, n_act, nit, int(conv)))
        csv_file.write("{:.6f},{:.8e},{:.8e},{:.8e},{:.8e}\n".format(*rows[-1]))
        diag_file.write("{:.6f},{:.8e},{:.8e},{:.8e},{:d},{:d},{:d}\n".format(*diag[-1]))

    record(0.0, True, 0)
    interrupted = False
    while analysis.KeepAdvancingSolutionLoop():
        analysis.time = analysis._AdvanceTime()
        try:
            analysis.InitializeSolutionStep()
            conv = analysis._GetSolver().SolveSolutionStep()
            nit = pinfo[KM.NL_ITERATION_NUMBER] if a.scheme == "implicit" else 1
            analysis.FinalizeSolutionStep()
            analysis.OutputSolutionStep()
        except KeyboardInterrupt:
            interrupted = True
            print(f"interrupted at t = {analysis.time:.6f}: writing what was computed",
                  file=con, flush=True)
            break
        except RuntimeError as err:        # e.g. "ELEMENT ID: n INVERTED"
            msg = str(err).strip().splitlines()
            key = [m for m in msg if "INVERTED" in m] or [m for m in msg if "rror" in m] or msg
            aborted = "t = {:.6f}: {}".format(analysis.time, key[0].strip() if key else "")
            print("Kratos failed at " + aborted, file=con, flush=True)
            if t_valid is None:
                t_valid, reason = rows[-1][0], "Kratos aborted: " + aborted
            break
        step += 1
        total_it += nit
        if not conv:
            nonconv.append(analysis.time)
        record(analysis.time, conv, nit)
        if analysis.time >= next_print:
            r = rows[-1]
            print(f"t={r[0]:.4f}  A_uy={r[1]:+.4f}  E={r[2]:.2f}  yc={r[3]:.4f}  "
                  f"min_gap={r[4]:+.5f}  it={nit:d}  nonconv={len(nonconv):d}  "
                  f"wall={time.time() - t_wall0:.0f}s", file=con, flush=True)
            next_print += a.progress
            csv_file.flush()
            diag_file.flush()
        if (a.stop_invalid is not None and t_valid is not None
                and analysis.time > t_valid + a.stop_invalid):
            print(f"stopping: result invalid since t = {t_valid:.4f} ({reason})",
                  file=con, flush=True)
            break
    with contextlib.suppress(RuntimeError):
        analysis.Finalize()
    sys.stdout.flush()
    os.dup2(out_fd, 1)
    wall = time.time() - t_wall0

    arr = np.array(rows)
    t, uy, gap = arr[:, 0], arr[:, 1], arr[:, 4]
    t_last = float(t[-1])
    hit = np.nonzero(gap <= a.contact_tol)[0]
    t_imp = float(t[hit[0]]) if len(hit) else None
    t_imp_x = None
    if len(hit) and hit[0] >= 2:
        # zero of the gap extrapolated from the last two free steps (sub-step estimate)
        k = hit[0]
        v = (gap[k - 2] - gap[k - 1]) / (t[k - 1] - t[k - 2])
        t_imp_x = float(t[k - 1] + gap[k - 1] / v) if v > 0 else None
    eps = contact_episodes(t, gap, a.contact_tol)
    amp, t_amp, amp_complete = first_amplitude(t, uy, t_imp)
    valid_until = t_valid if t_valid is not None else t_last
    E0 = float(arr[0, 2])
    summary = {
        "settings": vars(a),
        "H": H, "thickness": THICK, "mass_upper": mesh.m_up, "density_upper": mesh.rho_up,
        "nodes": mesh.nn, "elements": len(mesh.elems),
        "wall_time_s": wall, "init_time_s": t_init, "steps": step,
        "t_last": t_last,
        "nonlinear_iterations": total_it if a.scheme == "implicit" else None,
        "nonconverged_steps": len(nonconv),
        "aborted": aborted,
        "interrupted": interrupted,
        "first_nonconverged_t": nonconv[0] if nonconv else None,
        "initial_penalty": penalty_used, "scale_factor": scale_used,
        "first_impact_t": t_imp,
        "first_impact_t_extrapolated": t_imp_x,
        "contact_episodes": eps,
        "second_collision_t": eps[1][0] if len(eps) > 1 else None,
        "first_amplitude_A": amp, "first_amplitude_t": t_amp,
        "first_amplitude_complete": bool(amp_complete),
        "min_gap": float(np.nanmin(gap)), "min_gap_t": float(t[np.nanargmin(gap)]),
        "E_total_0": E0, "E_total_end": float(arr[-1, 2]),
        "E_total_min": float(np.min(arr[:, 2])), "E_total_max": float(np.max(arr[:, 2])),
        "E_total_at_valid_until": float(arr[np.searchsorted(t, valid_until) - 1
                                            if valid_until > 0 else 0, 2]),
        "valid_until": valid_until,
        "invalid_reason": reason,
    }
    csv_file.write("# valid_until = {:.6f} s{}\n".format(valid_until,
                                                   ("  (" + reason + ")") if reason else ""))
    csv_file.close()
    diag_file.close()
    if snaps:
        np.savez_compressed(os.path.splitext(a.out)[0] + ".npz",
                            t=np.array([s_[0] for s_ in snaps]),
                            x=np.array([s_[1] for s_ in snaps]), conn=mesh.conn,
                            active_upper_bottom=np.array([s_[2] for s_ in snaps]),
                            lower_top=mesh.low_top, lower_bottom=mesh.low_bot,
                            upper_bottom=mesh.up_bot, upper_nodes=mesh.up_nodes)
    with open(a.out + ".json", "w") as f:
        json.dump(summary, f, indent=1)
    s = dict(summary)
    s.pop("settings")
    s.pop("contact_episodes")
    print(json.dumps(s, indent=1))
    print("contact episodes:", ", ".join("{:.4f}-{:.4f}".format(*tuple(e)) for e in eps[:12]))


if __name__ == "__main__":
    main()
