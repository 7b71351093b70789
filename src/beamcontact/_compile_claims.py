"""One compile of a kernel at a time among the processes that share the kernel cache
(docs/engines.md, "Compilation").

A process that finds a kernel missing from the disk cache claims it with a file
``compiling-<key>`` beside the cache (created exclusively, holding its process id) and
compiles it; a process that finds the claim taken waits until the claim is released
(the kernel is then in the cache, loaded from there) instead of compiling the same
kernel at the same time. Numba checks the cache only once, just before it compiles, so
two processes that both miss compile the same kernel twice: in a cold start the run
and its helper (beamcontact/_warmup.py) did so for ``contact_energy`` and for
``step_set_at``, the latter on the helper's way to the time loop (1.5 s; session 27),
and each worker of a sweep started with empty caches compiles every kernel the others
compile.

No deadlock: a process holds claims only on the kernels it is compiling, a chain of
callers and callees, so two processes waiting for each other's claims would need a
kernel that calls itself through another. A claim whose process has died is ignored,
and a wait ends after CLAIM_WAIT_S whatever happens (the process then compiles the
kernel itself); claims that cannot be written (a read-only cache) claim nothing."""

import atexit
import contextlib
import os
import time
from pathlib import Path

# the longest a process waits for another's claim: a claim is held while the kernel's
# callees compile inside it too, which for the time loop of a cold start on a busy core
# can take a minute (session 22: 85 s of compiles on one core); past it the waiting
# process compiles the kernel itself (the same kernel twice, as without claims)
CLAIM_WAIT_S = 120.0
POLL_S = 0.02
# a claim file that names no process this long after it was written was left by a
# process that failed to write it
UNWRITTEN_S = 5.0
# what a claim says besides its process id: the kernel is compiled inside another
# compile (a partial version, beamcontact/_native.py)
PARTIAL = "partial"

_held: set[Path] = set()


def take(claim: Path, partial: bool = False) -> bool:
    """Claim ``claim`` for this process (``partial``: for a compile inside another): True
    if this process may compile (the claim is its own now or already, or claims cannot
    be written), False if a live process holds it."""
    if claim in _held:
        return True
    for _ in range(2):
        try:
            fd = os.open(claim, os.O_CREAT | os.O_EXCL | os.O_WRONLY)
        except FileExistsError:
            if _holder_alive(claim):
                return False
            with contextlib.suppress(OSError):
                claim.unlink()  # left by a process that died
            continue
        except OSError:
            return True
        _held.add(claim)
        try:
            os.write(fd, f"{os.getpid()} {PARTIAL if partial else ''}".strip().encode())
        except OSError:
            release(claim)
        finally:
            os.close(fd)
        return True
    return True


def held_for_partial(claim: Path) -> bool:
    """Whether ``claim`` is held for a compile inside another compile (its partial
    version is of no use to a call from Python, which compiles the kernel whole)."""
    try:
        return claim.read_text().split()[1:] == [PARTIAL]
    except OSError:
        return False


def release(claim: Path) -> None:
    """Give up this process's claim ``claim`` (nothing if it is not this process's)."""
    if claim in _held:
        _held.discard(claim)
        with contextlib.suppress(OSError):
            claim.unlink()


def wait(claim: Path, within: float = CLAIM_WAIT_S) -> None:
    """Wait until ``claim`` is released, its process has died, or ``within`` seconds
    have passed."""
    deadline = time.monotonic() + within
    while claim.exists() and _holder_alive(claim) and time.monotonic() < deadline:
        time.sleep(POLL_S)


def _holder_alive(claim: Path) -> bool:
    """Whether the process named in ``claim`` lives (False once the claim is gone)."""
    try:
        if int(claim.read_text().split()[0]) == os.getpid():
            return claim in _held
    except (OSError, ValueError, IndexError):
        pass
    return named_process_alive(claim)


def named_process_alive(path: Path) -> bool:
    """Whether the process whose id starts the file ``path`` lives: False when the file
    is gone, names a process that has ended (or only waits to be collected by its
    parent), or names none UNWRITTEN_S after it was written; True while its writer may
    still be writing the id, or when the process is another user's."""
    try:
        pid = int(path.read_text().split()[0])
    except FileNotFoundError:
        return False
    except (OSError, ValueError, IndexError):
        try:
            return time.time() - path.stat().st_mtime < UNWRITTEN_S
        except OSError:
            return False
    return process_alive(pid)


def process_alive(pid: int) -> bool:
    """Whether process ``pid`` lives: not when it has ended, nor when it only waits to be
    collected by its parent; True for another user's process."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:
        return True
    try:  # a process that has ended but not been collected still answers kill(pid, 0)
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rsplit(")", 1)[1].split()[0] != "Z"
    except (OSError, IndexError):
        return True


@atexit.register
def _release_all() -> None:
    """A compile that failed never stored its kernel: its claims go with the process."""
    for claim in list(_held):
        release(claim)


def _forget_in_child() -> None:
    """A forked copy holds none of its parent's claims (the parent releases them)."""
    _held.clear()


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_forget_in_child)
