"""Barbs as ribbons (pipeline/convert/barb_curves.py, [geometry.barbs]): recipe keys, the
geometry against the maps it is built from, and the asset's ``geometry`` variant set."""

from __future__ import annotations

import math

import numpy as np
import pytest
from test_recipe import MINIMAL

from pavonine.base.errors import InputError
from pavonine.pipeline.convert.barb_curves import (
    END_COVERAGE,
    FILAMENT_SHARE,
    build_barbs,
    coverage_map,
    filament_share,
)
from pavonine.pipeline.convert.barb_form import CLOSED_COVERAGE, LOOSE_COVERAGE
from pavonine.pipeline.convert.barbs import barb_direction_field
from pavonine.pipeline.convert.rachis import RachisSpec
from pavonine.pipeline.convert.recipe import BarbOptions, parse_recipe
from pavonine.pipeline.convert.surface import FeatherFrame

RECIPE = MINIMAL + "[geometry]\nlength_cm = 20\n"


def _recipe(tmp_path, barbs: str):
    path = tmp_path / "r.toml"
    path.write_text(RECIPE + "[geometry.barbs]\n" + barbs)
    return parse_recipe(path)


def test_barb_keys_reach_the_options(tmp_path):
    text = (
        "enabled = false\nspacing_cm = 0.15\ntip_barbs = 180\nsegment_cm = 0.1\nwidth_share = 0.8\n"
    )
    assert _recipe(tmp_path, text).geometry.barbs == BarbOptions(False, 0.15, 180, 0.1, 0.8)
    assert _recipe(tmp_path, "").geometry.barbs == BarbOptions()
    assert _recipe(tmp_path, "tip_barbs = 0\n").geometry.barbs.tip_barbs == 0  # no fan


@pytest.mark.parametrize(
    ("text", "key", "words"),
    [
        ("thickness = 1\n", "geometry.barbs.thickness", "unknown key"),
        ('enabled = "yes"\n', "geometry.barbs.enabled", "true or false"),
        ("spacing_cm = -0.2\n", "geometry.barbs.spacing_cm", "positive"),
        ("spacing_cm = 0.001\n", "geometry.barbs.spacing_cm", "must lie in [0.01, 2] cm"),
        ("segment_cm = 5.0\n", "geometry.barbs.segment_cm", "must lie in"),
        ("segment_cm = nan\n", "geometry.barbs.segment_cm", "finite"),
        ("tip_barbs = 2.5\n", "geometry.barbs.tip_barbs", "integer"),
        ("tip_barbs = 2\n", "geometry.barbs.tip_barbs", "[4, 4000]"),
        ("tip_barbs = -1\n", "geometry.barbs.tip_barbs", "must not be negative"),
        ("width_share = 3\n", "geometry.barbs.width_share", "(0, 2]"),
    ],
)
def test_bad_barb_keys_are_one_line_errors_naming_the_key(tmp_path, text, key, words):
    with pytest.raises(InputError) as info:
        _recipe(tmp_path, text)
    message = str(info.value)
    assert f"r.toml: {key}" in message and words in message and "\n" not in message


def test_barbs_must_be_a_table(tmp_path):
    path = tmp_path / "r.toml"
    path.write_text(RECIPE + "barbs = 3\n")
    with pytest.raises(InputError, match=r"geometry\.barbs: expected a table"):
        parse_recipe(path)


# --------------------------------------------------------------------------- geometry

SIZE = 256
LENGTH = 20.0
ANGLE = 45.0  # barbs leave the rachis at 45°
STREAK = 0.012  # streak period along the rachis (feather units) painted in the test maps


def _maps(alpha_left: float = 1.0) -> dict[str, np.ndarray]:
    """A 2:1 (height:width) feather: straight barbs at 45° to the rachis, a rectangular vane
    |x| < 0.18, 0.05 < y < 0.85; alpha 1 on the right, ``alpha_left`` on the left; gradation =
    v, melanin = u, angle grey 0.2 (36°), ocellar class 1 above v = 0.5, 2 below."""
    h, w = SIZE, SIZE // 2
    rows, cols = np.mgrid[0:h, 0:w]
    x = ((cols + 0.5) / w - 0.5) * 0.5
    y = 1.0 - (rows + 0.5) / h
    inside = (np.abs(x) < 0.18) & (y > 0.05) & (y < 0.85)
    alpha = np.where(inside, np.where(x < 0, alpha_left, 1.0), 0.0).astype(np.float32)
    y0 = y - np.abs(x) / math.tan(math.radians(ANGLE))
    ridge = (0.5 + 0.5 * np.cos(2 * np.pi * y0 / STREAK)) ** 3
    return {
        "alpha": alpha,
        "displacement": (ridge * inside).astype(np.float32),
        "gradation": y.astype(np.float32),
        "melanin": ((cols + 0.5) / w).astype(np.float32),
        "angle": np.full((h, w), 0.2, np.float32),
        "ocellar": np.where(y > 0.5, 0.8, 0.6).astype(np.float32),  # classes 1 and 2
    }


