"""``render_stage``: a USD stage to a scene-linear spectral image, progressively, in passes.

The stage is translated by :class:`~pavonine.render.delegate.StageDelegate`, rendered with
Mitsuba's ``path`` integrator in the chosen spectral variant (``llvm_ad_spectral`` by default),
with a box pixel filter so that each pixel is the plain mean of its samples. Passes use seeds
derived from ``seed`` and are averaged; the same seed gives the same image.

With ``moments=True`` the image is rendered in at least min(spp, 16) passes and the per-pixel
variance of the final estimate is ``s² / P`` with ``s²`` the unbiased variance of the P pass
means (in linear Rec.709, so exact for the RGB that is reported).
"""

from __future__ import annotations

import gc
import os
import re
import time as _time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from pavonine.backend import select_variant
from pavonine.pipeline.errors import InputError
from pavonine.render import camera as camera_translator
from pavonine.render import instance_primvars, lights
from pavonine.render.delegate import StageDelegate, open_stage, render_time
from pavonine.render.diagnostics import Diagnostics, first_line
from pavonine.render.imageio import write_exr, write_png
from pavonine.render.settings import DEFAULT_RESOLUTION, read_render_settings

__all__ = ["RenderResult", "render_stage", "write_exr", "write_png"]

LANES_PER_PASS = 1 << 22  # samples in flight per pass (memory bound of the LLVM wavefront)
MIN_MOMENT_PASSES = 16
MAX_DEPTH = 8
SEED_STRIDE = 65537


@dataclass
class RenderResult:
    """A finished render."""

    rgb: np.ndarray  # H×W×3 float32, scene-linear Rec.709 (sRGB primaries, D65)
    variance: np.ndarray | None  # H×W×3 variance of each pixel's estimate (``moments=True``)
    metadata: dict[str, Any]
    warnings: list[str] = field(default_factory=list)


def render_stage(
    stage_path: str | os.PathLike,
    *,
    spp: int,
    resolution: tuple[int, int] | None = None,
    seed: int = 0,
    camera: str | None = None,
    time: float | None = None,
    variant: str | None = None,
    moments: bool = False,
    progress: bool = True,
) -> RenderResult:
    """Render ``stage_path`` with ``spp`` samples per pixel; see the module docstring."""
    if spp < 1:
        raise InputError("spp", f"must be at least 1, got {spp}")
    if moments and spp < 2:
        raise InputError("spp", "moments need at least 2 samples per pixel")
    if resolution is not None and (len(resolution) != 2 or min(resolution) < 1):
        raise InputError("resolution", f"must be two positive integers, got {resolution}")
    backend = _select(variant)
    import drjit as dr
    import mitsuba as mi

    started = _time.perf_counter()
    diag = Diagnostics()
    stage = open_stage(stage_path, diag)
    time_code = render_time(stage, time)
    delegate = StageDelegate(stage, time_code, diag)
    synced = delegate.sync()
    settings = read_render_settings(stage, diag)
    width, height = resolution or settings.resolution or DEFAULT_RESOLUTION
    film_width = max(1, round(width * settings.pixel_aspect))  # Mitsuba's pixels are square

    camera_path = camera or settings.camera
    if camera_path is not None and camera_path not in synced.cameras:
        known = ", ".join(sorted(synced.cameras)) or "none"
        where = "--camera" if camera else f"{settings.path}.camera"
        raise InputError(
            where, f"no visible camera at {camera_path} (cameras in the stage: {known})"
        )
    if camera_path is None and synced.cameras:
        camera_path = sorted(synced.cameras)[0]
    if synced.bounds is None:
        diag.warn(str(stage_path), "the stage has no renderable geometry")
    if camera_path is not None:
        prim = synced.cameras[camera_path]
        try:
            sensor = camera_translator.translate_camera(
                prim,
                delegate.xforms.world(prim),
                time_code,
                (width, height),
                settings.pixel_aspect,
                settings.conform,
                diag,
            )
        except ValueError as exc:
            raise InputError(camera_path, str(exc).split(": ", 1)[-1]) from None
    else:
        bounds = synced.bounds or (np.full(3, -1.0), np.full(3, 1.0))
        sensor = camera_translator.framing_camera(bounds, synced.up_axis)
    emitters = dict(synced.emitters)
    if not emitters and not synced.mesh_lights:
        up = np.eye(3)[2 if synced.up_axis == "Z" else 1]
        center, radius = delegate.bounding_sphere()
        emitters = lights.default_lights(sensor.to_world, up, center, radius)

    scene_dict: dict[str, Any] = {
        "type": "scene",
        "integrator": {"type": "path", "max_depth": MAX_DEPTH},
        "sensor": {
            **sensor.sensor,
            "film": {
                "type": "hdrfilm",
                "width": int(film_width),
                "height": int(height),
                "pixel_format": "rgb",
                "rfilter": {"type": "box"},
            },
            "sampler": {"type": "independent"},
        },
    }
    scene_dict.update(scene_objects(synced.shapes, emitters))
    gc.collect()  # see _render_pass
    try:
        scene = mi.load_dict(scene_dict)
    except Exception as exc:
        raise InputError(
            os.fspath(stage_path), f"Mitsuba could not build the scene: {first_line(exc)}"
        ) from None
    instance_primvars.bind(scene, delegate.table, delegate.feather_bsdfs)

    spp_pass = _samples_per_pass(spp, film_width * height, moments)
    passes = spp // spp_pass
    resample = _pixel_aspect_resampler(film_width, width)
    total = np.zeros((height, width, 3), dtype=np.float64)
    total_sq = np.zeros_like(total) if moments else None
    from rich.console import Console
    from rich.progress import (
        BarColumn,
        Progress,
        TextColumn,
        TimeElapsedColumn,
        TimeRemainingColumn,
    )

    columns = (
        TextColumn(f"render {os.path.basename(os.fspath(stage_path))} {width}×{height}"),
        BarColumn(),
        TextColumn("{task.completed}/{task.total} spp"),
        TimeElapsedColumn(),
        TimeRemainingColumn(),
    )
    with Progress(
        *columns, console=Console(stderr=True), disable=not progress, transient=False
    ) as bar:
        task = bar.add_task("render", total=spp)
        for index in range(passes):
            pass_seed = (seed * SEED_STRIDE + index) & 0xFFFFFFFF
            image = _render_pass(mi, scene, spp_pass, pass_seed)
            if resample is not None:
                image = np.einsum("jk,ikc->ijc", resample, image)
            total += image
            if total_sq is not None:
                total_sq += image * image
            bar.update(task, advance=spp_pass)
    dr.sync_thread()
    rgb = (total / passes).astype(np.float32)
    variance = None
    if total_sq is not None:
        mean = total / passes
        sample_var = np.maximum(total_sq / passes - mean * mean, 0.0) * passes / (passes - 1)
        variance = (sample_var / passes).astype(np.float32)

    metadata = {
        "stage": os.fspath(stage_path),
        "variant": backend.variant,
        "spp": int(spp),
        "seed": int(seed),
        "resolution": [int(width), int(height)],
        "camera": camera_path or "(framing camera)",
        "time": "default"
        if time_code.IsDefault()
        else ("earliest" if time_code.IsEarliestTime() else float(time_code.GetValue())),
        "passes": int(passes),
        "seconds": round(_time.perf_counter() - started, 3),
        "colorspace": "lin_rec709_scene",
        "versions": _versions(),
    }
    return RenderResult(rgb=rgb, variance=variance, metadata=metadata, warnings=list(diag.messages))


