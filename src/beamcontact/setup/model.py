"""From a validated case to the discrete model: refined axes, meshes, numbering, loads.

Host-side NumPy; the result is a :class:`Model` pytree plus a :class:`Discretization`
that keeps what the writers need (curves, offsets, names).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from beamcontact._jax import model_array
from beamcontact._x64 import as_float
from beamcontact.assembly.model import ElementBlock, Model, PointLoads
from beamcontact.beam.free_ends import fold_rows, free_end
from beamcontact.beam.mesh import BeamMesh, build_mesh, point_basis, refine_axis
from beamcontact.beam.section import Section, circle_section, rectangle_section
from beamcontact.io.case import Beam, Case, at_fraction
from beamcontact.solvers.linear import use_sparse
from beamcontact.spline import NurbsCurve, arc, line


@dataclass(frozen=True, eq=False)
class DiscreteBeam:
    """One discretised beam on the host: its refined axis and mesh (``BeamMesh``), its
    section, and where its control points start in the global numbering (the case
    file's table of it is ``io.case.Beam``; its kernel arrays an ``ElementBlock``)."""

    name: str
    mesh: BeamMesh
    section: Section
    offset: int  # global index of its first control point
    length: float  # reference arc length

    @property
    def curve(self) -> NurbsCurve:
        """The refined reference axis."""
        return self.mesh.curve

    @property
    def n_cp(self) -> int:
        """Number of control points."""
        return self.curve.n_points

    def parameter(self, fraction: float) -> float:
        """Parameter at a fraction of the reference arc length."""
        return float(self.curve.parameters_at_lengths([fraction])[0])


@dataclass(frozen=True, eq=False)
class Discretization:
    """All beams, in global order, and the total number of control points."""

    beams: tuple[DiscreteBeam, ...]
    n_cp: int

    def beam(self, name: str) -> DiscreteBeam:
        """The beam called ``name``."""
        return next(b for b in self.beams if b.name == name)

    @property
    def length_scale(self) -> float:
        """Longest reference beam length (scale of the increment tolerance)."""
        return max(b.length for b in self.beams)


def axis_curve(beam: Beam) -> NurbsCurve:
    """The exact reference axis of a beam as given in the case."""
    if beam.line is not None:
        return line(beam.line.start, beam.line.end)
    if beam.arc is not None:
        a = beam.arc
        return arc(a.center, a.radius, a.start_angle, a.end_angle)
    nb = beam.nurbs
    knots = np.asarray(nb.knots, float)
    knots = (knots - knots[0]) / (knots[-1] - knots[0])
    w = np.ones(len(nb.points)) if nb.weights is None else np.asarray(nb.weights, float)
    return NurbsCurve(nb.degree, knots, np.asarray(nb.points, float), w)


def make_section(beam: Beam) -> Section:
    """Section quadrature for the beam's cross section."""
    s = beam.section
    if s.shape == "circle":
        return circle_section(s.radius)
    return rectangle_section(s.width, s.height)


def _reference_metric(mesh: BeamMesh) -> tuple[np.ndarray, np.ndarray]:
    x = mesh.curve.points[mesh.conn]  # (n_el, n_loc, 2)
    g1 = np.einsum("eqk,ekd->eqd", mesh.dR, x)
    g1d = np.einsum("eqk,ekd->eqd", mesh.ddR, x)
    g = np.sum(g1 * g1, axis=-1)
    K = (g1[..., 0] * g1d[..., 1] - g1[..., 1] * g1d[..., 0]) / g**1.5
    return g, K


def discretize(case: Case) -> Discretization:
    """Refine every beam's axis and build its mesh (numbering follows the case order)."""
    infos, offset = [], 0
    for b in case.beams:
        axis = axis_curve(b)
        curve = refine_axis(axis, b.degree, b.elements, b.smoothness)
        try:
            # modes are a matter of dynamics: statics ignores the key (io/case.py)
            ends = (tuple(free_end(curve, at) for at in b.unsupported_ends)
                    if b.remove_outliers and case.analysis.kind == "dynamic" else ())
        except ValueError as exc:
            raise ValueError(f"beam {b.name!r}: {exc}") from None
        mesh = build_mesh(curve, free_ends=ends)
        section = make_section(b)
        _, K = _reference_metric(mesh)
        if np.max(np.abs(K)) * section.half_depth >= 1.0:
            raise ValueError(f"beam {b.name!r}: the section half-depth exceeds the radius of "
                             f"curvature of the axis")
        # the refined curve is the same curve: its length from the few spans of the axis
        infos.append(DiscreteBeam(b.name, mesh, section, offset, axis.arc_length()))
        offset += curve.n_points
    return Discretization(tuple(infos), offset)


def _element_data(info: DiscreteBeam, beam: Beam) -> dict:
    """Host arrays of every element of one beam, keyed by the ElementBlock fields."""
    mesh = info.mesh
    g, K = _reference_metric(mesh)
    sec = info.section
    n_el = mesh.conn.shape[0]

    def each(value):
        return np.broadcast_to(np.asarray(value, float), (n_el, *np.shape(value)))

    return {"conn": mesh.conn + info.offset, "R": mesh.R, "dR": mesh.dR, "ddR": mesh.ddR,
            "wq": mesh.wq, "g_ref": g, "K_ref": K, "eta": each(sec.eta),
            "w_eta": each(sec.weights), "E": each(beam.material.E),
            "rho_area": each(beam.material.density * sec.area),
            "rho_inertia": each(beam.material.density * sec.inertia),
            "gravity_on": each(1.0 if beam.gravity else 0.0)}


def _blocks(disc: Discretization, case: Case) -> tuple[ElementBlock, ...]:
    """One ElementBlock per shape of element data (degree, Gauss points, section points),
    the elements of all beams of that shape concatenated in beam order."""
    groups: dict[tuple, list[dict]] = {}
    for info, beam in zip(disc.beams, case.beams, strict=True):
        data = _element_data(info, beam)
        shape = (data["R"].shape[1:], data["eta"].shape[1:])
        groups.setdefault(shape, []).append(data)
    blocks = []
    for parts in groups.values():
        cat = {k: np.concatenate([d[k] for d in parts]) for k in parts[0]}
        conn = model_array(cat.pop("conn"))
        blocks.append(ElementBlock(conn=conn, **{k: as_float(v) for k, v in cat.items()}))
    return tuple(blocks)


def _point_loads(case: Case, disc: Discretization) -> PointLoads:
    n_loc = max(b.curve.degree + 1 for b in disc.beams)
    n = len(case.loads)
    conn = np.zeros((n, n_loc), dtype=np.int64)
    R = np.zeros((n, n_loc))
    dR = np.zeros((n, n_loc))
    for i, load in enumerate(case.loads):
        info = disc.beam(load.beam)
        idx, d = point_basis(info.curve, info.parameter(at_fraction(load.at)))
        d = fold_rows(idx + info.offset, d, info.mesh.free_ends, info.offset)
        m = len(idx)
        conn[i, :m] = idx + info.offset
        R[i, :m], dR[i, :m] = d[0], d[1]
    force = np.array([ld.force for ld in case.loads], float).reshape(n, 2)
    moment = np.array([ld.moment for ld in case.loads], float)
    return PointLoads(conn=model_array(conn), R=as_float(R), dR=as_float(dR),
                      force=as_float(force), moment=as_float(moment))


def dependent_dofs(disc: Discretization) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The dofs that the free ends' constraints tie to others (beam/free_ends.py), in
    global numbering: dependent (n_t,), masters (n_t, 3), weights (n_t, 3); the x and y
    components of each end are two ties."""
    dep, masters, weights = [], [], []
    for info in disc.beams:
        for end in info.mesh.free_ends:
            for a in (0, 1):
                dep.append(2 * (info.offset + end.dependent) + a)
                masters.append([2 * (info.offset + m) + a for m in end.masters])
                weights.append(end.weights)
    return (np.array(dep, dtype=np.int64), np.array(masters, dtype=np.int64).reshape(-1, 3),
            np.array(weights, dtype=float).reshape(-1, 3))


def supported_dofs(case: Case, disc: Discretization) -> np.ndarray:
    """Boolean mask of supported dofs (pinned: end point; clamped: also its neighbour)."""
    fixed = np.zeros(2 * disc.n_cp, dtype=bool)
    for b, info in zip(case.beams, disc.beams, strict=True):
        for s in b.supports:
            count = 1 if s.type == "pinned" else 2
            local = range(count) if s.at == "start" else range(info.n_cp - count, info.n_cp)
            for c in local:
                fixed[2 * (info.offset + c) : 2 * (info.offset + c) + 2] = True
    return fixed


def build_model(case: Case, disc: Discretization | None = None) -> tuple[Model, Discretization]:
    """The Model pytree for a validated case."""
    disc = discretize(case) if disc is None else disc
    x_ref = np.concatenate([b.curve.points for b in disc.beams])
    dep, masters, weights = dependent_dofs(disc)
    # a tied dof leaves the solve as a supported one does (free = 0)
    held = supported_dofs(case, disc)
    held[dep] = True
    model = Model(
        beams=_blocks(disc, case),
        loads=_point_loads(case, disc), x_ref=as_float(x_ref),
        free=as_float(~held), gravity=as_float(case.analysis.gravity),
        tied=model_array(dep), tie_masters=model_array(masters),
        tie_weights=as_float(weights),
        sparse=use_sparse(case.solver.linear_solver, x_ref.size))
    return model, disc


def point_sampler(disc: Discretization, name: str, fraction: float) -> tuple[np.ndarray,
                                                                              np.ndarray]:
    """Global control-point indices and basis values giving the point at ``fraction``."""
    info = disc.beam(name)
    idx, d = point_basis(info.curve, info.parameter(fraction))
    return idx + info.offset, d[0]


def polyline_matrix(info: DiscreteBeam, samples_per_element: int):
    """The matrix (:class:`~beamcontact.spline.curve.BasisRows`) mapping the beam's
    control points to polyline vertices along its axis."""
    breaks = info.mesh.breaks
    u = np.unique(np.concatenate([np.linspace(a, b, samples_per_element + 1)
                                  for a, b in zip(breaks[:-1], breaks[1:], strict=True)]))
    return info.curve.sparse_basis(u)


def uniform_velocities(disc, velocities) -> np.ndarray:
    """Global control-point velocities from one uniform velocity per beam (flat)."""
    v = np.zeros((disc.n_cp, 2))
    for info, vel in zip(disc.beams, velocities, strict=True):
        v[info.offset : info.offset + info.n_cp] = vel
    return v.ravel()
