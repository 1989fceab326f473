"""The barbs for hosts without Pavonine: ``pavonine export ASSET -o X.usdc --geometry barbs``
writes the asset as one USD layer whose barb curves are the renderer's own flat ribbons as a
mesh, coloured by their ``displayColor`` through a bound ``UsdPreviewSurface``
(docs/pipeline.md, "Portable USD export"). With ``$PAVONINE_BPY_PYTHON`` (a Python with
Blender's ``bpy``), Blender's USD importer is checked to bind that colour to the mesh."""

from __future__ import annotations

import json
import os
import subprocess
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from pxr import Sdf, Usd, UsdGeom, UsdShade, UsdUtils

from pavonine.apps.cli import cli
from pavonine.pipeline.export.selection import open_selected
from pavonine.render.curves.ribbons import plain_ribbons

REPO = Path(__file__).resolve().parents[2]
EYE = REPO / "assets" / "feathers" / "eye_feather"
BARBS = "/eye_feather/Geom/Barbs"
CHILD = REPO / "benchmarks" / "blender_render_barbs.py"


#: Stages kept open for the module (a prim outlives its stage only while the stage is held).
_OPENED: dict[Path, Usd.Stage] = {}


def run(*args):
    return CliRunner().invoke(cli, [str(a) for a in args])


@pytest.fixture(scope="module")
def portable(tmp_path_factory):
    """The shipped eye's barbs exported as a portable USD, its report and the asset's curves."""
    out = tmp_path_factory.mktemp("portable") / "eye_barbs.usdc"
    result = run("export", EYE, "-o", out, "--geometry", "barbs", "--json", "-")
    assert result.exit_code == 0, result.output
    asset, _ = open_selected(EYE / "eye_feather.usd", None, "barbs")  # in its session layer
    _OPENED[EYE] = asset
    return out, json.loads(result.stdout), asset.GetPrimAtPath(BARBS)


def _mesh(out: Path) -> UsdGeom.Mesh:
    """The exported barbs (their stage kept open for the module)."""
    stage = _OPENED.setdefault(out, Usd.Stage.Open(str(out)))
    return UsdGeom.Mesh(stage.GetPrimAtPath(BARBS))


def test_the_barbs_become_the_renderers_own_ribbon_vertices(portable):
    import jsonschema

    from pavonine.apps.cli.export import JSON_SCHEMA

    out, report, curves = portable
    jsonschema.validate(report, JSON_SCHEMA)  # the documented --json report (docs/cli.md)
    assert report["geometry"] == "barbs" and report["lod"] == "high"
    assert [m["path"] for m in report["meshes"]] == [BARBS]
    mesh = _mesh(out)
    assert mesh.GetPrim().GetTypeName() == "Mesh"
    drawn = plain_ribbons(curves)  # what the CLI hands the export: the renderer's ribbons
    points = np.array(mesh.GetPointsAttr().Get())
    assert np.array_equal(points, drawn.topology.points.astype(np.float32))
    indices = np.array(mesh.GetFaceVertexIndicesAttr().Get())
    assert np.array_equal(indices, drawn.topology.face_vertex_indices)
    assert set(mesh.GetFaceVertexCountsAttr().Get()) == {3}
    assert report["meshes"][0]["triangles"] == len(indices) // 3


