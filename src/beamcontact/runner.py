"""Run a validated case into an output folder (DESIGN.md Sec. 4 results contract).

Writes history.csv, summary.json, results.h5, vtk/*.vtu + beams.pvd and plots/*.png.
Results are written step by step; on failure everything computed so far is kept and
summary.json says why the run stopped.
"""

import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from beamcontact import __version__, require_x64
from beamcontact.assembly.build import (
    Discretization,
    build_model,
    discretize,
    point_sampler,
    polyline_matrix,
)
from beamcontact.io.case import Case, CaseError, at_fraction
from beamcontact.io.results import HistoryWriter, StateWriter, read_history, write_summary
from beamcontact.io.vtk import VtkSeries
from beamcontact.plot import plot_point_histories, plot_shapes
from beamcontact.solvers.newton import NewtonOptions
from beamcontact.statics.driver import StaticStep, solve_static

Progress = Callable[[float, str], None]


class OutputPoints:
    """Evaluates the followed points from the global control points."""

    def __init__(self, case: Case, disc: Discretization, x_ref: np.ndarray):
        self.names = [p.name for p in case.output.points]
        self._samplers = [point_sampler(disc, p.beam, at_fraction(p.at))
                          for p in case.output.points]
        self._ref = [R @ x_ref[idx] for idx, R in self._samplers]

    def columns(self) -> list[str]:
        """history.csv columns of the points."""
        return [f"{n}_{c}" for n in self.names for c in ("x", "y", "ux", "uy")]

    def values(self, x: np.ndarray) -> dict:
        """Positions and displacements of every point for control points x."""
        row = {}
        for n, (idx, R), ref in zip(self.names, self._samplers, self._ref, strict=True):
            p = R @ x[idx]
            row.update({f"{n}_x": p[0], f"{n}_y": p[1], f"{n}_ux": p[0] - ref[0],
                        f"{n}_uy": p[1] - ref[1]})
        return row


def _discretize(case: Case) -> Discretization:
    try:
        return discretize(case)
    except ValueError as exc:
        raise CaseError(f"beams: {exc}") from None


def run_case(case: Case, case_text: str, out_dir: Path, progress: Progress | None = None,
             ) -> dict:
    """Run ``case`` and write its results into ``out_dir``; returns the summary."""
    require_x64()
    if case.analysis.kind != "static":
        raise CaseError('analysis.kind: "dynamic" is not available in this version yet')
    if case.contact.model != "none":
        raise CaseError(f'contact.model: "{case.contact.model}" is not available in this '
                        f'version yet (use "none")')
    out_dir.mkdir(parents=True, exist_ok=True)
    (out_dir / "plots").mkdir(exist_ok=True)
    wall0 = time.perf_counter()
    disc = _discretize(case)
    model, disc = build_model(case, disc)
    x_ref = np.asarray(model.x_ref)
    points = OutputPoints(case, disc, x_ref)
    columns = (["step", "load_factor", *points.columns(), "E_strain", "E_gravity", "E_ext",
                "E_total", "newton_iters", "cutbacks"])
    history = HistoryWriter(out_dir / "history.csv", columns)
    states = StateWriter(out_dir / "results.h5", case_text, disc.beams, model.n_dof,
                         "load_factor")
    vtk = VtkSeries(out_dir, [polyline_matrix(b, case.output.samples_per_element)
                              for b in disc.beams],
                    [b.section.half_depth for b in disc.beams], x_ref,
                    [b.offset for b in disc.beams], [b.n_cp for b in disc.beams])
    snapshots: list[tuple[float, np.ndarray]] = []

    def on_step(s: StaticStep) -> None:
        x = x_ref + s.u.reshape(-1, 2)
        e = s.energies
        history.write({"step": s.step, "load_factor": s.load_factor, **points.values(x), **e,
                       "E_total": e["E_strain"] + e["E_gravity"] + e["E_ext"],
                       "newton_iters": s.iterations, "cutbacks": s.cutbacks})
        states.write(s.step, s.load_factor, s.u)
        if s.step % case.output.vtk_every == 0 or s.load_factor >= 1.0 - 1e-12:
            vtk.write(s.load_factor, x)
        snapshots.append((s.load_factor, x))
        if progress is not None:
            progress(s.load_factor, f"load factor {s.load_factor:.3f}")

    opts = NewtonOptions(case.solver.max_iterations, case.solver.rtol, 0.0, case.solver.utol)
    try:
        result = solve_static(model, case.analysis.load_steps, opts, disc.length_scale,
                              case.solver.max_cutbacks, on_step)
    finally:
        history.close()
        states.close()
    _static_plots(case, disc, out_dir, snapshots, points)
    summary = {
        "title": case.title, "kind": "static", "status": result.status,
        "message": result.message, "steps": result.steps,
        "newton_iterations": result.iterations, "cutbacks": result.cutbacks,
        "final_load_factor": result.load_factor,
        "wall_time_s": time.perf_counter() - wall0,
        "solve_time_s": result.wall_time, "compile_time_s": result.compile_time,
        "n_dof": model.n_dof, "n_elements": sum(b.mesh.n_elements for b in disc.beams),
        "extremes": _extremes(out_dir / "history.csv", points.names),
        "beamcontact_version": __version__,
    }
    write_summary(out_dir / "summary.json", summary)
    return summary


def _extremes(path: Path, names: list[str]) -> dict:
    h = read_history(path)
    out = {}
    for n in names:
        for c in ("ux", "uy"):
            v = h[f"{n}_{c}"]
            out[f"{n}_{c}"] = {"min": float(v.min()), "max": float(v.max()),
                               "final": float(v[-1])}
    return out


def _static_plots(case: Case, disc: Discretization, out_dir: Path,
                  snapshots: list[tuple[float, np.ndarray]], points: OutputPoints) -> None:
    maps = [(polyline_matrix(b, case.output.samples_per_element),
             slice(b.offset, b.offset + b.n_cp)) for b in disc.beams]

    def axes(x):
        return [m @ x[s] for m, s in maps]

    if not snapshots:
        return
    picks = snapshots if len(snapshots) <= 11 else [
        snapshots[i] for i in np.unique(np.linspace(0, len(snapshots) - 1, 11).astype(int))]
    plot_shapes([(f"load factor {lam:.2f}", axes(x)) for lam, x in picks[1:]],
                axes(snapshots[0][1]), out_dir / "plots" / "shapes.png", case.title)
    if points.names:
        plot_point_histories(read_history(out_dir / "history.csv"), "load_factor", points.names,
                             out_dir / "plots" / "points.png", case.title)
