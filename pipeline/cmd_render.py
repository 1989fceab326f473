"""``pavonine render STAGE``: a USD stage to a scene-linear EXR (and a display PNG)."""

from __future__ import annotations

import warnings
from pathlib import Path

import click

from pavonine.pipeline.errors import InputError, one_line_errors


def _resolution(
    ctx: click.Context, param: click.Parameter, value: str | None
) -> tuple[int, int] | None:
    if value is None:
        return None
    try:
        w, h = (int(v) for v in value.lower().split("x"))
    except ValueError:
        raise click.BadParameter(f"expected WIDTHxHEIGHT (e.g. 512x512), got {value!r}") from None
    if w < 1 or h < 1:
        raise click.BadParameter(f"width and height must be positive, got {value!r}")
    return w, h


@click.command("render")
@click.argument("stage", type=click.Path(dir_okay=False, path_type=Path))
@click.option(
    "-o",
    "--output",
    type=click.Path(dir_okay=False, path_type=Path),
    default=None,
    help="Scene-linear EXR to write [default: STAGE's name with .exr, here].",
)
@click.option(
    "--png",
    "png",
    is_flag=False,
    flag_value="",
    default=None,
    help="Also write a display PNG (OCIO sRGB display); without a value, beside the EXR.",
)
@click.option(
    "--spp", type=click.IntRange(min=1), default=64, show_default=True, help="Samples per pixel."
)
@click.option(
    "--resolution",
    callback=_resolution,
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
@click.option("--view", default=None, help="OCIO view for the PNG [default: Un-tone-mapped].")
@click.option("-q", "--quiet", is_flag=True, help="No progress bar.")
@one_line_errors
def render(
    stage: Path,
    output: Path | None,
    png: str | None,
    spp: int,
    resolution,
    camera: str | None,
    time_: float | None,
    seed: int,
    variant: str | None,
    view: str | None,
    quiet: bool,
) -> None:
    """Render a USD STAGE with the spectral Mitsuba delegate.

    Without a camera the stage is framed automatically; without lights it is lit by a default
    sun (from the right) and sky, so a bare feather asset renders as it is.
    """
    from pavonine.render.api import render_stage
    from pavonine.render.diagnostics import StageWarning
    from pavonine.render.imageio import write_exr, write_png

    output = output or Path(stage.stem + ".exr")
    if output.suffix.lower() != ".exr":
        raise InputError(str(output), "output must be an .exr file (use --png for a display image)")
    png_path = None if png is None else (Path(png) if png else output.with_suffix(".png"))

    def show(message, category, filename, lineno, file=None, line=None):
        click.echo(f"warning: {message}", err=True)

    with warnings.catch_warnings():
        warnings.simplefilter("always", StageWarning)
        warnings.showwarning = show
        result = render_stage(
            stage,
            spp=spp,
            resolution=resolution,
            seed=seed,
            camera=camera,
            time=time_,
            variant=variant,
            progress=not quiet,
        )
    write_exr(output, result.rgb, result.metadata)
    written = [str(output)]
    if png_path is not None:
        if view:
            write_png(png_path, result.rgb, view=view)
        else:
            write_png(png_path, result.rgb)
        written.append(str(png_path))
    w, h = result.metadata["resolution"]
    click.echo(
        f"{' + '.join(written)}: {w}×{h}, {spp} spp, {result.metadata['variant']}, "
        f"{result.metadata['seconds']:.1f} s"
    )
