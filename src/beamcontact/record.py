"""What a run keeps: the history rows and the snapshots, in memory and optionally on disk.

A :class:`RunRecord` always holds the history (one row per accepted step, the columns of
``history.csv``) and the snapshots (control points at the VTU cadence) in memory, so
that :func:`beamcontact.simulate` can return them without files. With an output folder it
also writes them as they come (docs/architecture.md, "Results"): ``history.csv`` row by row,
``results.h5`` (every state, for restart), ``vtk/*.vtu`` + ``beams.pvd``, and after the
run the standard plots. Nothing is lost when a run stops: every file is valid after each
step.
"""

import math
import os
import re
import time
from collections.abc import Iterator
from contextlib import contextmanager, suppress
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from beamcontact.drawer import Call, Drawer, draw_here
from beamcontact.io.case import Case, at_fraction
from beamcontact.io.results import (
    DISK_RESERVE,
    HistoryWriter,
    OutputError,
    StateWriter,
    free_space,
    read_history,
)
from beamcontact.io.vtk import VtkSeries, write_obstacles
from beamcontact.setup.model import Discretization, point_sampler, polyline_matrix


def _reason(exc: Exception) -> str:
    """The short reason of a failed write: the system's words for its errno (HDF5 puts
    them into a long message of its own)."""
    if isinstance(exc, OSError) and exc.errno:
        return os.strerror(exc.errno)
    found = re.search(r"error message = '([^']*)'", str(exc))
    return found.group(1) if found else str(exc).splitlines()[0]


@contextmanager
def writing(what: str, record: "RunRecord | None" = None,
            errors: tuple = (OSError, RuntimeError)) -> Iterator[None]:
    """Raise a failed write of ``what`` as an :class:`OutputError` (h5py reports a full
    disk as OSError or RuntimeError); ``record``'s files count as broken from then on."""
    try:
        yield
    except OutputError:
        raise
    except errors as exc:
        if record is not None:
            record.broken = True
        raise OutputError(f"cannot write {what}: {_reason(exc)}") from None


class OutputPoints:
    """Evaluates the followed points from the global control points."""

    def __init__(self, case: Case, disc: Discretization, x_ref: np.ndarray):
        self.names = [p.name for p in case.output.points]
        self._samplers = [point_sampler(disc, p.beam, at_fraction(p.at))
                          for p in case.output.points]
        # the same sum as every row's, so that a point at rest has zero displacement
        self._ref = [self._point(idx, R, x_ref[None])[0] for idx, R in self._samplers]

    @staticmethod
    def _point(idx: np.ndarray, R: np.ndarray, x: np.ndarray) -> np.ndarray:
        """The point of basis values R on control points idx of x (k, n_cp, 2): (k, 2).
        The terms are summed in order, so that a row is the same whatever its alignment
        in memory (the order of a BLAS dot product depends on it)."""
        p = np.zeros((len(x), 2))
        for j, r in zip(idx, R, strict=True):
            p += r * x[:, j]
        return p

    def columns(self) -> list[str]:
        """history.csv columns of the points."""
        return [f"{n}_{c}" for n in self.names for c in ("x", "y", "ux", "uy")]

    def table(self, x: np.ndarray) -> np.ndarray:
        """Positions and displacements of every point, in the order of :meth:`columns`,
        for k sets of control points x (k, n_cp, 2): (k, 4 points)."""
        parts = []
        for (idx, R), ref in zip(self._samplers, self._ref, strict=True):
            p = self._point(idx, R, x)
            parts += [p, p - ref]
        return np.concatenate(parts, axis=1) if parts else np.empty((len(x), 0))


@dataclass(frozen=True)
class Snapshot:
    """The control points (n_cp, 2) of all beams at time or load factor ``parameter``."""

    parameter: float
    x: np.ndarray


class _Files:
    """The writers of an output folder."""

    def __init__(self, record: "RunRecord", out_dir: Path, case_text: str, n_dof: int,
                 resume: tuple[int, float] | None):
        out_dir.mkdir(parents=True, exist_ok=True)
        (out_dir / "plots").mkdir(exist_ok=True)
        step = None if resume is None else resume[0]
        # first: a history that cannot be continued leaves the folder as it was
        self.history = HistoryWriter(out_dir / "history.csv", record.columns, step)
        # the effective case, as a sweep's runs have it
        (out_dir / "case.toml").write_text(case_text, encoding="utf-8")
        self.states = StateWriter(out_dir / "results.h5", case_text, record.disc.beams, n_dof,
                                  record.abscissa, step)
        self.vtk = VtkSeries(out_dir, [m for m, _ in record.maps],
                             [b.section.half_depth for b in record.disc.beams], record.x_ref,
                             [b.offset for b in record.disc.beams],
                             [b.n_cp for b in record.disc.beams],
                             None if resume is None else resume[1])
        if record.case.obstacles:
            axes = np.concatenate(record.axes(record.x_ref))
            write_obstacles(out_dir / "obstacles.vtu", record.case.obstacles,
                            axes.min(axis=0), axes.max(axis=0))

    def close(self) -> None:
        self.history.close()
        self.states.close()


