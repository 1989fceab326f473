"""IES profiles (UsdLux ``ShapingAPI`` ``shaping:ies:*``): the LM-63 parser against closed forms,
and lights shaped by a profile with a step at 30° lighting a floor where the file says."""

from __future__ import annotations

import math

import numpy as np
import pytest
from pxr import Gf, Sdf, UsdGeom, UsdLux
from render_helpers import new_stage, quad, render

from pavonine.render.lights import ies

#: a type C profile, symmetric about its axis: 1000 cd up to 30° off the nadir, none beyond
STEP_IES = """IESNA:LM-63-2002
[TEST] step at 30 degrees
[MANUFAC] Pavonine tests
TILT=NONE
1 -1 1 6 1 1 2 0.0 0.0 0.0
1.0 1.0 10
0, 29.99, 30.01, 90,
120 180
0.0
1000 1000 0 0 0 0
"""
STEP_DEG = 30.0
STEP_CD = 1000.0


def step_file(tmp_path, text=STEP_IES):
    path = tmp_path / "step.ies"
    path.write_text(text)
    return path


def test_parser_reads_the_lm63_layout_and_its_flux_is_the_closed_form(tmp_path):
    profile = ies.read_ies(step_file(tmp_path))
    assert profile.vertical_deg.tolist() == [0, 29.99, 30.01, 90, 120, 180]
    assert profile.candela.shape == (1, 6) and profile.lumens_per_lamp == -1
    theta = np.radians([0.0, 20.0, 29.9, 30.1, 60.0, 150.0])
    assert profile.intensity(theta, 1.0).tolist() == [1000, 1000, 1000, 0, 0, 0]
    # a cone of half-angle 30° at I: Φ = 2π I (1 − cos 30°), to within the midpoint rule's
    # misplacement of the step by up to half a cell (π/2048): 2π I sin 30° · π/2048
    cone = 2.0 * math.pi * STEP_CD * (1.0 - math.cos(math.radians(STEP_DEG)))
    half_cell = 2.0 * math.pi * STEP_CD * math.sin(math.radians(STEP_DEG)) * math.pi / 2048
    assert abs(profile.flux(1024) - cone) <= half_cell


def test_tilt_include_multipliers_and_quadrant_symmetry():
    text = """TILT=INCLUDE
1
3
0 45 90
1 0.9 0.8
2 100 2 3 3 1 1 0 0 0
0.5 1 50
0 45 90
0 45 90
10 10 10
20 20 20
30 30 30
"""
    profile = ies.parse_ies(text)
    assert profile.candela[:, 0].tolist() == [10, 20, 30]  # × multiplier 2 × ballast 0.5
    at = [math.radians(a) for a in (0, 45, 90, 135, 180, 225, 315)]
    values = profile.intensity(np.full(7, 0.2), np.array(at))
    assert values.tolist() == pytest.approx([10, 20, 30, 20, 10, 20, 20])  # mirrored per quadrant


@pytest.mark.parametrize(
    ("text", "field"),
    [
        ("1 2 3\n", "no TILT= line"),
        ("TILT=NONE\n1 -1 1 4 1 1 2 0 0 0\n1 1 10\n0 90\n0\n1 2\n", "cut short"),
        ("TILT=NONE\n1 -1 1 2 1 1 2 0 0 0\n1 1 10\n90 0\n0\n1 2\n", "vertical angles"),
        ("TILT=NONE\n1 -1 1 2 1 7 2 0 0 0\n1 1 10\n0 90\n0\n1 2\n", "photometric type"),
        ("TILT=NONE\n1 -1 1 2 1 1 2 0 0 0\n1 1 10\n0 90\n0\n1 x\n", "'x' is not a number"),
    ],
)
def test_a_malformed_file_is_one_error_naming_the_file(text, field):
    with pytest.raises(ies.IesError, match=field) as info:
        ies.parse_ies(text, "lamp.ies")
    assert str(info.value).startswith("lamp.ies: ")


