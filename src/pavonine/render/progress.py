"""Progress of the long loops of one render, on stderr (hidden by ``-q``; rich, transient).

:class:`SyncProgress` counts what the stage translation has done (prims visited, instances made)
so that a stage with thousands of instances shows it is working; the sampling bar,
:class:`SampleProgress`, over every product's samples. Both are no-ops when progress is off.
"""

from __future__ import annotations

import os
import time

#: Seconds between redraws of the translation counter.
REFRESH_SECONDS = 0.2


class SyncProgress:
    """A one-line counter: ``translating STAGE: N prims, M instances``."""

    def __init__(self, stage_path: str | os.PathLike, enabled: bool):
        self.enabled = enabled
        self.label = f"translating {os.path.basename(os.fspath(stage_path))}"
        self.prims = 0
        self.instances = 0
        self._last = 0.0
        self._status = None

    def __enter__(self) -> SyncProgress:
        if self.enabled:
            from rich.console import Console

            self._status = Console(stderr=True).status(self.label)
            self._status.__enter__()
        return self

    def __exit__(self, *exc) -> None:
        if self._status is not None:
            self._status.__exit__(*exc)
            self._status = None

    def prim(self) -> None:
        """One more prim visited."""
        self.prims += 1
        self._redraw()

    def instanced(self, count: int) -> None:
        """``count`` instances made so far."""
        self.instances = count
        self._redraw()

    def _redraw(self) -> None:
        if self._status is None:
            return
        now = time.monotonic()
        if now - self._last < REFRESH_SECONDS:
            return
        self._last = now
        self._status.update(f"{self.label}: {self.prims:,} prims, {self.instances:,} instances")


class SampleProgress:
    """A rich progress bar over every product's samples (on stderr; hidden when disabled)."""

    def __init__(
        self, stage_path: str | os.PathLike, sizes: list[tuple[int, int]], spp: int, enabled: bool
    ):
        from rich.console import Console
        from rich.progress import (
            BarColumn,
            Progress,
            TextColumn,
            TimeElapsedColumn,
            TimeRemainingColumn,
        )

        label_sizes = ", ".join(f"{w}×{h}" for w, h in sizes)
        label = f"render {os.path.basename(os.fspath(stage_path))} {label_sizes}"
        self.bar = Progress(
            TextColumn(label),
            BarColumn(),
            TextColumn("{task.completed}/{task.total} spp"),
            TimeElapsedColumn(),
            TimeRemainingColumn(),
            console=Console(stderr=True),
            disable=not enabled,
            transient=False,
        )
        self.total = spp * len(sizes)

    def __enter__(self):
        self.bar.__enter__()
        task = self.bar.add_task("render", total=self.total)
        return lambda n: self.bar.update(task, advance=n)

    def __exit__(self, *exc):
        return self.bar.__exit__(*exc)
