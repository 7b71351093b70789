"""Command line: ``beamcontact run``, ``check``, ``compare`` and ``sweep``; ``--version``.

Exit codes: 0 success, 1 the solver stopped (results so far are kept), 2 invalid input,
130 interrupted by Ctrl-C (results up to the last accepted step, or the finished runs of a
sweep, are kept). Invalid input includes an output folder or file that cannot be created or
written (checked before anything runs) and a static case in which a beam that its supports
do not hold has no contact partner (a mechanism: its stiffness matrix is singular). A beam
that may touch another is left to the solver, which stops with exit code 1 if contact
does not hold it either (statics/restraint.py).

Progress is drawn within 80 columns at any terminal width (progress.progress_bar for a run,
progress.SweepProgress for a sweep). Help texts are rich markup: a literal ``[`` that could start a
tag is written ``\\[`` (e.g. ``\\[solver]``), or the markup renderer swallows it.
"""

import atexit
import gc
import inspect
import os
import sys
import tempfile
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from importlib import resources
from pathlib import Path
from typing import Annotated

import typer

from beamcontact import terminal
from beamcontact.cores import usable_cores

app = typer.Typer(add_completion=False, no_args_is_help=True,
                  help="Contact dynamics of slender elastic beams.")

BUNDLED_CASE = "free_fall/case_cg.toml"


def _print_version(value: bool) -> None:
    """Print ``beamcontact <version>`` and exit 0 when ``--version`` is given.

    Eager, so it answers before any command is parsed; it reads the version from the
    package, which imports no JAX, so it is instant.
    """
    if value:
        from beamcontact import __version__

        typer.echo(f"beamcontact {__version__}")
        raise typer.Exit()


@app.callback()
def _options(
    version: Annotated[bool, typer.Option(
        "--version", callback=_print_version, is_eager=True,
        help="Print the version and exit.")] = False,
) -> None:
    """Options before the command (``beamcontact --version``); the commands do the work."""


def bundled_case() -> Path:
    """Path of the bundled benchmark case (installed package or source checkout)."""
    installed = resources.files("beamcontact") / "examples" / BUNDLED_CASE
    if installed.is_file():
        return Path(str(installed))
    return Path(__file__).resolve().parents[2] / "examples" / BUNDLED_CASE


def _fail(message: str, code: int) -> None:
    """Print ``message`` (one line per problem, each "error: ...") and exit with ``code``."""
    for line in message.splitlines() or [""]:
        typer.echo(f"error: {line}", err=True)
    raise typer.Exit(code)


def _load(case: Path):
    from beamcontact.io.case import CaseError, read_case_file

    try:
        return read_case_file(case)
    except CaseError as exc:
        _fail(str(exc), 2)


def _check_static_restraints(parsed) -> None:
    """Reject a static case with a beam that nothing can hold (statics/restraint.py)."""
    if parsed.analysis.kind != "static":
        return
    from beamcontact.setup.checks import static_mechanisms
    from beamcontact.setup.model import discretize

    try:
        disc = discretize(parsed)
    except ValueError as exc:
        _fail(f"beams: {exc}", 2)
    found = static_mechanisms(parsed, disc)
    if found:
        more = f" (and {len(found) - 1} more beam(s) like it)" if len(found) > 1 else ""
        _fail(found[0] + more, 2)


def _folder_problem(path: Path, itself: bool = True) -> str | None:
    """Why the folder ``path`` cannot be created or written, or None if it can (the reason
    calls ``path`` "it" when ``itself``, else names it).

    Nothing is created (a case error found later leaves no empty folder behind): the
    nearest existing folder on the way must be a folder in which a file can be written,
    found by a real probe, since permission bits alone miss read-only file systems.
    """
    existing = next(p for p in (path, *path.parents) if p.exists())
    it = "it" if existing == path and itself else str(existing)
    if not existing.is_dir():
        return f"{it} is a file, not a folder"
    try:
        with tempfile.TemporaryFile(dir=existing):
            pass
    except OSError as exc:
        return f"cannot write in {it} ({(exc.strerror or str(exc)).lower()})"
    return None


