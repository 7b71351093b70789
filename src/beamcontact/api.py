"""The Python API: load or build a case, simulate it, and work with the result in memory.

    import beamcontact as bc

    case = bc.load_case("examples/free_fall/case_cg.toml")
    result = bc.simulate(case)                 # nothing written; result in memory
    result.history["A_uy"].min()               # pandas DataFrame, the columns of history.csv
    result.summary["first_amplitude"]          # the content of summary.json
    result.states.centrelines["upper"]         # (n_saved, n_samples, 2) beam axes
    result.plot_points("points.png")           # the standard figures, on request

A case can also be built from the classes of :mod:`beamcontact.io.case` (``Case``,
``Analysis``, ``Beam``, ``Line``, ``Arc``, ``Nurbs``, ``CircleSection``, ...), which run
the checks of a case file, and converted to TOML with ``case.to_toml()``.
``simulate(case, out="folder")`` writes exactly what ``beamcontact run`` writes.
"""

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from beamcontact.io.case import Case, read_case_file

if TYPE_CHECKING:
    import pandas
    from matplotlib.figure import Figure

    from beamcontact.record import RunRecord


def load_case(path: str | Path) -> Case:
    """Read and validate a TOML case file (raises :class:`~beamcontact.io.case.CaseError`
    naming the offending key)."""
    return read_case_file(path)[0]


@dataclass(frozen=True)
class SavedStates:
    """The states saved during a run, at the VTU cadence (dynamics: every
    ``output.vtk_interval`` seconds, statics: every ``output.vtk_every`` load steps).

    Attributes:
        parameter: time [s] (dynamics) or load factor (statics) of each saved state, (n,).
        control_points: the control points of all beams, (n, n_control_points, 2) [m].
        centrelines: each beam's axis sampled ``output.samples_per_element`` times per
            element, by beam name: (n, n_samples, 2) [m].
    """

    parameter: np.ndarray
    control_points: np.ndarray
    centrelines: dict[str, np.ndarray]

    def __len__(self) -> int:
        return len(self.parameter)


@dataclass(frozen=True, repr=False)
class Result:
    """The outcome of :func:`simulate`.

    Attributes:
        case: the case that was run.
        summary: the content of summary.json (status, message, steps, iterations,
            energies, first impact and amplitudes, solver settings, ...).
        history: one row per accepted step, the columns of history.csv.
        states: the saved states (beam centre lines).
        out: the output folder, or None when nothing was written.
    """

    case: Case
    summary: dict[str, Any]
    history: "pandas.DataFrame"
    states: SavedStates
    out: Path | None

    @property
    def status(self) -> str:
        """"completed", "failed" (the solver stopped; see ``summary["message"]``) or
        "interrupted"."""
        return self.summary["status"]

    def __repr__(self) -> str:
        """One line: the case, the outcome, the counts and where the files are (the
        dataclass's own repr printed every row of the history and every state)."""
        s = self.summary
        where = "in memory" if self.out is None else f"out={str(self.out)!r}"
        return (f"Result({self.case.title or 'untitled'!r}: {s['status']}, "
                f"{s.get('steps', 0)} steps, {s.get('newton_iterations', 0)} Newton "
                f"iterations, {s.get('wall_time_s', 0.0):.3g} s, {where})")

    def _repr_html_(self) -> str:
        """A short table for notebooks: outcome, message, counts, folder."""
        from html import escape

        s = self.summary
        rows = [("case", self.case.title or ""), ("status", s["status"]),
                ("message", s.get("message", "")), ("steps", s.get("steps", "")),
                ("Newton iterations", s.get("newton_iterations", "")),
                ("wall time [s]", f"{s.get('wall_time_s', 0.0):.3g}"),
                ("history", f"{len(self.history)} rows x {len(self.history.columns)} "
                            f"columns"),
                ("saved states", len(self.states)),
                ("output folder", "" if self.out is None else str(self.out))]
        body = "".join(f"<tr><th style='text-align:left'>{escape(str(k))}</th>"
                       f"<td style='text-align:left'>{escape(str(v))}</td></tr>"
                       for k, v in rows)
        return f"<table><caption>beamcontact Result</caption>{body}</table>"

    @property
    def _abscissa(self) -> str:
        return "t" if "t" in self.history.columns else "load_factor"

    def _columns(self) -> dict[str, np.ndarray]:
        return {c: self.history[c].to_numpy() for c in self.history.columns}

    def plot_points(self, path: str | Path | None = None) -> "Figure":
        """Displacements of the output points against time or load factor (Fig. 7);
        saved to ``path`` if given."""
        from beamcontact.plot import plot_point_histories

        points = [p.name for p in self.case.output.points]
        return plot_point_histories(self._columns(), self._abscissa, points,
                                    _path(path), self.case.title)

    def plot_energies(self, path: str | Path | None = None) -> "Figure":
        """Energies and the energy account against time (dynamics)."""
        from beamcontact.plot import plot_energies

        if self._abscissa != "t":
            raise ValueError("plot_energies: a static run has no energy history over time")
        return plot_energies(self._columns(), _path(path), self.case.title)

    def plot_snapshots(self, path: str | Path | None = None, count: int = 9) -> "Figure":
        """A grid of ``count`` saved states evenly spread over the run (Fig. 6)."""
        from beamcontact.plot import plot_snapshots

        n = len(self.states)
        picks = np.unique(np.linspace(0, n - 1, min(n, count)).astype(int))
        frames = [(float(self.states.parameter[i]),
                   [lines[i] for lines in self.states.centrelines.values()]) for i in picks]
        radii = [b.section.radius if b.section.shape == "circle" else 0.5 * b.section.height
                 for b in self.case.beams]
        return plot_snapshots(frames, radii, _path(path), self.case.title)

    def animate(self, path: str | Path, fps: int = 20) -> None:
        """Write a GIF of the beams' axes over the saved states."""
        from beamcontact.plot import animate

        frames = [(float(t), [lines[i] for lines in self.states.centrelines.values()])
                  for i, t in enumerate(self.states.parameter)]
        animate(frames, Path(path), self.case.title, fps)


