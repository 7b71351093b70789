"""Progress of a running case: what the solver reports after every accepted step.

The runner calls a ``Progress`` callback with a :class:`ProgressInfo`; the command line
draws it as a one-line bar (:func:`progress_bar`), a sweep forwards ``fraction`` and
:meth:`ProgressInfo.text` to the client, a script may record it. Nothing here touches the
solver, and importing this module does not import rich (the bar imports it when drawn).

The bar fits in 80 columns at any terminal width of 80 or more: the case title is printed
once above it (a title inside the bar squeezes the bar until the line wraps, and a wrapped
line is reprinted at every refresh), the bar itself has a fixed width, and every text column
has a fixed width, so the line neither grows with the terminal nor jitters from step to step.
"""

from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any


@dataclass(frozen=True)
class ProgressInfo:
    """The state of a run after one accepted step (or before the first one)."""

    fraction: float          # of the run done, 0..1 (t / t_end, or the load factor)
    parameter: str           # "t" (dynamics) or "load_factor" (statics)
    value: float             # the time [s] or load factor reached
    step: int                # accepted steps so far
    dt: float | None = None  # the last step [s] (dynamics)
    iterations: int = 0      # Newton iterations of the last step

    def text(self) -> str:
        """A short description, e.g. ``t 1.234 s  dt 1.0e-03 s  it 2``."""
        if self.step == 0:
            return "compiling"
        if self.parameter == "t":
            dt = "" if self.dt is None else f"  dt {self.dt:.1e} s"
            return f"t {self.value:.4g} s{dt}  it {self.iterations}"
        return f"load {self.value:.3f}  it {self.iterations}"


Progress = Callable[[ProgressInfo], None]

MAX_WIDTH = 80
"""The widest line the bar and its title may take, whatever the terminal width."""

_BAR_WIDTH = 16
_REFRESH_PER_SECOND = 4
# (task field, column width): value reached, step size, Newton iterations of the last step.
# With the bar, the percentage, elapsed and "eta" + remaining time and one space between
# columns, a line is 16+4+13+12+6+7+3+7 + 7 = 75 columns wide.
_FIELD_WIDTHS = (("value", 13), ("dt", 12), ("iterations", 6))


def _fields(info: ProgressInfo) -> dict[str, str]:
    """The texts of the bar's columns for ``info`` (time or load factor, dt, iterations)."""
    if info.step == 0:
        return {"value": "compiling", "dt": "", "iterations": ""}
    value = f"t {info.value:.4g} s" if info.parameter == "t" else f"load {info.value:.3f}"
    dt = "" if info.dt is None else f"dt {info.dt:.1e} s"
    return {"value": value, "dt": dt, "iterations": f"it {info.iterations}"}


def _columns() -> list[Any]:
    """The bar's rich columns, each of fixed width, so that a line stays within 80 columns."""
    from rich.progress import (
        BarColumn,
        TaskProgressColumn,
        TextColumn,
        TimeElapsedColumn,
        TimeRemainingColumn,
    )
    from rich.table import Column

    def fixed(width: int) -> Column:
        return Column(width=width, no_wrap=True, overflow="ellipsis")

    text = [TextColumn(f"{{task.fields[{name}]}}", markup=False, table_column=fixed(width))
            for name, width in _FIELD_WIDTHS]
    return [BarColumn(bar_width=_BAR_WIDTH), TaskProgressColumn(table_column=fixed(4)), *text,
            TimeElapsedColumn(), TextColumn("eta"), TimeRemainingColumn()]


def _completed(fraction: float) -> float:
    """``fraction`` clamped to 0..1, and 1 when within round-off of it (t_end reached as a
    sum of steps), so that a finished run shows a full bar and no time left."""
    return 1.0 if fraction >= 1.0 - 1e-9 else max(fraction, 0.0)


def _print_title(console: Any, title: str) -> None:
    """Print the case title on its own line, cut with an ellipsis to at most 80 columns."""
    from rich.text import Text

    width = min(console.width, MAX_WIDTH)
    console.print(Text(title), width=width, no_wrap=True, overflow="ellipsis", crop=True)


def _ignore(info: ProgressInfo) -> None:
    """The callback of a disabled bar: does nothing."""


LOG_SECONDS = 10.0
"""Where the output is not a terminal (a batch job's log), a progress line this often."""


def _log_lines(title: str, console: Any) -> Progress:
    """The callback that prints the title, then a line of progress every LOG_SECONDS and
    when the run is done: a log file gets a readable record instead of a bar's frames."""
    import time

    console.print(title, markup=False, highlight=False, soft_wrap=True)
    start = time.monotonic()
    last = [-float("inf")]

    def log(info: ProgressInfo) -> None:
        now = time.monotonic()
        done = _completed(info.fraction) >= 1.0
        if info.step == 0 or (now - last[0] < LOG_SECONDS and not done):
            return
        last[0] = now
        f = _fields(info)
        console.print(f"{100 * _completed(info.fraction):5.1f} %  {f['value']}  {f['dt']}  "
                      f"{f['iterations']}  step {info.step}  {now - start:.0f} s elapsed",
                      markup=False, highlight=False, soft_wrap=True)

    return log


