"""Parameter sweeps: Cartesian products of case-file overrides, run with Dask distributed.

``beamcontact sweep CASE --set KEY=V1,V2 [--set ...] --out DIR`` (the paper's studies,
Figs. 7-10). A KEY is a dotted path into the case file; entries of a list of tables
(``beams``, ``loads``, ``output.points``) are addressed by their ``name`` or by their index
(``beams.upper.material.E``, ``loads.0.force``). A value is read as a TOML value (number,
boolean, array ``[0.0, -9.81]``); anything else is a string (``contact.model=cg,ipip``).
Commas inside brackets or quotes do not split values. Every member of the product is
validated by the case schema before anything runs.

Member ``NAME`` runs into ``DIR/NAME/`` with the outputs of ``beamcontact run`` plus its
effective ``case.toml``. A member is complete when that case.toml equals the one the sweep
would write and its summary.json says "completed": running the same sweep again skips it and
reruns every other member from scratch. ``DIR/sweep.csv`` lists every member (parameters,
status, key results); ``DIR/plots/`` overlays the output points of all members.

Execution: a local Dask cluster of worker processes started and stopped here, or an existing
scheduler (``--scheduler tcp://HOST:PORT``), whose workers must see DIR (a shared file
system) and have beamcontact installed. A member that fails or whose worker dies is recorded
and never stops the others. Progress: each worker forwards its run's ProgressInfo (fraction
and text) as a Dask worker event at most twice a second; SweepEvents hands them to the client.
"""

import contextlib
import logging
import shutil
import time
import tomllib
import traceback
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np

from beamcontact.io.case import CaseError, parse_case
from beamcontact.io.results import read_history, read_summary, write_summary, write_table
from beamcontact.progress import Progress, ProgressInfo, SweepEvents
from beamcontact.sweep_settings import Member, format_value

PROGRESS_TOPIC = "beamcontact-sweep-progress"
_COMPLETED = "completed"


def completed_summary(member: Member, run_dir: Path) -> dict | None:
    """The summary of a finished member whose case equals this one, else None."""
    case_file, summary_file = run_dir / "case.toml", run_dir / "summary.json"
    if not (case_file.is_file() and summary_file.is_file()):
        return None
    if case_file.read_text(encoding="utf-8") != member.case_text:
        return None
    summary = read_summary(summary_file)
    return summary if summary and summary.get("status") == _COMPLETED else None


def run_member(member: Member, run_dir: str | Path, report: Progress | None = None) -> dict:
    """Run one member into ``run_dir`` (replacing what is there) and return its summary.

    ``report`` is the runner's progress callback (a ProgressInfo after every accepted step).

    Never raises for a failing run: an exception becomes status "error" with its message
    in the summary (and in ``run_dir/summary.json``), so a sweep goes on.
    """
    from beamcontact import enable_x64
    from beamcontact._cache import enable_compilation_cache
    from beamcontact.runner import run_case

    enable_x64()
    enable_compilation_cache()
    run_dir = Path(run_dir)
    try:
        if run_dir.exists():
            shutil.rmtree(run_dir)
        run_dir.mkdir(parents=True)
        (run_dir / "case.toml").write_text(member.case_text, encoding="utf-8")
        case = parse_case(tomllib.loads(member.case_text))
        return run_case(case, member.case_text, run_dir, report)
    except Exception as exc:  # noqa: BLE001 - a failing member is recorded, not fatal
        summary = {"status": "error", "message": f"{type(exc).__name__}: {exc}",
                   "traceback": traceback.format_exc()}
        with contextlib.suppress(OSError):  # the folder itself may be the problem
            write_summary(run_dir / "summary.json", summary)
        return summary


