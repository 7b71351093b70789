"""Run a validated case (the results contract of docs/architecture.md, "Results").

:func:`execute` runs statics or dynamics and returns the summary and the in-memory
:class:`~beamcontact.record.RunRecord` (history and snapshots); with an output folder it
writes history.csv, summary.json, results.h5, vtk/*.vtu + beams.pvd and plots/*.png as the
run goes. On failure or interruption (Ctrl-C) everything accepted so far is kept and the
summary says why the run stopped, with every counter known at that point. Dynamic runs
can be continued with ``restart=True`` from the last state in results.h5.
"""

from __future__ import annotations

import time
import tomllib
from contextlib import suppress
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from beamcontact import __version__, _native, _warmup, require_x64
from beamcontact._native import Stopwatch
from beamcontact.assembly.model import LoadState, Model
from beamcontact.contact.laws import CoarseGrained
from beamcontact.contact.overlap import describe, initial_overlaps, obstacle_overlaps
from beamcontact.contact.resolution import contact_resolution, resolution_warning
from beamcontact.drawer import Drawer
from beamcontact.dynamics.control import KINDS, EnergyAccount, total_energy
from beamcontact.dynamics.driver import StepBatch, solve_dynamic
from beamcontact.dynamics.hht import DynState
from beamcontact.dynamics.report import DIAGNOSTICS
from beamcontact.io.case import Case, CaseError, ignored_keys, parse_case
from beamcontact.io.output_folder import claimed
from beamcontact.io.results import read_last_state, write_summary
from beamcontact.progress import Progress, ProgressInfo
from beamcontact.record import OutputError, RunRecord, writing
from beamcontact.setup.contact import obstacle_names
from beamcontact.setup.start import (
    Prepared,
    choose_engine,
    compile_loop_early,
    dynamic_start,
    prepare,
    static_engine,
)
from beamcontact.statics.driver import StaticStep, solve_static
from beamcontact.stop_signals import interrupt_of, stopped_by
from beamcontact.summary import (
    contact_summary,
    effective_settings,
    integration_energy_warning,
    set_change_warning,
    shared_cores_warning,
    unfinished_amplitude_warning,
)

ENERGY_COLUMNS = ["E_strain", "E_gravity", "E_ext", "E_contact", "E_total", "min_gap"]
DYNAMIC_COLUMNS = ["E_kin", *ENERGY_COLUMNS, "E_dissipated", "E_set_change", "p_x", "p_y",
                   "error"]  # then newton_iters, cutbacks, dt


@dataclass
class _Tally:
    """Counters of the accepted steps, kept by the runner so that an interrupted run
    still reports them (the solvers' own result never comes back then)."""

    start: Stopwatch = field(default_factory=Stopwatch)
    steps: int = 0
    iterations: int = 0
    cutbacks: int = 0
    reached: float = 0.0
    first_step_s: float | None = None  # until the first step, outside Numba's compiles
    rejected: np.ndarray | None = None  # by kind (dynamics)
    writing_s: float = 0.0  # the accepted steps written (history, states, snapshots)

    def accept(self, step: int, reached: float, iterations: int, cutbacks: int,
               rejected: np.ndarray | None = None) -> None:
        if self.first_step_s is None:
            self.first_step_s = self.start.outside_compiles()
        self.steps, self.reached, self.cutbacks = step, reached, cutbacks
        self.iterations += iterations
        self.rejected = rejected

    def rejections(self) -> dict | None:
        """The rejected attempts by kind so far (None: not counted)."""
        return None if self.rejected is None else _rejections(self.rejected, {})

    def interrupted(self, parameter: str, exc: KeyboardInterrupt) -> dict:
        """The counters as the solvers' summary fields of a run interrupted by ``exc``
        (Ctrl-C, or SIGTERM/SIGHUP: :mod:`beamcontact.stop_signals`)."""
        by = stopped_by(exc)
        return {**self._counters(), "status": "interrupted",
                "signal": None if by == "the user" else by,
                "message": f"interrupted by {by} at {self._where(parameter)} after "
                           f"{self.steps} steps; every accepted step is kept"}

    def failed_output(self, parameter: str, exc: OSError) -> dict:
        """The counters as the solvers' summary fields of a run whose results could not
        be written (:class:`~beamcontact.record.OutputError`)."""
        return {**self._counters(), "status": "output_failed",
                "message": f"{exc}; stopped at {self._where(parameter)} after {self.steps} "
                           f"steps; what was written before is kept"}

    def _where(self, parameter: str) -> str:
        return f"t = {self.reached:.6g} s" if parameter == "t" else \
            f"load factor {self.reached:.6g}"

    def _counters(self) -> dict:
        return {"steps": self.steps, "newton_iterations": self.iterations,
                "cutbacks": self.cutbacks, "solve_time_s": time.perf_counter() - self.start.wall,
                "compile_time_s": self.first_step_s or 0.0, "writing_time_s": self.writing_s}