@contextmanager
def progress_bar(title: str, enabled: bool = True, console: Any = None,
                 lines: bool | None = None) -> Iterator[Progress]:
    """Draw the progress of one run as a bar at most 80 columns wide, for a ``with`` block.

    Prints ``title`` once on its own line, then yields the :data:`Progress` callback to
    hand to the runner: each call moves the bar and shows the time (or load factor)
    reached, the last step size, the Newton iterations of the last step, the elapsed time
    and an estimate of the time left. The bar is redrawn at most four times a second
    whatever the step rate, and is left on screen in its last state when the block ends
    (also on an exception, e.g. Ctrl-C, so that a message printed afterwards comes below
    it). With ``enabled`` false nothing is drawn and the callback does nothing (``--quiet``).
    ``console`` is a rich Console to draw on (default: rich's console on stdout; tests pass
    one writing to a string). Where stdout is not a terminal (``lines`` None: a batch
    job's log, a pipe) the progress is a line every :data:`LOG_SECONDS` instead
    (``lines`` True or False forces either).
    """
    if not enabled:
        yield _ignore
        return
    from rich.console import Console
    from rich.progress import Progress as RichProgress

    if lines is None:
        lines = console is None and not Console().is_terminal
    if lines:
        yield _log_lines(title, console or Console())
        return

    bar = RichProgress(*_columns(), console=console, refresh_per_second=_REFRESH_PER_SECOND,
                       transient=False)
    _print_title(bar.console, title)
    task = bar.add_task("", total=1.0, **_fields(ProgressInfo(0.0, "t", 0.0, 0)))

    def show(info: ProgressInfo) -> None:
        bar.update(task, completed=_completed(info.fraction), **_fields(info))

    with bar:
        yield show


def _tail(text: str, width: int) -> str:
    """``text`` cut to ``width`` characters from the left ("…" + its end): sweep members'
    names differ mostly in their last parameter, so the end is the part worth keeping."""
    return text if len(text) <= width else "\u2026" + text[len(text) - width + 1:]


class SweepProgress:
    """Rich progress across runs: one bar for the sweep, one per run in flight.

    Every column has a fixed width (run names are cut from the left), so each line takes at
    most 78 columns whatever the terminal width: a line wider than the terminal wraps and is
    then reprinted at every refresh. Lines are redrawn at most four times a second.
    """

    NAME_WIDTH, BAR_WIDTH, INFO_WIDTH = 22, 16, 30  # + elapsed 7 + 3 spaces = 78

    def __init__(self, total: int, show: bool = True, console=None):
        from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn
        from rich.table import Column

        def text(field: str, width: int) -> TextColumn:
            return TextColumn(field, markup=False, table_column=Column(
                width=width, no_wrap=True, overflow="ellipsis"))

        self.bar = Progress(text("{task.description}", self.NAME_WIDTH),
                            BarColumn(bar_width=self.BAR_WIDTH),
                            text("{task.fields[info]}", self.INFO_WIDTH), TimeElapsedColumn(),
                            console=console, refresh_per_second=4, disable=not show)
        self.total, self.runs, self.done, self.failed = total, {}, set(), 0
        self.sweep = self.bar.add_task("sweep", total=total, info="")

    def __enter__(self):
        self.bar.__enter__()
        return self

    def __exit__(self, *exc):
        return self.bar.__exit__(*exc)

    def started(self, todo: int, done: int) -> None:
        """Show how many runs were complete before and how many are to run."""
        self.bar.update(self.sweep, completed=done, info=f"{done} done before, {todo} to run")

    def progress(self, name: str, fraction: float, info: str) -> None:
        """Move the bar of run ``name`` (adding it on its first event); ``info`` is the
        runner's ProgressInfo.text() forwarded by the worker."""
        if name in self.done:  # a late event of a finished run
            return
        if name not in self.runs:
            label = "  " + _tail(name, self.NAME_WIDTH - 2)
            self.runs[name] = self.bar.add_task(label, total=1.0, info="")
        self.bar.update(self.runs[name], completed=fraction, info=info)

    def finished(self, member, summary: dict) -> None:
        """Drop the run's bar, advance the sweep's, and print the run's status once."""
        self.done.add(member.name)
        if member.name in self.runs:
            self.bar.remove_task(self.runs.pop(member.name))
        self.failed += summary.get("status") != "completed"
        self.bar.advance(self.sweep)
        self.bar.update(self.sweep, info=f"{self.failed} failed" if self.failed else "")
        self.bar.console.print(f"{member.name}: {summary.get('status')}"
                               f" ({summary.get('wall_time_s') or 0:.1f} s)",
                               markup=False, highlight=False)

    def events(self):
        """The callbacks that run_sweep calls (SweepEvents) drawing on this display."""

        return SweepEvents(self.started, self.progress, self.finished)


@dataclass(frozen=True)
class SweepEvents:
    """Callbacks of a running sweep (the CLI draws progress with them).

    ``started(todo, done)`` once with the numbers of runs to do and done before;
    ``progress(name, fraction, info)`` as a run advances (``info``: ProgressInfo.text() of
    its last reported step, or "starting"); ``finished(member, summary)`` when a run ends.
    """

    started: Callable[[int, int], None] = lambda todo, done: None
    progress: Callable[[str, float, str], None] = lambda name, fraction, info: None
    finished: Callable[[Any, dict], None] = lambda member, summary: None  # (Member, summary)
