"""USD's default view: a stage without a camera is framed as usdrecord / usdview frame it."""

from __future__ import annotations

import math

import numpy as np
import pytest
from pxr import Gf, UsdGeom, UsdLux
from render_helpers import render

from pavonine.render import camera


def test_usd_view_matrix_is_frame_recorders():
    """frameRecorder.cpp: distance = |half diagonal in the image plane| / tan(half fov) + depth/2,
    plus the near clip (1) when that is closer than it."""
    half_fov = math.atan(20.955 / 100.0)
    matrix = camera.usd_view_matrix(([-1, -1, -1], [1, 1, 1]), "Y")
    assert matrix[3, :3] == pytest.approx([0, 0, math.sqrt(2) / math.tan(half_fov) + 1], rel=1e-6)
    z_up = camera.usd_view_matrix(([0, 0, 0], [2, 2, 2]), "Z")
    assert z_up[3, :3] == pytest.approx([1, 1 - (math.sqrt(2) / math.tan(half_fov) + 1), 1])
    assert z_up[2, :3] == pytest.approx([0, -1, 0])  # the camera's +Z (it looks down −Z) is −Y
    tiny = camera.usd_view_matrix(([-0.01] * 3, [0.01] * 3), "Y")
    near = 0.01 * math.sqrt(2) / math.tan(half_fov) + 0.01
    assert tiny[3, 2] == pytest.approx(near + 1.0, rel=1e-6)


def row_of_cubes(tmp_path, up="Y"):
    """Five unit cubes along +X (x = 0..8), lit from the front by a sun shining down −Z."""
    from pxr import Usd

    stage = Usd.Stage.CreateNew(str(tmp_path / f"row_{up}.usda"))
    UsdGeom.SetStageUpAxis(stage, up)
    for i in range(5):
        cube = UsdGeom.Cube.Define(stage, f"/Row/Cube{i}")
        cube.CreateSizeAttr(1.0)
        cube.AddTranslateOp().Set(Gf.Vec3d(2.0 * i, 0, 0))
    sun = UsdLux.DistantLight.Define(stage, "/Sun")
    sun.CreateIntensityAttr(3.0)
    sun.CreateNormalizeAttr(True)  # irradiance 3, whatever its angle
    if up == "Z":
        sun.AddRotateXOp().Set(90.0)  # shine along +Y, onto the faces the Z-up view sees
    return stage


def projected_box(bounds, up: str, size: tuple[int, int]) -> tuple[float, float, float, float]:
    """Pixel bounds (x0, x1, y0, y1) of the stage's box through usdrecord's camera, projected by
    USD's own ``GfFrustum`` (independent of the renderer's sensor)."""
    gf = Gf.Camera()
    gf.transform = Gf.Matrix4d(camera.usd_view_matrix(bounds, up).tolist())
    frustum = gf.frustum
    to_ndc = frustum.ComputeViewMatrix() * frustum.ComputeProjectionMatrix()
    lo, hi = bounds
    corners = [
        Gf.Vec3d(x, y, z) for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])
    ]
    ndc = np.array([list(to_ndc.Transform(c))[:2] for c in corners])
    w, h = size
    xs = (ndc[:, 0] + 1) / 2 * w
    ys = (1 - ndc[:, 1]) / 2 * h  # image rows run down
    return xs.min(), xs.max(), ys.min(), ys.max()


@pytest.mark.render
@pytest.mark.parametrize("up", ["Y", "Z"])
def test_a_stage_without_camera_is_seen_as_usdrecord_sees_it(tmp_path, up):
    """usd-wg normalsTypes: a row of cubes along +X must come out horizontal, seen from the front."""
    stage = row_of_cubes(tmp_path, up)
    size = camera.usd_view_resolution(96)
    assert size == (96, 70)  # 96 / (20.955 / 15.2908), as usdrecord sizes its image
    result = render(stage, spp=4, resolution=size)
    assert result.metadata["camera"] == "(framing camera)"
    seen = result.rgb.mean(axis=2) > 0.02
    rows, cols = np.nonzero(seen)
    x0, x1, y0, y1 = projected_box(([-0.5, -0.5, -0.5], [8.5, 0.5, 0.5]), up, size)
    assert cols.min() == pytest.approx(x0, abs=1.0) and cols.max() + 1 == pytest.approx(x1, abs=1.0)
    assert rows.min() == pytest.approx(y0, abs=1.0) and rows.max() + 1 == pytest.approx(y1, abs=1.0)
    assert (x1 - x0) > 5 * (y1 - y0)  # horizontal
    # seen from the front: five separate cubes with four gaps between them along the row
    middle = seen[int((y0 + y1) / 2)]
    assert np.count_nonzero(np.diff(np.r_[0, middle.astype(int)]) == 1) == 5


@pytest.mark.render
def test_portrait_framing_stays_an_explicit_choice(tmp_path):
    stage = row_of_cubes(tmp_path)
    usd = render(stage, spp=1, resolution=(32, 32))
    portrait = render(stage, spp=1, resolution=(32, 32), framing="portrait")
    assert not np.array_equal(usd.rgb, portrait.rgb)
    with pytest.raises(Exception, match="framing"):
        render(stage, spp=1, resolution=(8, 8), framing="sideways")
