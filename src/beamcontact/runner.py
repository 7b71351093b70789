"""Run a validated case into an output folder (DESIGN.md Sec. 4 results contract).

Writes history.csv, summary.json, results.h5, vtk/*.vtu + beams.pvd and plots/*.png.
Results are written step by step; on failure or interruption everything accepted so far
is kept and summary.json says why the run stopped. Dynamic runs can be continued with
``restart=True`` from the last state in results.h5.
"""

import time
import tomllib
from collections.abc import Callable
from pathlib import Path

import jax.numpy as jnp
import numpy as np

from beamcontact import __version__, require_x64
from beamcontact.assembly.build import (
    Discretization,
    build_model,
    discretize,
    point_sampler,
    polyline_matrix,
)
from beamcontact.assembly.model import LoadState, Model, initial_load_state
from beamcontact.contact.overlap import describe, initial_overlaps
from beamcontact.contact.problem import build_contact
from beamcontact.contact.resolution import contact_resolution, resolution_warning
from beamcontact.dynamics.driver import (
    DIAGNOSTICS,
    DynamicStep,
    EnergyAccount,
    StepControl,
    host_diagnostics,
    solve_dynamic,
    uniform_velocities,
)
from beamcontact.dynamics.hht import DynState, initial_state
from beamcontact.io.case import Case, CaseError, at_fraction, parse_case
from beamcontact.io.results import (
    HistoryWriter,
    StateWriter,
    read_history,
    read_last_state,
    write_summary,
)
from beamcontact.io.vtk import VtkSeries
from beamcontact.plot import (
    animate,
    plot_energies,
    plot_point_histories,
    plot_shapes,
    plot_snapshots,
)
from beamcontact.solvers.newton import NewtonOptions
from beamcontact.statics.driver import StaticStep, solve_static

Progress = Callable[[float, str], None]

ENERGY_COLUMNS = ["E_strain", "E_gravity", "E_ext", "E_contact", "E_total", "min_gap"]
DYNAMIC_COLUMNS = ["E_kin", *ENERGY_COLUMNS, "E_dissipated", "E_set_change", "p_x", "p_y",
                   "error"]  # then newton_iters, cutbacks, dt


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


