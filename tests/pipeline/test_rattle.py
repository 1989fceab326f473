"""The rattle (``[rattle]`` of a train recipe, ``pipeline/assemble/rattle.py``): time samples
as measured by Dakin et al. 2016, nothing changed without it, bad keys refused on one line."""

from __future__ import annotations

import json
import math
import shutil
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from pxr import Sdf, Usd, UsdGeom

from pavonine.apps.cli import cli
from pavonine.pipeline.assemble import flex as F
from pavonine.pipeline.assemble import rattle as R
from pavonine.pipeline.assemble.recipe import parse_train_recipe

REPO = Path(__file__).parents[2]
TRAIN = REPO / "assets" / "recipes" / "peacock_train.toml"
RATTLE = REPO / "assets" / "recipes" / "peacock_rattle.toml"
SHIPPED = REPO / "assets" / "assemblies" / "peacock_rattle" / "peacock_rattle.usda"
SCENE = REPO / "assets" / "shots" / "peacock_rattle.usda"
FEATHERS = REPO / "assets" / "feathers"


def _absolute(text: str) -> str:
    return text.replace('"../feathers/', f'"{FEATHERS}/')


@pytest.fixture(scope="module")
def rattled(tmp_path_factory) -> tuple[Path, dict]:
    """The shipped rattle recipe assembled into a fresh folder."""
    recipe = tmp_path_factory.mktemp("recipe") / "rattle.toml"
    recipe.write_text(_absolute(RATTLE.read_text()))
    out = tmp_path_factory.mktemp("out")
    result = CliRunner().invoke(
        cli, ["assemble", "train", str(recipe), "-o", str(out), "--json", "-"]
    )
    assert result.exit_code == 0, result.output
    report = json.loads(result.output[result.output.index("{") :])
    return out / "peacock_rattle" / "peacock_rattle.usda", report


def test_without_a_rattle_the_assembly_is_byte_identical_to_the_shipped_train(tmp_path):
    """No [rattle]: not one byte of the train assembly (or its layout plot) changes."""
    assets = tmp_path / "assets"
    shutil.copytree(FEATHERS, assets / "feathers")
    (assets / "recipes").mkdir()
    shutil.copy(TRAIN, assets / "recipes" / TRAIN.name)
    result = CliRunner().invoke(
        cli, ["assemble", "train", str(assets / "recipes" / TRAIN.name), "-o",
              str(assets / "assemblies")],
    )  # fmt: skip
    assert result.exit_code == 0, result.output
    assert "rattle:" not in result.output
    for name in ("peacock_train.usda", "peacock_train_layout.png"):
        ours = assets / "assemblies" / "peacock_train" / name
        shipped = REPO / "assets" / "assemblies" / "peacock_train" / name
        assert ours.read_bytes() == shipped.read_bytes(), name
    assert sorted(p.name for p in (assets / "assemblies" / "peacock_train").iterdir()) == [
        "peacock_train.usda",
        "peacock_train_layout.png",
    ]
    assert parse_train_recipe(TRAIN).rattle is None


def test_the_rattle_recipe_is_the_train_with_a_rattle():
    train, rattle = parse_train_recipe(TRAIN), parse_train_recipe(RATTLE)
    assert rattle.rows == train.rows and rattle.seed == train.seed
    assert rattle.jitter == train.jitter and rattle.variation == train.variation
    assert rattle.rattle == R.Rattle()  # the shipped shot is the documented defaults
    shot = rattle.rattle
    assert (shot.frequency_hz, shot.eyespot_mm, shot.barb_mm) == (25.6, 1.7, 9.6)
    assert shot.frames == 6 and (shot.start_frame, shot.end_frame) == (1, 6)


