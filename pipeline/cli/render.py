"""``pavonine render STAGE``: a USD stage to a scene-linear EXR (and a display PNG)."""

from __future__ import annotations

import warnings
from pathlib import Path

import click

from pavonine.pipeline.errors import InputError, one_line_errors
from pavonine.pipeline.farm.options import farm_options


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
    is_flag=True,
    help="Also write a display PNG (OCIO sRGB display) beside the EXR (OUTPUT with .png).",
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
@click.option("--view", default=None, help="OCIO view for the PNG [default: Un-tone-mapped].")
@click.option("-q", "--quiet", is_flag=True, help="No progress bar.")
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
    view: str | None,
    quiet: bool,
) -> None:
    """Render a USD STAGE with the spectral Mitsuba delegate.

    Without a camera the stage is framed automatically; without lights it is lit by a default
    sun (from the right) and sky, so a bare feather asset renders as it is.

    Frame ranges, turntables, several cameras or RenderProducts write numbered images
    (OUT.####.exr; docs/farm.md) and run on a Dask cluster: embedded (--workers N, the default
    for more than one image) or existing (--scheduler ADDRESS).
    """
    from pavonine.materials.colour import DEFAULT_VIEW
    from pavonine.render.api import render_stage
    from pavonine.render.diagnostics import StageWarning
    from pavonine.render.imageio import check_view, check_writable, write_render
    from pavonine.render.settings import parse_resolution

    # Everything the user typed is checked before the (possibly long) render.
    size = None if resolution is None else parse_resolution(resolution)
    batch = (frames, turntable, products, all_products, variance, scheduler, split)
    if len(cameras) > 1 or any(batch) or workers:
        from pavonine.pipeline.farm.cli import render_batch

        render_batch(
            stage, output, png, png_out, spp, size, cameras, products, all_products, frames,
            turntable, variance, workers, scheduler, split, time_, seed, variant, view, quiet,
        )  # fmt: skip
        return
    camera = cameras[0] if cameras else None
    output = output or Path(stage.stem + ".exr")
    if output.suffix.lower() != ".exr":
        raise InputError(str(output), "output must be an .exr file (use --png for a display image)")
    if png_out is not None and png_out.suffix.lower() != ".png":
        raise InputError(f"--png-out {png_out}", "must name a .png file")
    png_path = png_out or (output.with_suffix(".png") if png else None)
    view = check_view(view or DEFAULT_VIEW)
    for path in (output, png_path):
        if path is not None:
            check_writable(path)

    def show(message, category, filename, lineno, file=None, line=None):
        click.echo(f"warning: {message}", err=True)

    with warnings.catch_warnings():
        warnings.simplefilter("always", StageWarning)
        warnings.showwarning = show
        result = render_stage(
            stage,
            spp=spp,
            resolution=size,
            seed=seed,
            camera=camera,
            time=time_,
            variant=variant,
            progress=not quiet,
        )
    write_render(output, result.rgb, result.metadata, png_path=png_path, view=view)
    written = [str(p) for p in (output, png_path) if p is not None]
    w, h = result.metadata["resolution"]
    click.echo(
        f"{' + '.join(written)}: {w}×{h}, {spp} spp, {result.metadata['variant']}, "
        f"{result.metadata['seconds']:.1f} s"
    )
