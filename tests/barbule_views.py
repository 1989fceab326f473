"""Close-ups of the shipped eye feather's barbs for the barbule tests (issue 33): scenes aimed at
places found on the asset itself, and the fine-detail measure.

* :func:`targets`: the vane (a point on the barbs 60 % up, 68 % across the feather's bounds, as the
  look-dev contact sheet's "vane 5 mm") and the heart's edge (the median of the barb vertices
  where the ocellar class steps from the heart's 5 to the blue-green 4, its right-most tenth).
* :func:`close_up`: a stage looking straight down the feather's normal (+z) at a target, a
  ``field_cm`` field (50 mm lens, 24 mm aperture), the README hero's sun, no sky.
* :func:`shared_detail`: the fine detail two renders with different seeds share: luminance
  high-passed (minus its Gaussian blur, σ = :data:`HIGH_PASS_SIGMA` px), the two seeds'
  covariance over the square of the mean luminance, per window of :data:`WINDOW` px, median over
  the windows. Sampling noise is independent between seeds and drops out; what remains is
  detail in the scene.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from barb_measures import luminance, shared_windows

REPO = Path(__file__).resolve().parents[1]
ASSET = REPO / "assets" / "feathers" / "eye_feather" / "eye_feather.usd"
WINDOW = 20
HIGH_PASS_SIGMA = 2.0


def _barbs(asset: Path = ASSET):
    from pxr import Usd, UsdGeom

    stage = Usd.Stage.Open(str(asset))
    stage.SetEditTarget(stage.GetSessionLayer())  # not the shipped layer (tests/conftest.py)
    root = stage.GetDefaultPrim()
    root.GetVariantSets().GetVariantSet("geometry").SetVariantSelection("barbs")
    for prim in Usd.PrimRange(root):
        if prim.IsA(UsdGeom.BasisCurves):
            curves = UsdGeom.BasisCurves(prim)
            points = np.array(curves.GetPointsAttr().Get(), dtype=np.float64)
            klass = UsdGeom.PrimvarsAPI(prim).GetPrimvar("pavonine_ocellarClass").Get()
            counts = np.array(curves.GetCurveVertexCountsAttr().Get())
            return points, np.array(klass), counts
    raise AssertionError(f"{asset}: no barbs")


def targets(asset: Path = ASSET) -> dict[str, np.ndarray]:
    """Points on the barbs (cm, the asset's space): ``vane`` and ``heart_edge``."""
    points, klass, counts = _barbs(asset)
    lo, hi = points.min(axis=0), points.max(axis=0)

    def on_surface(x: float, y: float) -> np.ndarray:
        d = np.hypot(points[:, 0] - x, points[:, 1] - y)
        return np.array([x, y, points[np.argsort(d)[:40], 2].max()])

    vane = on_surface(lo[0] + 0.68 * (hi[0] - lo[0]), lo[1] + 0.6 * (hi[1] - lo[1]))
    ends = np.cumsum(counts) - 1
    step = (klass[:-1] == 5) & (klass[1:] == 4)
    step[ends[:-1]] = False
    edge = 0.5 * (points[:-1][step] + points[1:][step])
    right = edge[edge[:, 0] > np.percentile(edge[:, 0], 90)]  # the heart's right-hand edge
    heart = on_surface(*np.median(right[:, :2], axis=0))
    return {"vane": vane, "heart_edge": heart}


def close_up(
    folder: Path,
    name: str,
    target: np.ndarray,
    field_cm: float,
    resolution: int,
    geometry: str = "barbs",
    asset: Path = ASSET,
) -> Path:
    """A stage looking down −z at ``target`` from ``field_cm``·50/24 above it (module docstring)."""
    distance = field_cm * 50.0 / 24.0
    x, y, z = (float(v) for v in target)
    text = f"""#usda 1.0
(
    defaultPrim = "World"
    metersPerUnit = 0.01
    upAxis = "Y"
    renderSettingsPrimPath = "/Render/Settings"
)
def Xform "World"
{{
    def Xform "Feather" (
        prepend references = @{asset}@
        variants = {{ string geometry = "{geometry}" }}
    )
    {{
    }}
    def Camera "Camera"
    {{
        float focalLength = 50
        float horizontalAperture = 24
        float verticalAperture = 24
        float2 clippingRange = ({distance / 50:.4f}, 100)
        double3 xformOp:translate = ({x:.5f}, {y:.5f}, {z + distance:.5f})
        uniform token[] xformOpOrder = ["xformOp:translate"]
    }}
    def DistantLight "Sun"
    {{
        float inputs:angle = 0.53
        float inputs:intensity = 3.14159
        bool inputs:normalize = 1
        float xformOp:rotateY = 25
        uniform token[] xformOpOrder = ["xformOp:rotateY"]
    }}
}}
def Scope "Render"
{{
    def RenderSettings "Settings"
    {{
        rel camera = </World/Camera>
        int2 resolution = ({resolution}, {resolution})
    }}
}}
"""
    path = folder / f"{name}_{geometry}.usda"
    path.write_text(text)
    return path


def shared_detail(first: np.ndarray, second: np.ndarray) -> float:
    """The fine detail two seeds' renders of one view share (module docstring)."""
    from scipy import ndimage

    a, b = luminance(first), luminance(second)
    ha = a - ndimage.gaussian_filter(a, HIGH_PASS_SIGMA)
    hb = b - ndimage.gaussian_filter(b, HIGH_PASS_SIGMA)
    windows = shared_windows((a, b), WINDOW, detail=(ha, hb))
    return float(np.median([cov / mean**2 for cov, mean in windows]))


def render(path: Path, spp: int, seed: int) -> np.ndarray:
    """The stage's colour (linear Rec. 709)."""
    from pavonine.render.api import render_stage

    return render_stage(path, spp=spp, seed=seed, progress=False).rgb