class _Outputs:
    """The writers of one run and the shape plots, shared by statics and dynamics."""

    def __init__(self, case: Case, case_text: str, disc: Discretization, model: Model,
                 out_dir: Path, abscissa: str, extra_columns: list[str],
                 resume: tuple[int, float] | None = None):
        self.case, self.disc, self.out_dir = case, disc, out_dir
        self.x_ref = np.asarray(model.x_ref)
        self.points = OutputPoints(case, disc, self.x_ref)
        self.abscissa = abscissa
        self.columns = ["step", abscissa, *self.points.columns(), *extra_columns,
                        "newton_iters", "cutbacks"] + (["dt"] if abscissa == "t" else [])
        out_dir.mkdir(parents=True, exist_ok=True)
        (out_dir / "plots").mkdir(exist_ok=True)
        step = None if resume is None else resume[0]
        self.history = HistoryWriter(out_dir / "history.csv", self.columns, step)
        self.states = StateWriter(out_dir / "results.h5", case_text, disc.beams, model.n_dof,
                                  abscissa, step)
        self.maps = [(polyline_matrix(b, case.output.samples_per_element),
                      slice(b.offset, b.offset + b.n_cp)) for b in disc.beams]
        self.vtk = VtkSeries(out_dir, [m for m, _ in self.maps],
                             [b.section.half_depth for b in disc.beams], self.x_ref,
                             [b.offset for b in disc.beams], [b.n_cp for b in disc.beams],
                             None if resume is None else resume[1])

    def x(self, u) -> np.ndarray:
        """Control points for the flat displacement u."""
        return self.x_ref + np.asarray(u).reshape(-1, 2)

    def row(self, step: int, parameter: float, u, values: dict, iterations: int,
            cutbacks: int, **extra) -> None:
        """Append one history row."""
        self.history.write({"step": step, self.abscissa: parameter,
                            **self.points.values(self.x(u)), **values,
                            "newton_iters": iterations, "cutbacks": cutbacks, **extra})

    def close(self) -> None:
        """Close the files."""
        self.history.close()
        self.states.close()

    def axes(self, u) -> list[np.ndarray]:
        """Polylines of every beam axis."""
        x = self.x(u)
        return [m @ x[s] for m, s in self.maps]

    def plots(self) -> None:
        """shapes.png from the saved states, points.png; dynamics also energies.png,
        snapshots.png (a grid of instants) and animation.gif (every VTU instant)."""
        import h5py

        with h5py.File(self.out_dir / "results.h5", "r") as f:
            params = f["states/parameter"][:]
            n = len(params)
            if n == 0:
                return
            picks = np.unique(np.linspace(0, n - 1, min(n, 9)).astype(int))
            shapes = [(params[i], self.axes(f["states/u"][i])) for i in picks]
            if self.abscissa == "t":
                interval = self.case.output.vtk_interval or self.case.analysis.t_end / 100
                marks = np.arange(0.0, params[-1] + 1e-9, interval)
                frames_idx = np.unique(np.searchsorted(params, marks - 1e-9).clip(0, n - 1))
                if len(frames_idx) > 300:
                    frames_idx = frames_idx[:: int(np.ceil(len(frames_idx) / 300))]
                frames = [(params[i], self.axes(f["states/u"][i])) for i in frames_idx]
        plot_shapes([(f"{self.abscissa} {p:.3g}", a) for p, a in shapes],
                    self.axes(np.zeros(self.x_ref.size)),
                    self.out_dir / "plots" / "shapes.png", self.case.title)
        if self.abscissa == "t":
            radii = [b.section.half_depth for b in self.disc.beams]
            plot_snapshots(shapes, radii, self.out_dir / "plots" / "snapshots.png",
                           self.case.title)
            if len(frames) > 1:
                animate(frames, self.out_dir / "animation.gif", self.case.title)
        history = read_history(self.out_dir / "history.csv")
        if self.points.names:
            plot_point_histories(history, self.abscissa, self.points.names,
                                 self.out_dir / "plots" / "points.png", self.case.title)
        if self.abscissa == "t":
            plot_energies(history, self.out_dir / "plots" / "energies.png", self.case.title)

    def extremes(self) -> dict:
        """Smallest, largest and final displacement of every output point."""
        h = read_history(self.out_dir / "history.csv")
        return {f"{n}_{c}": {"min": float(h[f"{n}_{c}"].min()),
                             "max": float(h[f"{n}_{c}"].max()),
                             "final": float(h[f"{n}_{c}"][-1])}
                for n in self.points.names for c in ("ux", "uy")}


def _discretize(case: Case) -> Discretization:
    try:
        return discretize(case)
    except ValueError as exc:
        raise CaseError(f"beams: {exc}") from None


def run_case(case: Case, case_text: str, out_dir: Path, progress: Progress | None = None,
             restart: bool = False) -> dict:
    """Run ``case`` and write its results into ``out_dir``; returns the summary.

    BLAS/LAPACK (OpenBLAS, used by JAX's CPU linear solves) runs on one thread during the
    run: the summation order of a threaded LU depends on the thread count, and in the
    multi-collision benchmark that round-off grows to millimetres, so results would
    depend on the machine and on how many runs share it (a sweep's workers are
    single-threaded). For the small dense systems here one thread is also the fastest.
    """
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=1, user_api="blas"):
        return _run_case(case, case_text, out_dir, progress, restart)


