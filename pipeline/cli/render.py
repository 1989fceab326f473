"""``pavonine render STAGE``: a USD stage to a scene-linear EXR (and a display PNG)."""

from __future__ import annotations

from dataclasses import asdict
from pathlib import Path

import click

from pavonine.pipeline.cli.options import (
    display_options,
    emit_json,
    json_option,
    output_option,
    requires,
    say,
    show_progress,
    threads_option,
    warnings_to_log,
)
from pavonine.pipeline.errors import InputError, one_line_errors
from pavonine.pipeline.farm.options import farm_options

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
    folder=False, help="Scene-linear EXR to write [default: STAGE's name with .exr, here]."
)
@click.option(
    "--png",
    "png",
    is_flag=True,
    help="Also write a display PNG beside the EXR (OUTPUT with .png).",
)
@click.option(
    "--png-out",
    type=click.Path(dir_okay=False, path_type=Path),
    default=None,
    metavar="FILE.png",
    help="Also write the display PNG, to FILE.png (implies --png).",
)
@click.option(
    "--spp", type=click.IntRange(min=1), default=64, show_default=True, help="Samples per pixel."
)
@click.option(
    "--resolution",
    metavar="WxH",
    help="Image size [default: the stage's RenderSettings, else 512x512].",
)
@click.option(
    "--camera",
    "cameras",
    metavar="PRIM",
    multiple=True,
    help="Camera prim path [default: RenderSettings camera, else the first camera, else a framing "
    "camera]; repeat it to render several cameras (one image each).",
)
@farm_options
@click.option(
    "--time", "time_", type=float, default=None, help="USD time code [default: the stage's start]."
)
@click.option(
    "--seed",
    type=int,
    default=0,
    show_default=True,
    help="Random seed; the same seed gives the same image.",
)
@click.option("--variant", default=None, help="Mitsuba variant [default: llvm_ad_spectral].")
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
    spp: int,
    resolution: str | None,
    cameras: tuple[str, ...],
    products: tuple[str, ...],
    all_products: bool,
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
) -> None:
    """Render a USD STAGE with the spectral Mitsuba delegate.

    Without a camera the stage is framed automatically; without lights it is lit by a default
    sun (from the right) and sky, so a bare feather asset renders as it is. Anything the
    renderer cannot render as USD says is named in a warning.

    Frame ranges, turntables, several cameras or RenderProducts write numbered images
    (OUT.####.exr; docs/farm.md) and run on a Dask cluster: embedded (--workers N, the default
    for more than one image) or existing (--scheduler ADDRESS).
    """
    from pavonine.backend import BackendWarning
    from pavonine.pipeline.farm.render import image_record
    from pavonine.render.api import render_stage
    from pavonine.render.diagnostics import StageWarning
    from pavonine.render.imageio import check_writable, write_render
    from pavonine.render.settings import parse_resolution

    # Everything the user typed is checked before the (possibly long) render.
    size = None if resolution is None else parse_resolution(resolution)
    batch = (frames, turntable, products, all_products, variance, scheduler, split)
    if len(cameras) > 1 or any(batch) or workers:
        from pavonine.pipeline.farm.cli import render_batch

        render_batch(
            stage, output, png, png_out, spp, size, cameras, products, all_products, frames,
            turntable, variance, workers, scheduler, split, time_, seed, variant, display,
            json_target,
        )  # fmt: skip
        return
    camera = cameras[0] if cameras else None
    output = output or Path(stage.stem + ".exr")
    if output.suffix.lower() != ".exr":
        raise InputError(str(output), "output must be an .exr file (use --png for a display image)")
    if png_out is not None and png_out.suffix.lower() != ".png":
        raise InputError(f"--png-out {png_out}", "must name a .png file")
    png_path = png_out or (output.with_suffix(".png") if png else None)
    for path in (output, png_path):
        if path is not None:
            check_writable(path)

    with warnings_to_log(StageWarning, BackendWarning):
        result = render_stage(
            stage,
            spp=spp,
            resolution=size,
            seed=seed,
            camera=camera,
            time=time_,
            variant=variant,
            progress=show_progress(),
        )
    write_render(output, result.rgb, result.metadata, png_path=png_path, display=display)
    written = [str(p) for p in (output, png_path) if p is not None]
    w, h = result.metadata["resolution"]
    say(
        f"{' + '.join(written)}: {w}×{h}, {spp} spp, {result.metadata['variant']}, "
        f"{result.metadata['seconds']:.1f} s"
    )
    image = image_record(
        result.metadata,
        exr=output,
        png=png_path,
        label=output.name,
        warnings=result.warnings,
    )
    emit_json(
        json_target,
        {
            "images": [image],
            "spp": spp,
            "seed": seed,
            "variant": result.metadata["variant"],
            "seconds": result.metadata["seconds"],
            "display": None if png_path is None else asdict(display),
            "warnings": list(result.warnings),
            "workers": 0,
            "scheduler": None,
        },
    )
