"""What native libraries print straight to the process's file descriptors (USD's ``TF_WARN``,
pymeshlab's plugin loader), kept off the command's own output."""

from __future__ import annotations

import contextlib
import os
import sys
import tempfile
from collections.abc import Iterator


@contextlib.contextmanager
def silenced(*fds: int) -> Iterator[None]:
    """File descriptors ``fds`` (default 1 and 2) go to ``/dev/null`` inside the block and come
    back after it. Python's own streams are flushed first, so nothing written before the block is
    lost. Where a descriptor cannot be duplicated (no stdout or stderr at all) the block runs
    as it is."""
    fds = fds or (1, 2)
    _flush_python_streams()
    try:
        saved = [os.dup(fd) for fd in fds]
    except OSError:  # nothing to keep clean
        yield
        return
    try:
        with open(os.devnull, "wb") as null:
            for fd in fds:
                os.dup2(null.fileno(), fd)
            yield
    finally:
        for fd, copy in zip(fds, saved, strict=True):
            os.dup2(copy, fd)
            os.close(copy)


@contextlib.contextmanager
def captured(fd: int = 2) -> Iterator[list[str]]:
    """What is written to descriptor ``fd`` inside the block (by native code: Dr.Jit's kernel
    cache, Mitsuba's logger), as the list of its non-blank lines, filled when the block ends,
    also when it raises. Python's streams are flushed first; where ``fd`` cannot be duplicated
    nothing is captured."""
    lines: list[str] = []
    _flush_python_streams()
    try:
        saved = os.dup(fd)
    except OSError:
        yield lines
        return
    with tempfile.TemporaryFile() as sink:
        os.dup2(sink.fileno(), fd)
        try:
            yield lines
        finally:
            os.dup2(saved, fd)
            os.close(saved)
            sink.seek(0)
            text = sink.read().decode("utf-8", errors="replace")
            lines.extend(line for line in text.splitlines() if line.strip())


def _flush_python_streams() -> None:
    """Write out what Python buffered for stdout and stderr before their descriptors move."""
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(AttributeError, OSError, ValueError):
            stream.flush()