def _path(path: str | Path | None) -> Path | None:
    return None if path is None else Path(path)


def simulate(case: Case | str | Path, out: str | Path | None = None, *,
             progress: bool = False, restart: bool = False,
             overwrite: bool = False) -> Result:
    """Run a case (statics or dynamics) and return its :class:`Result`.

    Args:
        case: a validated case, or the path of a TOML case file.
        out: output folder: when given, exactly what ``beamcontact run`` writes
            (history.csv, summary.json, results.h5, ParaView series, plots) is written
            there as the run goes; when None, nothing is written.
        progress: draw a progress bar on the terminal.
        restart: continue the dynamic run in ``out`` from its last saved state.
        overwrite: replace the results of an earlier run in ``out`` (without it, a folder
            that holds results is refused with a CaseError, as is a folder another run is
            writing into).

    JAX is switched to float64 (``jax_enable_x64``) and, unless JAX already has a
    persistent compilation cache, pointed at beamcontact's (as the command line does:
    a second run of a model of the same shape compiles in well under a second).
    Ctrl-C stops the run and returns what was computed, with ``status ==
    "interrupted"``. Invalid input raises :class:`~beamcontact.io.case.CaseError`.
    """
    from beamcontact import enable_x64
    from beamcontact._cache import enable_compilation_cache, jax_cache_dir
    from beamcontact.progress import progress_bar
    from beamcontact.runner import execute

    enable_x64()
    if not jax_cache_dir():
        enable_compilation_cache()
    if isinstance(case, Case):
        # validated again as a case file is: a copy made with model_copy(update=...)
        # skips pydantic's checks, and no case that a file could not hold runs
        text = case.to_toml()
        case = Case.from_toml(text)
    else:
        case, text = read_case_file(case)
    out_dir = None if out is None else Path(out)
    with progress_bar(case.title, enabled=progress) as report:
        summary, record = execute(case, text, out_dir, report, restart, overwrite)
    return _result(case, summary, record, out_dir)


def _result(case: Case, summary: dict, record: "RunRecord", out: Path | None) -> Result:
    import pandas

    history = pandas.DataFrame(record.history())
    for column in ("step", "newton_iters", "cutbacks"):
        history[column] = history[column].astype(np.int64)
    snaps = record.snapshots
    states = SavedStates(
        np.array([s.parameter for s in snaps]),
        np.array([s.x for s in snaps]).reshape(len(snaps), -1, 2),
        record.centrelines())
    return Result(case, summary, history, states, out)