def _check_out_dir(path: Path) -> None:
    """Exit with code 2, naming the folder and the reason, if ``--out`` cannot be used."""
    problem = _folder_problem(path)
    if problem:
        _fail(f"--out {path}: cannot use this output folder: {problem}", 2)


def _figure_format(path: Path) -> None:
    """Exit with code 2, naming the formats there are, unless matplotlib writes figures
    in the format of ``path``'s suffix."""
    from matplotlib.backend_bases import FigureCanvasBase

    formats = sorted(FigureCanvasBase.get_supported_filetypes())
    if path.suffix.lstrip(".").lower() not in formats:
        _fail(f"--out {path}: unknown figure format {path.suffix or '(no suffix)'!r}; give a "
              f"file name ending in one of {', '.join('.' + f for f in formats)}", 2)


def _write_target(path: Path) -> None:
    """Make sure the file ``--out path`` can be written (its folder is created), else exit
    with code 2 naming the file and the reason."""
    problem = "it is a folder" if path.is_dir() else _folder_problem(path.parent, False)
    if problem is None and path.exists() and not os.access(path, os.W_OK):
        problem = "permission denied"
    if problem is None:
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            problem = (exc.strerror or str(exc)).lower()
    if problem:
        _fail(f"--out {path}: cannot write this file: {problem}", 2)


def _fresh_dir(stem: str) -> Path:
    base = Path.cwd() / f"results_{stem}"
    path, k = base, 1
    while path.exists():
        k += 1
        path = Path(f"{base}_{k}")
    return path


@app.command()
def run(
    case: Annotated[Path | None, typer.Argument(
        help="Case file (TOML). Without it, the bundled benchmark runs.")] = None,
    out: Annotated[Path | None, typer.Option(
        "--out", "-o", help="Output folder (default: a new results_<case> folder here).")] = None,
    quiet: Annotated[bool, typer.Option("--quiet", "-q", help="No progress bar.")] = False,
    restart: Annotated[bool, typer.Option(
        "--restart", help="Continue the dynamic run in --out from its last saved state to "
        "the case's t_end (only t_end, \\[solver] and \\[output] may have changed).")] = False,
    overwrite: Annotated[bool, typer.Option(
        "--overwrite", help="Replace the results of an earlier run in --out (without it, "
        "a folder that holds results is refused).")] = False,
) -> None:
    """Run a case and write history.csv, summary.json, results.h5, VTU/PVD and plots.

    Exit code 0 when the run completed, 1 when the solver stopped, 2 for invalid input
    (also: another run is writing into --out, or --out holds an earlier run's results and
    neither --overwrite nor --restart is given), 130 when interrupted (Ctrl-C), 143 and 129
    when stopped by SIGTERM and SIGHUP (the results up to the last accepted step are kept,
    summary.json says where it stopped, --restart continues). A result that cannot be
    written (a full disk) ends the run with code 1 and one line; what was written is kept.
    """
    from beamcontact.drawer import Drawer

    global _RAN
    _RAN = True
    # the drawer first: it imports matplotlib while this process imports its engine
    with _collector_paused(), Drawer.started() as drawer:  # the collector runs while
        _run(case, out, quiet, restart, overwrite, drawer)  # the steps do


def _run(case: Path | None, out: Path | None, quiet: bool, restart: bool,
         overwrite: bool, drawer) -> None:
    import beamcontact
    from beamcontact._cache import enable_compilation_cache

    beamcontact.enable_x64()
    enable_compilation_cache()
    case = bundled_case() if case is None else case
    parsed, text = _load(case)
    if restart and out is None:
        _fail("--restart needs --out DIR, the folder of the run to continue", 2)
    if restart and overwrite:
        _fail("--restart continues the run in --out, --overwrite replaces it: give one", 2)
    _check_static_restraints(parsed)
    out = _fresh_dir(case.parent.name if case.name == "case.toml" else case.stem) \
        if out is None else out
    _check_out_dir(out)
    import beamcontact.runner  # noqa: F401
    from beamcontact.stop_signals import stop_signals_interrupt

    with stop_signals_interrupt():
        summary = _run_with_progress(parsed, text, out, parsed.title or case.name,
                                     show=not quiet, restart=restart, overwrite=overwrite,
                                     drawer=drawer)
    _report_run(summary, out)


