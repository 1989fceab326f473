"""``pavonine bake ASSET``: re-bake a feather asset's textures and portable materials in place."""

from __future__ import annotations

from pathlib import Path

import click

from pavonine.apps.cli.options import (
    emit_json,
    json_option,
    progress_bar,
    requires,
    say,
)
from pavonine.apps.cli.values import max_pixels_option
from pavonine.base.errors import one_line_errors

JSON_SCHEMA = {
    "type": "object",
    "required": ["asset", "resolution", "materials"],
    "properties": {
        "asset": {"type": "string", "description": "root layer of the asset baked"},
        "resolution": {"type": "integer", "description": "texels along each side"},
        "materials": {
            "type": "array",
            "description": "one entry per PavonineFeatherAPI material",
            "items": {
                "type": "object",
                "required": ["material", "portable", "meshes", "layer", "textures", "mtlx"],
                "properties": {
                    "material": {"type": "string", "description": "the material's prim path"},
                    "portable": {"type": "string", "description": "its portable (OpenPBR) twin"},
                    "meshes": {"type": "array", "items": {"type": "string"}},
                    "layer": {"type": "string", "description": "the material layer rewritten"},
                    "textures": {
                        "type": "object",
                        "description": "texture name → file written",
                        "additionalProperties": {"type": "string"},
                    },
                    "mtlx": {"type": "string", "description": "the MaterialX document written"},
                },
            },
        },
    },
}


@click.command("bake")
@click.argument("asset", type=click.Path(path_type=Path))
@click.option(
    "--resolution",
    default=1024,
    show_default=True,
    type=click.IntRange(16, 8192),
    help="Texels along each side of the baked textures.",
)
@json_option(JSON_SCHEMA)
@requires("MaterialX")
@max_pixels_option
@one_line_errors
def bake(asset: Path, resolution: int, json_target: str | None) -> None:
    """Bake ASSET's feather materials into textures over the st atlas.

    ASSET is a feather asset's root layer (or its folder): a component model whose feather
    material is defined in a layer inside the asset's folder, the only place bake writes. A
    scene referencing feathers or a .usdz package is refused (bake the unpacked asset, then
    package it again). Maps of unequal aspect are refused as by convert. For every
    PavonineFeatherAPI material:
    the base colour under the reference light and view, opacity, roughness and thin-film
    thickness/index/weight are written to textures/ beside its material layer; its
    UsdPreviewSurface reads them (opacityThreshold 0.5); <name>.mtlx and its USD MaterialX
    networks are rewritten, with a portable OpenPBR twin bound for the preview purpose.
    pavonine convert does the same for new assets. Reference: docs/pipeline.md, "Baking".
    """
    from pavonine.pipeline.bake.asset import bake_asset

    with progress_bar() as progress:
        task = progress.add_task("baking", total=None)

        def report(material: str) -> None:
            progress.update(task, description=f"baking {material}")

        result = bake_asset(asset, resolution, report)
    for entry in result.materials:
        say(f"baked   {entry['material']}: {resolution}x{resolution} textures, {entry['mtlx']}")
    emit_json(json_target, result.as_dict())
