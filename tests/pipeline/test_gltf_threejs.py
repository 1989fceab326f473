"""Acceptance (issue 26): the exported ``.glb`` drawn by three.js (0.187.0, ``.ci/package.json``)
in headless Chromium with software WebGL against Pavonine's render of the same camera and sun,
face-on and tilted (``pipeline.export.iridescence.TILT_DEG`` about the feather's vertical axis):
per ocellus zone (tests/ocellus_zones.py), CIE ΔE2000 of the mean colours, the render taken as a
display shows it (negative, out-of-gamut components clipped, as ``pavonine render --png`` does).

The ``.glb`` is exported for the scene's camera (``pavonine export --eye``: the look is fitted
to the views from there). Every zone within ΔE 5, as the issue asks (measured:
docs/pipeline.md, *glTF export*).

And three.js draws what ``pipeline/export/iridescence.py`` says it draws (the model the fit
inverts): a flat quad of one material, free-standing film or over a coloured substrate, within
1 %.

    pytest tests/pipeline/test_gltf_threejs.py -s   # prints the zone tables
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from gltf_browser import SUN, THREE, chromium, compare_zones, draw, page_view, scene_eye
from ocellus_zones import ZONE_NAMES

from pavonine.pipeline.export import iridescence as irid

pytestmark = pytest.mark.browser
RESOLUTION = (128, 192)
SPP = 32
#: The zones the issue names: the heart, the three rings, the vane (class 0, a sliver below the
#: eye in this view, is printed but not held to the bounds).
ZONES = (5, 4, 3, 2, 1)
#: Per zone, the issue's bound.
MAX_DELTA_E = 5.0


@pytest.fixture(scope="module", autouse=True)
def _browser():
    if chromium() is None:
        pytest.skip("Chromium not installed")
    if not THREE.is_dir():
        pytest.skip("three.js not installed in .ci/node_modules (run .ci/setup)")


def _quad(path: Path, base, weight, thickness, roughness, ior, substrate) -> None:
    import pygltflib as gl

    points = np.array([[-0.05, -0.05, 0], [0.05, -0.05, 0], [0.05, 0.05, 0], [-0.05, 0.05, 0]])
    normals = np.tile([0.0, 0.0, 1.0], (4, 1))
    blob = points.astype(np.float32).tobytes() + normals.astype(np.float32).tobytes()
    blob += np.array([0, 1, 2, 0, 2, 3], np.uint32).tobytes()
    doc = gl.GLTF2(asset=gl.Asset(version="2.0"), buffers=[gl.Buffer(byteLength=len(blob))])
    doc.bufferViews = [
        gl.BufferView(buffer=0, byteOffset=0, byteLength=48, target=gl.ARRAY_BUFFER),
        gl.BufferView(buffer=0, byteOffset=48, byteLength=48, target=gl.ARRAY_BUFFER),
        gl.BufferView(buffer=0, byteOffset=96, byteLength=24, target=gl.ELEMENT_ARRAY_BUFFER),
    ]
    doc.accessors = [
        gl.Accessor(
            bufferView=0,
            componentType=gl.FLOAT,
            count=4,
            type=gl.VEC3,
            min=[-0.05, -0.05, 0],
            max=[0.05, 0.05, 0],
        ),
        gl.Accessor(bufferView=1, componentType=gl.FLOAT, count=4, type=gl.VEC3),
        gl.Accessor(bufferView=2, componentType=gl.UNSIGNED_INT, count=6, type=gl.SCALAR),
    ]
    film = {"iridescenceFactor": weight, "iridescenceIor": ior}
    film["iridescenceThicknessMaximum"] = thickness
    doc.materials = [
        gl.Material(
            pbrMetallicRoughness=gl.PbrMetallicRoughness(
                baseColorFactor=[*base, 1.0], metallicFactor=0.0, roughnessFactor=roughness
            ),
            extensions={
                "KHR_materials_iridescence": film,
                "KHR_materials_specular": {
                    "specularFactor": 1.0,
                    "specularColorFactor": [float(f) / 0.04 for f in substrate],
                },
            },
        )
    ]
    doc.extensionsUsed = ["KHR_materials_iridescence", "KHR_materials_specular"]
    primitive = gl.Primitive(attributes=gl.Attributes(POSITION=0, NORMAL=1), indices=2, material=0)
    doc.meshes = [gl.Mesh(primitives=[primitive])]
    doc.nodes, doc.scenes, doc.scene = [gl.Node(mesh=0)], [gl.Scene(nodes=[0])], 0
    doc.set_binary_blob(blob)
    doc.save_binary(str(path))


@pytest.mark.parametrize(
    ("weight", "thickness", "roughness", "substrate"),
    [
        (1.0, 400.0, 0.4, (0.0, 0.0, 0.0)),
        (0.8, 550.0, 0.6, (0.0, 0.0, 0.0)),
        (1.0, 300.0, 0.3, (0.2, 0.3, 0.1)),
        (0.5, 250.0, 0.5, (0.35, 0.12, 0.45)),
    ],
)
def test_threejs_draws_the_model_the_fit_inverts(tmp_path, weight, thickness, roughness, substrate):
    base = np.array([0.1, 0.2, 0.05])
    _quad(tmp_path / "quad.glb", base, weight, thickness, roughness, 1.56, substrate)
    light = np.array([SUN])
    views = irid.tilted_views([0.0, irid.TILT_DEG])
    expected = irid.glTF_reflectance(
        base[None], [weight], [thickness], light, views[None], [roughness], 1.56, [substrate]
    )[0]
    for k, tilt in enumerate((0.0, irid.TILT_DEG)):
        view = page_view(
            tilt, (0.0, 0.0, 1.0), resolution=[16, 16], fov_deg=1.0, near=0.1, far=10.0
        )
        view |= {"sky_color": [0.0, 0.0, 0.0], "sky_intensity": 0.0}
        pixels = draw(tmp_path / "quad.glb", view, tmp_path / f"page{k}")
        drawn = pixels[8, 8, :3] / SUN[2]  # radiance E cos θ_i f, E = π → reflectance factor
        assert drawn == pytest.approx(expected[k], rel=0.01, abs=2e-3), (tilt, drawn, expected[k])
    assert not np.allclose(expected[0], expected[1], atol=0.05)  # the film moves with the view


@pytest.mark.render
def test_exported_glb_in_threejs_matches_the_render_face_on_and_tilted(eye_asset, tmp_path):
    from click.testing import CliRunner

    from pavonine.apps.cli import cli

    glb = tmp_path / "eye_feather.glb"
    eye = [str(v) for v in scene_eye()]  # the look fitted for the scene's camera
    result = CliRunner().invoke(
        cli, ["export", str(eye_asset.parent), "-o", str(glb), "--eye", *eye]
    )
    assert result.exit_code == 0, result.output
    drawn = {}
    for tilt in (0.0, irid.TILT_DEG):
        found = compare_zones(glb, eye_asset, tilt, tmp_path, RESOLUTION, SPP)
        drawn[tilt] = (found.delta_e, found.means)
        print(f"\ntilt {tilt:+.0f}°  zone  pixels  ΔE2000 (render vs three.js)")
        for k, de in found.delta_e.items():
            print(f"{ZONE_NAMES[k]:>16}  {found.pixels[k]:>6}  {de:6.2f}")
    for tilt, (delta_e, _) in drawn.items():
        assert set(delta_e) >= set(ZONES), (tilt, sorted(delta_e))
        assert max(delta_e[k] for k in ZONES) <= MAX_DELTA_E, (tilt, delta_e)
    # Not a view-independent bake: the colour moves with the view in the render and in three.js.
    from pavonine.materials.colour import delta_e2000, linear_srgb_to_lab

    face, tilted = drawn[0.0][1], drawn[irid.TILT_DEG][1]
    for image in (0, 1):
        moved = [
            float(
                delta_e2000(
                    linear_srgb_to_lab(face[k][image]), linear_srgb_to_lab(tilted[k][image])
                )
            )
            for k in (2, 3, 4)
        ]
        assert min(moved) > 10.0, (image, moved)