def run_case(case: Case, case_text: str, out_dir: Path | None,
             progress: Progress | None = None, restart: bool = False,
             overwrite: bool = False, drawer: Drawer | None = None) -> dict:
    """Run ``case``, write its results into ``out_dir`` (if given); returns the summary."""
    return execute(case, case_text, out_dir, progress, restart, overwrite, drawer)[0]


def execute(case: Case, case_text: str, out_dir: Path | None,
            progress: Progress | None = None, restart: bool = False,
            overwrite: bool = False, drawer: Drawer | None = None) -> tuple[dict, RunRecord]:
    """Run ``case``; returns the summary and the run's in-memory record.

    ``case_text`` is the TOML stored in results.h5 and written as ``case.toml`` (the case
    file's text, comments included; empty: the case's own TOML); ``progress`` is called
    after every accepted step. The run holds ``out_dir`` throughout
    (:func:`~beamcontact.io.output_folder.claimed`: one run per folder; earlier results
    are refused unless ``restart`` continues them or ``overwrite`` replaces them).
    ``drawer``: the process that draws the figures (:mod:`beamcontact.drawer`), started
    by a process of our own (the command line), not a user's or a sweep's worker;
    without one they are drawn here.

    BLAS/LAPACK (OpenBLAS, used by JAX's CPU linear solves) runs on one thread during the
    run: the summation order of a threaded LU depends on the thread count, and in the
    multi-collision benchmark that round-off grows to millimetres, so results would
    depend on the machine and on how many runs share it (a sweep's workers are
    single-threaded). For the small dense systems here one thread is also the fastest.
    """
    require_x64()  # before the folder is claimed: a refused run leaves nothing behind
    # scipy.linalg loads the OpenBLAS that JAX's LAPACK calls, so that the limit below
    # reaches it (a library loaded later keeps its threads). The native engine calls no
    # BLAS (its kernels have their own LU; numpy's BLAS, loaded with numpy, is limited)
    # but loads scipy.linalg when Numba compiles; a run whose loop is cached normally
    # compiles nothing and never loads it: 0.12 s of a warm run
    if choose_engine(case)[0] != "native" or not _warmup.loop_cached():
        import scipy.linalg  # noqa: F401
    from threadpoolctl import threadpool_limits

    with claimed(out_dir, restart=restart, overwrite=overwrite), \
            threadpool_limits(limits=1, user_api="blas"):
        return _execute(case, case_text or case.to_toml(), out_dir, progress, restart,
                        drawer)


