"""Geometry translators seen in renders: implicit prims, subdivision, back faces, curves, skinning."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from pxr import Gf, Sdf, Usd, UsdGeom, UsdLux

from pavonine.render.api import render_stage
from pavonine.render.diagnostics import StageWarning

pytestmark = pytest.mark.render
SIZE = 48
FRAME = 3.0  # the orthographic camera sees [-1.5, 1.5]² of the z = 0 plane


def lit_stage(path, sun_tilt=0.0):
    """A stage with an orthographic camera looking down −Z at [-1.5, 1.5]² and a sun behind it
    (``sun_tilt`` degrees about X off the view direction)."""
    stage = Usd.Stage.CreateNew(str(path))
    cam = UsdGeom.Camera.Define(stage, "/Cam")
    cam.CreateProjectionAttr(UsdGeom.Tokens.orthographic)
    cam.CreateHorizontalApertureAttr(FRAME * 10)  # tenths of a scene unit
    cam.CreateVerticalApertureAttr(FRAME * 10)
    cam.CreateClippingRangeAttr(Gf.Vec2f(0.1, 100))
    cam.AddTranslateOp().Set(Gf.Vec3d(0, 0, 10))
    sun = UsdLux.DistantLight.Define(stage, "/Sun")
    sun.CreateAngleAttr(0.0)
    sun.CreateIntensityAttr(math.pi)
    sun.CreateNormalizeAttr(True)
    sun.AddRotateXOp().Set(sun_tilt)
    return stage


def render(stage, spp=4):
    stage.Save()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", StageWarning)
        result = render_stage(
            stage.GetRootLayer().realPath, spp=spp, resolution=(SIZE, SIZE), progress=False
        )
    return result.rgb.mean(axis=2), result.warnings


def coverage(image):
    return float((image > 0.02).mean())


def test_sphere_silhouette_is_the_disc_of_its_radius(tmp_path):
    stage = lit_stage(tmp_path / "sphere.usda")
    UsdGeom.Sphere.Define(stage, "/Ball").CreateRadiusAttr(1.2)
    image, warnings_ = render(stage)
    assert warnings_ == []
    assert coverage(image) == pytest.approx(math.pi * 1.2**2 / FRAME**2, rel=0.03)


def test_capsule_along_x_is_wider_than_tall(tmp_path):
    stage = lit_stage(tmp_path / "capsule.usda")
    capsule = UsdGeom.Capsule.Define(stage, "/Pill")
    capsule.CreateAxisAttr("X")
    capsule.CreateRadiusAttr(0.4)
    capsule.CreateHeightAttr(1.6)
    image, _ = render(stage)
    rows, cols = np.nonzero(image > 0.02)
    width, height = (np.ptp(cols) + 1) * FRAME / SIZE, (np.ptp(rows) + 1) * FRAME / SIZE
    assert width == pytest.approx(1.6 + 0.8, abs=2 * FRAME / SIZE)
    assert height == pytest.approx(0.8, abs=2 * FRAME / SIZE)


def test_subdivided_cube_is_rounder_than_its_cage(tmp_path):
    covered = {}
    for scheme in ("none", "catmullClark"):
        stage = lit_stage(tmp_path / f"{scheme}.usda")
        mesh = UsdGeom.Mesh.Define(stage, "/Cube")
        mesh.CreatePointsAttr([(x, y, z) for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)])
        mesh.CreateFaceVertexCountsAttr([4] * 6)
        quads = [[0, 1, 3, 2], [4, 6, 7, 5], [0, 4, 5, 1], [2, 3, 7, 6], [0, 2, 6, 4], [1, 5, 7, 3]]
        mesh.CreateFaceVertexIndicesAttr([i for q in quads for i in q])
        mesh.CreateSubdivisionSchemeAttr(scheme)
        image, _ = render(stage)
        covered[scheme] = image > 0.02
    cage, smooth = covered["none"], covered["catmullClark"]
    assert coverage(cage) == pytest.approx(4 / FRAME**2, rel=0.05)  # the 2 × 2 square
    assert np.all(cage[smooth])  # the limit surface lies inside the cage
    assert coverage(smooth) < 0.8 * coverage(cage)
    corner = SIZE // 2 - round(0.95 * SIZE / FRAME)  # a pixel near the cage's corner
    assert cage[corner, corner] and not smooth[corner, corner]


def test_single_sided_back_faces_are_culled_double_sided_are_not(tmp_path):
    seen = {}
    for double_sided in (False, True):
        # the sun 50° off the view: the card's shadow falls beside the middle of the wall (shadow
        # rays still stop at culled faces: see the next test and render/facing.py)
        stage = lit_stage(tmp_path / f"sided_{double_sided}.usda", sun_tilt=50.0)
        back = UsdGeom.Mesh.Define(stage, "/Wall")  # faces the camera, lit
        back.CreatePointsAttr([(-1.4, -1.4, -1), (1.4, -1.4, -1), (1.4, 1.4, -1), (-1.4, 1.4, -1)])
        back.CreateFaceVertexCountsAttr([4])
        back.CreateFaceVertexIndicesAttr([0, 1, 2, 3])
        back.CreateSubdivisionSchemeAttr("none")
        back.CreateDisplayColorAttr([(1.0, 0.0, 0.0)])
        card = UsdGeom.Mesh.Define(stage, "/Card")  # wound clockwise: its back faces the camera
        card.CreatePointsAttr([(-0.5, -0.5, 0), (0.5, -0.5, 0), (0.5, 0.5, 0), (-0.5, 0.5, 0)])
        card.CreateFaceVertexCountsAttr([4])
        card.CreateFaceVertexIndicesAttr([0, 3, 2, 1])
        card.CreateSubdivisionSchemeAttr("none")
        card.CreateDoubleSidedAttr(double_sided)
        card.CreateDisplayColorAttr([(0.0, 0.0, 1.0)])
        stage.Save()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", StageWarning)
            rgb = render_stage(
                stage.GetRootLayer().realPath, spp=4, resolution=(SIZE, SIZE), progress=False
            ).rgb
        seen[double_sided] = rgb[SIZE // 2 - 2 : SIZE // 2 + 2, SIZE // 2 - 2 : SIZE // 2 + 2].mean(
            axis=(0, 1)
        )
    culled, shown = seen[False], seen[True]
    assert culled[0] > 0.3 and culled[2] < 0.05  # the red wall shows through the culled card
    assert shown[2] > 0.3 and shown[0] < 0.05  # the double-sided card is blue from behind


def test_single_sided_card_casts_its_shadow_whichever_side_faces_the_light(tmp_path):
    """Culling is for the rays that look: shadow rays stop at a single-sided card from either side
    (the integrator lets shadow rays through ``mask``\\ s, so a front-facing mask would leak light)."""
    for front_up in (True, False):
        stage = lit_stage(tmp_path / f"shadow_{front_up}.usda", sun_tilt=30.0)
        floor = UsdGeom.Mesh.Define(stage, "/Floor")
        floor.CreatePointsAttr([(-2, -2, 0), (2, -2, 0), (2, 2, 0), (-2, 2, 0)])
        floor.CreateFaceVertexCountsAttr([4])
        floor.CreateFaceVertexIndicesAttr([0, 1, 2, 3])
        floor.CreateSubdivisionSchemeAttr("none")
        card = UsdGeom.Mesh.Define(stage, "/Card")  # 1 above the floor, its shadow 0.58 aside
        card.CreatePointsAttr([(-0.5, -0.5, 1), (0.5, -0.5, 1), (0.5, 0.5, 1), (-0.5, 0.5, 1)])
        card.CreateFaceVertexCountsAttr([4])
        card.CreateFaceVertexIndicesAttr([0, 1, 2, 3] if front_up else [0, 3, 2, 1])
        card.CreateSubdivisionSchemeAttr("none")
        image, _ = render(stage)
        # floor strips beside the card's footprint, 0.6-1.0 units above and below it
        strips = sorted([image[8:14, 18:30].mean(), image[34:40, 18:30].mean()])
        assert strips[0] < 0.03 and strips[1] > 0.3, (front_up, strips)


def test_primvar_interpolations_survive_a_render(tmp_path):
    """A vertex displayColor on a subdivided quad renders (the shading side reads the attribute);
    here only that the delegate builds and renders it without a warning."""
    stage = lit_stage(tmp_path / "primvars.usda")
    mesh = UsdGeom.Mesh.Define(stage, "/Quad")
    mesh.CreatePointsAttr([(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)])
    mesh.CreateFaceVertexCountsAttr([4])
    mesh.CreateFaceVertexIndicesAttr([0, 1, 2, 3])
    UsdGeom.PrimvarsAPI(mesh).CreatePrimvar(
        "displayColor", Sdf.ValueTypeNames.Color3fArray, "vertex"
    ).Set([(1, 0, 0), (0, 1, 0), (0, 0, 1), (1, 1, 1)])
    image, warnings_ = render(stage)
    assert warnings_ == [] and coverage(image) == pytest.approx(4 / FRAME**2, rel=0.05)


def test_curves_render_as_tubes_of_their_width(tmp_path):
    stage = lit_stage(tmp_path / "curves.usda")
    curve = UsdGeom.BasisCurves.Define(stage, "/Hair")
    curve.CreateTypeAttr("cubic")
    curve.CreateBasisAttr("bspline")
    curve.CreateWrapAttr("pinned")
    curve.CreateCurveVertexCountsAttr([4])
    curve.CreatePointsAttr([(-1.2, 0, 0), (-0.4, 0, 0), (0.4, 0, 0), (1.2, 0, 0)])
    curve.CreateWidthsAttr([0.3])
    curve.SetWidthsInterpolation("constant")
    image, warnings_ = render(stage)
    assert warnings_ == []
    rows, cols = np.nonzero(image > 0.02)
    # pinned: from end point to end point (Mitsuba's tubes end flat)
    assert (np.ptp(cols) + 1) * FRAME / SIZE == pytest.approx(2.4, abs=2 * FRAME / SIZE)
    assert (np.ptp(rows) + 1) * FRAME / SIZE == pytest.approx(0.3, abs=2 * FRAME / SIZE)


def test_skinned_mesh_renders_in_its_animated_pose(tmp_path):
    from test_geometry import skinned_bar

    stage = lit_stage(tmp_path / "skinned.usda")
    skinned_bar(stage)
    stage.SetStartTimeCode(10)
    stage.SetEndTimeCode(10)
    image, warnings_ = render(stage)
    assert warnings_ == []
    # at time 10 the tip points up: lit pixels above the bar's row, right of the joint at x = 1
    column = SIZE // 2 + round(1.0 * SIZE / FRAME)
    rows = np.nonzero(image[:, column] > 0.02)[0]
    assert rows.size and (SIZE // 2 - rows.min()) * FRAME / SIZE == pytest.approx(1.0, abs=0.15)