def test_angle_scale_is_the_usdlux_formula():
    theta = np.radians([10.0, 90.0, 170.0])
    assert ies.scaled_theta(theta, 0.0) == pytest.approx(theta)
    assert ies.scaled_theta(theta, 0.5) == pytest.approx(theta / 0.5)
    assert ies.scaled_theta(theta, -0.5) == pytest.approx((theta - math.pi) / 0.5 + math.pi)


def test_normalised_table_keeps_the_light_s_power(tmp_path):
    profile = ies.read_ies(step_file(tmp_path))
    table = ies.profile_table(profile, 0.0, True, 720, 1)
    assert ies.sphere_integral(table) == pytest.approx(4.0 * math.pi, rel=1e-6)
    raw = ies.profile_table(profile, 0.0, False, 720, 1)
    assert raw.max() == STEP_CD  # unnormalised: the candela values scale the radiance (UsdLux)


# -- rendered: the step lands on the floor where the file puts it ---------------------------------

HEIGHT = 1.0  # the light over the floor
HALF_VIEW = 1.5  # the orthographic camera sees ±1.5 around the light's foot
SIZE = 96


def floor_stage(tmp_path, name, kind, ies_file=None, **shaping):
    stage = new_stage(tmp_path / f"{name}.usda", up="Z", camera_z=5.0)
    camera = UsdGeom.Camera.Get(stage, "/Cam")
    camera.CreateProjectionAttr(UsdGeom.Tokens.orthographic)
    camera.CreateHorizontalApertureAttr(20.0 * HALF_VIEW)  # tenths of a unit: ±1.5 units
    camera.CreateVerticalApertureAttr(20.0 * HALF_VIEW)
    quad(stage, "/Floor", size=4.0)
    if kind == "point":
        light = UsdLux.SphereLight.Define(stage, "/Lamp")
        light.CreateTreatAsPointAttr(True)
    elif kind == "sphere":
        light = UsdLux.SphereLight.Define(stage, "/Lamp")
        light.CreateRadiusAttr(0.01)
    elif kind == "disk":
        light = UsdLux.DiskLight.Define(stage, "/Lamp")
        light.CreateRadiusAttr(0.01)
    elif kind == "rect":
        light = UsdLux.RectLight.Define(stage, "/Lamp")
        light.CreateWidthAttr(0.02)
        light.CreateHeightAttr(0.02)
    else:
        light = UsdLux.CylinderLight.Define(stage, "/Lamp")
        light.CreateRadiusAttr(0.01)
        light.CreateLengthAttr(0.02)
    light.CreateIntensityAttr(1.0)
    light.CreateNormalizeAttr(True)
    light.AddTranslateOp().Set(Gf.Vec3d(0, 0, HEIGHT))  # its −Z axis points at the floor
    if ies_file is not None:
        shaping_api = UsdLux.ShapingAPI.Apply(light.GetPrim())
        shaping_api.CreateShapingIesFileAttr(Sdf.AssetPath(str(ies_file)))
        for key, value in shaping.items():
            light.GetPrim().GetAttribute(f"inputs:shaping:ies:{key}").Set(value)
    return stage


def shaped_ratio(tmp_path, kind, spp=16, **shaping):
    """Per pixel of the floor, the shaped light's irradiance ÷ the unshaped light's, and the
    pixels' distances from the light's foot (floor units)."""
    plain = render(floor_stage(tmp_path, f"{kind}_plain", kind), spp=spp, resolution=(SIZE, SIZE))
    shaped = render(
        floor_stage(tmp_path, f"{kind}_ies", kind, step_file(tmp_path), **shaping),
        spp=spp,
        resolution=(SIZE, SIZE),
    )
    assert not [w for w in shaped.warnings if "ies" in w], shaped.warnings
    luminance = np.array([0.2126, 0.7152, 0.0722])
    ratio = (shaped.rgb[..., :3] @ luminance) / np.maximum(plain.rgb[..., :3] @ luminance, 1e-9)
    centres = (np.arange(SIZE) + 0.5) / SIZE * 2.0 * HALF_VIEW - HALF_VIEW
    x, y = np.meshgrid(centres, centres)
    return ratio, np.hypot(x, y)