def test_each_ribbon_is_flat_as_wide_as_authored_and_faces_its_normal(portable):
    out, _, curves = portable
    mesh = _mesh(out)
    points = np.array(mesh.GetPointsAttr().Get(), dtype=np.float64)
    normals = np.array(mesh.GetNormalsAttr().Get(), dtype=np.float64)
    # linear curves: each segment is two samples (its ends), each sample two points (its edges)
    piece = points.reshape(-1, 4, 3)
    across = piece[:, [1, 3]] - piece[:, [0, 2]]
    along = piece[:, 2] - piece[:, 0] + piece[:, 3] - piece[:, 1]
    widths = np.linalg.norm(across, axis=2).ravel()
    authored = UsdGeom.BasisCurves(curves)
    counts = np.array(authored.GetCurveVertexCountsAttr().Get())
    w = np.array(authored.GetWidthsAttr().Get(), dtype=np.float64)
    ends = np.cumsum(counts)
    not_first = np.ones(len(w), bool)  # a segment ends at every vertex but a curve's first
    not_first[np.concatenate([[0], ends[:-1]])] = False
    not_last = np.ones(len(w), bool)  # and starts at every vertex but its last
    not_last[ends - 1] = False
    expected = np.concatenate([w[not_last], w[not_first]])
    assert np.allclose(np.sort(widths), np.sort(expected), atol=1e-5)  # the authored widths
    unit = across / np.maximum(np.linalg.norm(across, axis=2, keepdims=True), 1e-30)
    tangent = along / np.linalg.norm(along, axis=1, keepdims=True)
    wide = widths.reshape(-1, 2) > 0.01  # float32 points: 2e-6 cm apart at 30 cm
    assert np.abs(np.sum(unit * tangent[:, None], axis=2))[wide].max() < 1e-3  # across the barb
    edge_normals = normals.reshape(-1, 2, 2, 3)[:, :, 0]
    assert np.abs(np.sum(unit * edge_normals, axis=2))[wide].max() < 1e-3  # and its normal
    # flat: each triangle faces its vertices' normal (a ribbon, not a tube)
    corners = points[np.array(mesh.GetFaceVertexIndicesAttr().Get()).reshape(-1, 3)]
    face = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    area = np.linalg.norm(face, axis=1)
    ok = area > 1e-6 * np.median(area)
    vertex = normals[np.array(mesh.GetFaceVertexIndicesAttr().Get()).reshape(-1, 3)[:, 0]]
    cosine = np.sum(face[ok] / area[ok, None] * vertex[ok], axis=1)
    facing = area[ok][cosine > 0.999].sum() / area[ok].sum()  # within 2.6°, by area
    # The few tilted: slivers where barbs taper, and the fringe's clumped tails, which bend in
    # the vane toward their clump and droop out of it at once (a ribbon bent both ways twists):
    # 0.079 % of the area before the clumps, 0.213 % with them (shipped eye, barb_clumps.py).
    assert facing > 0.997 and cosine.min() > 0.0