def test_time_samples_are_dense_across_every_shutter_interval():
    shot = R.Rattle()
    times = shot.times()
    assert len(times) == 6 * 16 + 1
    assert times[0] == 0.5 and times[-1] == 6.5  # half a frame either side of frames 1-6
    assert np.allclose(np.diff(times), 1 / 16)
    # 25.6 Hz at 24 fps: 0.9375 frames a period, beyond Nyquist (12 Hz); 15 samples a period.
    assert shot.frequency_hz > shot.fps / 2
    assert shot.samples_per_period() == pytest.approx(15.0)
    for frame in range(1, 7):  # a shutter of -0.25..0.25 frames holds 9 samples
        inside = (times >= frame - 0.25) & (times <= frame + 0.25)
        assert inside.sum() == 9


def test_the_assembly_is_animated_as_written(rattled):
    root, report = rattled
    assert report["rattle"]["frames"] == [1, 6] and report["rattle"]["time_samples"] == 97
    assert report["rattle"]["variants"] == 16
    layer = Sdf.Layer.FindOrOpen(str(root))
    assert (layer.timeCodesPerSecond, layer.framesPerSecond) == (24, 24)
    assert (layer.startTimeCode, layer.endTimeCode) == (1, 6)
    assert layer.subLayerPaths == ["./peacock_rattle_rattle.usdc"]
    stage = Usd.Stage.Open(str(root))
    instancer = UsdGeom.PointInstancer(stage.GetPrimAtPath("/peacock_rattle/Feathers"))
    targets = instancer.GetPrototypesRel().GetTargets()
    assert [t.name for t in targets][:4] == [f"blue_rattle{k}" for k in range(4)]
    for target in targets:
        prim = stage.GetPrimAtPath(target)
        assert prim.GetTypeName() == "SkelRoot"
        assert prim.GetVariantSet("lod").GetVariantSelection() == "medium"
        weights = prim.GetChild("Motion").GetAttribute("blendShapeWeights")
        assert len(weights.GetTimeSamples()) == 97
    orient = instancer.GetOrientationsfAttr()
    assert len(orient.GetTimeSamples()) == 97
    indices = np.array(instancer.GetProtoIndicesAttr().Get())
    assert indices.max() < len(targets) and len(np.unique(indices % 4)) == 4  # every phase used
    assert report["instances"] == 220
    # at rest (default time) the fan is the static train's
    static = parse_train_recipe(TRAIN)
    from pavonine.pipeline.assemble.fan import layout

    fan = layout(static)
    q = np.array([[x.real, *x.imaginary] for x in orient.Get(Usd.TimeCode.Default())])
    assert np.allclose(q, fan.orientations, atol=1e-6)


def _world_displacements(root: Path, times) -> dict[str, tuple[float, float]]:
    """Largest movement (mm) of each component's eyespot points and of its other vane points,
    over ``times``: the renderer's skinning (render/skel.py) and instance transforms."""
    from pavonine.render import skel
    from pavonine.render.diagnostics import Diagnostics
    from pavonine.render.xform import TransformCache

    stage = Usd.Stage.Open(str(root))
    instancer = UsdGeom.PointInstancer(stage.GetPrimAtPath("/peacock_rattle/Feathers"))
    targets = instancer.GetPrototypesRel().GetTargets()
    indices = np.array(instancer.GetProtoIndicesAttr().Get())
    mask_map = F._eyespot_lock(FEATHERS / "eye_feather" / "eye_feather.usd")[0]

    def matrices(t):
        m = instancer.ComputeInstanceTransformsAtTime(t, t)
        return np.array(m, dtype=np.float64).reshape(-1, 4, 4)

    rest_m = matrices(Usd.TimeCode.Default())
    worst: dict[str, list[float]] = {}
    for t in times:
        code = Usd.TimeCode(t)
        skinned = skel.skin_stage(stage, code, TransformCache(code), Diagnostics()).points
        moved_m = matrices(code)
        for j, target in enumerate(targets):
            component = target.name.split("_rattle")[0]
            vane = stage.GetPrimAtPath(target.AppendPath("Geom/Vane"))
            rest = np.array(UsdGeom.Mesh(vane).GetPointsAttr().Get(), dtype=np.float64)
            moved = skinned.get(str(vane.GetPath()), rest)
            uv = np.array(UsdGeom.PrimvarsAPI(vane).GetPrimvar("pavonine_featherUV").Get())
            eye = F._sample(mask_map, uv) if component == "eye" else np.zeros(len(rest), bool)
            a, b = np.c_[rest, np.ones(len(rest))], np.c_[moved, np.ones(len(rest))]
            entry = worst.setdefault(component, [0.0, 0.0])
            for i in np.flatnonzero(indices == j):
                d = 10.0 * np.linalg.norm((b @ moved_m[i] - a @ rest_m[i])[:, :3], axis=1)
                if eye.any():
                    entry[0] = max(entry[0], float(d[eye].max()))
                entry[1] = max(entry[1], float(d[~eye].max()))
    return {k: (v[0], v[1]) for k, v in worst.items()}


