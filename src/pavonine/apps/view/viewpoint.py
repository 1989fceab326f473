"""The page's viewpoint as a USD layer over the opened stage, for ``pavonine render``.

"Render this view" writes ``view.usda``: the opened stage as its sublayer, and over it the
camera (the stage's render camera, else ``/ViewCamera``) placed at the page's eye looking at
its target with its vertical field of view, the sun (the stage's first ``DistantLight``, else
``/ViewSun``) turned toward the page's sun direction with its irradiance, the sky (first
``DomeLight``, else ``/ViewSky``) at the page's radiance, and the page's variant selections.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from pavonine.base.errors import InputError

#: Keys of the POST body, each a list of floats of this length.
VIEW_VECTORS = {"eye": 3, "target": 3, "up": 3, "sun": 3, "irradiance": 3, "sky": 3}


def _unit(v) -> np.ndarray:
    v = np.asarray(v, dtype=np.float64)
    n = np.linalg.norm(v)
    if not np.isfinite(n) or n < 1e-12:
        raise InputError("view", "a direction is zero or not finite")
    return v / n


def frame_rows(z, up=(0.0, 1.0, 0.0)) -> np.ndarray:
    """Rows x, y, z of a right-handed frame with the given +Z (USD cameras look down −Z)."""
    z = _unit(z)
    helper = np.asarray(up, dtype=np.float64)
    if abs(float(np.dot(_unit(helper), z))) > 0.999:
        helper = np.array([1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.array([0.0, 0.0, 1.0])
    x = _unit(np.cross(helper, z))
    return np.stack([x, np.cross(z, x), z])


def check_view(view: dict) -> dict:
    """The POST body checked: the vectors, ``fov`` (degrees), ``width``/``height``, ``spp``."""
    out: dict = {}
    for key, n in VIEW_VECTORS.items():
        value = view.get(key)
        if not isinstance(value, list) or len(value) != n:
            raise InputError(f"view.{key}", f"expected {n} numbers")
        try:
            out[key] = [float(v) for v in value]
        except (TypeError, ValueError):
            raise InputError(f"view.{key}", "expected numbers") from None
        if not all(math.isfinite(v) for v in out[key]):
            raise InputError(f"view.{key}", "not finite")
    fov = view.get("fov")
    if not isinstance(fov, int | float) or not 1.0 <= fov <= 170.0:
        raise InputError("view.fov", "expected degrees in [1, 170]")
    out["fov"] = float(fov)
    for key, lo, hi in (("width", 8, 1024), ("height", 8, 1024), ("spp", 1, 256)):
        value = view.get(key)
        if not isinstance(value, int) or not lo <= value <= hi:
            raise InputError(f"view.{key}", f"expected an integer in [{lo}, {hi}]")
        out[key] = value
    variants = view.get("variants") or {}
    if not isinstance(variants, dict) or not all(
        isinstance(k, str) and isinstance(v, str) for k, v in variants.items()
    ):
        raise InputError("view.variants", "expected names to names")
    out["variants"] = variants
    return out


def _xform(prim, rows: np.ndarray, origin) -> None:
    from pxr import Gf, UsdGeom

    m = np.eye(4)
    m[:3, :3] = rows
    m[3, :3] = origin
    xf = UsdGeom.Xformable(prim)
    xf.ClearXformOpOrder()
    xf.AddTransformOp().Set(Gf.Matrix4d(*m.ravel().tolist()))


def _prim(stage, path: str | None, fallback: str, type_name: str):
    if path and stage.GetPrimAtPath(path):
        return stage.OverridePrim(path)
    return stage.DefinePrim(fallback, type_name)


def write_view_layer(scene, view: dict, folder: Path) -> tuple[Path, str]:
    """Write ``folder/view.usda`` (module docstring); returns it and the camera's path."""
    from pxr import Gf, Sdf, Usd, UsdGeom, UsdLux

    view = check_view(view)
    base = Usd.Stage.Open(str(scene.stage_path))
    path = folder / "view.usda"
    layer = Sdf.Layer.CreateNew(str(path))
    layer.subLayerPaths.append(str(scene.stage_path))
    stage = Usd.Stage.Open(layer)
    UsdGeom.SetStageMetersPerUnit(stage, UsdGeom.GetStageMetersPerUnit(base))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.GetStageUpAxis(base))
    if base.GetDefaultPrim():
        stage.SetDefaultPrim(stage.GetPrimAtPath(base.GetDefaultPrim().GetPath()))
    for prim in stage.Traverse():
        sets = prim.GetVariantSets()
        for name, choice in view["variants"].items():
            if sets.HasVariantSet(name) and choice in sets.GetVariantSet(name).GetVariantNames():
                sets.GetVariantSet(name).SetVariantSelection(choice)

    eye, target = np.asarray(view["eye"]), np.asarray(view["target"])
    camera = _prim(stage, scene.camera.get("path"), "/ViewCamera", "Camera")
    _xform(camera, frame_rows(eye - target, view["up"]), eye)
    cam = UsdGeom.Camera(camera)
    focal = 50.0
    vertical = 2.0 * focal * math.tan(math.radians(view["fov"]) / 2.0)
    cam.CreateFocalLengthAttr().Set(focal)
    cam.CreateVerticalApertureAttr().Set(vertical)
    cam.CreateHorizontalApertureAttr().Set(vertical * view["width"] / view["height"])
    cam.CreateHorizontalApertureOffsetAttr().Set(0.0)
    cam.CreateVerticalApertureOffsetAttr().Set(0.0)
    distance = float(np.linalg.norm(eye - target))
    radius = float(scene.camera.get("radius", distance))
    near = max(1e-3, (distance - 4.0 * radius) * 0.5)
    cam.CreateClippingRangeAttr().Set(Gf.Vec2f(near, distance + 8.0 * radius))

    sun = _prim(stage, scene.sun.get("path"), "/ViewSun", "DistantLight")
    _xform(sun, frame_rows(view["sun"]), (0.0, 0.0, 0.0))
    e = np.asarray(view["irradiance"])
    peak = float(e.max()) if e.max() > 0 else 1.0
    light = UsdLux.DistantLight(sun)
    light.CreateNormalizeAttr().Set(True)
    light.CreateAngleAttr().Set(0.53)
    light.CreateIntensityAttr().Set(peak)
    light.CreateExposureAttr().Set(0.0)
    light.CreateColorAttr().Set(Gf.Vec3f(*(e / peak).tolist()))

    sky_prim = _prim(stage, scene.sky.get("path"), "/ViewSky", "DomeLight")
    s = np.asarray(view["sky"])
    peak = float(s.max()) if s.max() > 0 else 1.0
    sky = UsdLux.DomeLight(sky_prim)
    sky.CreateIntensityAttr().Set(float(s.max()))
    sky.CreateExposureAttr().Set(0.0)
    sky.CreateColorAttr().Set(Gf.Vec3f(*(s / peak).tolist()))
    layer.Save()
    return path, str(camera.GetPath())
