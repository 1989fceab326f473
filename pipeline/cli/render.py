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

JSON_SCHEMA = {
    "type": "object",
    "required": ["exr", "png", "resolution", "spp", "seed", "variant", "seconds", "warnings"],
    "properties": {
        "exr": {"type": "string", "description": "scene-linear EXR written"},
        "png": {"type": ["string", "null"], "description": "display PNG written, if any"},
        "resolution": {
            "type": "array",
            "items": {"type": "integer"},
            "minItems": 2,
            "maxItems": 2,
            "description": "[width, height] in pixels",
        },
        "spp": {"type": "integer", "description": "samples per pixel"},
        "seed": {"type": "integer"},
        "camera": {"type": "string", "description": "camera prim used"},
        "variant": {"type": "string", "description": "Mitsuba variant"},
        "seconds": {"type": "number", "description": "render wall time"},
        "display": {
            "type": ["object", "null"],
            "description": "OCIO config, display, view and exposure of the PNG",
        },
        "warnings": {
            "type": "array",
            "items": {"type": "string"},
            "description": "what the renderer could not render as USD says (also on stderr)",
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
    metavar="PRIM",
    help="Camera prim path [default: RenderSettings camera, else the first camera, else a framing camera].",
)
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
    camera: str | None,
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
    """
    from pavonine.backend import BackendWarning
    from pavonine.render.api import render_stage
    from pavonine.render.diagnostics import StageWarning
    from pavonine.render.imageio import check_writable, write_render
    from pavonine.render.settings import parse_resolution

    # Everything the user typed is checked before the (possibly long) render.
    size = None if resolution is None else parse_resolution(resolution)
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
    emit_json(
        json_target,
        {
            "exr": str(output),
            "png": None if png_path is None else str(png_path),
            "resolution": [w, h],
            "spp": spp,
            "seed": seed,
            "camera": str(result.metadata.get("camera", "")),
            "variant": result.metadata["variant"],
            "seconds": result.metadata["seconds"],
            "display": None if png_path is None else asdict(display),
            "warnings": list(result.warnings),
        },
    )