def test_the_eyespots_hold_still_while_the_loose_barbs_swing(rattled):
    """Dakin et al. 2016: eyespots at most 1.7 mm, loose barbs up to 9.6 mm (world, all
    instances, over a period of the drive)."""
    root, _ = rattled
    worst = _world_displacements(root, [1 + j / 16 for j in range(16)])
    eye_still, eye_loose = worst["eye"]
    assert eye_still <= 1.7 + 1e-3
    assert eye_still > 1.5  # the sway itself is there
    assert 7.0 < eye_loose <= 9.6 + 1e-3
    assert eye_loose > 4 * eye_still  # the eyes hover against the moving train
    for component in ("fishtail", "yellow", "blue"):
        assert 0.5 < worst[component][1] <= 9.6 + 1e-3, component


def test_the_flex_follows_the_physics():
    """Rachis: a half sine from the base to the eyespot's lower edge (the node), nothing above;
    barbs: the cantilever mode of their distance from the rachis, zero on the eyespot."""
    recipe = parse_train_recipe(RATTLE)
    eye = FEATHERS / "eye_feather" / "eye_feather.usd"
    geometry = F.read_geometry("eye", eye, "medium", "sheet")
    node = F.node_height(geometry)
    tip = F.tip_height(geometry)
    assert 0.5 * tip < node < 0.7 * tip  # the ocellus' lower edge (paint.py: 0.565 of the map)
    shape = F.prototype_shape(geometry, geometry.loose_reach_cm, tip, recipe.seed)
    vane = next(d for d in shape.deformed if d.path == "Geom/Vane")
    peak = F.peak_displacement(vane)
    assert np.all(peak[vane.eyespot] < 1e-6)  # locked barbs do not flex
    points = geometry.prims[[p.path for p in geometry.prims].index("Geom/Vane")].points
    moving = points[vane.indices]
    on_rachis = np.abs(moving[:, 0]) < 0.05
    above = moving[:, 1] > node
    assert np.all(np.abs(vane.sin[on_rachis & above, 0]) < 1e-3)
    middle = on_rachis & (np.abs(moving[:, 1] - node / 2) < 0.5)
    assert np.allclose(vane.sin[middle, 0], 1.0, atol=0.02)  # the antinode
    assert F.cantilever_mode(np.array([0.0]))[0] == 0 and F.cantilever_mode(np.array([1.0]))[
        0
    ] == pytest.approx(1.0)
    # phases: seeded, spread over the cycle, and the nearest variant
    phases = R.instance_phases(7, 192, 1.0)
    assert np.array_equal(phases, R.instance_phases(7, 192, 1.0))
    assert phases.min() >= 0 and phases.max() < 2 * math.pi
    assert np.array_equal(R.variant_of(np.array([0.0, 1.6, 3.2, 4.7, 6.2]), 4), [0, 1, 2, 3, 0])


