"""Warnings raised while translating a stage: one per problem, each naming the prim."""

from __future__ import annotations

import re
import warnings
from dataclasses import dataclass, field


class StageWarning(UserWarning):
    """A prim that could not be rendered as authored (skipped, or rendered with a fallback)."""


@dataclass
class Diagnostics:
    """Collects ``/prim/path: message`` lines; each distinct line is kept (and warned) once."""

    messages: list[str] = field(default_factory=list)
    _seen: set[str] = field(default_factory=set, repr=False)

    def warn(self, where: str, message: str) -> None:
        """Record a warning about ``where`` (a prim path or file)."""
        line = f"{where}: {message}"
        if line not in self._seen:
            self._seen.add(line)
            self.messages.append(line)
            warnings.warn(line, StageWarning, stacklevel=3)


def first_line(exc: object) -> str:
    """The first informative line of an exception's message, for one-line errors and warnings.

    Skips a bare ``Error …`` header that USD puts before the message when more lines follow, and
    drops Mitsuba's ``[file.cpp:123]`` source location prefix.
    """
    lines = [line.strip() for line in str(exc).splitlines() if line.strip()]
    if not lines:
        return type(exc).__name__
    line = next((ln for ln in lines if not ln[:12].startswith("Error")), lines[0])
    return re.sub(r"^\[[\w.]+:\d+\]\s*", "", line)
