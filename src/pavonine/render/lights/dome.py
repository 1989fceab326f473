"""``DomeLight`` / ``DomeLight_1`` → Mitsuba ``envmap`` (textured) or ``constant`` radiance.

Orientation (the UsdLux docs, as usdImaging applies them):

* ``DomeLight``: the top pole is the world's +Y whatever the stage's up axis, and the latlong
  image follows the OpenEXR convention (longitude 0 towards +Z, π/2 towards +X) — which is also
  Mitsuba's ``envmap`` convention, so the light's own transform is all there is;
* ``DomeLight_1``: ``poleAxis`` ``Y``, or ``scene`` on a Y-up stage, as above; ``Z``, or ``scene``
  on a stage whose authored ``upAxis`` is Z, first turns the dome +90° about X (pole +Y → +Z).

The texture is multiplied by the light's colour (per channel), intensity and exposure; only the
light's rotation is used (an environment has no position or size). ``normalize`` has no effect on
domes (UsdLux); a 180° cone (``ShapingAPI``) shapes nothing. ``latlong`` and ``automatic`` textures are read as latitude-longitude maps; the
other formats are warned about and read as latlong.
"""

from __future__ import annotations

import numpy as np
from pxr import UsdGeom

from pavonine.render.lights.common import (
    LightReader,
    bitmap,
    cone_has_no_effect,
    light_texture,
    radiance,
    rgb,
    transform,
)
from pavonine.render.xform import to_mitsuba

Z_UP = np.array([[1, 0, 0, 0], [0, 0, -1, 0], [0, 1, 0, 0], [0, 0, 0, 1]], dtype=np.float64)
LATLONG_FORMATS = ("automatic", "latlong")
MIN_SIZE = (3, 4)  # Mitsuba's envmap needs a few texels in each direction (height, width)


def translate(reader: LightReader, world_usd: np.ndarray) -> dict:
    """The Mitsuba emitter of a dome light."""
    L = radiance(reader)
    reader.no_effect("dome lights have no size to normalize by (UsdLux)", "inputs:normalize")
    cone_has_no_effect(reader, 180.0)  # a 180° cone: no shaping at all
    texels = light_texture(reader, "inputs:texture:file")
    if texels is None:
        reader.honour("inputs:texture:format")
        return {"type": "constant", "radiance": rgb(L)}
    fmt = str(reader.value("inputs:texture:format", "automatic"))
    if fmt not in LATLONG_FORMATS:
        reader.warn(
            f"inputs:texture:format {fmt!r} is not supported; the texture is read as latlong"
        )
    texels = _at_least(texels * L, MIN_SIZE)
    to_world = to_mitsuba(_rotation_only(world_usd)) @ pole_rotation(reader)
    return {"type": "envmap", "bitmap": bitmap(texels), "to_world": transform(to_world)}


def pole_rotation(reader: LightReader) -> np.ndarray:
    """The dome's starting alignment (identity, or +90° about X for a Z pole), DomeLight_1 only."""
    if reader.prim.GetTypeName() != "DomeLight_1":
        return np.eye(4)
    pole = str(reader.value("poleAxis", "scene"))
    if pole == "scene":
        stage = reader.prim.GetStage()
        authored = stage.HasAuthoredMetadata("upAxis")
        z_up = authored and UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.z
        return Z_UP if z_up else np.eye(4)
    return Z_UP if pole == "Z" else np.eye(4)


def _rotation_only(world_usd: np.ndarray) -> np.ndarray:
    """The light's transform without translation and scale (an environment is infinitely far)."""
    m = np.eye(4)
    for i in range(3):
        row = np.asarray(world_usd[i, :3], dtype=np.float64)
        n = np.linalg.norm(row)
        m[i, :3] = row / n if n > 0 else np.eye(3)[i]
    return m


def _at_least(texels: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    """Repeat texels so the image has at least ``size`` (height, width) (e.g. a 1×1 colour)."""
    h, w = texels.shape[:2]
    rows = -(-size[0] // h) if h < size[0] else 1
    cols = -(-size[1] // w) if w < size[1] else 1
    return np.repeat(np.repeat(texels, rows, axis=0), cols, axis=1)