def test_the_shipped_rattle_is_up_to_date(rattled):
    root, _ = rattled
    ours, shipped = (Usd.Stage.Open(str(p)) for p in (root, SHIPPED))
    for attr in ("/peacock_rattle/Feathers.protoIndices", "/peacock_rattle/Feathers.positions"):
        assert np.array_equal(
            np.array(ours.GetAttributeAtPath(attr).Get()),
            np.array(shipped.GetAttributeAtPath(attr).Get()),
        ), "the shipped rattle is out of date: re-run pavonine assemble train"
    attr = "/peacock_rattle/Feathers/Prototypes/eye_rattle1/Motion.blendShapeWeights"
    assert np.allclose(
        ours.GetAttributeAtPath(attr).Get(3.25), shipped.GetAttributeAtPath(attr).Get(3.25)
    )


def test_the_shot_has_a_shutter_and_six_frames():
    stage = Usd.Stage.Open(str(SCENE))
    assert stage.GetTimeCodesPerSecond() == 24
    assert (stage.GetStartTimeCode(), stage.GetEndTimeCode()) == (1, 6)
    camera = UsdGeom.Camera(stage.GetPrimAtPath("/World/Camera"))
    assert (camera.GetShutterOpenAttr().Get(), camera.GetShutterCloseAttr().Get()) == (-0.25, 0.25)
    settings = stage.GetPrimAtPath("/Render/Settings")
    assert tuple(settings.GetAttribute("resolution").Get()) == (512, 384)
    instancer = stage.GetPrimAtPath("/World/Train/Feathers")
    assert len(instancer.GetAttribute("orientationsf").GetTimeSamples()) == 97


@pytest.mark.parametrize(
    ("table", "message"),
    [
        ("frequency_hz = 0", "rattle.frequency_hz: must lie in [1, 100], got 0"),
        ("frequency_hz = nan", "rattle.frequency_hz: must be finite, got nan"),
        ('frequency_hz = "fast"', "rattle.frequency_hz: expected a number, got 'fast'"),
        ("eyespot_mm = -1.7", "rattle.eyespot_mm: must not be negative, got -1.7"),
        ("barb_mm = inf", "rattle.barb_mm: must be finite, got inf"),
        ("phase_spread = 1.5", "rattle.phase_spread: must lie in [0, 1], got 1.5"),
        ("phases = 2.5", "rattle.phases: expected an integer, got 2.5"),
        ("phases = 0", "rattle.phases: must lie in [1, 16], got 0"),
        ("fps = true", "rattle.fps: expected a number, got True"),
        ("duration_s = 0", "rattle.duration_s: must lie in [0.001, 60], got 0"),
        ("start_frame = 1.5", "rattle.start_frame: expected an integer, got 1.5"),
        ("start_frame = -1000000", "rattle.start_frame: must lie in [-100000, 100000], got -1e+06"),
        ("samples_per_frame = 2", "rattle.samples_per_frame: 2 a frame is 1.9 a period"),
        ("duration_s = 60\nsamples_per_frame = 64", "rattle.duration_s: 1440 frames × 64"),
        ("wobble = 1", "rattle.wobble: unknown key"),
    ],
)
def test_bad_rattle_keys_give_one_line_naming_the_key_and_no_output(tmp_path, table, message):
    text = _absolute(TRAIN.read_text()) + f"\n[rattle]\n{table}\n"
    recipe = tmp_path / "bad.toml"
    recipe.write_text(text)
    result = CliRunner().invoke(
        cli, ["assemble", "train", str(recipe), "-o", str(tmp_path / "out")]
    )
    assert result.exit_code == 2, result.output
    assert message in result.output and result.output.count("\n") == 1, result.output
    assert not (tmp_path / "out").exists()


def test_a_rattle_that_is_not_a_table_is_refused(tmp_path):
    recipe = tmp_path / "bad.toml"
    recipe.write_text(_absolute(TRAIN.read_text()).replace("seed = 7", "seed = 7\nrattle = 1"))
    result = CliRunner().invoke(cli, ["assemble", "train", str(recipe), "-o", str(tmp_path / "o")])
    assert result.exit_code == 2 and "rattle: expected a table [rattle]" in result.output
    assert not (tmp_path / "o").exists()