def _run_with_progress(parsed, text: str, out: Path, title: str, *, show: bool,
                       restart: bool, overwrite: bool = False, drawer=None) -> dict:
    """Run the case under a progress bar (unless not ``show``) and return its summary.

    The runner reports an interrupt (Ctrl-C) inside the step loop as status "interrupted";
    one outside it (while preparing or writing) arrives here as KeyboardInterrupt and
    exits with code 130 too. The bar is closed before any message, so messages come below it.
    ``drawer`` draws the figures (:mod:`beamcontact.drawer`; None: drawn here).
    """
    from beamcontact.io.case import CaseError
    from beamcontact.progress import progress_bar
    from beamcontact.record import OutputError
    from beamcontact.runner import run_case
    from beamcontact.stop_signals import interrupt_of

    try:
        with progress_bar(title, enabled=show) as progress:
            return run_case(parsed, text, out, _collect_during_steps(progress),
                            restart=restart, overwrite=overwrite, drawer=drawer)
    except CaseError as exc:
        _fail(str(exc), 2)
    except OutputError as exc:
        _fail(f"{exc}; what was written before is in {out}", 1)
    except (KeyboardInterrupt, SystemError) as exc:
        _interrupted(out, getattr(interrupt_of(exc), "name", None))


@contextmanager
def _collector_paused() -> Iterator[None]:
    """Python's cyclic garbage collector paused within the block, but while the steps run
    (:func:`_collect_during_steps`); after the block it is as it was before."""
    was = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        (gc.enable if was else gc.disable)()


def _collect_during_steps(progress):
    """``progress``, with Python's cyclic garbage collector running while the steps run
    and paused before and after them.

    ``beamcontact run`` starts with the collector paused: the imports and the start of a
    run (Numba's own start, the compiled kernels, the model) make objects that live as
    long as the process, and the collector's passes over them find nothing (about 0.1 s
    of a short run: the stiff drop of benchmarks/peers.py 2.11 -> 1.98 s). The first
    report of accepted steps moves what exists then out of the collector's sight
    (``gc.freeze``) and starts it, since a long run may make cyclic garbage; the report
    that the steps reached the end pauses it again for the figures (matplotlib's
    objects) and the exit, which free everything anyway.
    A run that stops early draws its figures with the collector running. After the
    command the collector is as it was before (:func:`_collector_paused`)."""
    def report(info):
        if info.fraction >= 1.0:
            gc.disable()
        elif not gc.isenabled():
            gc.freeze()
            gc.enable()
        progress(info)

    return report


def _interrupted(out: Path, signal_name: str | None) -> None:
    """Say where the results of an interrupted run are and exit with code 130 (Ctrl-C) or
    128 + the signal's number (SIGTERM 143, SIGHUP 129)."""
    import signal

    by = "interrupted" if signal_name is None else f"stopped by {signal_name}"
    typer.echo(f"{by}; results up to the last accepted step are in {out}", err=True)
    raise typer.Exit(130 if signal_name is None else 128 + signal.Signals[signal_name])


