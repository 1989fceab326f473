"""Motion blur (``pavonine.render.motion.blur``): the camera's shutter, time slices of one scene, and
frames synced incrementally (``RenderSession``). The stage: ``tests/motion_scene.py``."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from motion_scene import (
    INSTANCED,
    SIZE,
    coverage,
    crossings,
    expected_streak,
    motion_stage,
    skinned_prototype_stage,
)

from pavonine.apps.cli import cli
from pavonine.render.api import RenderSession, render_stage
from pavonine.render.diagnostics import StageWarning
from pavonine.render.imageio import write_exr
from pavonine.render.motion import blur
from pavonine.render.options import RenderOptions

pytestmark = pytest.mark.render
ROW = SIZE[1] // 2
SHUTTER = (-0.25, 0.25)


def render(path: Path, **options):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", StageWarning)
        return render_stage(path, RenderOptions(progress=False, **{"time": 1.0, **options}))


def plateau(folder: Path, how: str = "xform") -> float:
    """The radiance of the glowing surface in the image, read from a sharp render at the frame's
    time (the quad's, or the backdrop's beside it for ``instancer``)."""
    motion_stage(folder / "sharp.usda", None, how)
    sharp = render(folder / "sharp.usda", spp=64)
    column = 4 if how in INSTANCED else SIZE[0] // 2
    return float(sharp.rgb[ROW - 4 : ROW + 4, column - 4 : column + 4, 0].mean())


@pytest.mark.parametrize(
    "how", ["xform", "points", "camera", "velocities", "instancer", "prototype"]
)
def test_streak_width_and_profile_match_the_motion(tmp_path, how):
    """The quad moves 16 px while the shutter is open: its streak (a trapezoid, 28 px wide, 4 px
    of plateau at 12/16 of the quad's radiance) matches the one computed from the motion alone,
    its edges and its 25/50/60 % crossings within 2 px, its plateau within 6 %, whether the quad
    moves by a transform, by points, by velocities (of points or of a PointInstancer's instance),
    by the points of a PointInstancer's prototype (its shape group moved in place), or the
    camera moves."""
    path = tmp_path / "moving.usda"
    motion_stage(path, SHUTTER, how)
    level = plateau(tmp_path, how)
    result = render(path, spp=256)
    assert result.metadata["time_slices"] == blur.DEFAULT_SLICES
    assert result.metadata["shutter"] == list(SHUTTER)
    measured = coverage(result.rgb, how, level)
    wanted = expected_streak(SHUTTER)
    for fraction in (0.02, 0.25, 0.5, 0.6):
        got, want = crossings(measured, fraction), crossings(wanted, fraction)
        assert abs(got[0] - want[0]) <= 2 and abs(got[1] - want[1]) <= 2, (fraction, got, want)
    assert (measured > 0.02).sum() == pytest.approx((wanted > 0.02).sum(), abs=2)
    top = wanted == wanted.max()  # the plateau's columns
    assert measured[top].mean() == pytest.approx(wanted.max(), rel=0.06)
    assert measured.sum() == pytest.approx(wanted.sum(), rel=0.03)  # all the light, spread


@pytest.mark.parametrize(
    "shutter, settings",
    [
        (SHUTTER, {"instantaneousShutter": True}),
        (SHUTTER, {"disableMotionBlur": True}),
        ((0.1, 0.1), None),
        (None, None),
    ],
)
def test_an_instant_renders_sharp_bit_for_bit(tmp_path, shutter, settings):
    """``instantaneousShutter``, ``disableMotionBlur``, a zero interval and no shutter at all
    render the frame's time, with the render's own seed: the unblurred image, bit for bit."""
    sharp_path = tmp_path / "sharp.usda"
    motion_stage(sharp_path, None)
    path = tmp_path / "instant.usda"
    motion_stage(path, shutter, settings=settings)
    result = render(path, spp=8, seed=3)
    assert "time_slices" not in result.metadata
    assert np.array_equal(result.rgb, render(sharp_path, spp=8, seed=3).rgb)
    assert (result.rgb[ROW, :, 0] > 0.1).sum() == 12  # the quad's 12 columns, sharp


def test_close_before_open_is_one_line_error_naming_file_and_field(tmp_path):
    path = tmp_path / "backwards.usda"
    motion_stage(path, (0.25, -0.25))
    out = tmp_path / "out.exr"
    result = CliRunner().invoke(cli, ["render", str(path), "-o", str(out), "--spp", "2", "-q"])
    assert result.exit_code == 2, result.output
    lines = [line for line in result.output.splitlines() if line.startswith("error: ")]
    assert len(lines) == 1, result.output
    assert f"{path}: /Cam.shutter:close: -0.25 is before shutter:open 0.25" in lines[0]
    assert not out.exists()


def test_nan_shutter_and_nan_time_samples_are_warned_never_rendered(tmp_path):
    """A NaN shutter: warned, sharp. A NaN time sample of the motion: the slices where the
    transform is NaN keep the quad at the frame's time (the translator's warning names the
    xformOp); the image is finite and the quad is where the motion puts it otherwise."""
    path = tmp_path / "nan_shutter.usda"
    motion_stage(path, (float("nan"), 0.25))
    result = render(path, spp=4)
    assert any(
        "/Cam: shutter:open = nan" in w and "without motion blur" in w for w in result.warnings
    )
    assert (result.rgb[ROW, :, 0] > 0.1).sum() == 12
    path = tmp_path / "nan_sample.usda"
    motion_stage(path, SHUTTER, samples={0.0: -1.0, 1.0: 0.0, 1.125: float("nan"), 2.0: 1.0})
    result = render(path, spp=64)
    assert np.isfinite(result.rgb).all()
    assert any("/World/Quad: transform is NaN" in w and "xformOp:translate" in w
               for w in result.warnings)  # fmt: skip
    row = result.rgb[ROW, :, 0]
    assert row[:14].max() == 0.0 and row[50:].max() == 0.0  # nothing beyond the motion
    assert (row > 0).sum() >= 12


def test_blurred_frame_is_the_mean_of_its_instantaneous_sub_frames(tmp_path):
    """The blurred image equals the sample-weighted mean of K single-time renders at the slices'
    times: with the slices' own seeds to float rounding, and, with independent seeds, by
    ``pavonine compare --method stat`` (the definition of the blur, tested by its noise)."""
    path = tmp_path / "moving.usda"
    motion_stage(path, SHUTTER)
    instant = tmp_path / "sharp.usda"  # the same motion without a shutter: sub-frames
    motion_stage(instant, None)
    spp, slices, seed = 64, 8, 5
    blurred = render(path, spp=spp, seed=seed, motion_slices=slices, moments=True)
    times = blur.Shutter(*SHUTTER).times(1.0, slices, seed)
    counts = blur.slice_spp(spp, slices)
    same = np.zeros_like(blurred.rgb, dtype=np.float64)
    other = np.zeros_like(same)
    other_variance = np.zeros_like(same)
    for i, (when, count) in enumerate(zip(times, counts, strict=True)):
        sub = render(instant, spp=count, seed=blur.slice_seed(seed, i, slices), time=when,
                     moments=True)  # fmt: skip
        same += sub.rgb * (count / spp)
        independent = render(instant, spp=count, seed=100 + i, time=when, moments=True)
        other += independent.rgb * (count / spp)
        other_variance += independent.variance * (count / spp) ** 2
    assert np.abs(blurred.rgb - same).max() < 1e-5
    assert not np.array_equal(blurred.rgb, other)
    files = {}
    for name, image, variance in (
        ("blurred", blurred.rgb, blurred.variance),
        ("mean", other, other_variance),
    ):
        files[name] = tmp_path / f"{name}.exr"
        write_exr(files[name], image.astype(np.float32), {})
        write_exr(tmp_path / f"{name}.variance.exr", variance.astype(np.float32), {})
    result = CliRunner().invoke(
        cli,
        ["compare", str(files["blurred"]), str(files["mean"]), "--method", "stat",
         "--test-variance", str(tmp_path / "blurred.variance.exr"),
         "--ref-variance", str(tmp_path / "mean.variance.exr"), "-o", str(tmp_path / "maps")],
    )  # fmt: skip
    assert result.exit_code == 0, result.output
    sharp = render(instant, spp=spp, seed=seed, moments=True)
    write_exr(tmp_path / "sharp.exr", sharp.rgb, {})
    result = CliRunner().invoke(
        cli,
        ["compare", str(tmp_path / "sharp.exr"), str(files["mean"]), "--method", "stat",
         "--ref-variance", str(tmp_path / "mean.variance.exr"), "-o", str(tmp_path / "maps")],
    )  # fmt: skip
    assert result.exit_code == 1, result.output  # the test can fail: a sharp frame differs


def test_frames_after_the_first_sync_only_what_varies_and_equal_a_fresh_render(tmp_path):
    """A session synced at frame 0 and moved to frame 1 and 2 (only the quad translated again)
    gives, unblurred, the single-time render of each frame with the same seed, bit for bit."""
    path = tmp_path / "moving.usda"
    motion_stage(path, None)
    session = RenderSession(path, RenderOptions(spp=8, seed=2, time=0.0, progress=False))
    assert [p.GetPath().pathString for p, _, _ in session.plan.gprims] == ["/World/Quad"]
    assert session.plan.complete
    first = session.render()[0]
    for frame in (1.0, 2.0, 0.5):
        moved = session.render(time=frame)[0]
        fresh = render(path, spp=8, seed=2, time=frame)
        assert moved.metadata["time"] == frame
        assert np.array_equal(moved.rgb, fresh.rgb), frame
    assert len(session.sync_seconds) == 4 and session.plan.retimes >= 3
    assert not np.array_equal(first.rgb, moved.rgb)


def test_blurred_frames_of_a_session_move_once_a_slice_and_equal_fresh_renders(tmp_path):
    """A blurred frame's sync is its first slice's retime (no retime to the frame's time before
    the slices, none back after them), and its image is a fresh render's; a sharp image of the
    same frame afterwards is moved back first and equals its fresh render too."""
    path = tmp_path / "moving.usda"
    motion_stage(path, SHUTTER)
    options = RenderOptions(spp=8, seed=2, time=0.0, progress=False, motion_slices=4)
    session = RenderSession(path, options)
    session.render()
    for frame in (1.0, 2.0):
        before = session.plan.retimes
        moved = session.render(time=frame)[0]
        assert session.plan.retimes - before == 4  # one a slice: none to, none from the frame
        assert moved.metadata["sync"] == "moved" and moved.metadata["sync_seconds"] > 0
        fresh = render(path, spp=8, seed=2, time=frame, motion_slices=4)
        assert np.array_equal(moved.rgb, fresh.rgb), frame
    session.shutters = [blur.Shutter() for _ in session.shutters]  # the product made sharp
    sharp = session.render()[0]
    instant = tmp_path / "sharp.usda"
    motion_stage(instant, None)
    assert np.array_equal(sharp.rgb, render(instant, spp=8, seed=2, time=2.0).rgb)


def test_an_open_shutter_on_a_still_stage_moves_nothing(tmp_path):
    """Nothing varies: one slice (nothing moves in the image: ``motion_reach``), so the image is
    the sharp one bit for bit; with the slices asked for, they render the same scene (no
    parameters to move), the sharp image up to noise; nothing is warned."""
    path = tmp_path / "still.usda"
    motion_stage(path, SHUTTER, samples={1.0: 0.0})
    result = render(path, spp=32)
    assert result.metadata["time_slices"] == 1 and result.warnings == []
    sharp_path = tmp_path / "sharp.usda"
    motion_stage(sharp_path, None, samples={1.0: 0.0})
    sharp = render(sharp_path, spp=32)
    assert (result.rgb[ROW, :, 0] > 0.1).sum() == 12
    np.testing.assert_array_equal(result.rgb, sharp.rgb)
    sliced = render(path, spp=32, motion_slices=4)
    assert sliced.metadata["time_slices"] == 4 and sliced.warnings == []
    assert sliced.rgb.mean() == pytest.approx(sharp.rgb.mean(), rel=0.03)


def test_frames_of_a_still_stage_reuse_the_scene(tmp_path):
    """Nothing varies (no parameters traversed): a later frame moves nothing and renders as a
    fresh render of that time, bit for bit."""
    path = tmp_path / "still.usda"
    motion_stage(path, None, samples={1.0: 0.0})
    session = RenderSession(path, RenderOptions(spp=4, seed=1, time=0.0, progress=False))
    assert session.plan.static and session.params is None
    later = session.render(time=2.0)[0]
    assert later.metadata["sync"] == "moved" and later.metadata["time"] == 2.0
    assert np.array_equal(later.rgb, render(path, spp=4, seed=1, time=2.0).rgb)


def test_frames_move_a_prototype_in_place_and_equal_a_fresh_render(tmp_path):
    """A PointInstancer prototype whose points vary is moved in place between frames (its shape
    group's meshes, not a full sync), giving the single-time render of each frame bit for bit."""
    path = tmp_path / "prototype.usda"
    motion_stage(path, None, "prototype")
    session = RenderSession(path, RenderOptions(spp=8, seed=2, time=0.0, progress=False))
    [(root, group, moving)] = session.plan.prototypes
    assert root.GetPath().pathString == "/World/PI/Protos/Quad"
    assert [(prim.GetPath().pathString, indices, fast) for prim, indices, fast in moving] == [
        ("/World/PI/Protos/Quad", [0], None)  # points samples, no skeleton: translated again
    ]
    assert group.startswith("shapegroup_") and session.plan.complete
    first = session.render()[0]
    for frame in (1.0, 2.0):
        moved = session.render(time=frame)[0]
        assert moved.metadata["sync"] == "moved"
        fresh = render(path, spp=8, seed=2, time=frame)
        assert np.array_equal(moved.rgb, fresh.rgb), frame
    assert not np.array_equal(first.rgb, moved.rgb)


def test_a_skinned_prototype_moves_by_its_points_and_equals_a_fresh_render(tmp_path):
    """A skeleton inside a PointInstancer's prototype: between frames its bar moves by its
    skinned points alone (render/motion/deform.py, checked against the translation when the plan is
    made), and each frame is the single-time render of its time, bit for bit."""
    import mitsuba as mi
    from pxr import Usd

    path = skinned_prototype_stage(tmp_path / "rig.usda")
    session = RenderSession(path, RenderOptions(spp=4, seed=3, time=0.0, progress=False))
    [(root, _, [(prim, indices, fast)])] = session.plan.prototypes
    assert prim.GetName() == "Bar" and indices == [0] and fast is not None
    for time in (5.0, 10.0):  # the arrays the translation makes, positions and normals
        view = session.delegate.at_time(Usd.TimeCode(time))
        [(positions, normals)] = fast.arrays(view.skinning.points[str(prim.GetPath())])
        [translated] = view.prototype_prim_shapes(root, prim)
        params = mi.traverse(translated)
        assert np.array_equal(np.asarray(params["vertex_positions"]), positions.ravel())
        assert np.array_equal(np.asarray(params["vertex_normals"]), normals.ravel())
    first = session.render()[0]
    for frame in (5.0, 10.0):
        moved = session.render(time=frame)[0]
        assert moved.metadata["sync"] == "moved" and moved.warnings == []
        fresh = render(path, spp=4, seed=3, time=frame)
        assert np.array_equal(moved.rgb, fresh.rgb), frame
    assert not np.array_equal(first.rgb, moved.rgb)  # the bar bent


def test_the_rattle_shot_moves_every_skinned_prim_by_its_points():
    """The shipped rattle shot: the Vane and Rachis of every prototype its instances use are
    skinned, and every one follows its points (no prim is translated again from USD at a
    frame's move); a prototype no instance uses is not synced."""
    from pxr import Usd, UsdGeom

    shot = Path(__file__).parents[2] / "assets" / "shots" / "peacock_rattle.usda"
    options = RenderOptions(resolution=(8, 6), spp=1, time=1.0, progress=False)
    plan = RenderSession(shot, options).plan
    stage = Usd.Stage.Open(str(shot))
    instancer = next(
        UsdGeom.PointInstancer(p) for p in stage.Traverse() if p.IsA(UsdGeom.PointInstancer)
    )
    targets = instancer.GetPrototypesRel().GetForwardedTargets()
    used = {str(targets[i]) for i in instancer.GetProtoIndicesAttr().Get(1.0)}
    moving = [entry for _, _, entries in plan.prototypes for entry in entries]
    assert plan.complete and {str(root.GetPath()) for root, _, _ in plan.prototypes} == used
    assert sorted({prim.GetName() for prim, _, _ in moving}) == ["Rachis", "Vane"]
    assert all(fast is not None for _, _, fast in moving)


def test_a_moved_instance_feather_reads_its_attributes_through_its_new_frame(tmp_path):
    """Two eye feathers through one PointInstancer, the second turned 25° between frames 0 and 1:
    a session moved to frame 1 renders what a fresh render of frame 1 does. The feather BSDF
    reads its mesh attributes through each instance's frame (instance_primvars), refreshed when
    the instances move; with the first frame's frames it was off by up to 0.66 (measured). Not
    bit for bit under the sun: up to 4.5e-5 measured, against a mean of 0.065."""
    from pxr import Gf, Usd, UsdGeom
    from test_instance_primvars import feather_pair

    path = feather_pair(tmp_path / "pair.usda", "pavonine:gradationOffset", [0.0, 0.0])
    stage = Usd.Stage.Open(str(path))
    orientations = UsdGeom.PointInstancer(stage.GetPrimAtPath("/Pair")).CreateOrientationsAttr()
    turn = Gf.Quath(Gf.Rotation(Gf.Vec3d(0, 1, 0), 25).GetQuat())
    orientations.Set([Gf.Quath(1), Gf.Quath(1)], 0)
    orientations.Set([Gf.Quath(1), turn], 1)
    stage.GetRootLayer().Save()
    session = RenderSession(path, RenderOptions(spp=4, seed=1, time=0.0, progress=False))
    first = session.render()[0]
    moved = session.render(time=1.0)[0]
    assert moved.metadata["sync"] == "moved"
    fresh = render(path, spp=4, seed=1, time=1.0)
    assert np.abs(moved.rgb - fresh.rgb).max() < 1e-3
    assert np.abs(first.rgb - fresh.rgb).max() > 0.1  # the turn shows
