"""Results written while the run goes: history.csv, summary.json, results.h5.

Every row and state is flushed when written, so a crash or Ctrl-C keeps everything up to
the last accepted step.
"""

import csv
import json
import math
import shutil
import time
from pathlib import Path

import h5py
import numpy as np

# a run stops writing (status "output_failed") when less than this is free on the disk of
# its folder: HDF5 that meets a full disk in the middle of a write leaves its file in a
# state that it cannot close (a stack of errors and a crash at exit), so the run stops
# while the files can still be closed whole
DISK_RESERVE = 4 * 2**20


def free_space(path: Path) -> int:
    """Bytes free on the disk that holds ``path`` (a file or folder that exists)."""
    return shutil.disk_usage(path).free


class OutputError(OSError):
    """The results could not be written (a full disk, a folder removed meanwhile, ...);
    one line that names the file and the reason."""


class HistoryWriter:
    """history.csv: one row per accepted step, flushed at once.

    With ``resume_after_step`` the existing file is kept up to that step (rows written after
    the last saved state of an interrupted run are dropped) and appended to; a damaged file
    (a line that is not a row of these columns) is a ValueError naming the line, and the
    file is left as it was.
    """

    def __init__(self, path: Path, columns: list[str], resume_after_step: int | None = None):
        self.columns = columns
        kept: list[list[str]] = []
        if resume_after_step is not None:
            with open(path, newline="", encoding="utf-8") as f:
                rows = list(csv.reader(f))
            if not rows or rows[0] != columns:
                raise ValueError("its columns differ from this case's")
            # every row whole but the last, which may be a write cut short by a kill: it
            # is dropped with the rows after the state (a ValueError names a bad line)
            for line_no, r in enumerate(rows[1:-1], start=2):
                if len(r) != len(columns):
                    raise ValueError(f"line {line_no} has {len(r)} values, not {len(columns)}")
                int(r[0])
                [float(v) for v in r[1:]]
            kept = [r for r in rows[1:]
                    if len(r) == len(columns) and int(r[0]) <= resume_after_step]
        self._file = open(path, "w", newline="", encoding="utf-8")  # noqa: SIM115
        self._csv = csv.writer(self._file, lineterminator="\n")
        self._csv.writerow(columns)
        self._csv.writerows(kept)
        self._file.flush()

    def write(self, row: list) -> None:
        """Append one row, its values (Python ints and floats) in the order of the
        columns: each by its repr, the text that csv.writer gives them, without a call per
        value."""
        self.write_many([row])

    def write_many(self, rows: list[list]) -> None:
        """Append rows (each as :meth:`write` takes it) in one write, then flush."""
        for row in rows:
            if len(row) != len(self.columns):
                raise ValueError(f"a row of {len(row)} values for {len(self.columns)} columns")
        self._file.write("".join(",".join(map(repr, row)) + "\n" for row in rows))
        self._file.flush()

    def close(self) -> None:
        """Close the file."""
        self._file.close()


def _fmt(v) -> str:
    """A float as its shortest repr (it reads back exactly), anything else as str."""
    if type(v) is float:
        return repr(v)
    if isinstance(v, np.floating):
        return repr(float(v))
    return str(v)


def read_history(path: Path) -> dict[str, np.ndarray]:
    """history.csv as a dict of float columns."""
    data = np.genfromtxt(path, delimiter=",", names=True, dtype=float, ndmin=1)
    return {name: np.atleast_1d(data[name]) for name in data.dtype.names}


def write_summary(path: Path, summary: dict) -> None:
    """summary.json (NaN and infinities become null)."""

    def clean(v):
        if isinstance(v, dict):
            return {k: clean(x) for k, x in v.items()}
        if isinstance(v, list | tuple):
            return [clean(x) for x in v]
        if isinstance(v, float | np.floating):
            return float(v) if math.isfinite(v) else None
        if isinstance(v, np.integer):
            return int(v)
        return v

    path.write_text(json.dumps(clean(summary), indent=2) + "\n", encoding="utf-8")


def read_summary(path: Path) -> dict | None:
    """summary.json, or None when it is missing or unreadable (a run cut off mid-write)."""
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None


def write_table(path: Path, columns: list[str], rows: list[dict]) -> None:
    """A CSV table (sweep.csv), written whole to a temporary file and renamed, so that a
    reader never sees half of it. None becomes an empty cell."""
    tmp = path.with_suffix(path.suffix + ".tmp")
    with open(tmp, "w", newline="", encoding="utf-8") as f:
        writer = csv.writer(f, lineterminator="\n")
        writer.writerow(columns)
        writer.writerows([["" if r.get(c) is None else _fmt(r[c]) for c in columns]
                          for r in rows])
    tmp.replace(path)


