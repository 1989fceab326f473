"""The ``[rattle]`` table of a train recipe: its keys, their ranges and defaults (Dakin et al.
2016, *PLoS ONE* 11(4): e0152759), checked into a :class:`Rattle` (``docs/pipeline.md``, *The
rattle*). What the rattle does with it: :mod:`.rattle`."""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from pathlib import Path
from typing import Any

import numpy as np

from pavonine.pipeline.convert.recipe import _check_keys, _fail, _number

#: Dakin et al. 2016: mean train-rattling frequency of 14 males (high-speed video).
MEAN_FREQUENCY_HZ = 25.6
#: Dakin et al. 2016: the eyespots' largest side-to-side movement while rattling.
EYESPOT_MM = 1.7
#: Dakin et al. 2016: the loose barbs' largest lateral movement, near the eyespots too.
BARB_MM = 9.6
#: Time samples per period of the drive below which linear interpolation of a sine fails (a
#: chord of a quarter period misses the crest by 29 %; at 8 samples a period by 7.6 %).
MIN_SAMPLES_PER_PERIOD = 4
#: Most time samples one rattle may write (frames × samples_per_frame + 1).
MAX_TIME_SAMPLES = 4096

#: ``[rattle]`` keys: (low, high, integer). ``frequency_hz``, ``fps`` and ``duration_s`` must
#: be positive; the rest may be zero.
RANGES: dict[str, tuple[float, float, bool]] = {
    "frequency_hz": (1.0, 100.0, False),
    "eyespot_mm": (0.0, 50.0, False),
    "barb_mm": (0.0, 100.0, False),
    "phase_spread": (0.0, 1.0, False),
    "phases": (1, 16, True),
    "fps": (1.0, 240.0, False),
    "duration_s": (0.001, 60.0, False),
    "start_frame": (-100_000, 100_000, True),
    "samples_per_frame": (1, 64, True),
}


@dataclass(frozen=True)
class Rattle:
    """A parsed ``[rattle]`` table (defaults: Dakin et al. 2016, a 0.25 s shot at 24 fps)."""

    frequency_hz: float = MEAN_FREQUENCY_HZ
    eyespot_mm: float = EYESPOT_MM
    barb_mm: float = BARB_MM
    phase_spread: float = 1.0  # instance phases uniform in [0, phase_spread) cycles
    phases: int = 4  # phase-shifted variants of each prototype (the flex)
    fps: float = 24.0  # frames per second = the layer's timeCodesPerSecond
    duration_s: float = 0.25
    start_frame: int = 1
    samples_per_frame: int = 16

    @property
    def frames(self) -> int:
        """Frames of the shot: ``duration_s × fps``, rounded up."""
        return max(1, math.ceil(self.duration_s * self.fps - 1e-9))

    @property
    def end_frame(self) -> int:
        return self.start_frame + self.frames - 1

    def times(self) -> np.ndarray:
        """Time codes of the samples: every ``1/samples_per_frame`` frame from half a frame
        before the first frame to half a frame after the last."""
        count = self.frames * self.samples_per_frame + 1
        return self.start_frame - 0.5 + np.arange(count) / self.samples_per_frame

    def samples_per_period(self) -> float:
        return self.samples_per_frame * self.fps / self.frequency_hz


def parse_rattle(path: Path, table: Any) -> Rattle:
    """Check a ``[rattle]`` table; :class:`InputError` naming ``rattle.<key>``."""
    if not isinstance(table, dict):
        raise _fail(path, "rattle", "expected a table [rattle]")
    _check_keys(path, table, {f.name for f in fields(Rattle)}, "rattle.")
    values: dict[str, Any] = {}
    for key, value in table.items():
        low, high, integer = RANGES[key]
        where = f"rattle.{key}"
        number = _number(path, where, value, positive=False, integer=integer) if low >= 0 else (
            _signed(path, where, value, integer)
        )  # fmt: skip
        if not low <= number <= high:
            raise _fail(path, where, f"must lie in [{low:g}, {high:g}], got {number:g}")
        values[key] = int(number) if integer else float(number)
    rattle = Rattle(**values)
    if rattle.samples_per_period() < MIN_SAMPLES_PER_PERIOD:
        need = math.ceil(MIN_SAMPLES_PER_PERIOD * rattle.frequency_hz / rattle.fps)
        raise _fail(
            path,
            "rattle.samples_per_frame",
            f"{rattle.samples_per_frame} a frame is {rattle.samples_per_period():.2g} a period of "
            f"{rattle.frequency_hz:g} Hz at {rattle.fps:g} fps; at least {need} needed "
            f"({MIN_SAMPLES_PER_PERIOD} a period)",
        )
    if rattle.frames * rattle.samples_per_frame + 1 > MAX_TIME_SAMPLES:
        raise _fail(
            path,
            "rattle.duration_s",
            f"{rattle.frames} frames × {rattle.samples_per_frame} samples exceed "
            f"{MAX_TIME_SAMPLES} time samples",
        )
    return rattle


def _signed(path: Path, key: str, value: Any, integer: bool) -> float:
    if isinstance(value, bool) or not isinstance(value, int if integer else (int, float)):
        kind = "an integer" if integer else "a number"
        raise _fail(path, key, f"expected {kind}, got {value!r}")
    if not math.isfinite(value):
        raise _fail(path, key, f"must be finite, got {value}")
    return value
