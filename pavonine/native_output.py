"""What native libraries print straight to the process's file descriptors (USD's ``TF_WARN``,
pymeshlab's plugin loader), kept off the command's own output.

A file descriptor belongs to the whole process: two threads that each saved and moved descriptor
2 would restore each other's copy (the second saves the first one's ``/dev/null``, and stderr
stays there for good: a command's error line vanished when convert read and wrote maps on
threads). So one block at a time moves descriptors, whichever thread it is in (:data:`_MOVING`).
"""

from __future__ import annotations

import contextlib
import os
import sys
import tempfile
import threading
from collections.abc import Iterator

#: Held while a block has moved descriptors (re-entrant: a block may nest in another's thread).
_MOVING = threading.RLock()


@contextlib.contextmanager
def silenced(*fds: int) -> Iterator[None]:
    """File descriptors ``fds`` (default 1 and 2) go to ``/dev/null`` inside the block and come
    back after it. Python's own streams are flushed first, so nothing written before the block is
    lost. Where a descriptor cannot be duplicated (no stdout or stderr at all) the block runs
    as it is."""
    fds = fds or (1, 2)
    with _MOVING:
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
    with _MOVING:
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