def _run_on_worker(member: Member, run_dir: str) -> dict:
    """run_member on a Dask worker, reporting progress as worker events (twice a second).

    The native kernels run on one thread here (a worker's run has its core). The runner
    hands a ProgressInfo to ``report``; the event carries only its fraction and its text
    (``{"run", "fraction", "info"}``, JSON-simple, so that any scheduler passes it on and
    the client needs no beamcontact class to read it).
    """
    from distributed import get_worker

    from beamcontact._native import single_thread

    single_thread()  # the runs of a sweep share the cores out already
    worker, last = get_worker(), [-1.0]

    def send(fraction: float, info: str) -> None:
        worker.log_event(PROGRESS_TOPIC, {"run": member.name, "fraction": float(fraction),
                                          "info": info})

    def report(info: ProgressInfo) -> None:
        now = time.monotonic()
        if now - last[0] >= 0.5:
            last[0] = now
            send(info.fraction, info.text())

    send(0.0, "starting")
    return run_member(member, run_dir, report)


@contextmanager
def dask_client(workers: int, scheduler: str | None,
                dashboard: bool = False) -> Iterator[Any]:
    """A client of an existing scheduler, or of a local cluster started and stopped here.

    A local cluster listens on 127.0.0.1 only, on ports the system picks (the scheduler,
    the workers and their nannies, each with an HTTP server of health routes); with
    ``dashboard`` the scheduler also serves Dask's dashboard at 127.0.0.1:8787 (or the
    next free port), else it serves none.
    """
    from distributed import Client, LocalCluster

    if scheduler is not None:
        try:
            client = Client(scheduler, timeout="10s")
        except (OSError, TimeoutError) as exc:
            raise CaseError(f"--scheduler {scheduler}: cannot connect ({exc})") from None
        except ValueError as exc:  # distributed's parsing of the address
            raise CaseError(f"--scheduler {scheduler}: not a scheduler address ({exc}); "
                            f"give tcp://HOST:PORT") from None
        with client:
            yield client
        return
    # dashboard_address=None would still start the scheduler's HTTP server at 8787
    http = {"dashboard": dashboard,
            "dashboard_address": "127.0.0.1:8787" if dashboard else "127.0.0.1:0"}
    with LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                      host="127.0.0.1", scheduler_port=0, dashboard_address=None,
                      scheduler_kwargs=http, silence_logs=logging.ERROR) as cluster, \
            Client(cluster) as client:
        yield client


# the energy account of a dynamic run (summary.json's "energy"; empty in statics): E_total
# at the start and the end, what the integrator dissipated and what the contact set's
# changes added, and E_total's end + dissipated - set changes - start (zero when the
# account closes)
ENERGY_COLUMNS = ("E_total_initial", "E_total_final", "E_dissipated", "E_set_change",
                  "balance_residual")


def result_columns(point_names: list[str]) -> list[str]:
    """Columns of sweep.csv after the parameters."""
    per_point = [c for p in point_names for c in (f"{p}_first_amplitude",
                                                  f"{p}_first_amplitude_t")]
    return ["status", "message", "first_impact_time", *per_point, "min_gap",
            "max_penetration", *ENERGY_COLUMNS, "steps", "newton_iterations", "cutbacks",
            "wall_time_s"]


def member_row(member: Member, summary: dict | None, point_names: list[str]) -> dict:
    """One row of sweep.csv."""
    s = summary or {"status": "pending", "message": ""}
    row = {"run": member.name, **{k: format_value(v) for k, v in member.params},
           "status": s.get("status"), "message": s.get("message", "")}
    amplitude = s.get("first_amplitude") or {}
    for p in point_names:
        row[f"{p}_first_amplitude"] = amplitude.get(p, {}).get("uy")
        row[f"{p}_first_amplitude_t"] = amplitude.get(p, {}).get("t")
    for key in ("first_impact_time", "min_gap", "max_penetration", "steps",
                "newton_iterations", "cutbacks", "wall_time_s"):
        row[key] = s.get(key)
    energy = s.get("energy") or {}
    for key in ENERGY_COLUMNS:
        row[key] = energy.get(key)
    return row