def _run_case(case: Case, case_text: str, out_dir: Path, progress: Progress | None,
              restart: bool) -> dict:
    require_x64()
    if restart and case.analysis.kind != "dynamic":
        raise CaseError("--restart continues dynamic runs only (analysis.kind = \"dynamic\")")
    wall0 = time.perf_counter()
    disc = _discretize(case)
    model, disc = build_model(case, disc)
    opts = NewtonOptions(case.solver.max_iterations, case.solver.rtol, 0.0, case.solver.utol)
    contact = build_contact(case, disc)
    warnings = [] if restart else _check_initial_overlap(case, model, contact)
    run = _run_static if case.analysis.kind == "static" else _run_dynamic
    summary = run(case, case_text, disc, model, out_dir, opts, progress, restart, contact)
    if contact is not None and contact.law == "cg" and summary.get("min_gap") is not None:
        res = contact_resolution(contact.elements, contact.params, summary["min_gap"])
        summary["cg_resolution"] = res.as_dict()
        if res.under_resolved:
            warnings.append(resolution_warning(res, [b.name for b in case.beams]))
    summary["warnings"] = warnings
    summary.update({"title": case.title, "kind": case.analysis.kind,
                    "solver": effective_settings(case),
                    "wall_time_s": time.perf_counter() - wall0, "n_dof": model.n_dof,
                    "n_elements": sum(b.mesh.n_elements for b in disc.beams),
                    "beamcontact_version": __version__})
    write_summary(out_dir / "summary.json", summary)
    return summary


# an initial interpenetration deeper than this fraction of the smallest radius is an input
# error; a shallower one (a hair of overlap, e.g. to start with the contact stiffness
# engaged) is a warning
OVERLAP_ERROR = 1e-3


def _check_initial_overlap(case: Case, model: Model, contact) -> list[str]:
    """Raise CaseError if beams interpenetrate in the initial configuration (naming both
    and the place); return a warning for a shallow overlap."""
    if contact is None:
        return []
    findings = initial_overlaps(np.asarray(model.x_ref), contact.elements,
                                [b.name for b in case.beams])
    if not findings:
        return []
    r_min = float(np.min(np.asarray(contact.elements.radius)))
    if findings[0].gap < -OVERLAP_ERROR * r_min:
        raise CaseError(f"{describe(findings)}; move the beams apart")
    return [describe(findings)]


def _run_static(case, case_text, disc, model, out_dir, opts, progress, _restart,
                contact) -> dict:
    out = _Outputs(case, case_text, disc, model, out_dir, "load_factor", ENERGY_COLUMNS)

    def on_step(s: StaticStep) -> None:
        e = s.energies
        e = {**e, "E_total": e["E_strain"] + e["E_gravity"] + e["E_ext"] + e["E_contact"]}
        out.row(s.step, s.load_factor, s.u, e, s.iterations, s.cutbacks)
        out.states.write(s.step, s.load_factor, s.u)
        if s.step % case.output.vtk_every == 0 or s.load_factor >= 1.0 - 1e-12:
            out.vtk.write(s.load_factor, out.x(s.u))
        if progress is not None:
            progress(s.load_factor, f"load factor {s.load_factor:.3f}")

    try:
        result = solve_static(model, case.analysis.load_steps, opts, disc.length_scale,
                              case.solver.max_cutbacks, on_step, contact,
                              case.contact.capacity, [b.name for b in disc.beams])
    except KeyboardInterrupt:
        _interrupted(out, out_dir)
        raise
    out.close()
    out.plots()
    return {"status": result.status, "message": result.message, "steps": result.steps,
            "newton_iterations": result.iterations, "cutbacks": result.cutbacks,
            "final_load_factor": result.load_factor, "solve_time_s": result.wall_time,
            "compile_time_s": result.compile_time, "extremes": out.extremes()}


def _interrupted(out: _Outputs, out_dir: Path) -> None:
    out.close()
    write_summary(out_dir / "summary.json", {
        "status": "interrupted",
        "message": "interrupted by the user; every accepted step is in history.csv and "
                   "results.h5"})