def _report_run(summary: dict, out: Path) -> None:
    """Print the outcome of a run and exit with its code (0 completed, 1 stopped or its
    results could not be written, 130 / 143 / 129 interrupted by Ctrl-C / SIGTERM /
    SIGHUP)."""
    if summary["status"] == "interrupted":
        _interrupted(out, summary.get("signal"))
    typer.echo(f"{summary['status']}: {summary['message']}")
    typer.echo(f"steps {summary['steps']}, Newton iterations {summary['newton_iterations']}, "
               f"cut-backs {summary['cutbacks']}, wall time {summary['wall_time_s']:.2f} s "
               f"(compile {summary['compile_time_s']:.2f} s"
               + (f", writing the steps {summary['writing_time_s']:.2f} s"
                  if "writing_time_s" in summary else "") + ")")
    for warning in summary.get("warnings", []):
        typer.echo(f"warning: {warning}", err=True)
    _helper_note()
    typer.echo(f"results in {out}")
    if summary.get("figures", "").startswith("not drawn: interrupted"):
        import signal

        name = summary.get("signal")
        typer.echo(f"{summary['figures'].replace('not drawn: ', '')} while drawing the "
                   f"figures: every result but the figures is in {out}", err=True)
        raise typer.Exit(130 if name is None else 128 + signal.Signals[name])
    if summary["status"] != "completed":
        raise typer.Exit(1)


def _helper_note() -> None:
    """Say so if the helper that this run started with empty caches still compiles the
    native time loop (beamcontact/_warmup.py): it goes on after the run, and a run
    started before it is done makes its steps more slowly."""
    if "beamcontact._warmup" not in sys.modules:
        return
    from beamcontact import _warmup

    if _warmup.helper_busy():
        typer.echo("note: a helper process goes on compiling the native kernels into "
                   "the cache for about half a minute; a run started before it is done "
                   "takes longer", err=True)


@app.command()
def compare(
    runs: Annotated[list[Path], typer.Argument(help="Output folders of runs to overlay.")],
    point: Annotated[str, typer.Option(help="Output point to plot.")] = "A",
    component: Annotated[str, typer.Option(help="ux, uy, x or y.")] = "uy",
    out: Annotated[Path, typer.Option("--out", "-o", help="PNG file to write.")] = Path(
        "compare.png"),
    labels: Annotated[list[str] | None, typer.Option(
        "--label", help="Curve labels, one per run (default: folder names).")] = None,
) -> None:
    """Overlay one output point of several runs against time or load factor (Figs. 7-10)."""
    from beamcontact.io.results import read_history
    from beamcontact.plot import plot_run_overlay

    if labels and len(labels) != len(runs):
        _fail(f"--label: give one label per run ({len(runs)}), got {len(labels)}", 2)
    curves = []
    for k, run_dir in enumerate(runs):
        path = run_dir / "history.csv"
        if not path.is_file():
            _fail(f"{path}: no such file (is {run_dir} a beamcontact output folder?)", 2)
        h = read_history(path)
        column = f"{point}_{component}"
        if column not in h:
            _fail(f"{path}: no column {column!r} (output points: "
                  f"{sorted({c.rsplit('_', 1)[0] for c in h if c.endswith('_uy')})})", 2)
        curves.append((labels[k] if labels else run_dir.name, h))
    if len({"t" in h for _, h in curves}) > 1:
        _fail("cannot overlay static (load_factor) and dynamic (t) runs", 2)
    if not out.is_dir():  # a folder in the way is _write_target's to say
        _figure_format(out)
    _write_target(out)
    try:
        plot_run_overlay(curves, column, out)
    except OSError as exc:  # e.g. the folder changed meanwhile
        _fail(f"--out {out}: cannot write this file: {(exc.strerror or str(exc)).lower()}", 2)
    typer.echo(f"wrote {out}")


