"""The barbs in USD: one ``BasisCurves`` prim of ribbons, its baked colours and the preview
material that shows them in any viewer.

``NAME_geo_barbs.usdc`` holds ``/NAME/Geom/Barbs``: linear, non-periodic curves, one per barb,
with authored ``normals`` (vertex: the vane normal, so USD draws each curve as a ribbon facing
it), ``widths`` (vertex, cm: the barb with its barbules' span) and vertex primvars sampled from the
maps (names in :data:`PRIMVARS`, and ``primvars:pavonine_featherUV`` as on the sheet);
``primvars:pavonine_barbId`` is uniform (one per barb), ``primvars:displayColor`` (vertex)
the baked preview colour, and ``primvars:pavonine_barbules`` (vertex) asks Pavonine to render
each barb's ramus and barbules (:mod:`pavonine.render.barbules`), reaching that share of the half
width past the authored edge (:func:`barbule_reach`). No ``pavonine_barbTangent``: on a curve the barb direction is its
tangent ``dP/du`` (the renderer's contract, docs/render.md). The asset's root layer payloads it
in the ``barbs`` variant of its ``geometry`` variant set (:mod:`pavonine.pipeline.convert.asset`).
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import numpy as np

from pavonine.base.truncation import save_whole
from pavonine.materials.parameters import FeatherParameters
from pavonine.pipeline.convert.barb_polylines import BarbCurves
from pavonine.schemas.primvars import (
    BARB_ID_PRIMVAR,
    BARBULES_PRIMVAR,
    FEATHER_UV_PRIMVAR,
    INPUT_PRIMVARS,
)

BARBS = "Barbs"
#: Preview material of the barbs (preview-purpose binding): their baked ``displayColor``.
BARBS_PREVIEW = "FeatherBarbsPreview"
#: Vertex primvars sampled along each barb: primvar name → :class:`BarbCurves` field.
PRIMVARS = {
    INPUT_PRIMVARS["ocellar"]: "ocellar_class",
    INPUT_PRIMVARS["gradation"]: "gradation",
    INPUT_PRIMVARS["melanin"]: "melanin",
    INPUT_PRIMVARS["angle"]: "barbule_angle_deg",
}
BARB_ID = BARB_ID_PRIMVAR
#: Vertex float: the curves carry barbules (the renderer's ramus and barbule pattern), reaching
#: this share of the authored half width past the authored edge (:func:`barbule_reach`).
BARBULES = BARBULES_PRIMVAR
#: Below this alpha coverage the barbs are free filaments: their barbules reach no further than
#: the authored edge (:func:`barbule_reach`).
LOOSE_COVERAGE = 0.75


def barbule_reach(coverage: np.ndarray) -> np.ndarray:
    """How far past a barb's authored edge its barbules reach (share of its half width):
    :data:`~pavonine.materials.barbule_pattern.BARBULE_OVERLAP` where the vane is closed
    (coverage 1: the eye's barbules interlock and overlap their neighbours'), none where the
    coverage is below :data:`LOOSE_COVERAGE` and barbs hang loose as free filaments (Dakin et
    al. 2016, PLoS ONE 11: e0152759), linear between: the free filaments cover the share of the
    vane the sheet's alpha does."""
    from pavonine.materials.barbule_pattern import BARBULE_OVERLAP

    c = np.asarray(coverage, dtype=np.float64)
    return BARBULE_OVERLAP * np.clip((c - LOOSE_COVERAGE) / (1.0 - LOOSE_COVERAGE), 0.0, 1.0)


#: GGX roughness of the barbs' preview surface: the crescent spread is in the bake's colour.
PREVIEW_ROUGHNESS = 0.45


def barb_colors(
    barbs: BarbCurves, maps: Mapping[str, np.ndarray], params: FeatherParameters
) -> np.ndarray:
    """Baked preview colour (linear Rec. 709) of every barb vertex: the sheet's bake
    (:func:`pavonine.pipeline.bake.appearance.texel_appearance`, same reference light and view)
    evaluated at the barb's vertices in its own frame (vane normal, barb tangent)."""
    from pavonine.pipeline.bake.appearance import texel_appearance
    from pavonine.pipeline.bake.texels import SurfaceTexels
    from pavonine.schemas.authoring import preview_roughness

    across = np.cross(barbs.tangent, barbs.normals)
    samples = SurfaceTexels(
        resolution=1,
        index=np.arange(barbs.vertex_count),
        feather_uv=barbs.feather_uv,
        normal=barbs.normals,
        barb=barbs.tangent,
        across=across,
    )
    return texel_appearance(samples, maps, params, preview_roughness(params)).base_color


