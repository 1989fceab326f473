"""A sunlit close-up of the shipped eye feather's ocellus, with glitter (issue 24's test scene).

The camera looks straight down the vane normal from 3 cm at the edge of the ocellus's dark
centre, on a field ``field_mm`` wide: at 128 pixels a pixel covers about 23 µm, about one block
(25 µm long, 20 µm across). The sun (0.53°) comes from the right, ``sun_deg`` off the normal
about the feather's vertical axis, as in ``assets/scenes/eye_feather_sun.usda``.
"""

from __future__ import annotations

from pathlib import Path

from pxr import Gf, Sdf, Usd, UsdGeom, UsdLux, UsdRender
from render_helpers import render_product

ROOT = Path(__file__).resolve().parents[1]
EYE = ROOT / "assets" / "feathers" / "eye_feather" / "eye_feather.usd"
#: The boundary of the ocellus's dark centre (class 5) and its first ring (class 4), 1.5 cm right of
#: the rachis: ocellar texel (306, 262) of 512 x 1024, feather uv (0.598, 0.744); 1 texel = 293 µm.
TARGET = (1.465, 22.31, -1.1)


def closeup_stage(
    path: Path,
    glitter: float,
    *,
    sun_deg: float = 25.0,
    field_mm: float = 3.0,
    resolution: int = 128,
    uv: bool = False,
    glitter_seed: int | None = None,
    geometry: str | None = None,
    distance_cm: float = 3.0,
) -> Path:
    """Write the close-up stage at ``path`` (referencing the shipped eye feather; ``geometry``:
    its ``geometry`` variant, ``sheet`` or ``barbs``, else the asset's default; ``distance_cm``:
    the camera's distance, the lens still framing ``field_mm`` there)."""
    stage = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageMetersPerUnit(stage, 0.01)
    UsdGeom.SetStageUpAxis(stage, "Y")
    world = UsdGeom.Xform.Define(stage, "/World")
    stage.SetDefaultPrim(world.GetPrim())
    feather = stage.DefinePrim("/World/Feather", "Xform")
    feather.GetReferences().AddReference(str(EYE))
    if geometry is not None:
        feather.GetVariantSets().GetVariantSet("geometry").SetVariantSelection(geometry)
    material = stage.OverridePrim("/World/Feather/Materials/Feather")
    material.CreateAttribute("pavonine:glitter", Sdf.ValueTypeNames.Float).Set(float(glitter))
    if glitter_seed is not None:
        material.CreateAttribute("pavonine:glitterSeed", Sdf.ValueTypeNames.Int).Set(glitter_seed)
    camera = UsdGeom.Camera.Define(stage, "/World/Camera")
    camera.CreateHorizontalApertureAttr(24.0)
    camera.CreateVerticalApertureAttr(24.0)
    camera.CreateFocalLengthAttr(24.0 * distance_cm * 10.0 / field_mm)
    camera.CreateClippingRangeAttr(Gf.Vec2f(0.5, 100.0))
    x, y, z = TARGET
    camera.AddTranslateOp().Set(Gf.Vec3d(x, y, z + distance_cm))
    sun = UsdLux.DistantLight.Define(stage, "/World/Sun")
    sun.CreateAngleAttr(0.53)
    sun.CreateIntensityAttr(3.14159)
    sun.CreateNormalizeAttr(True)
    sun.AddRotateYOp().Set(float(sun_deg))
    settings = UsdRender.Settings.Define(stage, "/Render/Settings")
    settings.CreateCameraRel().SetTargets([camera.GetPath()])
    settings.CreateResolutionAttr(Gf.Vec2i(resolution, resolution))
    if uv:
        render_product(
            stage,
            {"color": None, "uv": None},
            camera=str(camera.GetPath()),
            resolution=(resolution, resolution),
        )
    stage.GetRootLayer().Save()
    return path