@app.command()
def sweep(
    case: Annotated[Path | None, typer.Argument(
        help="Base case file (TOML). Without it, the bundled benchmark.")] = None,
    sets: Annotated[list[str], typer.Option(
        "--set", help="KEY=V1,V2,...: a dotted case key (list entries by name, e.g. "
        "beams.upper.material.E, contact.penalty, analysis.alpha) and its values (TOML: "
        "numbers, true/false, arrays such as \\[0, -9.81]; other text is a string). "
        "Several --set form the Cartesian product.")] = None,
    out: Annotated[Path | None, typer.Option(
        "--out", "-o", help="Sweep folder: one subfolder per run, sweep.csv, plots/. "
        "Running the same sweep again skips completed runs.")] = None,
    workers: Annotated[int | None, typer.Option(
        "--workers", "-w", min=1, help="Worker processes of the local Dask cluster "
        "(default: the cores this process may run on, at most the number of runs).")] = None,
    scheduler: Annotated[str | None, typer.Option(
        "--scheduler", help="Address of an existing Dask scheduler (tcp://HOST:PORT) "
        "instead of a local cluster; its workers need beamcontact and must see --out.")] = None,
    dashboard: Annotated[bool, typer.Option(
        "--dashboard", help="Serve Dask's dashboard of the local cluster at "
        "http://127.0.0.1:8787 (else no dashboard; every listener is on 127.0.0.1).")] = False,
    dry_run: Annotated[bool, typer.Option(
        "--dry-run", help="List the runs and exit.")] = False,
    quiet: Annotated[bool, typer.Option("--quiet", "-q", help="No progress display.")] = False,
) -> None:
    """Run a parameter study (Figs. 7-10) in parallel: one run per combination of --set values.

    Writes DIR/<run>/ (the outputs of `run`), DIR/sweep.csv (parameters, status, first
    impact, first amplitudes, smallest gap, wall time per run) and DIR/plots/ (overlays).

    Exit code 0 when every run completed, 1 when some failed, 2 for invalid input, 130 when
    interrupted (Ctrl-C; finished runs are kept and the same command goes on from there).
    """
    import tomllib

    from beamcontact.io.case import CaseError
    from beamcontact.sweep_settings import expand, parse_setting

    case = bundled_case() if case is None else case
    parsed, text = _load(case)
    if not sets:
        _fail("--set KEY=V1,V2,... is required (e.g. --set contact.penalty=1e5,1e6)", 2)
    try:
        members = expand(tomllib.loads(text), [parse_setting(s) for s in sets])
    except CaseError as exc:
        _fail(str(exc), 2)
    if dry_run:
        for m in members:
            typer.echo(f"{m.name}\t{m.label}")
        typer.echo(f"{len(members)} run(s)")
        return
    if out is None:
        _fail("--out DIR is required (the sweep folder; rerunning into it resumes)", 2)
    _check_out_dir(out)
    n_workers = workers or max(1, min(usable_cores(), len(members)))
    rows = _sweep_with_progress(members, out, [p.name for p in parsed.output.points],
                                n_workers, scheduler, show=not quiet, dashboard=dashboard)
    _report_sweep(rows, out)


def _sweep_with_progress(members, out: Path, points: list[str], workers: int,
                         scheduler: str | None, *, show: bool,
                         dashboard: bool = False) -> list[dict]:
    """Run the sweep under its progress display (unless not ``show``); return sweep.csv's rows.

    Exits with code 2 for a member the runner rejects and 130 on Ctrl-C (finished members
    are kept, and running the same command again goes on from there).
    """
    from beamcontact.io.case import CaseError
    from beamcontact.progress import SweepProgress
    from beamcontact.sweep import run_sweep

    try:
        with SweepProgress(len(members), show) as progress:
            return run_sweep(members, out, points, workers=workers, scheduler=scheduler,
                             events=progress.events(), dashboard=dashboard)
    except CaseError as exc:
        _fail(str(exc), 2)
    except KeyboardInterrupt:
        typer.echo(f"interrupted; finished runs are kept in {out} (run the same command to "
                   "go on)", err=True)
        raise typer.Exit(130) from None


def _report_sweep(rows: list[dict], out: Path) -> None:
    """Print how many runs completed and each failure; exit with code 1 if any failed."""
    failed = [r for r in rows if r["status"] != "completed"]
    typer.echo(f"{len(rows) - len(failed)} of {len(rows)} run(s) completed; "
               f"table {out / 'sweep.csv'}, plots in {out / 'plots'}")
    for r in failed:
        typer.echo(f"  {r['run']}: {r['status']}: {r['message']}", err=True)
    if failed:
        raise typer.Exit(1)


