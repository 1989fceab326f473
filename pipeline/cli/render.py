"""``pavonine render STAGE``: a USD stage to a scene-linear EXR (and a display PNG)."""

from __future__ import annotations

import warnings
from pathlib import Path

import click

from pavonine.pipeline.errors import InputError, one_line_errors


@click.command("render")
@click.argument("stage", type=click.Path(dir_okay=False, path_type=Path))
@click.option(
    "-o",
    "--output",
    type=click.Path(dir_okay=False, path_type=Path),
    default=None,
    help="Scene-linear EXR of the (first) render product [default: its productName, else STAGE's "
    "name with .exr, here]. Further products are written beside it.",
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
@click.option(
    "--product",
    metavar="PRIM",
    default=None,
    help="Render only this RenderProduct [default: every product of the stage's RenderSettings].",
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
    camera: str | None,
    time_: float | None,
    seed: int,
    product: str | None,
    variant: str | None,
    view: str | None,
    quiet: bool,
) -> None:
    """Render a USD STAGE with the spectral Mitsuba delegate.

    Every RenderProduct of the stage's RenderSettings is rendered (each with its camera, resolution
    and RenderVars as layers of one EXR). Without a camera the stage is framed automatically;
    without lights it is lit by a default sun (from the right) and sky, so a bare feather asset
    renders as it is.
    """
    from pavonine.materials.colour import DEFAULT_VIEW
    from pavonine.render.api import render_products
    from pavonine.render.diagnostics import StageWarning
    from pavonine.render.imageio import RenderFiles, check_view, check_writable, write_renders
    from pavonine.render.settings import parse_resolution

    # Everything the user typed is checked before the (possibly long) render.
    size = None if resolution is None else parse_resolution(resolution)
    if output is not None and output.suffix.lower() != ".exr":
        raise InputError(str(output), "output must be an .exr file (use --png for a display image)")
    if png_out is not None and png_out.suffix.lower() != ".png":
        raise InputError(f"--png-out {png_out}", "must name a .png file")
    view = check_view(view or DEFAULT_VIEW)
    paths = output_paths(stage, output, planned_products(stage, product))
    for path in (*paths, png_out):
        if path is not None:
            check_writable(path)

    def show(message, category, filename, lineno, file=None, line=None):
        click.echo(f"warning: {message}", err=True)

    with warnings.catch_warnings():
        warnings.simplefilter("always", StageWarning)
        warnings.showwarning = show
        results = render_products(
            stage,
            spp=spp,
            resolution=size,
            seed=seed,
            camera=camera,
            time=time_,
            variant=variant,
            progress=not quiet,
            products=[product] if product else None,
        )
    files = []
    for index, (result, exr) in enumerate(zip(results, paths, strict=True)):
        wants_png = (png or png_out is not None) and result.has_beauty
        png_path = png_out if index == 0 and png_out is not None else exr.with_suffix(".png")
        files.append(
            RenderFiles(
                exr,
                result.rgb,
                result.metadata,
                png_path if wants_png else None,
                result.exr_layers(),
            )
        )
    if png_out is not None and not results[0].has_beauty:
        click.echo(
            f"warning: --png-out: {results[0].product.path} has no beauty layer; no PNG", err=True
        )
    write_renders(files, view=view)
    for out, result in zip(files, results, strict=True):
        written = [str(p) for p in (out.exr_path, out.png_path) if p is not None]
        w, h = result.metadata["resolution"]
        layers = ", ".join(c for layer in result.layers for c in layer.channels)
        click.echo(
            f"{' + '.join(written)}: {w}×{h}, {spp} spp, {result.metadata['variant']}, "
            f"{result.metadata['seconds']:.1f} s, channels {layers}"
        )


def planned_products(stage: Path, product: str | None) -> list:
    """The products ``render_products`` will render (read before rendering, to check outputs)."""
    from pavonine.render.api import choose_products
    from pavonine.render.delegate import open_stage
    from pavonine.render.diagnostics import Diagnostics
    from pavonine.render.settings import read_render_settings

    diag = Diagnostics()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        settings = read_render_settings(open_stage(stage, diag), diag)
    return choose_products(settings.products, [product] if product else None, False)


def output_paths(stage: Path, output: Path | None, products: list) -> list[Path]:
    """The EXR of each product: ``-o`` (or the first's productName, else STAGE.exr) for the first;
    the others' productName (or ``<first>.<product prim>.exr``) beside it, never twice the same."""
    first = output or _product_file(products[0]) or Path(stage.stem + ".exr")
    paths = [first]
    for product in products[1:]:
        name = None if output is not None else _product_file(product)
        prim = (product.path or "product").rsplit("/", 1)[-1]
        candidate = first.parent / (name.name if name else f"{first.stem}.{prim}.exr")
        n = 1
        while candidate in paths:
            candidate, n = first.parent / f"{first.stem}.{prim}_{n}.exr", n + 1
        paths.append(candidate)
    return paths


def _product_file(product) -> Path | None:
    """A product's ``productName`` when it names an EXR file."""
    name = getattr(product, "product_name", "")
    return Path(name) if name and name.lower().endswith(".exr") else None
