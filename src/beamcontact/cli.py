"""Command line: ``beamcontact run`` and ``beamcontact check``.

Exit codes: 0 success, 1 the solver stopped (results so far are kept), 2 invalid input.
"""

import sys
from importlib import resources
from pathlib import Path
from typing import Annotated

import typer

app = typer.Typer(add_completion=False, no_args_is_help=True,
                  help="Contact dynamics of slender elastic beams.")

BUNDLED_CASE = "free_fall/case_cg.toml"


def bundled_case() -> Path:
    """Path of the bundled benchmark case (installed package or source checkout)."""
    installed = resources.files("beamcontact") / "examples" / BUNDLED_CASE
    if installed.is_file():
        return Path(str(installed))
    return Path(__file__).resolve().parents[2] / "examples" / BUNDLED_CASE


def _fail(message: str, code: int) -> None:
    typer.echo(f"error: {message}", err=True)
    raise typer.Exit(code)


def _load(case: Path):
    from beamcontact.io.case import CaseError, load_case

    try:
        return load_case(case)
    except CaseError as exc:
        _fail(str(exc), 2)


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
        "the case's t_end (only t_end, [solver] and [output] may have changed).")] = False,
) -> None:
    """Run a case and write history.csv, summary.json, results.h5, VTU/PVD and plots."""
    import beamcontact
    from beamcontact.io.case import CaseError
    from beamcontact.runner import run_case

    beamcontact.enable_x64()
    case = bundled_case() if case is None else case
    parsed, text = _load(case)
    if restart and out is None:
        _fail("--restart needs --out DIR, the folder of the run to continue", 2)
    out = _fresh_dir(case.parent.name if case.name == "case.toml" else case.stem) \
        if out is None else out
    from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

    columns = (TextColumn("{task.description}"), BarColumn(), TextColumn("{task.fields[info]}"),
               TimeElapsedColumn())
    with Progress(*columns, disable=quiet, transient=False) as bar:
        task = bar.add_task(parsed.title or case.name, total=1.0, info="compiling")

        def progress(fraction: float, info: str) -> None:
            bar.update(task, completed=fraction, info=info)

        try:
            summary = run_case(parsed, text, out, progress, restart=restart)
        except CaseError as exc:
            _fail(str(exc), 2)
        except KeyboardInterrupt:
            bar.stop()
            _fail(f"interrupted; results up to the last accepted step are in {out}", 130)
    typer.echo(f"{summary['status']}: {summary['message']}")
    typer.echo(f"steps {summary['steps']}, Newton iterations {summary['newton_iterations']}, "
               f"cut-backs {summary['cutbacks']}, wall time {summary['wall_time_s']:.2f} s "
               f"(compile {summary['compile_time_s']:.2f} s)")
    typer.echo(f"results in {out}")
    if summary["status"] != "completed":
        raise typer.Exit(1)


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
    from beamcontact.plot import plot_overlay

    if labels and len(labels) != len(runs):
        _fail(f"--label: give one label per run ({len(runs)}), got {len(labels)}", 2)
    curves, abscissa = [], "t"
    for k, run_dir in enumerate(runs):
        path = run_dir / "history.csv"
        if not path.is_file():
            _fail(f"{path}: no such file (is {run_dir} a beamcontact output folder?)", 2)
        h = read_history(path)
        column = f"{point}_{component}"
        if column not in h:
            _fail(f"{path}: no column {column!r} (output points: "
                  f"{sorted({c.rsplit('_', 1)[0] for c in h if c.endswith('_uy')})})", 2)
        abscissa = "t" if "t" in h else "load_factor"
        curves.append((labels[k] if labels else run_dir.name, h[abscissa], h[column]))
    plot_overlay(curves, out, "t [s]" if abscissa == "t" else "load factor",
                 f"{point} {component} [m]")
    typer.echo(f"wrote {out}")


@app.command()
def check(case: Annotated[Path, typer.Argument(help="Case file (TOML).")]) -> None:
    """Validate a case file without running it."""
    parsed, _ = _load(case)
    typer.echo(f"{case}: valid ({parsed.analysis.kind}, {len(parsed.beams)} beam(s), "
               f"{len(parsed.loads)} load(s))")


def main() -> None:
    """Console-script entry point."""
    app(prog_name="beamcontact")


if __name__ == "__main__":
    sys.exit(main())