class StateWriter:
    """results.h5: the model (knots, weights, reference points) and every accepted state.

    Layout: ``/model/<beam>/{knots, weights, reference_points}`` with attrs degree and
    offset; ``/states/{step, parameter, u}`` growing along the first axis (``parameter`` is
    the load factor in statics and the time in dynamics); root attrs ``case_toml``.
    """

    flush_seconds = 2.0
    flush_bytes = 2**24  # and at least every 16 MB of queued states

    def __init__(self, path: Path, case_text: str, beams, n_dof: int, parameter_name: str,
                 resume_after_step: int | None = None):
        self._path = path
        self._pending: list[dict] = []
        self._sizes: list[int] = []  # bytes of each queued state
        self._queued = 0  # and their sum
        self._last_flush = time.monotonic()
        if resume_after_step is not None:
            self._h5 = h5py.File(path, "a")
            st = self._h5["states"]
            keep = int(np.sum(st["step"][:] <= resume_after_step))
            for name in st:
                st[name].resize(keep, axis=0)
            self._h5.attrs["case_toml"] = case_text
            self._h5.flush()
            return
        self._h5 = h5py.File(path, "w")
        self._h5.attrs["case_toml"] = case_text
        self._h5.attrs["parameter"] = parameter_name
        grp = self._h5.create_group("model")
        for b in beams:
            g = grp.create_group(b.name)
            g.attrs["degree"] = b.curve.degree
            g.attrs["offset"] = b.offset
            g["knots"] = b.curve.knots
            g["weights"] = b.curve.weights
            g["reference_points"] = b.curve.points
        st = self._h5.create_group("states")
        st.create_dataset("step", (0,), maxshape=(None,), dtype="i8")
        st.create_dataset("parameter", (0,), maxshape=(None,), dtype="f8")
        st.create_dataset("u", (0, n_dof), maxshape=(None, n_dof), dtype="f8",
                          chunks=_row_chunks(n_dof))
        self._h5.flush()

    def write(self, step: int, parameter: float, u: np.ndarray, **extra: np.ndarray) -> None:
        """Queue one state; ``extra`` arrays (velocities, ...) get datasets of their own.

        States reach the file in batches, at least every ``flush_seconds`` of wall time and
        on close (also after Ctrl-C); history.csv is written every step regardless.
        """
        self.write_many([step], [parameter], np.asarray(u, float)[None],
                        **{k: np.asarray(v, float)[None] for k, v in extra.items()})

    def write_many(self, steps, parameters, u: np.ndarray, **extra: np.ndarray) -> None:
        """Queue k states at once (:meth:`write` of each; u and ``extra`` (k, ...))."""
        block = {"step": np.asarray(steps, np.int64), "parameter": np.asarray(parameters, float),
                 "u": np.asarray(u, float), **{k: np.asarray(v, float) for k, v in extra.items()}}
        k = len(block["step"])
        if k == 0:
            return
        self._pending.append(block)
        size = sum(v.nbytes for v in block.values()) // k
        self._sizes += [size] * k
        self._queued += size * k
        if (time.monotonic() - self._last_flush > self.flush_seconds
                or self._queued > self.flush_bytes):
            self.flush()

    def flush(self) -> None:
        """Write the queued states and flush the file; an :class:`OutputError` (and the
        queued states dropped) when the disk has no room for them and
        :data:`DISK_RESERVE` besides, before HDF5 meets the full disk."""
        full = None
        if self._pending:
            free = free_space(self._path)
            if free < 2 * self._queued + DISK_RESERVE:
                # the states that fit, in order (a restart continues from the last of
                # them); the rest are dropped
                fits = int(np.searchsorted(2 * np.cumsum(self._sizes), free - DISK_RESERVE,
                                           side="right"))
                full = OutputError(f"cannot write {self._path}: its disk is full "
                                   f"({free / 2**20:.1f} MB free)")
                kept = []
                for block in self._pending:
                    rows = min(len(block["step"]), fits)
                    if rows:
                        kept.append({name: v[:rows] for name, v in block.items()})
                    fits -= rows
                self._pending = kept
        if self._pending:
            st = self._h5["states"]
            n = st["step"].shape[0]
            for name in self._pending[0]:
                values = np.concatenate([p[name] for p in self._pending])
                k = len(values)
                if name not in st:
                    shape = values.shape[1:]
                    st.create_dataset(name, (0, *shape), maxshape=(None, *shape),
                                      dtype=values.dtype,
                                      chunks=_row_chunks(*shape))
                st[name].resize(n + k, axis=0)
                st[name][n:] = values
            self._pending.clear()
            self._h5.flush()
        self._sizes.clear()
        self._queued = 0
        self._last_flush = time.monotonic()
        if full is not None:
            raise full

    def close(self) -> None:
        """Write what is queued and close the file (closed also when that fails)."""
        try:
            self.flush()
        finally:
            self._h5.close()


def _row_chunks(*shape: int) -> tuple[int, ...] | bool:
    """HDF5 chunks of a dataset of rows of ``shape`` that grows by rows: as many rows as
    fill about 64 kB (at least one); h5py's own choice for empty rows. A chunk per row
    made every batch of states thousands of chunk writes."""
    size = int(np.prod(shape))
    if size == 0:
        return True
    return (max(1, 2**16 // (8 * size)), *shape)


def read_last_state(path: Path) -> tuple[str, dict[str, np.ndarray]]:
    """The stored case text and the arrays of the last saved state of results.h5."""
    with h5py.File(path, "r") as f:
        st = f["states"]
        n = st["step"].shape[0]
        if n == 0:
            raise ValueError(f"{path} holds no state")
        return str(f.attrs["case_toml"]), {name: st[name][n - 1] for name in st}
