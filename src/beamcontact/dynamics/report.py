"""What one attempt at a time step reports to the step controller, whichever engine made
it (docs/architecture.md, "Engines"): the names of its quantities, its status flags and
the attempt itself.

An engine returns the quantities of :data:`VALUES` (float64) and :data:`COUNTS`
(integers, the :class:`StepFlags` first) as two vectors, one copy each from compiled code;
:func:`read_report` turns them into the dict the controller (dynamics/control.py) and the
driver (dynamics/driver.py) read.
"""

from dataclasses import dataclass
from enum import IntFlag

# the diagnostics of a state
DIAGNOSTICS = ("E_strain", "E_gravity", "E_ext", "E_contact", "E_kin", "p_x", "p_y")
# the quantities of one attempt (float64) and its counts (integers, the status flags first)
VALUES = ("residual_norm", "initial_residual_norm", "h", "error", "approach", "min_gap",
          "E_contact_before", "energy_floor", *DIAGNOSTICS)
COUNTS = ("flags", "iterations", "count", "count_after", "load", "load_after")


class StepFlags(IntFlag):
    """Status of an attempt as the engine reports it (one integer, never a float)."""

    CONVERGED = 1  # Newton converged
    MISSING_BLOCK = 2  # the solution left the candidate search: a contact block was missed


@dataclass(frozen=True)
class Attempt:
    """One attempt at a step: the engine's state after it (meaningful when accepted), the
    report (every name of :data:`VALUES` and :data:`COUNTS` but ``flags``, as Python
    numbers) and the status flags."""

    state: object
    report: dict
    flags: StepFlags


@dataclass(frozen=True)
class Overflow:
    """An attempt that could not be made: the candidate search needs ``count`` blocks and
    cells of ``load`` boxes, more than its capacities (they grow, the attempt is redone)."""

    count: int
    load: int


def read_report(values, counts) -> tuple[dict, StepFlags]:
    """The report and the flags of an attempt from its two vectors (sequences of numbers
    in the order of :data:`VALUES` and :data:`COUNTS`)."""
    report = {**dict(zip(VALUES, values, strict=True)), **dict(zip(COUNTS, counts, strict=True))}
    return report, StepFlags(report.pop("flags"))