def _restart_state(case: Case, out_dir: Path, model: Model) -> tuple[DynState, dict]:
    path = out_dir / "results.h5"
    if not path.is_file():
        raise CaseError(f"--restart: {path} does not exist (run without --restart first)")
    try:
        stored_text, last = read_last_state(path)
    except (OSError, KeyError, ValueError) as exc:
        raise CaseError(f"--restart: cannot read the last state from {path} ({exc}); is "
                        f"another run writing it?") from None
    stored = parse_case(tomllib.loads(stored_text))
    _same_model(stored, case)
    if "v" not in last or last["u"].shape != (model.n_dof,):
        raise CaseError(f"--restart: {path} does not hold a dynamic run of this case")
    if "energy_account" not in last:
        raise CaseError(f"--restart: {path} was written by an older beamcontact without the "
                        f"energy account; run the case again without --restart")
    state = DynState(jnp.asarray(last["parameter"]), jnp.asarray(last["u"]),
                     jnp.asarray(last["v"]), jnp.asarray(last["a"]), jnp.asarray(last["f_pot"]),
                     LoadState(jnp.asarray(last["load_theta"]),
                               jnp.asarray(last["load_tangent"])))
    return state, last


def _account_record(diag: dict) -> np.ndarray:
    """The energies of a saved state as results.h5 keeps them for a restart."""
    return np.array([diag[k] for k in (*DIAGNOSTICS, "E_dissipated", "E_set_change")])


def _account_from_record(record: np.ndarray) -> EnergyAccount:
    """Inverse of :func:`_account_record`."""
    values = dict(zip((*DIAGNOSTICS, "E_dissipated", "E_set_change"), record.tolist(),
                      strict=True))
    return EnergyAccount(values.pop("E_dissipated"), values.pop("E_set_change"), values)


def _same_model(stored: Case, case: Case) -> None:
    """Everything but t_end, solver and output settings must match for a restart."""
    a, b = stored.model_dump(), case.model_dump()
    for d in (a, b):
        d["analysis"].pop("t_end")
        d.pop("output")
        d.pop("solver")
        d.pop("title")

    def first_difference(x, y, path=""):
        if isinstance(x, dict) and isinstance(y, dict):
            for k in x:
                found = first_difference(x[k], y.get(k), f"{path}.{k}" if path else k)
                if found:
                    return found
            return None
        if isinstance(x, list) and isinstance(y, list) and len(x) == len(y):
            for i, (xi, yi) in enumerate(zip(x, y, strict=True)):
                found = first_difference(xi, yi, f"{path}[{i}]")
                if found:
                    return found
            return None
        return None if x == y else path

    diff = first_difference(a, b)
    if diff:
        raise CaseError(f"--restart: {diff} differs from the run being continued (only "
                        f"analysis.t_end, [solver] and [output] may change)")