def _build(maps, spacing_cm: float = 0.3, top: float = 0.8):
    frame = FeatherFrame(LENGTH, 0.5, 0.0, 0.0)
    rachis = RachisSpec(1.0, top, 0.05, 0.02)
    options = BarbOptions(spacing_cm=spacing_cm, segment_cm=0.1)
    field = barb_direction_field(maps["displacement"])
    return build_barbs(maps, field, frame, rachis, options), frame


def _rachis_barbs(barbs, side: float):
    """(first vertex, all vertices) of each barb starting on one side of the rachis below 0.75."""
    starts = np.cumsum(barbs.counts) - barbs.counts
    first = barbs.points[starts]
    chosen = (np.sign(first[:, 0]) == side) & (first[:, 1] < 0.75 * LENGTH)
    return starts[chosen], barbs.counts[chosen]


def test_barbs_leave_the_rachis_every_spacing_at_the_maps_angle():
    barbs, _ = _build(_maps())
    starts, counts = _rachis_barbs(barbs, 1.0)
    heights = np.sort(barbs.points[starts, 1])
    steps = np.diff(heights)
    assert np.allclose(steps, 0.3, rtol=0.02)
    # The direction the maps give: 45° to the rachis, measured from the streaks.
    mid = starts + counts // 2
    angle = np.degrees(np.arctan2(barbs.tangent[mid, 0], barbs.tangent[mid, 1]))
    assert np.median(angle) == pytest.approx(ANGLE, abs=3.0)


def test_ribbons_abut_where_the_vane_is_closed():
    """Alpha 1: each ribbon spans the distance to its neighbours, spacing x sin(angle)."""
    barbs, _ = _build(_maps())
    starts, counts = _rachis_barbs(barbs, 1.0)
    mid = starts + counts // 2
    expected = 0.3 * math.sin(math.radians(ANGLE))
    assert np.median(barbs.widths[mid]) == pytest.approx(expected, rel=0.05)


def test_barbs_end_at_the_silhouette():
    maps = _maps()
    barbs, frame = _build(maps)
    ends = np.cumsum(barbs.counts) - 1
    starts = ends - barbs.counts + 1
    end_x = np.abs(barbs.points[ends, 0]) / frame.width  # in the map's width units
    # Rachis barbs starting low enough to reach the side run out at the vane's edge |x| = 0.18
    # (feather units; 0.36 of the width) within one barb spacing, never past it.
    low = barbs.points[starts, 1] < 0.6 * LENGTH
    assert low.sum() >= 2 * 0.55 * LENGTH / 0.3 - 2
    edge = 0.18 / 0.5
    spacing_w = 0.3 / frame.width
    assert np.all(np.abs(end_x[low] - edge) < spacing_w)
    interior = np.ones(barbs.vertex_count, bool)
    interior[ends] = False
    assert np.all(barbs.coverage[interior] > END_COVERAGE)  # nothing drawn outside the vane
    assert np.all(barbs.coverage[ends[low]] < 0.1)  # the last vertex is on the fading edge


