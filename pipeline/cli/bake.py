"""``pavonine bake ASSET``: re-bake a feather asset's textures and portable materials in place."""

from __future__ import annotations

from pathlib import Path

import click

from pavonine.pipeline.cli.jsonout import json_option, say, write_json
from pavonine.pipeline.errors import one_line_errors


@click.command("bake")
@click.argument("asset", type=click.Path(path_type=Path))
@click.option(
    "--resolution",
    default=1024,
    show_default=True,
    type=click.IntRange(16, 8192),
    help="Texels along each side of the baked textures.",
)
@json_option
@click.option("-q", "--quiet", is_flag=True, help="No progress on stderr.")
@one_line_errors
def bake(asset: Path, resolution: int, json_target: str | None, quiet: bool) -> None:
    """Bake ASSET's feather materials into textures over the st atlas.

    ASSET is a feather asset's root layer (or its folder). For every PavonineFeatherAPI material:
    the base colour under the reference light and view, opacity, roughness and thin-film
    thickness/index/weight are written to textures/ beside its material layer; its
    UsdPreviewSurface reads them (opacityThreshold 0.5); <name>.mtlx and its USD MaterialX
    networks are rewritten, with a portable OpenPBR twin bound for the preview purpose.
    pavonine convert does the same for new assets. Reference: docs/pipeline.md, "Baking".
    """
    from rich.console import Console

    from pavonine.pipeline.bake.asset import bake_asset

    console = Console(stderr=True, quiet=quiet)
    with console.status("baking") as status:

        def report(material: str) -> None:
            status.update(f"baking {material}")

        result = bake_asset(asset, resolution, report)
    for entry in result.materials:
        say(
            f"baked   {entry['material']}: {resolution}x{resolution} textures, {entry['mtlx']}",
            json_target,
        )
    write_json(result.as_dict(), json_target)