def test_the_colour_is_bound_through_a_preview_surface(portable):
    out, report, curves = portable
    mesh = _mesh(out)
    material, _ = UsdShade.MaterialBindingAPI(mesh.GetPrim()).ComputeBoundMaterial()
    assert material and report["materials"] == [str(material.GetPath())]
    surface = material.ComputeSurfaceSource()[0]
    assert surface.GetShaderId() == "UsdPreviewSurface"
    reader = surface.GetInput("diffuseColor").GetConnectedSources()[0][0].source
    reader = UsdShade.Shader(reader.GetPrim())
    assert reader.GetShaderId() == "UsdPrimvarReader_float3"
    assert reader.GetInput("varname").Get() == "displayColor"
    colour = UsdGeom.PrimvarsAPI(mesh).GetPrimvar("displayColor")
    assert colour.GetInterpolation() == UsdGeom.Tokens.vertex
    values = np.array(colour.Get())
    assert len(values) == len(mesh.GetPointsAttr().Get())
    authored = np.array(UsdGeom.PrimvarsAPI(curves).GetPrimvar("displayColor").Get())
    # every mesh colour is an authored vertex colour (linear curves: sampled at their vertices)
    seen = {tuple(c) for c in authored.round(6)}
    assert all(tuple(c) in seen for c in values.round(6)[:: max(1, len(values) // 500)])
    assert np.ptp(values, axis=0).max() > 0.05  # coloured and varied, not a fallback grey


def test_the_layer_is_valid_whole_and_resolves_its_files(portable):
    out, report, _ = portable
    result = run("validate", out)
    assert result.exit_code == 0 and result.output == "1 file, no findings\n", result.output
    stage = Usd.Stage.Open(str(out))
    used = [layer for layer in stage.GetUsedLayers() if not layer.anonymous]
    assert not stage.GetRootLayer().subLayerPaths and used == [stage.GetRootLayer()]
    box = UsdGeom.BBoxCache(Usd.TimeCode.Default(), [UsdGeom.Tokens.default_, "render"])
    bound = box.ComputeWorldBound(stage.GetDefaultPrim()).ComputeAlignedRange()
    size = np.array(bound.GetSize())
    assert np.all(np.isfinite(size)) and 25.0 < size.max() < 40.0  # the 29.6 cm feather, cm
    mesh = _mesh(out)
    extent = np.array(mesh.GetExtentAttr().Get())
    points = np.array(mesh.GetPointsAttr().Get())
    assert np.allclose(extent, [points.min(0), points.max(0)])
    layer = Sdf.Layer.FindOrOpen(str(out))
    paths = UsdUtils.ExtractExternalReferences(str(out))
    files = [p for group in paths for p in group]
    assert files and all(not os.path.isabs(p) for p in files)
    assert all((out.parent / p).resolve().exists() for p in files), files
    assert layer is not None and report["bytes"] == out.stat().st_size


def test_a_train_with_a_barbs_prototype_exports_its_ribbons(tmp_path):
    """The shipped train (a PointInstancer of the feather assets) with its eye prototype at the
    barbs level: the prototype's curves become the ribbon mesh, instanced as before."""
    train = REPO / "assets" / "assemblies" / "peacock_train" / "peacock_train.usda"
    shot = tmp_path / "train_barbs.usda"
    layer = Sdf.Layer.CreateNew(str(shot))
    layer.subLayerPaths.append(str(train))
    layer.defaultPrim = "peacock_train"
    eye = Sdf.CreatePrimInLayer(layer, "/peacock_train/Feathers/Prototypes/eye")
    eye.variantSelections["geometry"] = "barbs"
    layer.Save()
    out = tmp_path / "train.usdc"
    result = run("export", shot, "-o", out, "--json", "-")
    assert result.exit_code == 0, result.output
    report = json.loads(result.stdout)
    barbs = "/peacock_train/Feathers/Prototypes/eye/Geom/Barbs"
    assert [m["path"] for m in report["meshes"]] == [barbs]
    stage = Usd.Stage.Open(str(out))
    assert stage.GetPrimAtPath(barbs).GetTypeName() == "Mesh"
    instancer = UsdGeom.PointInstancer(stage.GetPrimAtPath("/peacock_train/Feathers"))
    assert instancer and len(instancer.GetProtoIndicesAttr().Get()) > 0


@pytest.mark.parametrize(
    "args, what",
    [
        (["-o", "{tmp}/x.obj"], "x.obj"),
        (["-o", "{tmp}/x.usdc", "--eye", "0", "0", "90"], "--eye"),
        (["-o", "{tmp}/x.usdc", "--geometry", "hair"], "--geometry"),
        (["-o", "{tmp}/x.usdc", "--lod", "ultra"], "--lod"),
    ],
)
def test_bad_input_is_one_line_and_writes_nothing(tmp_path, args, what):
    result = run("export", EYE, *[a.format(tmp=tmp_path) for a in args])
    assert result.exit_code == 2 and what in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1, result.stderr
    assert not any(tmp_path.iterdir())


def test_blender_binds_the_colour_to_the_barbs(portable, tmp_path):
    """Blender's own USD importer (bpy, ``$PAVONINE_BPY_PYTHON``): the barbs are a mesh bound to
    a material whose Base Color is the imported ``displayColor``, not the default grey."""
    python = os.environ.get("PAVONINE_BPY_PYTHON")
    if not python:
        pytest.skip("$PAVONINE_BPY_PYTHON (a Python with Blender's bpy) is not set")
    out, _, _ = portable
    job = tmp_path / "job.json"
    job.write_text(json.dumps({"usd": str(out), "out": str(tmp_path), "views": []}))
    subprocess.run([python, str(CHILD), str(job)], check=True, timeout=600, capture_output=True)
    found = json.loads((tmp_path / "blender.json").read_text())
    barbs = found["objects"]["Barbs"]
    assert barbs["type"] == "MESH" and barbs["color_attributes"] == ["displayColor"]
    assert barbs["base_color"] == {"node": "ShaderNodeAttribute", "attribute": "displayColor"}