class RunRecord:
    """History and snapshots of one run, kept in memory and written to ``out_dir`` if given.

    ``abscissa`` is "t" (dynamics) or "load_factor" (statics); ``resume`` = (step, t) of a
    restart: the rows and snapshots up to it are read back from the folder.
    """

    def __init__(self, case: Case, case_text: str, disc: Discretization, x_ref: np.ndarray,
                 n_dof: int, out_dir: Path | None, abscissa: str, extra_columns: list[str],
                 resume: tuple[int, float] | None = None):
        self.case, self.disc, self.out_dir = case, disc, out_dir
        self.x_ref = np.asarray(x_ref)
        self.points = OutputPoints(case, disc, self.x_ref)
        self.abscissa = abscissa
        self.columns = ["step", abscissa, *self.points.columns(), *extra_columns,
                        "newton_iters", "cutbacks"] + (["dt"] if abscissa == "t" else [])
        # the columns that a row takes from its diagnostics and from its keywords
        self._value_columns = list(extra_columns)
        self._extra_columns = ["dt"] if abscissa == "t" else []
        self.maps = [(polyline_matrix(b, case.output.samples_per_element),
                      slice(b.offset, b.offset + b.n_cp)) for b in disc.beams]
        self._rows: list[np.ndarray] = []
        self.snapshots: list[Snapshot] = []
        self.broken = False  # a write failed: nothing more is written (the memory goes on)
        self._disk_checked = -math.inf
        self.files = None
        if out_dir is not None:
            with writing(f"the results in {out_dir}", self):
                self.files = _Files(self, out_dir, case_text, n_dof, resume)
        if resume is not None and out_dir is not None:
            self._read_back(out_dir, resume)
            if not self.files.vtk.resumed:  # beams.pvd missing or damaged: from results.h5
                for snap in self.snapshots:
                    self.files.vtk.write(snap.parameter, snap.x)

    def _read_back(self, out_dir: Path, resume: tuple[int, float]) -> None:
        """Rows and snapshots of the run being continued (already truncated to ``resume``)."""
        import h5py

        old = read_history(out_dir / "history.csv")
        self._rows = [np.array([[old[c][k] for c in self.columns]
                                for k in range(len(old["step"]))]).reshape(-1, len(self.columns))]
        with h5py.File(out_dir / "results.h5", "r") as f:
            params, u = f["states/parameter"][:], f["states/u"]
            picks = self.snapshot_indices(params)
            self.snapshots = [Snapshot(float(params[i]), self.x(u[i])) for i in picks]

    def snapshot_indices(self, params: np.ndarray) -> np.ndarray:
        """Indices of the saved states nearest the VTU cadence (dynamics: every
        output.vtk_interval seconds)."""
        interval = self.case.output.vtk_interval or self.case.analysis.t_end / 100
        marks = np.arange(0.0, params[-1] + 1e-9, interval)
        return np.unique(np.searchsorted(params, marks - 1e-9).clip(0, len(params) - 1))

    def x(self, u) -> np.ndarray:
        """Control points for the flat displacement u."""
        return self.x_ref + np.asarray(u).reshape(-1, 2)

    def row(self, step: int, parameter: float, u, values: dict, iterations: int,
            cutbacks: int, **extra) -> None:
        """Append one history row (``values`` holds the diagnostics' columns, ``extra`` the
        step "dt" in dynamics; a missing one is a KeyError: the header is fixed)."""
        self.rows([step], [parameter], np.asarray(u)[None], {k: [v] for k, v in values.items()},
                  [iterations], [cutbacks], **{k: [v] for k, v in extra.items()})

    def rows(self, steps, parameters, u, values: dict, iterations, cutbacks,
             **extra) -> None:
        """Append k history rows at once (:meth:`row` of each; u (k, n_dof), ``values``
        the diagnostics' columns and ``extra`` sequences of k), written to history.csv
        in one piece."""
        k = len(steps)
        points = self.points.table(self.x_ref + np.asarray(u).reshape(k, -1, 2))
        # the columns in order: integers (step, iterations, cut-backs) and floats
        columns = [np.asarray(steps, dtype=np.int64), np.asarray(parameters, dtype=float),
                   *points.T, *(np.asarray(values[c], dtype=float) for c in self._value_columns),
                   np.asarray(iterations, dtype=np.int64), np.asarray(cutbacks, dtype=np.int64),
                   *(np.asarray(extra[e], dtype=float) for e in self._extra_columns)]
        self._rows.append(np.column_stack(columns).astype(float, copy=False)
                          .reshape(k, len(self.columns)))
        if self._writes():
            # Python numbers (tolist gives them): history.csv writes them by repr
            rows = list(zip(*(c.tolist() for c in columns), strict=True))
            with writing(self.out_dir / "history.csv", self):
                self.files.history.write_many(rows)

    def state(self, step: int, parameter: float, u, **extra) -> None:
        """Save a full state (results.h5; only with an output folder)."""
        self.states([step], [parameter], np.asarray(u)[None],
                    **{k: np.asarray(v)[None] for k, v in extra.items()})

    def states(self, steps, parameters, u: np.ndarray, **extra: np.ndarray) -> None:
        """Save k full states at once (:meth:`state` of each; every array (k, ...))."""
        if self._writes():
            with writing(self.out_dir / "results.h5", self):
                self.files.states.write_many(steps, parameters, u, **extra)

    def snapshot(self, parameter: float, u) -> None:
        """Keep the control points at this instant (and write a VTU file)."""
        x = self.x(u)
        self.snapshots.append(Snapshot(float(parameter), x))
        if self._writes():
            with writing(self.out_dir / "vtk", self):
                self.files.vtk.write(parameter, x)

    def _writes(self) -> bool:
        """Whether the files take more (an output folder, no failed write, and room on
        its disk: :data:`DISK_RESERVE`, checked at most every quarter of a second)."""
        if self.files is None or self.broken:
            return False
        now = time.monotonic()
        if now - self._disk_checked > 0.25:
            self._disk_checked = now
            if free_space(self.out_dir) < DISK_RESERVE:
                self.broken = True
                raise OutputError(f"cannot write the results in {self.out_dir}: its disk "
                                  f"is full (less than {DISK_RESERVE // 2**20} MB free)")
        return True

    def history(self) -> dict[str, np.ndarray]:
        """The history as columns."""
        table = np.concatenate([np.empty((0, len(self.columns))), *self._rows])
        return {c: table[:, k] for k, c in enumerate(self.columns)}

    def close(self) -> None:
        """Close the files (they are complete after every step already). After a failed
        write only what can still be closed is (the error was reported once)."""
        if self.files is None:
            return
        if self.broken:
            for f in (self.files.history, self.files.states):
                with suppress(OSError, RuntimeError):
                    f.close()
            return
        with writing(f"the results in {self.out_dir}", self):
            self.files.close()

    def axes(self, x: np.ndarray) -> list[np.ndarray]:
        """Polylines of every beam axis for control points x."""
        return [m @ x[s] for m, s in self.maps]

    def centrelines(self) -> dict[str, np.ndarray]:
        """Each beam's axis at every snapshot: name -> (n_snapshots, n_samples, 2)."""
        lines = [self.axes(s.x) for s in self.snapshots]
        return {b.name: np.array([frame[k] for frame in lines])
                for k, b in enumerate(self.case.beams)}

    def extremes(self) -> dict:
        """Smallest, largest and final displacement of every output point."""
        h = self.history()
        return {f"{n}_{c}": {"min": float(h[f"{n}_{c}"].min()),
                             "max": float(h[f"{n}_{c}"].max()),
                             "final": float(h[f"{n}_{c}"][-1])}
                for n in self.points.names for c in ("ux", "uy")}

    def plots(self, drawer: "Drawer | None" = None) -> None:
        """Into out_dir/plots: shapes.png, points.png; dynamics also energies.png,
        snapshots.png (a grid of instants) and animation.gif (every snapshot, at most
        300). With a ``drawer`` (the command line's), drawn there, half by each of its
        two processes (:mod:`beamcontact.drawer`); else here."""
        if self.out_dir is None or not self.snapshots or self.broken:
            return
        first, second = self._figures()
        with writing(self.out_dir / "plots", self, errors=(OSError,)):
            if drawer is None:
                draw_here(first + second)
            else:
                drawer.draw(first, second)

    def _figures(self) -> tuple[list[Call], list[Call]]:
        """The figures as calls into beamcontact.plot, in two halves of about equal cost
        (0.15 s each for the peer drop of benchmarks/)."""
        plots, title = self.out_dir / "plots", self.case.title
        n = len(self.snapshots)
        picks = np.unique(np.linspace(0, n - 1, min(n, 9)).astype(int))
        shapes = [(self.snapshots[i].parameter, self.axes(self.snapshots[i].x)) for i in picks]
        walls = self.case.obstacles
        history = self.history()
        first: list[Call] = [("plot_shapes", (
            [(f"{self.abscissa} {p:.3g}", a) for p, a in shapes], self.axes(self.x_ref),
            plots / "shapes.png", title, walls), {})]
        second: list[Call] = []
        if self.points.names:
            first.append(("plot_point_histories", (
                history, self.abscissa, self.points.names, plots / "points.png", title), {}))
        if self.abscissa == "t":
            first.append(("plot_energies", (history, plots / "energies.png", title), {}))
            second.append(("plot_snapshots", (
                shapes, [b.section.half_depth for b in self.disc.beams],
                plots / "snapshots.png", title, walls), {}))
            frames = [(s.parameter, self.axes(s.x))
                      for s in self.snapshots[::int(np.ceil(n / 300))]]
            if len(frames) > 1:
                second.append(("animate", (frames, self.out_dir / "animation.gif", title),
                               {"obstacles": walls}))
        return first, second