def _execute(case: Case, case_text: str, out_dir: Path | None, progress: Progress | None,
             restart: bool, drawer: Drawer | None) -> tuple[dict, RunRecord]:
    require_x64()
    if restart and case.analysis.kind != "dynamic":
        raise CaseError("--restart continues dynamic runs only (analysis.kind = \"dynamic\")")
    if restart and out_dir is None:
        raise CaseError("a restart needs the output folder of the run to continue")
    watch = Stopwatch()
    as_python = case.analysis.kind == "dynamic" and compile_loop_early(case)
    with _native.one_thread(), _native.as_python(as_python):
        prepared = prepare(case)
    model, disc, contact = prepared.model, prepared.disc, prepared.contact
    warnings = _start_warnings(prepared, restart)
    run = _run_static if case.analysis.kind == "static" else _run_dynamic
    try:
        summary, record = run(prepared, case_text, out_dir, progress, restart, drawer,
                              as_python)
    except OutputError as exc:  # before the first step: the summary says so, if it can
        if out_dir is not None:
            with suppress(OSError):
                write_summary(out_dir / "summary.json", {
                    "status": "output_failed", "message": f"{exc}; the run did not start",
                    "steps": 0, "title": case.title, "kind": case.analysis.kind})
        raise
    finally:
        # a helper this run held compiles the loop from now on (a process that makes
        # more runs, the Python API's, needs it; the command line's ends here anyway)
        _warmup.release()
    if (contact is not None and isinstance(contact.law, CoarseGrained)
            and summary.get("min_gap") is not None):
        res = contact_resolution(contact.elements, contact.law, summary["min_gap"])
        summary["cg_resolution"] = res.as_dict()
        if res.under_resolved:
            warnings.append(resolution_warning(res, [b.name for b in case.beams]))
    if contact is not None and contact.law.closest_pairs:
        warnings.append(set_change_warning(summary.get("energy"), contact.law.pairing))
    if case.analysis.kind == "dynamic":
        warnings.append(integration_energy_warning(summary.get("energy"),
                                                   case.solver.error_tol == 0.0))
    warnings.append(unfinished_amplitude_warning(summary.get("first_amplitude") or {}))
    solver = {**effective_settings(case), **_engine_used(case, model, contact)}
    warnings.append(shared_cores_warning(summary.get("loop_threads"),
                                         solver.get("threads", 1),
                                         probe_s=summary.get("loop_probe_s") or 0.0))
    if drawer is not None and drawer.failure is not None:
        warnings.append(f"the figures were drawn by the run itself, not by its drawer "
                        f"process (beamcontact/drawer.py): {drawer.failure}")
    summary["warnings"] = [w for w in warnings if w is not None]
    # every compile of the run (the model, its start, the solve) and the first attempt's
    # time outside them (XLA, waiting for the helper that compiles the loop)
    summary["compile_time_s"] = summary.get("compile_time_s", 0.0) + watch.compiles()
    summary.update({"title": case.title, "kind": case.analysis.kind,
                    "solver": solver,
                    "wall_time_s": time.perf_counter() - watch.wall, "n_dof": model.n_dof,
                    "n_elements": sum(b.mesh.n_elements for b in disc.beams),
                    "beamcontact_version": __version__})
    if out_dir is not None:
        with writing(out_dir / "summary.json"):
            write_summary(out_dir / "summary.json", summary)
    return summary, record


def check_case(case: Case) -> list[str]:
    """What ``beamcontact check`` adds to the validation of the file, as a run would
    meet it before its first step: the model is built and the initial overlap checked
    (a CaseError), and the warnings of a run's start come back."""
    return _start_warnings(prepare(case))


def _start_warnings(prepared: Prepared, restart: bool = False) -> list[str]:
    """The checks of a run's start: keys the case ignores (warnings) and, unless it
    continues a run, the initial overlap (a CaseError, or a warning when shallow)."""
    case = prepared.case
    overlap = [] if restart else _check_initial_overlap(case, prepared.model,
                                                        prepared.contact)
    return ignored_keys(case) + overlap


def _engine_used(case: Case, model: Model, contact) -> dict:
    """The engine that ran the case and why; the linear solver it used."""
    name, why = choose_engine(case, None if contact is None else contact.law)
    used = {"engine_used": name, "engine_reason": why}
    if name == "jax":
        used["linear_solver_used"] = "sparse" if model.sparse else "dense"
    else:
        used["linear_solver_used"] = "bordered banded"
        used["threads"] = _native.most_threads()
    return used


# an initial interpenetration deeper than this fraction of the smallest radius is an input
# error; a shallower one (a hair of overlap, e.g. to start with the contact stiffness
# engaged) is a warning
OVERLAP_ERROR = 1e-3


def _check_initial_overlap(case: Case, model: Model, contact) -> list[str]:
    """Raise CaseError if beams interpenetrate in the initial configuration (naming both
    and the place); return a warning for a shallow overlap."""
    if contact is None:
        return []
    names = [b.name for b in case.beams]
    findings = initial_overlaps(np.asarray(model.x_ref), contact.elements, names)
    r_min = float(np.min(np.asarray(contact.elements.radius)))
    warnings = []
    if findings:
        if findings[0].gap < -OVERLAP_ERROR * r_min:
            raise CaseError(f"{describe(findings)}; move the beams apart")
        warnings.append(describe(findings))
    if contact.obstacles is not None:
        walls = obstacle_overlaps(np.asarray(model.x_ref), contact.elements,
                                  contact.obstacles, names, obstacle_names(case))
        if walls and walls[0][0] < -OVERLAP_ERROR * r_min:
            more = f" (and {len(walls) - 1} more)" if len(walls) > 1 else ""
            raise CaseError(f"{walls[0][1]}{more}; move the beam out of the obstacle")
        warnings += [message for _, message in walls]
    return warnings