def run_sweep(members: list[Member], out_dir: Path, point_names: list[str], *,
              workers: int = 1, scheduler: str | None = None,
              events: SweepEvents | None = None, dashboard: bool = False) -> list[dict]:
    """Run the members not yet complete in ``out_dir``; write sweep.csv and the overlays.

    Returns the rows of sweep.csv in member order. On KeyboardInterrupt the unfinished
    members are marked "interrupted" in sweep.csv before the interrupt goes on.
    """
    events = SweepEvents() if events is None else events
    out_dir.mkdir(parents=True, exist_ok=True)
    summaries: dict[str, dict | None] = {m.name: completed_summary(m, out_dir / m.name)
                                         for m in members}
    todo = [m for m in members if summaries[m.name] is None]
    columns = ["run", *[k for k, _ in members[0].params], *result_columns(point_names)]

    def table() -> list[dict]:
        rows = [member_row(m, summaries[m.name], point_names) for m in members]
        write_table(out_dir / "sweep.csv", columns, rows)
        return rows

    table()
    events.started(len(todo), len(members) - len(todo))
    if todo:
        try:
            _execute(todo, out_dir, workers, scheduler, events, summaries, table,
                     dashboard)
        except KeyboardInterrupt:
            for m in todo:
                if summaries[m.name] is None:
                    summaries[m.name] = {"status": "interrupted",
                                         "message": "the sweep was interrupted"}
            table()
            raise
    rows = table()
    plot_sweep(members, out_dir, point_names)
    return rows


def _execute(todo, out_dir, workers, scheduler, events, summaries, table,
             dashboard: bool = False) -> None:
    from distributed import as_completed

    with dask_client(workers, scheduler, dashboard) as client:
        client.subscribe_topic(
            PROGRESS_TOPIC,
            lambda event: events.progress(event[1]["run"], event[1]["fraction"],
                                          event[1]["info"]))
        futures = {client.submit(_run_on_worker, m, str((out_dir / m.name).resolve()),
                                 pure=False, key=f"beamcontact-{m.name}-{time.time_ns()}"): m
                   for m in todo}
        try:
            for future in as_completed(futures):
                member = futures[future]
                try:
                    summary = future.result()
                except Exception as exc:  # noqa: BLE001 - e.g. the worker process died
                    summary = {"status": "crashed", "message": f"{type(exc).__name__}: {exc}"}
                    run_dir = out_dir / member.name
                    if run_dir.is_dir():
                        write_summary(run_dir / "summary.json", summary)
                summaries[member.name] = summary
                table()
                events.finished(member, summary)
        finally:
            client.cancel(list(futures))
            client.unsubscribe_topic(PROGRESS_TOPIC)


def plot_sweep(members: list[Member], out_dir: Path, point_names: list[str]) -> list[Path]:
    """``plots/<point>_uy.png`` and ``_ux.png`` (and ``min_gap.png`` with contact,
    ``E_total.png`` in dynamics: the energy account of each run beside its motion): one
    curve per member that has a history, labelled by its parameters (Figs. 7-10)."""
    from beamcontact.plot import plot_run_overlay

    runs = []
    for m in members:
        path = out_dir / m.name / "history.csv"
        if path.is_file():
            history = read_history(path)
            if history and len(next(iter(history.values()))) > 1:
                runs.append((m.label, history))
    if not runs:
        return []
    (out_dir / "plots").mkdir(exist_ok=True)
    title = ", ".join(k for k, _ in members[0].params)
    written = []
    for column in ([f"{p}_{c}" for p in point_names for c in ("uy", "ux")]
                   + ["min_gap", "E_total"]):
        if all(column in h and np.any(np.isfinite(h[column])) for _, h in runs):
            path = out_dir / "plots" / f"{column}.png"
            plot_run_overlay(runs, column, path, f"sweep over {title}")
            written.append(path)
    return written
