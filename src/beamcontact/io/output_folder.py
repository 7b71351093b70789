"""One run per output folder: a lock held for the whole run, and the results of an
earlier run never mixed with a new one's.

A run (``beamcontact run``, :func:`beamcontact.simulate`, each run of a sweep) claims its
folder before it writes anything: it takes the lock ``.beamcontact.lock`` (an OS file lock
through ``filelock``: released by the system when the process ends, however it ends, so
no stale lock outlives a killed run), and a second run into the same folder meets it and
stops with a :class:`~beamcontact.io.case.CaseError` (exit code 2). A folder that holds an
earlier run's results is refused unless the run continues it (``--restart``) or is asked
to replace it (``--overwrite``), which removes what the earlier run wrote (the files of
:data:`RESULT_FILES` and the folders of :data:`RESULT_FOLDERS`, nothing else) before the
new run writes. The run then writes its effective case as ``case.toml``.
"""

from __future__ import annotations

import shutil
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from beamcontact.io.case import CaseError

LOCK = ".beamcontact.lock"
# what a run writes into its folder (docs/architecture.md, "Results")
RESULT_FILES = ("summary.json", "history.csv", "results.h5", "beams.pvd", "animation.gif",
                "obstacles.vtu", "case.toml")
RESULT_FOLDERS = ("vtk", "plots")


def earlier_results(folder: Path) -> list[str]:
    """The names of an earlier run's results in ``folder`` (empty: none)."""
    return [n for n in (*RESULT_FILES, *RESULT_FOLDERS) if (folder / n).exists()
            and (n != "case.toml" or (folder / "history.csv").exists()
                 or (folder / "summary.json").exists())]


def clear_results(folder: Path) -> None:
    """Remove an earlier run's results from ``folder`` (only the names a run writes)."""
    for name in RESULT_FILES:
        (folder / name).unlink(missing_ok=True)
    for name in RESULT_FOLDERS:
        shutil.rmtree(folder / name, ignore_errors=True)


@contextmanager
def claimed(folder: Path | None, *, restart: bool = False,
            overwrite: bool = False) -> Iterator[None]:
    """Hold ``folder`` for one run (nothing when None): its lock, and a folder free of an
    earlier run's results unless ``restart`` (which needs them); with ``overwrite`` they
    are removed first. Raises CaseError, naming the folder, when another run holds it or
    when it holds results that neither ``restart`` nor ``overwrite`` allows."""
    if folder is None:
        yield
        return
    from filelock import FileLock, Timeout

    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise CaseError(f"--out {folder}: cannot create this output folder "
                        f"({(exc.strerror or str(exc)).lower()})") from None
    lock = FileLock(folder / LOCK, timeout=0)
    try:
        lock.acquire()
    except Timeout:
        raise CaseError(f"--out {folder}: another beamcontact run is writing into this "
                        f"folder; wait for it to end or choose another folder") from None
    try:
        found = earlier_results(folder)
        if found and not restart:
            if not overwrite:
                raise CaseError(
                    f"--out {folder}: the folder holds the results of an earlier run "
                    f"({', '.join(found)}); choose another folder, --overwrite to replace "
                    f"them or --restart to continue that run")
            clear_results(folder)
        yield
    finally:
        lock.release()
