"""``pavonine render STAGE``: a USD stage to scene-linear EXRs (and display PNGs).

Every RenderProduct of the stage's RenderSettings is rendered (``--product`` picks some), each
with its camera, resolution and RenderVars as layers of one EXR, named by one rule
(:func:`pavonine.apps.farm.jobs.view_outputs`). One time code renders in this process, all
products in one Mitsuba scene; frames, turntables, several cameras, sample shards, ``--workers``
and ``--scheduler`` go through the farm (:mod:`pavonine.apps.farm`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import asdict, replace
from pathlib import Path
from typing import Any

import click

from pavonine.apps.cli.limits import limit_options
from pavonine.apps.cli.options import (
    display_options,
    emit_json,
    json_option,
    log,
    output_option,
    requires,
    say,
    show_progress,
    threads_option,
    warnings_to_log,
)
from pavonine.apps.cli.values import SEED, FiniteFloat
from pavonine.apps.farm.jobs import RenderJob, View
from pavonine.apps.farm.options import farm_options
from pavonine.base.errors import InputError, one_line_errors
from pavonine.render.integrator_settings import DEFAULT_SPP, MAX_DEPTH_LIMIT
from pavonine.render.limits import RenderLimits
from pavonine.render.options import RenderOptions

_PATH_OR_NULL = {"type": ["string", "null"]}

#: One image written (one per camera, RenderProduct and frame).
IMAGE_SCHEMA = {
    "type": "object",
    "required": ["exr", "png", "variance", "camera", "time", "resolution", "spp", "warnings"],
    "properties": {
        "exr": {"type": "string", "description": "scene-linear EXR written"},
        "png": {**_PATH_OR_NULL, "description": "display PNG written, if any"},
        "variance": {**_PATH_OR_NULL, "description": "per-pixel variance EXR, if any"},
        "label": {"type": "string", "description": "what tells it apart in a batch"},
        "camera": {**_PATH_OR_NULL, "description": "camera prim rendered through"},
        "time": {"type": ["number", "null"], "description": "USD time code"},
        "resolution": {
            "type": "array",
            "items": {"type": "integer"},
            "minItems": 2,
            "maxItems": 2,
            "description": "[width, height] in pixels",
        },
        "spp": {"type": "integer", "description": "samples per pixel (all shards)"},
        "variant": {"type": ["string", "null"], "description": "Mitsuba variant"},
        "product": {**_PATH_OR_NULL, "description": "the RenderProduct prim rendered, if any"},
        "channels": {
            "type": "array",
            "items": {"type": "string"},
            "description": "the EXR's channels (R, G, B, then the RenderVars' layers)",
        },
        "shards": {"type": "integer", "description": "sample shards merged into it"},
        "workers": {
            "type": "array",
            "items": {"type": "string"},
            "description": "Dask workers that rendered it (empty: this process)",
        },
        "warnings": {
            "type": "array",
            "items": {"type": "string"},
            "description": "the renderer's warnings for this image",
        },
        "seconds": {
            "type": ["number", "null"],
            "description": "seconds its render took (its tasks' sum on a farm)",
        },
        "sync_seconds": {
            "type": ["number", "null"],
            "description": "of which syncing the stage (a later frame: only what varies)",
        },
    },
}

JSON_SCHEMA = {
    "type": "object",
    "required": ["images", "spp", "seed", "variant", "seconds", "display", "warnings"],
    "properties": {
        "images": {"type": "array", "items": IMAGE_SCHEMA, "minItems": 1},
        "spp": {"type": "integer", "description": "samples per pixel asked for"},
        "seed": {"type": "integer"},
        "variant": {"type": ["string", "null"], "description": "Mitsuba variant"},
        "seconds": {"type": "number", "description": "wall time of the whole command's renders"},
        "display": {
            "type": ["object", "null"],
            "description": "OCIO config, display, view and exposure of the PNGs (null: no PNG)",
        },
        "warnings": {
            "type": "array",
            "items": {"type": "string"},
            "description": "what the renderer could not render as USD says (also on stderr)",
        },
        "workers": {
            "type": "integer",
            "description": "Dask workers the batch ran on (0: in this process)",
        },
        "scheduler": {**_PATH_OR_NULL, "description": "Dask scheduler address, if any"},
        "tasks": {
            "type": "array",
            "description": "per task of a batch: job, shard, spp, worker, seconds, bytes moved",
            "items": {"type": "object"},
        },
    },
}


@click.command("render")
@click.argument("stage", type=click.Path(dir_okay=False, path_type=Path))
@output_option(
    folder=False,
    help="Scene-linear EXR of the first image [default: its RenderProduct's productName, else "
    "STAGE's name with .exr, here]; further products and cameras are written beside it "
    "(OUT.<name>.exr), frames numbered (OUT.####.exr).",
)
@click.option(
    "--png",
    "png",
    is_flag=True,
    help="Also write a display PNG beside each EXR that holds the beauty (OUT.png).",
)
@click.option(
    "--png-out",
    type=click.Path(dir_okay=False, path_type=Path),
    default=None,
    metavar="FILE.png",
    help="Also write the display PNG, to FILE.png (implies --png; one image only).",
)
@click.option(
    "--spp",
    type=click.IntRange(min=1),
    default=None,
    help="Samples per pixel [default: the RenderSettings' mitsuba:sample_count, else 64].",
)
@click.option(
    "--max-depth",
    type=click.IntRange(min=-1, max=MAX_DEPTH_LIMIT),
    default=None,
    help="Longest path, in scattering vertices (-1: no limit; 1: emitters seen directly; 2: "
    "direct light) [default: the RenderSettings' mitsuba:integrator:max_depth, else 8].",
)
@click.option(
    "--motion-slices",
    type=click.IntRange(min=1),
    default=None,
    metavar="N",
    help="Time slices of a frame whose camera's shutter is open (motion blur; each a render "
    "pass of spp/N samples) [default: one per pixel the moving scene travels within the "
    "shutter, at most one per 8 spp and 16].",
)
@click.option(
    "--resolution",
    metavar="WxH",
    help="Image size of every image [default: each product's, else the RenderSettings', else "
    "512x512].",
)
@click.option(
    "--camera",
    "cameras",
    metavar="PRIM",
    multiple=True,
    help="Camera prim path, overriding the products' [default: each product's or the "
    "RenderSettings' camera, else the first camera, else a framing camera]; repeat it to render "
    "one product through several cameras (one image each).",
)
@farm_options
@click.option(
    "--time",
    "time_",
    type=FiniteFloat(),
    default=None,
    help="USD time code [default: the stage's start].",
)
@click.option(
    "--seed",
    type=SEED,
    default=0,
    show_default=True,
    help="Random seed; the same seed gives the same image.",
)
@click.option("--variant", default=None, help="Mitsuba variant [default: llvm_ad_spectral].")
@limit_options
@display_options
@threads_option
@json_option(JSON_SCHEMA)
@requires("mitsuba", "drjit")
@one_line_errors
def render(
    stage: Path,
    output: Path | None,
    png: bool,
    png_out: Path | None,
    spp: int | None,
    max_depth: int | None,
    motion_slices: int | None,
    resolution: str | None,
    cameras: tuple[str, ...],
    products: tuple[str, ...],
    frames: str | None,
    turntable: int | None,
    variance: bool,
    workers: int | None,
    scheduler: str | None,
    split: int | None,
    time_: float | None,
    seed: int,
    variant: str | None,
    display,
    json_target: str | None,
    limits: RenderLimits,
) -> None:
    """Render a USD STAGE with the spectral Mitsuba delegate.

    Every RenderProduct of the stage's RenderSettings is rendered (--product picks some), each
    with its camera, resolution and RenderVars as layers of one EXR. Without a camera the stage
    is framed automatically; without lights it is lit by a default sun (from the right) and sky,
    so a bare feather asset renders as it is. Anything the renderer cannot render as USD says is
    named in a warning.

    Frame ranges, turntables, several cameras and sample shards write numbered images
    (OUT.####.exr; docs/farm.md) and run on a Dask cluster: embedded (--workers N, the default
    for more than one image) or existing (--scheduler ADDRESS).

    Image size, samples per pixel and instance counts have ceilings (--max-pixels, --max-spp,
    --max-instances; docs/reliability.md), checked before the render starts. Ctrl-C stops a
    render with exit status 130 and writes nothing.
    """
    from pavonine.apps.farm import cli as farm
    from pavonine.base.commit import check_writable
    from pavonine.render.settings import parse_resolution

    # Everything the user typed is checked before the (possibly long) render.
    size = None if resolution is None else parse_resolution(resolution)
    if spp is not None:
        limits.check_spp(spp)
    if size is not None:
        limits.check_resolution(size, "--resolution")
    if output is not None and output.suffix.lower() != ".exr":
        raise InputError(str(output), "output must be an .exr file (use --png for a display image)")
    if png_out is not None and png_out.suffix.lower() != ".png":
        raise InputError(f"--png-out {png_out}", "must name a .png file")
    png = png or png_out is not None
    settings = farm.stage_settings(stage)
    if spp is None:
        spp = settings.sample_count or DEFAULT_SPP
        limits.check_spp(spp, settings.sample_count_field or "--spp")
    views = farm.render_views(settings, products, cameras)
    if farm.needs_farm(frames, turntable, workers, scheduler, split, cameras):
        batch = farm.plan_batch(
            stage, views, output, png, png_out, size, frames, turntable, variance, workers,
            scheduler, time_,
        )  # fmt: skip
        for path in (p for job in batch.jobs for p in _files(job)):
            check_writable(path)
        report = farm.render_batch(
            stage, batch, spp=spp, workers=workers, scheduler=scheduler, split=split, seed=seed,
            variant=variant, display=display, on_image=_show_with_warnings(), limits=limits,
            max_depth=max_depth, motion_slices=motion_slices,
        )  # fmt: skip
    else:
        from pavonine.apps.farm.jobs import plan

        jobs = plan(
            str(stage), output, views, None, time=time_, resolution=size, png=png,
            variance=variance,
        )  # fmt: skip
        if png_out is not None:
            if len(jobs) > 1:
                raise InputError(
                    "--png-out", f"names one file, the stage has {len(jobs)} RenderProducts: "
                    "use --png (a PNG beside each EXR) or pick one with --product",
                )  # fmt: skip
            jobs = [replace(jobs[0], png=png_out)]
        for path in (p for job in jobs for p in _files(job)):
            check_writable(path)
        options = RenderOptions(
            spp=spp, max_depth=max_depth, resolution=size, seed=seed, time=time_,
            variant=variant, moments=variance, progress=show_progress(), limits=limits,
            motion_slices=motion_slices,
        )  # fmt: skip
        report = _render_here(stage, views, jobs, options, display)
    images = report["images"]
    emit_json(
        json_target,
        {
            "spp": spp,
            "seed": seed,
            "variant": images[0]["variant"] if images else variant,
            "display": asdict(display) if any(i["png"] for i in images) else None,
            "warnings": sorted({w for image in images for w in image["warnings"]}),
            **report,
        },
    )


def _files(job: RenderJob) -> list[Path]:
    return [p for p in (job.output, job.png, job.variance) if p is not None]


def _show(record: dict[str, Any]) -> None:
    """One line per image written."""
    written = " + ".join(str(p) for p in (record["exr"], record["png"], record["variance"]) if p)
    w, h = record["resolution"]
    shards = f" in {record['shards']} shards" if record["shards"] > 1 else ""
    seconds = ""
    if record.get("seconds") is not None:
        seconds = f", {record['seconds']:.1f} s"
        if record.get("sync_seconds") is not None:
            seconds += f" (sync {record['sync_seconds']:.3f} s)"
    say(
        f"{written}: {w}×{h}, {record['spp']} spp{shards}, {record['variant']}, "
        f"channels {', '.join(record['channels'])}{seconds}"
    )


def _show_with_warnings() -> Callable[[dict[str, Any]], None]:
    """Shows a farm image's line and the warnings its tasks returned (workers do not log), each
    warning once per batch (every frame of a stage tends to return the same ones)."""
    said: set[str] = set()

    def show(record: dict[str, Any]) -> None:
        _show(record)
        for message in record["warnings"]:
            if message not in said:
                said.add(message)
                log.warning("%s", message)

    return show


def _render_here(
    stage: Path, views: list[View], jobs: list[RenderJob], options: RenderOptions, display
) -> dict[str, Any]:
    """Every view at one time code in this process, as ``options`` asks: one Mitsuba scene, a
    sensor per product."""
    from pavonine.apps.farm.render import image_record
    from pavonine.base.backend import BackendWarning
    from pavonine.render.api import render_products
    from pavonine.render.diagnostics import StageWarning
    from pavonine.render.imageio import RenderFiles, write_renders

    wanted = [v.product for v in views if v.product is not None]
    with warnings_to_log(StageWarning, BackendWarning):
        results = render_products(
            stage, options.but(camera=views[0].camera, products=wanted or None)
        )
    files, images = [], []
    for job, result in zip(jobs, results, strict=True):
        png = job.png if result.has_beauty else None
        if job.png is not None and png is None:
            log.warning("%s has no beauty layer: no PNG", result.product.path)
        layers = result.exr_layers()
        files.append(
            RenderFiles(
                job.output, result.rgb, result.metadata, png, layers, job.variance, result.variance
            )
        )
        images.append(
            image_record(
                result.metadata,
                exr=job.output,
                png=png,
                variance=job.variance,
                label=job.label,
                channels=[c for names, _ in layers for c in names],
                warnings=result.warnings,
            )
        )
    write_renders(files, display)
    for image in images:
        _show(image)
    return {
        "images": images,
        "seconds": results[0].metadata["seconds"],
        "workers": 0,
        "scheduler": None,
    }
