"""Acceptance: the converted eye feather rendered with only its UsdPreviewSurface (the baked
textures, as a viewer that knows nothing of Pavonine sees it) matches the spectral render of the
same stage under the same light: per ocellus zone, mean colours within CIE ΔE2000 10.

The asset is converted here from the shipped recipe (so the bake follows whatever the optics
model is now) and placed in the shipped scene. Zones come from the ocellar map at the feather
coordinate each pixel centre sees (a Mitsuba ray cast through the scene's own camera); pixels
are kept where the alpha map is above 0.9, one pixel in from every zone boundary.

    pytest tests/test_preview_delta_e.py -s   # prints the table, writes the side-by-side image
"""

from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[1]
RECIPE = REPO / "assets" / "recipes" / "eye_feather.toml"
SCENE = REPO / "assets" / "scenes" / "eye_feather_sun.usda"
RESOLUTION = (128, 192)
SPP = 32
MAX_DELTA_E = 10.0
MIN_PIXELS = 20


def _recipe(folder: Path) -> Path:
    """The shipped eye recipe with absolute map paths, lighter LODs and 512² textures."""
    data = tomllib.loads(RECIPE.read_text())
    lines = [f'name = "{data["name"]}"', "[maps]"]
    lines += [f'{k} = "{(RECIPE.parent / v).as_posix()}"' for k, v in data["maps"].items()]
    lines += ["[material]", f'preset = "{data["material"]["preset"]}"', "[geometry]"]
    lines += [f"{k} = {v}" for k, v in data["geometry"].items() if k != "lod"]
    lines += ["[geometry.lod]", "high = 30000", "medium = 8000", "low = 2000"]
    lines += ["[bake]", "resolution = 512"]
    path = folder / "eye.toml"
    path.write_text("\n".join(lines) + "\n")
    return path


def feather_hits(stage_path: Path, width: int, height: int, mesh: str = "Vane"):
    """Feather coordinate seen by each pixel centre through the stage's camera, and whether the
    ray hits ``mesh`` first (Mitsuba's uv of a feather mesh is the feather coordinate, v flipped)."""
    import drjit as dr
    import mitsuba as mi

    from pavonine.render import camera
    from pavonine.render.api import scene_objects
    from pavonine.render.delegate import StageDelegate, open_stage, render_time
    from pavonine.render.diagnostics import Diagnostics
    from pavonine.render.settings import read_render_settings

    diag = Diagnostics()
    stage = open_stage(stage_path, diag)
    time = render_time(stage, None)
    delegate = StageDelegate(stage, time, diag)
    synced = delegate.sync()
    settings = read_render_settings(stage, diag)
    prim = synced.cameras[settings.camera]
    sensor = camera.translate_camera(
        prim, delegate.xforms.world(prim), time, (width, height), 1.0, settings.conform, diag
    )
    film = {"type": "hdrfilm", "width": width, "height": height}
    scene = mi.load_dict(
        {
            "type": "scene",
            "sensor": {**sensor.sensor, "film": film},
            **scene_objects(synced.shapes, {}),
        }
    )
    rows, cols = np.mgrid[0:height, 0:width]
    position = mi.Point2f(((cols + 0.5) / width).ravel(), ((rows + 0.5) / height).ravel())
    ray, _ = scene.sensors()[0].sample_ray(0.0, 0.0, position, mi.Point2f(0.5, 0.5))
    hit = scene.ray_intersect(ray)
    ids = dr.reinterpret_array(mi.UInt32, hit.shape)
    on_mesh = np.zeros(width * height, dtype=bool)
    for shape in scene.shapes():
        if f"__{mesh}_" in shape.id():
            own = dr.reinterpret_array(mi.UInt32, mi.ShapePtr(shape))
            on_mesh |= np.asarray(ids == own) & np.asarray(hit.is_valid())
    uv = np.stack([np.asarray(hit.uv.x), 1.0 - np.asarray(hit.uv.y)], axis=-1)
    return uv.reshape(height, width, 2), on_mesh.reshape(height, width)


def zone_delta_e(maps: Path, uv, on_vane, first, second):
    """Per ocellus zone (the ocellar map at each pixel's feather coordinate, alpha above 0.9, one
    pixel in from every zone boundary): ``(zone image, {class: (pixels, ΔE2000 of the mean
    colours of the two images)})`` for zones of at least ``MIN_PIXELS``."""
    from scipy import ndimage

    from pavonine.materials.colour import delta_e2000, linear_srgb_to_lab
    from pavonine.pipeline.maps.io import read_map, sample_bilinear, sample_nearest
    from pavonine.pipeline.maps.paint import ocellar_class

    alpha = np.zeros(on_vane.shape)
    alpha[on_vane] = sample_bilinear(read_map(maps / "alpha.png", "alpha"), uv[on_vane])
    zone = np.full(on_vane.shape, -1)
    zone[on_vane] = ocellar_class(sample_nearest(read_map(maps / "ocellar.png", "o"), uv[on_vane]))
    results = {}
    for k in range(6):
        mask = ndimage.binary_erosion((zone == k) & (alpha > 0.9))
        if mask.sum() < MIN_PIXELS:
            continue
        a, b = first[mask].mean(axis=0), second[mask].mean(axis=0)
        results[k] = (
            int(mask.sum()),
            float(delta_e2000(linear_srgb_to_lab(a), linear_srgb_to_lab(b))),
        )
    return zone, results


@pytest.mark.render
def test_preview_surface_matches_the_spectral_render_per_ocellus_zone(tmp_path, monkeypatch):
    from pavonine.pipeline.convert.batch import convert_recipe
    from pavonine.render import materials
    from pavonine.render.api import render_stage
    from pavonine.render.imageio import write_png

    root = convert_recipe(_recipe(tmp_path), tmp_path / "assets").root
    scene = tmp_path / "scene.usda"
    scene.write_text(
        SCENE.read_text().replace("@../feathers/eye_feather/eye_feather.usd@", f"@{root}@")
    )
    width, height = RESOLUTION
    uv, on_vane = feather_hits(scene, width, height)  # the feather material: uv = featherUV
    spectral = render_stage(scene, spp=SPP, resolution=RESOLUTION, seed=0, progress=False)
    monkeypatch.setenv(materials.IGNORE_FEATHER_SCHEMA, "1")
    preview = render_stage(scene, spp=SPP, resolution=RESOLUTION, seed=0, progress=False)
    assert not [w for w in preview.warnings if "not found" in w or "rejected" in w], (
        preview.warnings
    )
    write_png(tmp_path / "spectral_vs_preview.png", np.concatenate([spectral.rgb, preview.rgb], 1))

    zone, results = zone_delta_e(root.parent / "maps", uv, on_vane, spectral.rgb, preview.rgb)
    print("\nzone  pixels  ΔE2000 (spectral vs UsdPreviewSurface)")
    for k, (pixels, de) in results.items():
        print(f"{k:>4}  {pixels:>6}  {de:6.2f}")
    assert set(results) >= {1, 2, 3, 4, 5}, results  # the ocellus and the vane around it
    assert all(de < MAX_DELTA_E for _, de in results.values()), results
    # Not a vacuous pass: the spectral render has colour, and the preview is not a grey card.
    assert np.ptp([spectral.rgb[zone == k].mean(axis=0)[2] for k in results]) > 0.02