def _render_pass(mi, scene, spp: int, seed: int) -> np.ndarray:
    """One ``mi.render`` pass as H×W×3 float64, with Python's cyclic garbage collector paused.

    Dr.Jit traces every registered BSDF instance when it records a virtual call; a Python-defined
    BSDF (the feather) of an earlier, unreachable scene freed by a collector run *during* that
    tracing leaves a dangling pointer and Mitsuba segfaults. :func:`render_stage` collects before
    building the scene, and no collection runs while a pass is traced.
    """
    enabled = gc.isenabled()
    gc.disable()
    try:
        image = mi.render(scene, spp=spp, seed=seed)
    finally:
        if enabled:
            gc.enable()
    return np.asarray(image, dtype=np.float64)[..., :3]


def _select(variant: str | None):
    try:
        return select_variant(variant)
    except (ImportError, ValueError, AttributeError) as exc:
        raise InputError(
            "--variant", f"cannot use Mitsuba variant {variant!r}: {first_line(exc)}"
        ) from None


def _samples_per_pass(spp: int, pixels: int, moments: bool) -> int:
    """Largest divisor of ``spp`` within the lane budget (and giving enough passes for moments)."""
    limit = max(1, LANES_PER_PASS // max(pixels, 1))
    if moments:
        limit = min(limit, max(1, spp // MIN_MOMENT_PASSES))
    return max(d for d in range(1, min(spp, limit) + 1) if spp % d == 0)


def _pixel_aspect_resampler(film_width: int, width: int) -> np.ndarray | None:
    """Box-resampling matrix (width × film_width) from square film pixels to wide/narrow pixels."""
    if film_width == width:
        return None
    edges = np.linspace(0.0, film_width, width + 1)
    lo, hi = edges[:-1, None], edges[1:, None]
    k = np.arange(film_width)[None, :]
    overlap = np.clip(np.minimum(hi, k + 1) - np.maximum(lo, k), 0.0, None)
    return overlap / overlap.sum(axis=1, keepdims=True)


def _versions() -> dict[str, str]:
    import drjit
    import mitsuba
    from pxr import Usd

    from pavonine import __version__

    return {
        "pavonine": __version__,
        "mitsuba": mitsuba.__version__,
        "drjit": drjit.__version__,
        "usd": ".".join(str(v) for v in Usd.GetVersion()),
    }


def scene_objects(shapes: dict[str, Any], emitters: dict[str, Any]) -> dict[str, Any]:
    """Shapes and emitters keyed by unique Mitsuba scene-dict ids.

    Prim-derived names (``/a/b#0``, ``/Sun``) become ``mesh_a__b_0`` / ``light_Sun`` (Mitsuba
    ids may not contain ``.`` or ``/``); a name that maps onto an id already taken gets a ``_N``
    suffix, so ``/a/b`` and ``/a__b`` stay two objects. Internal ids (``shapegroup_N``,
    ``instance_N``, ``default_sun``) are kept verbatim, since instances refer to them.
    """
    items = [("mesh", name, entry) for name, entry in shapes.items()]
    items += [("light", name, entry) for name, entry in emitters.items()]
    taken = {name for _, name, _ in items if not name.startswith("/")}
    objects: dict[str, Any] = {}
    for prefix, name, entry in items:
        key = name
        if name.startswith("/"):
            base = f"{prefix}_" + re.sub(r"[^A-Za-z0-9_]", "_", name[1:].replace("/", "__"))
            key, n = base, 1
            while key in taken:
                key, n = f"{base}_{n}", n + 1
            taken.add(key)
        objects[key] = entry
    return objects
