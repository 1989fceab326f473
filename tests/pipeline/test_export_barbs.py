"""The barbs beyond Pavonine: ``pavonine export --geometry barbs`` writes them to glTF as ribbon
meshes with their baked colours (Khronos validator: no errors), and ``pavonine package`` carries
them in the usdz."""

from __future__ import annotations

import json
import subprocess
import zipfile

import numpy as np
import pytest
from click.testing import CliRunner
from test_gltf import _validator

from pavonine.apps.cli import cli
from pavonine.pipeline.export.ribbons import ribbon_prim_mesh
from pavonine.render.curves.ribbons import plain_ribbons


def run(*args):
    return CliRunner().invoke(cli, [str(a) for a in args])


def test_a_ribbon_spans_its_width_across_its_normal_facing_it():
    from pxr import Usd, UsdGeom

    stage = Usd.Stage.CreateInMemory()
    curves = UsdGeom.BasisCurves.Define(stage, "/Ribbons")
    curves.CreateTypeAttr("linear")
    curves.CreateCurveVertexCountsAttr([3, 2])
    curves.CreatePointsAttr([(0.0, 0, 0), (0, 1, 0), (0, 2, 0), (5, 0, 0), (5, 1, 0)])
    curves.CreateNormalsAttr([(0.0, 0.0, 1.0)] * 5)
    curves.SetNormalsInterpolation("vertex")
    widths = np.array([0.2, 0.4, 0.0, 1.0, 1.0])
    curves.CreateWidthsAttr(widths.tolist())
    curves.SetWidthsInterpolation("vertex")
    mesh, colours = ribbon_prim_mesh(curves.GetPrim(), plain_ribbons)
    assert colours is None and len(mesh.triangles) == 2 * (2 + 1)  # two per segment
    edge = mesh.points[1::2] - mesh.points[0::2]  # across each sample: a segment's two ends
    expected = np.concatenate([widths[[0, 1, 3]], widths[[1, 2, 4]]])
    assert np.allclose(np.sort(np.linalg.norm(edge, axis=1)), np.sort(expected))
    assert np.allclose(edge[:, 1:], 0.0)  # across the curve (±x for a curve along +y)
    a, b, c = (mesh.points[mesh.triangles[:, k]] for k in range(3))
    facing = np.cross(b - a, c - a)[:, 2]
    assert np.all(facing[np.abs(facing) > 1e-12] > 0.0)  # counter-clockwise seen from +z


@pytest.fixture(scope="module")
def barbs_glb(eye_asset, tmp_path_factory):
    out = tmp_path_factory.mktemp("barbs_gltf") / "eye_barbs.glb"
    result = run("export", eye_asset.parent, "-o", out, "--geometry", "barbs", "--json", "-")
    assert result.exit_code == 0, result.output
    return out, json.loads(result.stdout)


def test_export_writes_the_barbs_as_ribbon_meshes_with_their_colours(barbs_glb):
    import pygltflib

    out, report = barbs_glb
    paths = [m["path"] for m in report["meshes"]]
    assert any(p.endswith("/Geom/Barbs") for p in paths)
    assert not any(p.endswith("/Geom/Vane") for p in paths)  # the sheet is not in this level
    doc = pygltflib.GLTF2().load_binary(str(out))
    barbs = next(m for m in doc.meshes if m.name == "Barbs")
    primitive = barbs.primitives[0]
    assert primitive.attributes.COLOR_0 is not None
    material = doc.materials[primitive.material]
    assert material.pbrMetallicRoughness.baseColorFactor == [1.0, 1.0, 1.0, 1.0]
    accessor = doc.accessors[primitive.attributes.COLOR_0]
    view = doc.bufferViews[accessor.bufferView]
    blob = doc.binary_blob()
    colours = np.frombuffer(
        blob[view.byteOffset : view.byteOffset + view.byteLength], dtype=np.float32
    ).reshape(-1, 3)
    assert colours.max() > 0.05 and np.ptp(colours, axis=0).max() > 0.05  # coloured, varied


def test_khronos_validator_accepts_the_barbs(barbs_glb):
    out, _ = barbs_glb
    result = subprocess.run(
        [*_validator(), str(out)], capture_output=True, text=True, check=False, timeout=300
    )
    report = json.loads(result.stdout)
    assert result.returncode == 0 and report["errors"] == 0, report["messages"][:10]


def test_an_unknown_geometry_is_one_line(eye_asset, tmp_path):
    result = run("export", eye_asset.parent, "-o", tmp_path / "x.glb", "--geometry", "hair")
    assert result.exit_code == 2 and "--geometry" in result.stderr
    assert result.stderr.count("\n") == 1 and not any(tmp_path.iterdir())


def test_package_carries_the_barbs(eye_asset, tmp_path):
    out = tmp_path / "eye.usdz"
    result = run("package", eye_asset.parent, "-o", out)
    assert result.exit_code == 0, result.output
    names = zipfile.ZipFile(out).namelist()
    assert any(n.endswith("_geo_barbs.usdc") for n in names), names
    from pxr import Usd, UsdGeom

    stage = Usd.Stage.Open(str(out))
    prim = stage.GetDefaultPrim()
    prim.GetVariantSets().GetVariantSet("geometry").SetVariantSelection("barbs")
    curves = UsdGeom.BasisCurves(stage.GetPrimAtPath(f"/{prim.GetName()}/Geom/Barbs"))
    assert len(curves.GetCurveVertexCountsAttr().Get()) > 100