def _run_static(prepared: Prepared, case_text, out_dir, progress, _restart, drawer,
                _as_python: bool = False) -> tuple[dict, RunRecord]:
    case, disc, model = prepared.case, prepared.disc, prepared.model
    rec = RunRecord(case, case_text, disc, model.x_ref, model.n_dof, out_dir, "load_factor",
                    ENERGY_COLUMNS)
    tally = _Tally()

    def on_step(s: StaticStep) -> None:
        t0 = time.perf_counter()
        e = s.energies
        e = {**e, "E_total": total_energy({**e, "E_kin": 0.0})}
        rec.row(s.step, s.load_factor, s.u, e, s.iterations, s.cutbacks)
        rec.state(s.step, s.load_factor, s.u)
        if s.step % case.output.vtk_every == 0 or s.load_factor >= 1.0 - 1e-12:
            rec.snapshot(s.load_factor, s.u)
        if s.step > 0:
            tally.accept(s.step, s.load_factor, s.iterations, s.cutbacks)
        tally.writing_s += time.perf_counter() - t0
        if progress is not None:
            progress(ProgressInfo(s.load_factor, "load_factor", s.load_factor, s.step,
                                  None, s.iterations))

    try:
        result = solve_static(static_engine(prepared), case.analysis.load_steps,
                              case.solver.max_cutbacks, on_step, case.contact.capacity,
                              [b.name for b in disc.beams])
        summary = {"status": result.status, "message": result.message,
                   "steps": result.steps, "newton_iterations": result.iterations,
                   "cutbacks": result.cutbacks, "final_load_factor": result.load_factor,
                   "solve_time_s": result.wall_time,
                   "compile_time_s": tally.first_step_s or 0.0,
                   "writing_time_s": tally.writing_s}
    except (KeyboardInterrupt, SystemError) as exc:
        summary = {**tally.interrupted("load_factor", interrupt_of(exc)),
                   "final_load_factor": tally.reached}
    except OutputError as exc:
        summary = {**tally.failed_output("load_factor", exc),
                   "final_load_factor": tally.reached}
    _finish(rec, summary, drawer)
    return {**summary, "extremes": rec.extremes()}, rec


def _rejections(before: np.ndarray, since: dict) -> dict:
    """The rejected attempts by kind of the whole run: those before a restart and those
    since (the kinds that occurred)."""
    total = {k: int(n) for k, n in zip(KINDS, before, strict=True)}
    for k, n in since.items():
        total[k] += n
    return {k: n for k, n in total.items() if n > 0}


def _finish(rec: RunRecord, summary: dict, drawer: Drawer | None) -> None:
    """Close the files and draw the figures; a failure of either ends the run as
    "output_failed" (the summary says so, with what was kept). An interrupt while
    drawing (a second Ctrl-C, or a signal) skips the figures, never the summary."""
    try:
        rec.close()
        rec.plots(drawer)
    except OutputError as exc:
        if summary["status"] == "completed":
            summary.update(status="output_failed",
                           message=f"{exc}; the run completed and the rest is written")
    except KeyboardInterrupt as exc:
        by = stopped_by(exc)
        summary["figures"] = f"not drawn: interrupted by {by}"
        if summary["status"] != "interrupted":  # the command line exits as interrupted
            summary["signal"] = None if by == "the user" else by


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
    if not (out_dir / "history.csv").is_file():
        raise CaseError(f"--restart: {out_dir / 'history.csv'} is missing, so the run cannot "
                        f"be continued; {_AGAIN}")
    if "v" not in last or last["u"].shape != (model.n_dof,):
        raise CaseError(f"--restart: {path} does not hold a dynamic run of this case")
    if "energy_account" not in last:
        raise CaseError(f"--restart: {path} was written by an older beamcontact without the "
                        f"energy account; run the case again without --restart")
    state = DynState(*(np.asarray(last[k]) for k in ("parameter", "u", "v", "a", "f_pot")),
                     LoadState(np.asarray(last["load_theta"]),
                               np.asarray(last["load_tangent"])))
    return state, last


_AGAIN = "run the case again without --restart (with --overwrite)"


# the energies of a saved state as results.h5 keeps them for a restart
_ACCOUNT = (*DIAGNOSTICS, "E_dissipated", "E_set_change")


def _account_record(diag: dict) -> np.ndarray:
    """The energies of a saved state as results.h5 keeps them for a restart."""
    return np.array([diag[k] for k in _ACCOUNT])


def _account_from_record(record: np.ndarray) -> EnergyAccount:
    """Inverse of :func:`_account_record`."""
    values = dict(zip(_ACCOUNT, record.tolist(), strict=True))
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


