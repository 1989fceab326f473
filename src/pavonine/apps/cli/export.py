"""``pavonine export ASSET -o X.glb``: a feather asset as glTF 2.0 for game engines and the web;
``-o X.usdc`` (``.usd``, ``.usda``): as one portable USD layer, its barb curves as ribbon meshes
bound to their preview (:mod:`pavonine.pipeline.export.portable_usd`)."""

from __future__ import annotations

from pathlib import Path

import click

from pavonine.apps.cli.options import (
    emit_json,
    json_option,
    output_option,
    requires,
    say,
)
from pavonine.apps.cli.values import FiniteFloat, max_pixels_option
from pavonine.base.errors import InputError, one_line_errors
from pavonine.pipeline.export.framing import FRAMING_RADII

JSON_SCHEMA = {
    "type": "object",
    "required": ["asset", "output", "lod", "meshes", "materials", "bytes"],
    "properties": {
        "asset": {"type": "string", "description": "root layer of the asset exported"},
        "output": {"type": "string", "description": "the .glb written"},
        "lod": {"type": ["string", "null"], "description": "the 'lod' variant exported"},
        "geometry": {
            "type": ["string", "null"],
            "description": "the 'geometry' variant exported (portable USD only)",
        },
        "meshes": {
            "type": "array",
            "items": {
                "type": "object",
                "required": ["path", "vertices", "triangles"],
                "properties": {
                    "path": {"type": "string", "description": "the USD mesh prim"},
                    "vertices": {"type": "integer"},
                    "triangles": {"type": "integer"},
                },
            },
        },
        "materials": {"type": "array", "items": {"type": "string"}},
        "bytes": {"type": "integer", "description": "size of the .glb"},
        "eye": {
            "type": "array",
            "items": {"type": "number"},
            "description": "the viewer the feather's look is fitted for (the asset's units; "
            ".glb only)",
        },
        "pivot": {
            "type": "array",
            "items": {"type": "number"},
            "description": "the point whose vertical the fitted tilted views turn about (.glb "
            "only)",
        },
    },
}


@click.command("export")
@click.argument("asset", type=click.Path(path_type=Path))
@output_option(
    folder=False,
    required=True,
    help="The file to write: .glb (binary glTF 2.0), or .usdc/.usd/.usda (one portable USD "
    "layer: ribbon curves as meshes bound to their displayColor preview).",
)
@click.option(
    "--lod", default=None, help="Level of detail (the asset's 'lod' variant) [default: its own]."
)
@click.option(
    "--geometry",
    default=None,
    help="The asset's 'geometry' variant: sheet or barbs (ribbon meshes with their displayColor: "
    "COLOR_0 in glTF, a bound preview in USD) [default: its own].",
)
@click.option(
    "--eye",
    type=FiniteFloat(),
    nargs=3,
    default=None,
    metavar="X Y Z",
    help="The viewer the feather's look is fitted for, in the asset's space and units; the "
    "glTF's one film is fitted to the views from there, face-on and turned 40° about the "
    "vertical through the asset's centre [default: where pavonine view frames the asset, "
    f"{FRAMING_RADII:g} bounding radii in front].",
)
@json_option(JSON_SCHEMA)
@requires("pygltflib")
@max_pixels_option
@one_line_errors
def export(
    asset: Path,
    output: Path,
    lod: str | None,
    geometry: str | None,
    eye: tuple[float, float, float] | None,
    json_target: str | None,
) -> None:
    """Export ASSET (a root layer, or its folder) as a binary glTF 2.0 file or a portable USD.

    The meshes of one LOD in metres, +Y up, with normals and st as TEXCOORD_0; the feather as
    a base colour with alpha MASK (cutoff = opacityThreshold), a roughness, a
    KHR_materials_iridescence film and a KHR_materials_specular substrate, fitted per texel to
    the model's colour under the reference sun as seen from --eye, face-on and turned 40°;
    other materials from their UsdPreviewSurface constants. Needs a baked asset (pavonine
    convert or bake). Reference: docs/pipeline.md, "glTF export".

    With -o X.usdc (.usd, .usda): the asset flattened into one layer with its variants
    selected, each ribbon BasisCurves (the barbs) replaced by the flat ribbon mesh Pavonine
    renders, with its displayColor and bound to its UsdPreviewSurface preview, so hosts that
    ignore curve normals or bind no material to curves (Blender) show flat coloured barbs.
    Reference: docs/pipeline.md, "Portable USD export".
    """
    from pavonine.pipeline.export.gltf import export_gltf
    from pavonine.pipeline.export.portable_usd import export_portable_usd, is_portable_target
    from pavonine.render.curves.ribbons import plain_ribbons  # the renderer's own ribbons

    if is_portable_target(output):
        if eye is not None:
            raise InputError("--eye", "fits the glTF's look; a portable USD has none to fit")
        usd = export_portable_usd(asset, output, plain_ribbons, lod, geometry)
        triangles = sum(m["triangles"] for m in usd.meshes)
        say(
            f"wrote   {usd.output}: {len(usd.meshes)} ribbon meshes, {triangles:,} triangles, "
            f"bound to {', '.join(usd.materials)}, {usd.bytes:,} bytes"
        )
        emit_json(json_target, usd.as_dict())
        return

    report = export_gltf(asset, output, lod, geometry, eye, plain_ribbons)
    triangles = sum(m["triangles"] for m in report.meshes)
    say(
        f"wrote   {report.output}: {len(report.meshes)} meshes, {triangles:,} triangles, "
        f"{len(report.materials)} materials, {report.bytes:,} bytes"
    )
    emit_json(json_target, report.as_dict())
