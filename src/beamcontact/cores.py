"""The cores this process may run on: its CPU affinity where the platform keeps one (a
process started under ``taskset`` or a batch scheduler's share of a node), else every
core. The one count from which the kernels' thread share (:class:`beamcontact._native.
CoreShare`), the drawer process (:mod:`beamcontact.drawer`) and a sweep's local workers
(``beamcontact sweep``) start. Importing it imports nothing but :mod:`os`."""

import os


def usable_cores() -> int:
    """The number of cores this process may run on (at least 1)."""
    if hasattr(os, "sched_getaffinity"):
        return max(1, len(os.sched_getaffinity(0)))
    return os.cpu_count() or 1