def _run_dynamic(case, case_text, disc, model, out_dir, opts, progress, restart,
                 contact) -> dict:
    an = case.analysis
    interval = case.output.vtk_interval or an.t_end / 100.0
    if restart:
        state, last = _restart_state(case, out_dir, model)
        step0, dt_start = int(last["step"]), float(last["dt_next"])
        before = {"iterations": int(last["iterations_total"]),
                  "cutbacks": int(last["cutbacks_total"])}
        account = _account_from_record(last["energy_account"])
        if float(state.t) >= an.t_end - 1e-12 * an.t_end:
            raise CaseError(f"--restart: the run in {out_dir} already reached t = "
                            f"{float(state.t):.6g} s >= analysis.t_end")
        out = _Outputs(case, case_text, disc, model, out_dir, "t", DYNAMIC_COLUMNS,
                       resume=(step0, float(state.t)))
    else:
        u0 = jnp.zeros(model.n_dof)
        v0 = jnp.asarray(uniform_velocities(disc, [b.initial_velocity for b in case.beams]))
        cs0 = None if contact is None else contact.grown_set(
            model.x_ref, 0.0, case.contact.capacity)[0]
        state = initial_state(u0, v0, model, initial_load_state(model),
                              None if contact is None else contact.elements, cs0,
                              "none" if contact is None else contact.law)
        step0, dt_start, before = 0, an.dt, {"iterations": 0, "cutbacks": 0}
        account = None
        out = _Outputs(case, case_text, disc, model, out_dir, "t", DYNAMIC_COLUMNS)
    next_snapshot = [np.floor(float(state.t) / interval + 1e-9) * interval + interval]
    totals = dict(before)

    def save(step: int, t: float, st: DynState, h: float, iterations: int, cutbacks: int,
             diag: dict, dt_next: float) -> None:
        out.row(step, t, st.u, diag, iterations, cutbacks, dt=h)
        out.states.write(step, t, st.u, v=st.v, a=st.a, f_pot=st.f_pot,
                         load_theta=st.load_state.theta, load_tangent=st.load_state.tangent,
                         dt=h, dt_next=dt_next, iterations_total=totals["iterations"],
                         cutbacks_total=cutbacks, energy_account=_account_record(diag))

    if not restart:
        diag0 = {**host_diagnostics(state, model, contact, cs0), "error": 0.0,
                 "E_dissipated": 0.0, "E_set_change": 0.0}
        save(0, 0.0, state, 0.0, 0, 0, diag0, an.dt)
        out.vtk.write(0.0, out.x(state.u))
        account = _account_from_record(_account_record(diag0))

    def on_step(s: DynamicStep) -> None:
        totals["iterations"] += s.iterations
        cutbacks = before["cutbacks"] + s.cutbacks
        save(s.step, s.t, s.state, s.dt, s.iterations, cutbacks, s.diagnostics, s.dt_next)
        if s.t >= next_snapshot[0] - 1e-9 * interval or s.t >= an.t_end - 1e-12:
            out.vtk.write(s.t, out.x(s.state.u))
            next_snapshot[0] = np.floor(s.t / interval + 1e-9) * interval + interval
        if progress is not None:
            progress(s.t / an.t_end, f"t = {s.t:.4g} s, dt = {s.dt:.3g} s")

    try:
        result = solve_dynamic(model, state, an.t_end, an.alpha, opts, disc.length_scale,
                               step_control(case), dt_start=dt_start, step0=step0,
                               on_step=on_step, contact=contact,
                               capacity=case.contact.capacity, account=account)
    except KeyboardInterrupt:
        _interrupted(out, out_dir)
        raise
    out.close()
    out.plots()
    h = read_history(out_dir / "history.csv")
    steps = step0 + result.steps
    iterations = before["iterations"] + result.iterations
    return {"status": result.status, "message": result.message, "steps": steps,
            "newton_iterations": iterations, "cutbacks": before["cutbacks"] + result.cutbacks,
            "rejections": result.rejections,
            "restarted_from_step": step0 if restart else None,
            "t_final": result.t, "mean_iterations_per_step": iterations / max(steps, 1),
            "solve_time_s": result.wall_time, "compile_time_s": result.compile_time,
            "min_step_s": float(h["dt"][1:].min()) if len(h["dt"]) > 1 else None,
            "max_step_s": float(h["dt"][1:].max()) if len(h["dt"]) > 1 else None,
            "energy": {"E_total_initial": float(h["E_total"][0]),
                       "E_total_final": float(h["E_total"][-1]),
                       "E_kin_max": float(h["E_kin"].max()),
                       "E_dissipated": float(h["E_dissipated"][-1]),
                       "E_set_change": float(h["E_set_change"][-1]),
                       "balance_residual": float(h["E_total"][-1] + h["E_dissipated"][-1]
                                                 - h["E_set_change"][-1] - h["E_total"][0])},
            "extremes": out.extremes(), **contact_summary(h, out.points.names, contact)}