def test_partial_alpha_thins_and_separates_barbs_instead_of_cutting_them():
    barbs, _ = _build(_maps(alpha_left=0.4))
    left, lcounts = _rachis_barbs(barbs, -1.0)
    right, rcounts = _rachis_barbs(barbs, 1.0)
    assert len(left) == len(right)  # as many barbs: none cut away
    assert np.median(lcounts) == pytest.approx(np.median(rcounts), rel=0.1)  # as long
    lw = np.median(barbs.widths[left + lcounts // 2])
    rw = np.median(barbs.widths[right + rcounts // 2])
    # Alpha 0.4 is loose (below LOOSE_COVERAGE): free filaments, FILAMENT_SHARE of the 40 %
    # the coverage alone gives, the rest background between them.
    assert lw / rw == pytest.approx(0.4 * FILAMENT_SHARE, abs=0.03)


def test_loose_barbs_thin_to_filaments_without_a_step():
    """The width's filament share: 1 where barbs interlock, FILAMENT_SHARE where they hang loose,
    linear between (continuous along a barb whose coverage crosses the levels)."""
    c = np.array([0.0, 0.4, LOOSE_COVERAGE, 0.5 * (LOOSE_COVERAGE + CLOSED_COVERAGE)])
    c = np.append(c, [CLOSED_COVERAGE, 1.0])
    share = filament_share(c)
    half = 0.5 * (1.0 + FILAMENT_SHARE)
    assert np.allclose(share, [FILAMENT_SHARE] * 3 + [half, 1.0, 1.0])
    fine = np.linspace(0.0, 1.0, 10_001)
    assert np.max(np.abs(np.diff(filament_share(fine)))) < 1e-3  # no step


def test_primvars_are_the_maps_at_each_vertex():
    """Against the analytic maps, read at each vertex's object-space position (not its UV)."""
    barbs, frame = _build(_maps())
    v = barbs.points[:, 1] / LENGTH
    u = barbs.points[:, 0] / frame.width + 0.5
    assert np.allclose(barbs.gradation, v, atol=1.5 / SIZE)
    assert np.allclose(barbs.melanin, u, atol=1.5 / (SIZE // 2))
    assert np.allclose(barbs.barbule_angle_deg, 36.0, atol=0.1)
    away = np.abs(v - 0.5) > 2.0 / SIZE
    assert np.all(barbs.ocellar_class[away] == np.where(v[away] > 0.5, 1, 2))
    assert np.array_equal(barbs.barb_id, np.arange(barbs.barb_count))


def test_coverage_is_the_alpha_map_over_one_spacing():
    alpha = np.zeros((64, 64), np.float32)
    alpha[:, ::2] = 1.0  # stripes: half covered at any scale above a texel
    assert coverage_map(alpha, 8.0)[16:48, 16:48] == pytest.approx(0.5, abs=0.07)


def test_the_eye_radiates_from_the_rachis_tip():
    from pavonine.pipeline.maps.paint import generate_maps

    maps = generate_maps("eye", 256, seed=4)
    frame = FeatherFrame(30.0, 0.5, 0.0, 0.0)
    rachis = RachisSpec(5.0, 0.74, 0.14, 0.03)
    field = barb_direction_field(maps["displacement"])
    barbs = build_barbs(maps, field, frame, rachis, BarbOptions())
    tip = np.array([0.0, 0.74 * 30.0])
    starts = np.cumsum(barbs.counts) - barbs.counts
    # Tip barbs start on a circle of the rachis tip's radius (0.03 cm) around it.
    from_tip = np.abs(np.linalg.norm(barbs.points[starts, :2] - tip, axis=1) - 0.03) < 0.002
    assert from_tip.sum() >= 0.8 * 240  # most of the 240 per turn survive in the eye
    ends = starts + barbs.counts - 1
    ray = barbs.points[ends[from_tip], :2] - tip
    first = barbs.points[starts[from_tip] + 1, :2] - tip
    cos = np.sum(ray * first, axis=1) / (
        np.linalg.norm(ray, axis=1) * np.linalg.norm(first, axis=1)
    )
    assert np.all(cos > 0.999)  # straight out from the tip


# --------------------------------------------------------------------------- the asset


def test_the_asset_switches_between_sheet_and_barbs(eye_asset):
    from pxr import Usd, UsdGeom, UsdShade

    from pavonine.pipeline.convert.barb_layer import BARB_ID, PRIMVARS
    from pavonine.schemas.findings import validate_stage
    from pavonine.schemas.primvars import FEATHER_UV_PRIMVAR

    stage = Usd.Stage.Open(str(eye_asset))
    stage.SetEditTarget(stage.GetSessionLayer())  # the shared asset's files stay as converted
    prim = stage.GetDefaultPrim()
    geom = f"/{prim.GetName()}/Geom"
    variants = prim.GetVariantSets().GetVariantSet("geometry")
    assert sorted(variants.GetVariantNames()) == ["barbs", "sheet"]
    assert variants.GetVariantSelection() == "sheet"  # shipped renders keep the sheet
    assert stage.GetPrimAtPath(f"{geom}/Vane").IsActive()
    assert not stage.GetPrimAtPath(f"{geom}/Barbs")
    variants.SetVariantSelection("barbs")
    assert not stage.GetPrimAtPath(f"{geom}/Vane").IsActive()
    assert stage.GetPrimAtPath(f"{geom}/Rachis").IsActive()
    curves = UsdGeom.BasisCurves(stage.GetPrimAtPath(f"{geom}/Barbs"))
    counts = np.array(curves.GetCurveVertexCountsAttr().Get())
    n = int(counts.sum())
    assert len(counts) > 100 and curves.GetTypeAttr().Get() == "linear"
    assert len(curves.GetNormalsAttr().Get()) == n and curves.GetNormalsInterpolation() == "vertex"
    widths = np.array(curves.GetWidthsAttr().Get())
    assert len(widths) == n and widths.max() > 0.0 and np.all(widths >= 0.0)
    api = UsdGeom.PrimvarsAPI(curves)
    for name in (FEATHER_UV_PRIMVAR, *PRIMVARS, "displayColor"):
        primvar = api.GetPrimvar(name)
        assert primvar.GetInterpolation() == "vertex" and len(primvar.Get()) == n, name
    assert len(api.GetPrimvar(BARB_ID).Get()) == len(counts)
    assert api.GetPrimvar(BARB_ID).GetInterpolation() == "uniform"
    binding = UsdShade.MaterialBindingAPI(curves.GetPrim())
    assert binding.ComputeBoundMaterial()[0].GetPath().name == "Feather"
    preview = binding.ComputeBoundMaterial(UsdShade.Tokens.preview)[0]
    assert preview.GetPath().name == "FeatherBarbsPreview"
    reader = UsdShade.Shader(preview.GetPrim().GetChild("DisplayColor"))
    assert reader.GetInput("varname").Get() == "displayColor"
    assert [f.line() for f in validate_stage(stage, str(eye_asset)) if f.severity == "ERROR"] == []
    # The lod variants still choose the rachis under the barbs.
    prim.GetVariantSets().GetVariantSet("lod").SetVariantSelection("low")
    assert stage.GetPrimAtPath(f"{geom}/Barbs") and stage.GetPrimAtPath(f"{geom}/Rachis")


def test_baked_barb_colours_follow_the_ocellus(eye_asset):
    """displayColor is the sheet's bake: the heart (class 5) is darker than the vane (class 1),
    where both face the sheet's way (within 25° of +z: loose barbs drooping out of the vane,
    ``barb_form``, face elsewhere and take the bake of their own tilt)."""
    from pxr import Usd, UsdGeom

    stage = Usd.Stage.Open(str(eye_asset))
    stage.SetEditTarget(stage.GetSessionLayer())
    prim = stage.GetDefaultPrim()
    prim.GetVariantSets().GetVariantSet("geometry").SetVariantSelection("barbs")
    api = UsdGeom.PrimvarsAPI(stage.GetPrimAtPath(f"/{prim.GetName()}/Geom/Barbs"))
    colour = np.array(api.GetPrimvar("displayColor").Get())
    klass = np.array(api.GetPrimvar("pavonine_ocellarClass").Get())
    facing = np.array(UsdGeom.BasisCurves(api.GetPrim()).GetNormalsAttr().Get())[:, 2] > 0.9
    assert np.all((colour >= 0.0) & (colour <= 1.0))
    # Darker as luminance (Rec. 709 Y of the linear colour), not as R + G + B: the heart's violet
    # is mostly blue (shipped asset: mean (0.10, 0.01, 0.45), Y 0.057 against the vane's 0.322).
    luminance = colour @ np.array([0.2126, 0.7152, 0.0722])
    heart, vane = (luminance[(klass == k) & facing].mean() for k in (5, 1))
    assert heart < vane, (heart, vane)


def test_a_train_row_can_take_the_barbs_still_instanced(tmp_path):
    """The front row of eye feathers as barbs: a second prototype of the same component with its
    geometry variant selected; the other rows keep the sheet."""
    from pathlib import Path

    from click.testing import CliRunner
    from pxr import Usd, UsdGeom

    from pavonine.apps.cli import cli

    repo = Path(__file__).parents[2]
    text = (repo / "assets" / "recipes" / "peacock_train.toml").read_text()
    text = text.replace('"../feathers/', f'"{repo / "assets" / "feathers"}/')
    front = "count = 28\nradius_cm = 32.4\n"
    assert front in text
    (tmp_path / "train.toml").write_text(text.replace(front, front + 'geometry = "barbs"\n'))
    result = CliRunner().invoke(
        cli, ["assemble", "train", str(tmp_path / "train.toml"), "-o", str(tmp_path / "out")]
    )
    assert result.exit_code == 0, result.output
    stage = Usd.Stage.Open(str(tmp_path / "out" / "peacock_train" / "peacock_train.usda"))
    instancer = next(
        UsdGeom.PointInstancer(p) for p in stage.Traverse() if p.IsA(UsdGeom.PointInstancer)
    )
    targets = instancer.GetPrototypesRel().GetTargets()
    names = [t.name for t in targets]
    assert names == ["blue", "eye", "fishtail", "yellow", "eye_barbs"]
    indices = np.array(instancer.GetProtoIndicesAttr().Get())
    assert np.sum(indices == names.index("eye_barbs")) == 28  # the front row
    assert np.sum(indices == names.index("eye")) > 100  # the rows behind keep the sheet
    barbs = stage.GetPrimAtPath(targets[-1])
    assert barbs.GetVariantSet("geometry").GetVariantSelection() == "barbs"
    assert barbs.GetChild("Geom").GetChild("Barbs").IsA(UsdGeom.BasisCurves)
    assert not barbs.GetChild("Geom").GetChild("Vane").IsActive()
    sheet = stage.GetPrimAtPath(targets[1])
    assert sheet.GetChild("Geom").GetChild("Vane").IsActive()
    assert not sheet.GetChild("Geom").GetChild("Barbs")


def test_a_bad_row_geometry_is_named(tmp_path):
    from pavonine.pipeline.assemble.recipe import parse_train_recipe

    text = (
        'name = "t"\n[components]\neye = "e.usd"\n'
        '[[rows]]\ncomponent = "eye"\ncount = 3\nradius_cm = 5\ngeometry = "fur"\n'
    )
    (tmp_path / "t.toml").write_text(text)
    (tmp_path / "e.usd").write_text("#usda 1.0\n")
    with pytest.raises(
        InputError, match=r"t\.toml: rows\.0\.geometry: expected one of sheet, barbs"
    ):
        parse_train_recipe(tmp_path / "t.toml")


def test_ring_boundaries_sit_where_the_map_puts_them_not_half_a_segment_off():
    """Classes 1 | 2 meet at v = 0.5 in the test maps: every barb crossing it switches class
    between two vertices straddling v = 0.5 (the bilinear mid-level contour of the map)."""
    barbs, _ = _build(_maps())
    v = barbs.points[:, 1] / LENGTH
    same_barb = barbs.barb_of_vertex()[:-1] == barbs.barb_of_vertex()[1:]
    switch = np.nonzero(same_barb & (barbs.ocellar_class[:-1] != barbs.ocellar_class[1:]))[0]
    assert len(switch) >= 20
    middle = 0.5 * (v[switch] + v[switch + 1])
    assert np.all(np.abs(middle - 0.5) < 2e-4)  # segments are 0.005 long in v
    assert np.all(np.abs(v[switch + 1] - v[switch]) < 2e-4)


def test_no_two_vertices_of_a_barb_coincide():
    """A renderer needs a direction on every segment (the eye's ring boundaries add vertices)."""
    from pavonine.pipeline.maps.paint import generate_maps

    maps = generate_maps("eye", 256, seed=4)
    frame = FeatherFrame(30.0, 0.5, 0.0, 0.0)
    rachis = RachisSpec(5.0, 0.74, 0.14, 0.03)
    barbs = build_barbs(
        maps, barb_direction_field(maps["displacement"]), frame, rachis, BarbOptions()
    )
    same = barbs.barb_of_vertex()[:-1] == barbs.barb_of_vertex()[1:]
    steps = np.linalg.norm(np.diff(barbs.points, axis=0), axis=1)[same]
    assert steps.min() > 1e-4  # cm; segments are 0.2 cm, boundary pairs 0.004 cm apart