def edge_and_level(ratio, radius, inside_within):
    """The lit disc's radius from its area (lit pixels × pixel area = π r²) and the mean ratio
    well inside it."""
    level = float(np.median(ratio[radius < inside_within]))
    lit = np.count_nonzero(ratio > 0.5 * level)
    pixel = (2.0 * HALF_VIEW / SIZE) ** 2
    return math.sqrt(lit * pixel / math.pi), level


@pytest.mark.render
@pytest.mark.parametrize("kind", ["point", "disk", "sphere", "rect", "cylinder"])
def test_a_step_at_30_degrees_lands_where_the_file_puts_it_with_the_light_s_power(tmp_path, kind):
    ratio, radius = shaped_ratio(tmp_path, kind, normalize=True)
    edge, level = edge_and_level(ratio, radius, 0.3)
    assert math.degrees(math.atan(edge / HEIGHT)) == pytest.approx(STEP_DEG, abs=1.0)
    # normalised, the light keeps its power: all of it in the 30° cone, f = 4π / Ω_cone inside
    cone = 2.0 * math.pi * (1.0 - math.cos(math.radians(STEP_DEG)))
    assert level == pytest.approx(4.0 * math.pi / cone, rel=0.05)
    assert np.percentile(ratio[radius > 1.2 * edge], 99) < 0.01 * level  # dark beyond the step


@pytest.mark.render
def test_angle_scale_moves_the_step_and_unnormalised_candela_scale_the_light(tmp_path):
    ratio, radius = shaped_ratio(tmp_path, "point", angleScale=0.5)
    edge, level = edge_and_level(ratio, radius, 0.15)
    # θ_ies = θ / 0.5: the file's 30° step is met at 15° off the axis
    assert math.degrees(math.atan(edge / HEIGHT)) == pytest.approx(STEP_DEG / 2, abs=1.0)
    assert level == pytest.approx(STEP_CD, rel=0.02)  # not normalised: × the candela values


@pytest.mark.render
def test_the_profile_point_light_starts_light_paths_as_it_ends_them():
    """``pavonine_ies_point``'s ``sample_ray`` (light tracing) against its ``sample_direction``
    (path tracing): Mitsuba's ``ptracer`` and ``path`` see the same floor under a 30° step."""
    import mitsuba as mi

    from pavonine.base.backend import select_variant
    from pavonine.render.lights import ies_emitter
    from pavonine.render.lights.common import bitmap, transform

    select_variant(None)
    ies_emitter.register()
    theta, _ = ies.texel_angles(720, 1)
    table = np.where(theta < math.radians(STEP_DEG), 1.0, 0.0)
    light = {
        "type": ies_emitter.POINT_PLUGIN,
        "inner": {"type": "point", "position": [0, 0, 1], "intensity": 1.0},
        "light_to_world": transform(np.eye(4)),
        "profile": bitmap(table[..., None]),
    }
    means = []
    for integrator in ("path", "ptracer"):
        scene = mi.load_dict(
            {
                "type": "scene",
                "integrator": {"type": integrator, "max_depth": 2},
                "sensor": {
                    "type": "perspective",
                    "fov": 60,
                    "to_world": mi.ScalarTransform4f().look_at([0, 0, 4], [0, 0, 0], [0, 1, 0]),
                    "film": {"type": "hdrfilm", "width": 32, "height": 32},
                },
                "floor": {"type": "rectangle", "to_world": mi.ScalarTransform4f().scale(3)},
                "light": light,
            }
        )
        means.append(float(np.mean(mi.render(scene, spp=64))))
    assert means[1] == pytest.approx(means[0], rel=0.05)
