"""The command line's standard streams, made so that a failing terminal never stops a run.

A run's messages are a courtesy; its results are on disk. When standard output or error
cannot be written (a log file on a full disk, ``> /dev/full``, a pipe whose reader has
gone: ``beamcontact run case.toml | head -1``), the write raised OSError and ended the
command with a traceback, often before its first step. :class:`LenientStream` wraps
each stream: the first failed write is remembered, that write and every later one are
dropped, and the run goes on; the command line says so at its end
(:func:`lost_output`), on the other stream if that one still works. The exit status is
the run's.

A broken pipe is treated like a full disk: Python ignores SIGPIPE, so the write raises
BrokenPipeError, and a simulation that has run for an hour should not end because the
program reading its messages did.
"""

import sys


class LenientStream:
    """A text stream that drops what it cannot write (``stream``: the stream wrapped;
    ``error``: the first OSError met, None while all went well). Any other attribute is
    the wrapped stream's, so that Rich and Click treat it as that stream."""

    def __init__(self, stream):
        self.stream = stream
        self.error: OSError | None = None

    def write(self, text: str) -> int:
        if self.error is None:
            try:
                return self.stream.write(text)
            except OSError as exc:
                self.error = exc
        return len(text)

    def flush(self) -> None:
        if self.error is None:
            try:
                self.stream.flush()
            except OSError as exc:
                self.error = exc

    def writelines(self, lines) -> None:
        for line in lines:
            self.write(line)

    def __getattr__(self, name):
        return getattr(self.stream, name)


def guard_streams() -> None:
    """Wrap sys.stdout and sys.stderr in :class:`LenientStream` (once; a stream that is
    None, closed at the start, stays None)."""
    for name in ("stdout", "stderr"):
        stream = getattr(sys, name)
        if stream is not None and not isinstance(stream, LenientStream):
            setattr(sys, name, LenientStream(stream))


def lost_output() -> None:
    """Say on a working stream which stream lost messages and why (nothing if none
    did)."""
    streams = {name: getattr(sys, name) for name in ("stdout", "stderr")}
    for name, stream in streams.items():
        error = getattr(stream, "error", None)
        if error is None:
            continue
        other = streams["stderr" if name == "stdout" else "stdout"]
        if other is not None and getattr(other, "error", None) is None:
            reason = error.strerror or type(error).__name__
            label = "output" if name == "stdout" else "error"
            other.write(f"warning: messages to standard {label} were lost from the "
                        f"first that could not be written ({reason}); the results are "
                        f"not affected\n")
            other.flush()