@app.command()
def check(case: Annotated[Path, typer.Argument(help="Case file (TOML).")]) -> None:
    """Validate a case file without running it.

    Checks its keys and values, and what a run checks before its first step (a static
    beam nothing holds, beams that interpenetrate in the initial configuration); keys
    that the case's model or analysis ignores are warnings.

    Exit code 0 when valid, 2 when not."""
    import beamcontact
    from beamcontact.io.case import CaseError
    from beamcontact.runner import check_case

    beamcontact.enable_x64()  # as run: float64 wherever the model meets JAX
    parsed, _ = _load(case)
    _check_static_restraints(parsed)
    try:
        warnings = check_case(parsed)
    except CaseError as exc:
        _fail(str(exc), 2)
    for warning in warnings:
        typer.echo(f"warning: {warning}", err=True)
    typer.echo(f"{case}: valid ({parsed.analysis.kind}, {len(parsed.beams)} beam(s), "
               f"{len(parsed.loads)} load(s)"
               + (f", {len(parsed.obstacles)} obstacle(s))" if parsed.obstacles else ")"))


# whether `run` ran in this process (main ends such a process without teardown)
_RAN = False


def _unwrapped(doc: str) -> str:
    """A command's docstring as its help: each paragraph on one line, for the terminal to
    wrap (Typer keeps the source's line breaks after the first paragraph, and the help
    then showed ragged lines at any width)."""
    return "\n\n".join(" ".join(p.split()) for p in inspect.cleandoc(doc).split("\n\n"))


for _command in app.registered_commands:
    _command.help = _unwrapped(inspect.getdoc(_command.callback) or "")


def main() -> None:
    """The command line in this process (it raises SystemExit with the exit code).

    The process ends with its heap frozen (``gc.freeze``): the cyclic collection that
    Python runs at exit would otherwise walk the objects of JAX and Numba once more, half
    a second of every run, for a process that frees everything anyway."""
    try:
        app(prog_name="beamcontact")
    finally:
        gc.freeze()


def console() -> None:
    """Console-script entry point (``beamcontact``, ``python -m beamcontact.cli``):
    :func:`main` with one OpenBLAS thread unless ``OPENBLAS_NUM_THREADS`` says
    otherwise, and after `run` the process ends without the interpreter's teardown
    (:func:`_end_now`); the process is ours, so nothing calls on after it."""
    global _RAN
    _RAN = False
    # OpenBLAS's threads, made at numpy's import, spin on the cores for 0.1-0.2 s, beside
    # the start of a run and its figures' drawer; a run limits BLAS to one thread anyway
    # (runner.run_case), so the command line's processes start with one (0.04 s a run)
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    # messages that cannot be written (a full disk, a closed pipe) never stop a run
    terminal.guard_streams()
    atexit.register(terminal.lost_output)
    try:
        main()
    except SystemExit as exc:
        if _RAN:
            _end_now(exc.code)
        raise


def _end_now(code) -> None:
    """End the process with the exit status of ``SystemExit(code)`` after the streams
    are flushed and the exit handlers have run, without the interpreter's teardown:
    freeing every module and object of Numba and NumPy one by one took 0.04-0.05 s of
    each run, and every file of a run is closed by then. Not while a thread that Python
    would wait for still runs."""
    main_thread = threading.main_thread()
    if any(t is not main_thread and not t.daemon and t.is_alive()
           for t in threading.enumerate()):
        return
    if code is None:
        status = 0
    elif isinstance(code, int):
        status = code
    else:  # as Python does: the object printed, status 1
        print(code, file=sys.stderr)
        status = 1
    _flush(sys.stdout, sys.stderr)  # a write that fails here is reported by an exit handler
    atexit._run_exitfuncs()
    if not _flush(sys.stdout, sys.stderr):
        status = status or 120  # as Python at exit
    os._exit(status & 0xFF)


def _flush(*streams) -> bool:
    """Flush ``streams``; whether all could be (a None stream is closed: nothing to do)."""
    flushed = True
    for stream in streams:
        try:
            if stream is not None:
                stream.flush()
        except Exception:  # noqa: BLE001
            flushed = False
    return flushed


if __name__ == "__main__":
    sys.exit(console())
