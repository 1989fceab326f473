"""Render jobs: RenderProducts, cameras, frame ranges and turntables → one image each, and the
file names they are written to.

Names (``docs/render.md``, ``docs/farm.md``), one rule for every image of a call
(:func:`view_outputs`, then :func:`output_name` per frame):

* the first view (RenderProduct, or camera) is written to ``-o OUT.exr``; without ``-o`` to its
  product's ``productName`` when that names an ``.exr``, else ``STAGE.exr`` here;
* every other view to its ``productName`` beside the first (without ``-o``), else
  ``OUT.<name>.exr`` (its product or camera prim's name; ``_1``, ``_2`` … if that is taken);
* frames are numbered ``….####.exr``, the time code zero-padded to four digits
  (``OUT.0012.exr``, ``OUT.-003.exr``, ``OUT.Wide.0012.exr``); ``OUT`` may carry the ``####``
  itself (``shot.####.beauty.exr``).

The variance of an image, when asked for, is ``….variance.exr`` beside it, and its display PNG
``….png``.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path

from pavonine.base.errors import InputError

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
    camera: str | None = None  # overrides the product's camera
    product: str | None = None  # the RenderProduct prim (None: the stage has none)
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
    """What one image looks through: a RenderProduct (its camera, resolution and RenderVars)
    and/or a camera overriding the product's."""

    name: str  # the product's or camera's prim name ("" for a stage without products)
    camera: str | None = None
    product: str | None = None
    product_name: str = ""  # the product's ``productName``


def _product_file(view: View) -> Path | None:
    """A view's ``productName`` when it names an EXR file."""
    name = view.product_name
    return Path(name) if name and name.lower().endswith(".exr") else None


def view_outputs(stage: str | Path, output: Path | None, views: list[View]) -> list[Path]:
    """The EXR of each view at one time (module docstring): ``-o`` (or the first's productName,
    else STAGE.exr) for the first; the others' productName (without ``-o``) or
    ``OUT.<name>.exr`` beside it, never twice the same."""
    first = output or _product_file(views[0]) or Path(Path(stage).stem + ".exr")
    paths = [first]
    for view in views[1:]:
        named = None if output is not None else _product_file(view)
        label = view.name or "view"
        options = [first.parent / named.name] if named else []
        options.append(output_name(first, label, None))
        candidate, n = next((c for c in options if c not in paths), None), 1
        while candidate is None or candidate in paths:
            candidate, n = output_name(first, f"{label}_{n}", None), n + 1
        paths.append(candidate)
    return paths


def plan(
    stage: str,
    output: Path | None,
    views: list[View],
    frames: list[int] | None,
    *,
    time: float | None = None,
    resolution: tuple[int, int] | None = None,
    png: bool = False,
    variance: bool = False,
    named_after: str | Path | None = None,
) -> list[RenderJob]:
    """Every image of a call: each view at each frame (or at ``time``). Outputs are named after
    ``named_after`` (default ``stage``) when there is no ``-o``."""
    jobs = []
    bases = view_outputs(named_after or stage, output, views)
    label_views = len(views) > 1
    for view, base in zip(views, bases, strict=True):
        for frame in frames if frames is not None else [None]:
            exr = output_name(base, None, frame)
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
                    product=view.product,
                    time=float(frame) if frame is not None else time,
                    resolution=resolution,
                    label=label or exr.name,
                    png=sibling(exr, ".png") if png else None,
                    variance=variance_path(exr) if variance else None,
                )
            )
    names = [job.output for job in jobs]
    if len(set(names)) != len(names):
        raise InputError("--output", "two images of this call would get the same file name")
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
