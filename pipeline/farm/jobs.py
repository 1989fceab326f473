"""Render jobs: frame ranges, cameras, RenderProducts and turntables → one image each, and the
file names they are written to.

Names (``docs/farm.md``): one image keeps ``-o OUT.exr``. Several frames are numbered
``OUT.####.exr``, the time code zero-padded to four digits (``OUT.0012.exr``, ``OUT.-003.exr``);
``OUT`` may carry the ``####`` itself (``shot.####.beauty.exr``). Several cameras or products add
their name before the number (``OUT.CamB.0012.exr``). The variance of an image, when asked for,
is ``….variance.exr`` beside it, and its display PNG ``….png``.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path

from pavonine.pipeline.errors import InputError

FRAME_TOKEN = "####"
_RANGE = re.compile(r"^\s*(-?\d+)\s*(?:-\s*(-?\d+)\s*(?::\s*(\d+)\s*)?)?$")


def parse_frames(text: str) -> list[int]:
    """``"1-24"``, ``"1-24:2"``, ``"12"`` → USD time codes (integers, inclusive, step ≥ 1)."""
    match = _RANGE.match(str(text))
    if not match:
        raise InputError("--frames", f"expected A-B[:STEP] (e.g. 1-24 or 1-24:2), got {text!r}")
    first = int(match.group(1))
    last = int(match.group(2)) if match.group(2) is not None else first
    step = int(match.group(3)) if match.group(3) is not None else 1
    if step < 1:
        raise InputError("--frames", f"step must be at least 1, got {step}")
    if last < first:
        raise InputError("--frames", f"the range ends before it starts ({first} > {last})")
    return list(range(first, last + 1, step))


def frame_label(frame: int) -> str:
    """A frame number as written in file names: four digits, zero-padded (``0012``, ``-003``)."""
    return f"{frame:04d}" if frame >= 0 else f"-{-frame:03d}"


@dataclass(frozen=True)
class RenderJob:
    """One image: the stage, its camera and time, and where it goes."""

    stage: str  # absolute path (workers read it from shared storage)
    output: Path  # the EXR
    camera: str | None = None
    time: float | None = None
    resolution: tuple[int, int] | None = None
    label: str = ""  # camera/product name, frame number: what distinguishes it in the batch
    png: Path | None = None
    variance: Path | None = None


def sibling(path: Path, suffix: str) -> Path:
    """``path`` with its extension replaced (``a.0001.exr`` → ``a.0001.png``)."""
    return path.with_suffix(suffix)


def variance_path(exr: Path) -> Path:
    """``OUT.0012.exr`` → ``OUT.variance.0012.exr``; ``OUT.exr`` → ``OUT.variance.exr``."""
    parts = exr.name.split(".")
    if len(parts) >= 3 and re.fullmatch(r"-?\d+", parts[-2]):
        return exr.with_name(".".join([*parts[:-2], "variance", *parts[-2:]]))
    return exr.with_name(f"{exr.stem}.variance{exr.suffix}")


def output_name(base: Path, view: str | None, frame: int | None) -> Path:
    """The EXR of one image of a batch (module docstring)."""
    name = base.name
    if frame is not None:
        if FRAME_TOKEN in name:
            name = name.replace(FRAME_TOKEN, frame_label(frame), 1)
        else:
            stem, dot, ext = name.rpartition(".")
            name = (
                f"{stem}.{frame_label(frame)}{dot}{ext}" if dot else f"{name}.{frame_label(frame)}"
            )
    elif FRAME_TOKEN in name:
        name = name.replace(f".{FRAME_TOKEN}", "").replace(FRAME_TOKEN, "")
    if view:
        stem, dot, ext = name.partition(".")
        name = f"{stem}.{view}{dot}{ext}"
    return base.with_name(name)


@dataclass(frozen=True)
class View:
    """A camera (or a RenderProduct's camera and resolution) to render through."""

    name: str
    camera: str | None
    resolution: tuple[int, int] | None = None


def plan(
    stage: str,
    output: Path,
    views: list[View],
    frames: list[int] | None,
    *,
    time: float | None = None,
    resolution: tuple[int, int] | None = None,
    png: bool = False,
    variance: bool = False,
) -> list[RenderJob]:
    """Every image of a batch: each view at each frame (or at ``time``)."""
    jobs = []
    label_views = len(views) > 1
    for view in views:
        for frame in frames if frames is not None else [None]:
            exr = output_name(output, view.name if label_views else None, frame)
            label = " ".join(
                part
                for part in (
                    view.name if label_views else "",
                    "" if frame is None else f"frame {frame}",
                )
                if part
            )
            jobs.append(
                RenderJob(
                    stage=stage,
                    output=exr,
                    camera=view.camera,
                    time=float(frame) if frame is not None else time,
                    resolution=resolution or view.resolution,
                    label=label or exr.name,
                    png=sibling(exr, ".png") if png else None,
                    variance=variance_path(exr) if variance else None,
                )
            )
    names = [job.output for job in jobs]
    if len(set(names)) != len(names):
        raise InputError("--output", "two images of this batch would get the same file name")
    return jobs


def split_samples(spp: int, shards: int) -> list[int]:
    """``spp`` samples over ``shards`` renders as evenly as possible (every shard ≥ 1)."""
    shards = max(1, min(shards, spp))
    base, extra = divmod(spp, shards)
    return [base + (1 if k < extra else 0) for k in range(shards)]


def shard_seed(seed: int, shard: int) -> int:
    """Seed of shard ``shard`` of a frame rendered with ``seed``: shard 0 keeps ``seed`` (an
    unsplit frame is the plain render); others are SplitMix64-mixed, so no two shards share a
    pass seed (``render_stage`` derives pass seeds as ``seed · 65537 + pass``)."""
    if shard == 0:
        return seed
    z = (seed * 0x9E3779B97F4A7C15 + shard * 0xBF58476D1CE4E5B9) & 0xFFFFFFFFFFFFFFFF
    z = ((z ^ (z >> 30)) * 0xBF58476D1CE4E5B9) & 0xFFFFFFFFFFFFFFFF
    z = ((z ^ (z >> 27)) * 0x94D049BB133111EB) & 0xFFFFFFFFFFFFFFFF
    return int((z ^ (z >> 31)) & 0x7FFFFFFF)


def shards_for(spp: int, moments: bool, shards: int) -> list[int]:
    """Shard sample counts; with ``moments`` every shard keeps at least 2 samples."""
    counts = split_samples(spp, shards)
    if moments and min(counts) < 2:
        counts = split_samples(spp, max(1, math.floor(spp / 2)))
    return counts
