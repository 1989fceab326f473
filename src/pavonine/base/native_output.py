"""What native libraries print straight to the process's file descriptors (USD's ``TF_WARN``,
pymeshlab's plugin loader), kept off the command's own output.

A file descriptor belongs to the whole process, and blocks on different threads overlap (convert
reads and writes maps on threads; USD's validators run on TBB workers inside a silenced block and
capture libpng's lines there). So each descriptor keeps one stack of the targets of the blocks now
open (:class:`_Redirect`): the first block saves the original, the newest open block's target is
where the descriptor points, and the original comes back when the last block closes, whichever
order they close in. The lock guards only the moves, never a block's body: a block on one thread
never waits for a block on another (holding it across the body deadlocked validate).

Where blocks overlap, what a thread writes goes to the newest block's target: descriptors cannot
tell threads apart, so an older capture misses those lines (they are not lost to the terminal
for good: the original descriptor always comes back).
"""

from __future__ import annotations

import contextlib
import os
import sys
import tempfile
import threading
from collections.abc import Iterator

#: Guards the descriptor moves and every :class:`_Redirect`; never held while a block runs.
_LOCK = threading.Lock()


class _Redirect:
    """The open blocks of one descriptor: the saved original and the targets, oldest first."""

    def __init__(self, fd: int) -> None:
        self.fd = fd
        self.original: int | None = None
        self.targets: list[tuple[object, int]] = []  # (block's token, target descriptor)

    def push(self, token: object, target: int) -> None:
        """Point the descriptor at ``target`` for the block ``token`` (saving the original first).
        Raises :class:`OSError` when the descriptor cannot be duplicated."""
        if not self.targets:
            self.original = os.dup(self.fd)
        os.dup2(target, self.fd)
        self.targets.append((token, target))

    def pop(self, token: object) -> None:
        """Close the block ``token``: the descriptor goes back to the newest block still open, or
        to the original when none is."""
        self.targets = [entry for entry in self.targets if entry[0] is not token]
        if self.targets:
            os.dup2(self.targets[-1][1], self.fd)
        elif self.original is not None:
            os.dup2(self.original, self.fd)
            os.close(self.original)
            self.original = None


_REDIRECTS: dict[int, _Redirect] = {}


@contextlib.contextmanager
def _redirected(fds: tuple[int, ...], target: int) -> Iterator[bool]:
    """Descriptors ``fds`` point at ``target`` inside the block; yields whether they moved (not
    where a descriptor cannot be duplicated: no stdout or stderr at all)."""
    token = object()
    moved: list[_Redirect] = []
    with _LOCK:
        _flush_python_streams()
        try:
            for fd in fds:
                redirect = _REDIRECTS.setdefault(fd, _Redirect(fd))
                redirect.push(token, target)
                moved.append(redirect)
        except OSError:
            for redirect in moved:
                redirect.pop(token)
            moved = []
    try:
        yield bool(moved)
    finally:
        with _LOCK:
            _flush_python_streams()
            for redirect in moved:
                redirect.pop(token)


@contextlib.contextmanager
def silenced(*fds: int) -> Iterator[None]:
    """File descriptors ``fds`` (default 1 and 2) go to ``/dev/null`` inside the block and come
    back after it. Python's own streams are flushed first, so nothing written before the block is
    lost. Where a descriptor cannot be duplicated the block runs as it is."""
    with open(os.devnull, "wb") as null, _redirected(fds or (1, 2), null.fileno()):
        yield


@contextlib.contextmanager
def captured(fd: int = 2) -> Iterator[list[str]]:
    """What is written to descriptor ``fd`` inside the block (by native code: Dr.Jit's kernel
    cache, Mitsuba's logger), as the list of its non-blank lines, filled when the block ends,
    also when it raises. Python's streams are flushed first; where ``fd`` cannot be duplicated
    nothing is captured."""
    lines: list[str] = []
    with tempfile.TemporaryFile() as sink:
        try:
            with _redirected((fd,), sink.fileno()):
                yield lines
        finally:
            sink.seek(0)
            text = sink.read().decode("utf-8", errors="replace")
            lines.extend(line for line in text.splitlines() if line.strip())


def _flush_python_streams() -> None:
    """Write out what Python buffered for stdout and stderr before their descriptors move."""
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(AttributeError, OSError, ValueError):
            stream.flush()