def effective_settings(case: Case) -> dict:
    """Every [solver] value, defaults included, and for dynamics the step bounds and
    alpha actually used: enough to reproduce the run."""
    settings = case.solver.model_dump()
    an = case.analysis
    if an.kind == "dynamic":
        settings.update(dt=an.dt, dt_min=an.smallest_step, alpha=an.alpha)
    else:
        settings.update(load_steps=an.load_steps)
    return settings


def step_control(case: Case) -> StepControl:
    """The step controller's settings of a validated dynamic case."""
    an, so = case.analysis, case.solver
    return StepControl(an.dt, an.smallest_step, so.error_tol, so.energy_tol, so.max_cutbacks)


def contact_summary(h: dict, points: list[str], contact) -> dict:
    """First impact, first amplitude of each output point after it, gap extremes.

    The first impact is the first accepted step whose smallest gap is below 1 % of the
    smallest contact radius; the first amplitude of a point is the extreme u_y of its
    first excursion after that time (until u_y changes sign, or the end of the run).
    """
    if contact is None:
        return {}
    gap = h["min_gap"]
    r_min = float(np.min(np.asarray(contact.elements.radius)))
    hit = np.where(gap <= 0.01 * r_min)[0]
    out = {"min_gap": float(np.nanmin(gap)),
           "max_penetration": float(max(0.0, -np.nanmin(gap))),
           "first_impact_time": float(h["t"][hit[0]]) if hit.size else None,
           "first_amplitude": {},
           "impacts": contact_episodes(h)}
    if hit.size:
        for name in points:
            out["first_amplitude"][name] = first_excursion_extreme(h["t"][hit[0]:],
                                                                   h[f"{name}_uy"][hit[0]:])
    return out


def contact_episodes(h: dict, level: float = 1e-4) -> list[dict]:
    """Every contact of the run: it starts at the first step whose contact energy exceeds
    ``level`` times the largest E_kin + E_strain + |E_contact| of the run, and ends at the
    first step after it where it falls below a quarter of that (the hysteresis keeps a
    grazing contact from counting as many). For each: start and end time (None if still
    in contact at the end), the smallest gap, and the changes of the total energy, of
    E_dissipated and of E_set_change from the step before it starts to the step where it
    ends (E_change = E_set_change - E_dissipated)."""
    e_con, t = np.abs(h["E_contact"]), h["t"]
    threshold = level * float(np.max(h["E_kin"] + h["E_strain"] + e_con))
    episodes, k, n = [], 0, len(t)
    while k < n:
        if not e_con[k] > threshold:
            k += 1
            continue
        begin = k
        while k < n and not e_con[k] < 0.25 * threshold:
            k += 1
        before, after = max(begin - 1, 0), min(k, n - 1)
        episodes.append({
            "start": float(t[begin]), "end": float(t[k]) if k < n else None,
            "min_gap": float(np.min(h["min_gap"][begin:after + 1])),
            "E_total_before": float(h["E_total"][before]),
            "E_change": float(h["E_total"][after] - h["E_total"][before]),
            "E_dissipated": float(h["E_dissipated"][after] - h["E_dissipated"][before]),
            "E_set_change": float(h["E_set_change"][after] - h["E_set_change"][before])})
    return episodes


def first_excursion_extreme(t: np.ndarray, uy: np.ndarray, level: float = 0.01) -> dict:
    """Extreme of the first excursion of ``uy``: it starts where |uy| first exceeds
    ``level`` times max |uy| and ends where uy passes that level with the opposite sign
    (or at the end), so that round-off wiggles about zero do not count as excursions."""
    tau = level * float(np.max(np.abs(uy)))
    if tau == 0.0:
        return {"uy": 0.0, "t": float(t[0])}
    k0 = int(np.argmax(np.abs(uy) > tau))
    sign = np.sign(uy[k0])
    back = np.where(sign * uy[k0:] < -tau)[0]
    end = k0 + (int(back[0]) if back.size else len(uy) - k0)
    k = k0 + int(np.argmax(sign * uy[k0:end]))
    return {"uy": float(uy[k]), "t": float(t[k])}
