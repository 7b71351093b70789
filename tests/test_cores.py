"""The cores a process may run on (beamcontact/cores.py): its CPU affinity, not the
machine's count, so that a run under ``taskset`` or a batch scheduler's share of a node
starts as many kernel threads, drawer processes and sweep workers as it has cores."""

import os
import subprocess
import sys

import pytest

from beamcontact.cores import usable_cores

linux_only = pytest.mark.skipif(not hasattr(os, "sched_getaffinity"),
                                reason="CPU affinity is a Linux interface")


@linux_only
def test_the_cores_are_the_affinity_of_the_process():
    assert usable_cores() == len(os.sched_getaffinity(0)) >= 1


@linux_only
def test_a_process_held_to_one_core_counts_one():
    """A child bound to one core before it asks: 1, whatever the machine has; and the
    command line's run then starts no drawer process beside it."""
    code = ("import os; os.sched_setaffinity(0, {min(os.sched_getaffinity(0))}); "
            "from beamcontact.cores import usable_cores; from beamcontact.drawer import Drawer\n"
            "with Drawer.started() as d: print(usable_cores(), d is None)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout.split()
    assert out == ["1", "True"]