@dataclass(frozen=True)
class _Start:
    """Where a dynamic run starts: its state, the counters so far (a restart continues
    them), its energy account and its record."""

    state: DynState
    step0: int
    dt_start: float
    iterations: int  # Newton iterations of every attempt
    cutbacks: int
    rejected: np.ndarray  # rejected attempts by kind (dynamics/control.py, KINDS)
    account: EnergyAccount
    rec: RunRecord


def _save(rec: RunRecord, batch: StepBatch, cutbacks: np.ndarray,
          iterations_total: np.ndarray, rejections_total: np.ndarray) -> None:
    """Accepted steps into history.csv and results.h5 (with what a restart needs: the
    state, the step to try next, the energy account and the run's counters so far:
    ``cutbacks``, ``iterations_total`` (k,) and ``rejections_total`` (k, len(KINDS))),
    all at once."""
    u, v, a, f_pot, theta, tangent = batch.state_arrays()
    diag = batch.diagnostics()
    number, t, dt = batch.step, batch.t, batch.dt
    rec.rows(number, t, u, diag, batch.iterations, cutbacks, dt=dt)
    rec.states(number, t, u, v=v, a=a, f_pot=f_pot, load_theta=theta, load_tangent=tangent,
               dt=dt, dt_next=batch.dt_next, iterations_total=iterations_total,
               cutbacks_total=cutbacks, rejections_total=rejections_total,
               energy_account=np.column_stack([diag[k] for k in _ACCOUNT]))


def _dynamic_start(prepared: Prepared, case_text, out_dir, restart) -> tuple[_Start, object]:
    """The start of a dynamic run: t = 0 (its row and snapshot written), or the last
    saved state of the run in out_dir (restart); and the engine of its time loop."""
    case, disc, model, contact = prepared.case, prepared.disc, prepared.model, prepared.contact
    an = case.analysis
    begin = dynamic_start(prepared, initial=not restart)
    if restart:
        state, last = _restart_state(case, out_dir, model)
        if float(state.t) >= an.t_end - 1e-12 * an.t_end:
            raise CaseError(f"--restart: the run in {out_dir} already reached t = "
                            f"{float(state.t):.6g} s >= analysis.t_end")
        step0 = int(last["step"])
        try:
            rec = RunRecord(case, case_text, disc, model.x_ref, model.n_dof, out_dir, "t",
                            DYNAMIC_COLUMNS, resume=(step0, float(state.t)))
        except (ValueError, UnicodeDecodeError) as exc:  # history.csv (HistoryWriter)
            raise CaseError(f"--restart: {out_dir / 'history.csv'} is damaged ({exc}), so "
                            f"the run cannot be continued; {_AGAIN}") from None
        # results.h5 of a run before the rejections were kept counts none of them
        rejected = np.asarray(last.get("rejections_total", np.zeros(len(KINDS))), float)
        return _Start(state, step0, float(last["dt_next"]), int(last["iterations_total"]),
                      int(last["cutbacks_total"]), rejected,
                      _account_from_record(last["energy_account"]), rec), begin
    state = begin.state
    rec = RunRecord(case, case_text, disc, model.x_ref, model.n_dof, out_dir, "t",
                    DYNAMIC_COLUMNS)
    first = None if contact is None else contact.first_capacity(case.contact.capacity)
    diag0 = begin.engine.energies(state, first)
    diag0 = {**diag0, "E_dissipated": 0.0, "E_set_change": 0.0}
    _save(rec, StepBatch.initial(state, diag0, an.dt), np.zeros(1, np.int64),
          np.zeros(1, np.int64), np.zeros((1, len(KINDS))))
    rec.snapshot(0.0, state.u)
    return _Start(state, 0, an.dt, 0, 0, np.zeros(len(KINDS)),
                  _account_from_record(_account_record(diag0)), rec), begin


