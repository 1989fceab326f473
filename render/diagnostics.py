"""Warnings raised while translating a stage: one per problem, each naming the prim."""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field


class StageWarning(UserWarning):
    """A prim that could not be rendered as authored (skipped, or rendered with a fallback)."""


@dataclass
class Diagnostics:
    """Collects ``/prim/path: message`` lines; each distinct line is kept (and warned) once."""

    messages: list[str] = field(default_factory=list)

    def warn(self, where: str, message: str) -> None:
        """Record a warning about ``where`` (a prim path or file)."""
        line = f"{where}: {message}"
        if line not in self.messages:
            self.messages.append(line)
            warnings.warn(line, StageWarning, stacklevel=3)