def write_barbs_layer(path: Path, name: str, barbs: BarbCurves, geom: str = "Geom") -> None:
    """Write ``/NAME/<geom>/Barbs`` (module docstring) into a new crate layer at ``path``."""
    from pxr import Sdf, Usd, UsdGeom, Vt

    layer = Sdf.Layer.CreateNew(str(path))
    if layer is None:
        raise OSError(f"{path}: cannot create USD layer")
    stage = Usd.Stage.Open(layer)
    UsdGeom.Xform.Define(stage, f"/{name}")
    UsdGeom.Scope.Define(stage, f"/{name}/{geom}")
    UsdGeom.SetStageMetersPerUnit(stage, 0.01)
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
    stage.SetDefaultPrim(stage.GetPrimAtPath(f"/{name}"))
    curves = UsdGeom.BasisCurves.Define(stage, f"/{name}/{geom}/{BARBS}")
    curves.CreateTypeAttr(UsdGeom.Tokens.linear)
    curves.CreateWrapAttr(UsdGeom.Tokens.nonperiodic)
    curves.CreateCurveVertexCountsAttr(Vt.IntArray.FromNumpy(barbs.counts.astype(np.int32)))
    curves.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(barbs.points.astype(np.float32)))
    curves.CreateNormalsAttr(Vt.Vec3fArray.FromNumpy(barbs.normals.astype(np.float32)))
    curves.SetNormalsInterpolation(UsdGeom.Tokens.vertex)
    curves.CreateWidthsAttr(Vt.FloatArray.FromNumpy(barbs.widths.astype(np.float32)))
    curves.SetWidthsInterpolation(UsdGeom.Tokens.vertex)
    curves.CreateExtentAttr(Vt.Vec3fArray.FromNumpy(barbs.extent().astype(np.float32)))
    curves.CreateDoubleSidedAttr(True)
    primvars = UsdGeom.PrimvarsAPI(curves)
    vertex = UsdGeom.Tokens.vertex
    primvars.CreatePrimvar(FEATHER_UV_PRIMVAR, Sdf.ValueTypeNames.TexCoord2fArray, vertex).Set(
        Vt.Vec2fArray.FromNumpy(barbs.feather_uv.astype(np.float32))
    )
    for primvar, attribute in PRIMVARS.items():
        values = getattr(barbs, attribute)
        if attribute == "ocellar_class":
            kind, array = (
                Sdf.ValueTypeNames.IntArray,
                Vt.IntArray.FromNumpy(values.astype(np.int32)),
            )
        else:
            kind, array = (
                Sdf.ValueTypeNames.FloatArray,
                Vt.FloatArray.FromNumpy(values.astype(np.float32)),
            )
        primvars.CreatePrimvar(primvar, kind, vertex).Set(array)
    primvars.CreatePrimvar(BARB_ID, Sdf.ValueTypeNames.IntArray, UsdGeom.Tokens.uniform).Set(
        Vt.IntArray.FromNumpy(barbs.barb_id.astype(np.int32))
    )
    # Pavonine renders the ramus and barbules under each barb (pavonine.render.barbules), their
    # reach past the authored edge where the vane is closed.
    primvars.CreatePrimvar(BARBULES, Sdf.ValueTypeNames.FloatArray, vertex).Set(
        Vt.FloatArray.FromNumpy(barbule_reach(barbs.coverage).astype(np.float32))
    )
    if barbs.display_color is not None:
        display = curves.CreateDisplayColorPrimvar(vertex)
        display.Set(Vt.Vec3fArray.FromNumpy(barbs.display_color.astype(np.float32)))
    curves.GetPrim().SetDocumentation(
        "Barbs as ribbons (pavonine convert, [geometry.barbs]): normals = vane normal, widths = "
        "barb + barbules span thinned by the alpha map's coverage; primvars sampled from the maps."
    )
    save_whole(stage.GetRootLayer(), path)


def author_barbs_preview(stage, path) -> object:
    """A ``UsdPreviewSurface`` material at ``path`` whose diffuse colour is the geometry's
    ``displayColor`` (``UsdPrimvarReader_float3``): the barbs' colours in any USD viewer."""
    from pxr import Gf, Sdf, UsdShade

    material = UsdShade.Material.Define(stage, path)
    reader = UsdShade.Shader.Define(stage, path.AppendChild("DisplayColor"))
    reader.SetShaderId("UsdPrimvarReader_float3")
    reader.CreateInput("varname", Sdf.ValueTypeNames.String).Set("displayColor")
    reader.CreateInput("fallback", Sdf.ValueTypeNames.Float3).Set(Gf.Vec3f(0.18, 0.18, 0.18))
    colour = reader.CreateOutput("result", Sdf.ValueTypeNames.Float3)
    shader = UsdShade.Shader.Define(stage, path.AppendChild("PreviewSurface"))
    shader.SetShaderId("UsdPreviewSurface")
    shader.CreateInput("diffuseColor", Sdf.ValueTypeNames.Color3f).ConnectToSource(colour)
    shader.CreateInput("roughness", Sdf.ValueTypeNames.Float).Set(PREVIEW_ROUGHNESS)
    shader.CreateInput("metallic", Sdf.ValueTypeNames.Float).Set(0.0)
    material.CreateSurfaceOutput().ConnectToSource(
        shader.CreateOutput("surface", Sdf.ValueTypeNames.Token)
    )
    material.GetPrim().SetDocumentation(
        "Preview of the barbs for hosts without Pavonine: their baked per-vertex displayColor."
    )
    return material