def _run_dynamic(prepared: Prepared, case_text, out_dir, progress, restart, drawer,
                 as_python: bool = False) -> tuple[dict, RunRecord]:
    """A dynamic run; ``as_python``: its start (the engine, the state and energies at
    t = 0) with the kernels as Python (setup.start.compile_loop_early)."""
    case, contact = prepared.case, prepared.contact
    an = case.analysis
    interval = case.output.vtk_interval or an.t_end / 100.0
    with _native.one_thread(), _native.as_python(as_python):
        start, begin = _dynamic_start(prepared, case_text, out_dir, restart)
    rec = start.rec
    next_snapshot = [np.floor(float(start.state.t) / interval + 1e-9) * interval + interval]
    tally = _Tally(steps=start.step0, iterations=start.iterations, cutbacks=start.cutbacks,
                   reached=float(start.state.t), rejected=start.rejected)

    def on_steps(batch: StepBatch) -> None:
        t0 = time.perf_counter()
        cutbacks = start.cutbacks + batch.cutbacks
        rejected = start.rejected + batch.rejected
        iterations = start.iterations + batch.iterations_total
        step, t = int(batch.step[-1]), float(batch.t[-1])
        tally.accept(step, t, int(iterations[-1]) - tally.iterations, int(cutbacks[-1]),
                     rejected[-1])
        _save(rec, batch, cutbacks, iterations, rejected)
        for j, tj in enumerate(batch.t.tolist()):
            if tj >= next_snapshot[0] - 1e-9 * interval or tj >= an.t_end - 1e-12:
                rec.snapshot(tj, batch.states[j].u)
                next_snapshot[0] = np.floor(tj / interval + 1e-9) * interval + interval
        tally.writing_s += time.perf_counter() - t0
        if progress is not None:
            progress(ProgressInfo(t / an.t_end, "t", t, step, float(batch.dt[-1]),
                                  int(batch.iterations[-1])))

    try:
        result = solve_dynamic(begin.engine, start.state, an.t_end, prepared.length,
                               begin.control, dt_start=start.dt_start, step0=start.step0,
                               on_steps=on_steps, capacity=case.contact.capacity,
                               account=start.account)
        summary = {"status": result.status, "message": result.message,
                   "steps": start.step0 + result.steps,
                   "newton_iterations": start.iterations + result.iterations,
                   "cutbacks": start.cutbacks + result.cutbacks,
                   "rejections": _rejections(start.rejected, result.rejections),
                   "t_final": result.t,
                   "solve_time_s": result.wall_time,
                   "compile_time_s": tally.first_step_s or 0.0,
                   "writing_time_s": tally.writing_s,
                   "loop_threads": _loop_threads(begin.engine),
                   "loop_probe_s": _loop_probe(begin.engine)}
    except (KeyboardInterrupt, SystemError) as exc:
        summary = {**tally.interrupted("t", interrupt_of(exc)), "rejections": tally.rejections(),
                   "t_final": tally.reached}
    except OutputError as exc:
        summary = {**tally.failed_output("t", exc), "rejections": tally.rejections(),
                   "t_final": tally.reached}
    _finish(rec, summary, drawer)
    summary["restarted_from_step"] = start.step0 if restart else None
    summary["mean_iterations_per_step"] = summary["newton_iterations"] / max(summary["steps"], 1)
    return {**summary, **_dynamic_results(rec, contact)}, rec


def _loop_threads(engine) -> dict[str, float] | None:
    """Seconds of the native engine's compiled time loop per count of threads its
    parallel kernels ran on (docs/engines.md, "Threads"); None for the JAX engine."""
    seconds = getattr(engine, "thread_seconds", None)
    return None if seconds is None else {str(k): round(v, 4)
                                         for k, v in sorted(seconds.items())}


def _loop_probe(engine) -> float | None:
    """Seconds of the native engine's compiled time loop on one thread before its first
    reading of the cores (_native.CoreShare; docs/engines.md, "Threads"): in
    ``loop_threads`` too, but no sign of cores shared with other processes. None for the
    JAX engine."""
    seconds = getattr(engine, "probe_seconds", None)
    return None if seconds is None else round(seconds, 4)


def _dynamic_results(rec: RunRecord, contact) -> dict:
    """Summary fields computed from the history of a dynamic run."""
    h = rec.history()
    steps = h["dt"][1:]
    return {
        "min_step_s": float(steps.min()) if len(steps) else None,
        "max_step_s": float(steps.max()) if len(steps) else None,
        "energy": {"E_total_initial": float(h["E_total"][0]),
                   "E_total_final": float(h["E_total"][-1]),
                   "E_kin_max": float(h["E_kin"].max()),
                   "E_dissipated": float(h["E_dissipated"][-1]),
                   "E_dissipated_min": float(h["E_dissipated"].min()),
                   "E_set_change": float(h["E_set_change"][-1]),
                   "balance_residual": float(h["E_total"][-1] + h["E_dissipated"][-1]
                                             - h["E_set_change"][-1] - h["E_total"][0])},
        "extremes": rec.extremes(), **contact_summary(h, rec.points.names, contact)}
