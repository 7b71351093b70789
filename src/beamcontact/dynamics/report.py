"""What one attempt at a time step reports to the step controller, whichever engine made
it (docs/architecture.md, "Engines"): the names of its quantities, its status flags and
the attempt itself.

An engine returns the quantities of :data:`VALUES` (float64) and :data:`COUNTS`
(integers, the :class:`StepFlags` first) as two vectors, one copy each from compiled code;
:func:`read_report` turns them into a dict of Python numbers; the step controller
(dynamics/control.py) reads the vectors at the positions named here (``V_*``, ``C_*``),
in Python and in compiled code alike.
"""

from dataclasses import dataclass
from enum import IntFlag

import numpy as np

# the diagnostics of a state
DIAGNOSTICS = ("E_strain", "E_gravity", "E_ext", "E_contact", "E_kin", "p_x", "p_y")
# the quantities of one attempt (float64) and its counts (integers, the status flags first)
VALUES = ("residual_norm", "initial_residual_norm", "h", "error", "approach", "min_gap",
          "E_contact_before", "energy_floor", *DIAGNOSTICS)
COUNTS = ("flags", "iterations", "count", "count_after", "load", "load_after")
# their positions, as constants that compiled code reads (dynamics/control.py)
(V_RESIDUAL, V_RESIDUAL0, V_H, V_ERROR, V_APPROACH, V_GAP, V_EC_BEFORE, V_FLOOR, V_STRAIN,
 V_GRAVITY, V_EXT, V_CONTACT, V_KIN, V_PX, V_PY) = range(len(VALUES))
C_FLAGS, C_ITERATIONS, C_COUNT, C_COUNT_AFTER, C_LOAD, C_LOAD_AFTER = range(len(COUNTS))
# the diagnostics are the last entries of VALUES, in their order
DIAG0 = V_STRAIN


class StepFlags(IntFlag):
    """Status of an attempt as the engine reports it (one integer, never a float)."""

    CONVERGED = 1  # Newton converged
    MISSING_BLOCK = 2  # the solution left the candidate search: a contact block was missed


# the flags as plain integers, for compiled code
CONVERGED, MISSING_BLOCK = int(StepFlags.CONVERGED), int(StepFlags.MISSING_BLOCK)


@dataclass(frozen=True)
class Attempt:
    """One attempt at a step: the engine's state after it (meaningful when accepted) and
    its report, the vectors ``values`` (float64, :data:`VALUES`) and ``counts`` (int64,
    :data:`COUNTS`)."""

    state: object
    values: np.ndarray
    counts: np.ndarray

    @property
    def report(self) -> dict:
        """The report as a dict of Python numbers (every name but ``flags``)."""
        return read_report(self.values.tolist(), self.counts.tolist())[0]

    @property
    def flags(self) -> StepFlags:
        """The status flags."""
        return StepFlags(int(self.counts[C_FLAGS]))


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
