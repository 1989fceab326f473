"""Ocellus zones of a rendered feather: which zone of the eye each pixel sees, and mean colours
per zone compared in CIE ΔE2000 (tests/pipeline/test_bake_preview.py, tests/pipeline/test_gltf_threejs.py).

Zones come from the ocellar map at the feather coordinate each pixel centre sees (a Mitsuba ray
cast through the scene's own camera); pixels are kept where the alpha map is above 0.9, one pixel
in from every zone boundary.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

MIN_PIXELS = 20
#: Ocellar classes (pipeline/maps/paint.py) by what the eye feather shows in them: 5 the heart,
#: 4…2 the rings, 1 the vane, 0 below it.
ZONE_NAMES = {
    5: "heart",
    4: "blue-green ring",
    3: "bronze ring",
    2: "outer ring",
    1: "vane",
    0: "lower vane",
}


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


def zone_masks(stage_path: Path, maps: Path, width: int, height: int) -> dict[int, np.ndarray]:
    """Per ocellar class with at least :data:`MIN_PIXELS` pixels: the pixels that see it
    (alpha above 0.9, eroded by one pixel)."""
    from scipy import ndimage

    from pavonine.base.map_files import read_map, sample_bilinear, sample_nearest
    from pavonine.pipeline.maps.paint import ocellar_class

    uv, on_vane = feather_hits(stage_path, width, height)
    alpha = np.zeros((height, width))
    alpha[on_vane] = sample_bilinear(read_map(maps / "alpha.png", "alpha"), uv[on_vane])
    zone = np.full((height, width), -1)
    zone[on_vane] = ocellar_class(sample_nearest(read_map(maps / "ocellar.png", "o"), uv[on_vane]))
    masks = {}
    for k in range(6):
        mask = ndimage.binary_erosion((zone == k) & (alpha > 0.9))
        if mask.sum() >= MIN_PIXELS:
            masks[k] = mask
    return masks


def zone_delta_e(a: np.ndarray, b: np.ndarray, masks: dict[int, np.ndarray]) -> dict[int, float]:
    """ΔE2000 between the mean linear Rec. 709 colours of images ``a`` and ``b`` per zone."""
    from pavonine.materials.colour import delta_e2000, linear_srgb_to_lab

    return {
        k: float(
            delta_e2000(
                linear_srgb_to_lab(a[m][:, :3].mean(axis=0)),
                linear_srgb_to_lab(b[m][:, :3].mean(axis=0)),
            )
        )
        for k, m in masks.items()
    }
