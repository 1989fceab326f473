"""Batches without a cluster: frame ranges, file names, exact shard merging, turntables,
animated cameras and lights, several cameras and RenderProducts (in this process)."""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from pxr import Gf, Usd, UsdGeom, UsdLux, UsdRender

from pavonine.apps.cli import cli
from pavonine.apps.farm.jobs import (
    View,
    frame_label,
    output_name,
    parse_frames,
    plan,
    shard_seed,
    split_samples,
    variance_path,
    view_outputs,
)
from pavonine.apps.farm.merge import merge_means, merge_variances
from pavonine.base.errors import InputError
from pavonine.render.imageio import read_exr

REPO = Path(__file__).parents[2]


@pytest.mark.parametrize(
    ("text", "frames"),
    [("1-4", [1, 2, 3, 4]), ("1-10:3", [1, 4, 7, 10]), ("7", [7]), ("-2-1", [-2, -1, 0, 1])],
)
def test_frame_ranges(text, frames):
    assert parse_frames(text) == frames


@pytest.mark.parametrize("text", ["1-", "a-b", "5-1", "1-4:0", "1.5-3"])
def test_bad_frame_ranges_name_the_option(text):
    with pytest.raises(InputError, match="--frames"):
        parse_frames(text)


def test_output_names():
    out = Path("/r/shot.exr")
    assert output_name(out, None, 12) == Path("/r/shot.0012.exr")
    assert output_name(out, "CamB", 3) == Path("/r/shot.CamB.0003.exr")
    assert output_name(Path("/r/s.####.beauty.exr"), None, 5) == Path("/r/s.0005.beauty.exr")
    assert output_name(out, None, -3) == Path("/r/shot.-003.exr") and frame_label(-3) == "-003"
    assert variance_path(Path("/r/shot.0012.exr")) == Path("/r/shot.variance.0012.exr")
    assert variance_path(out) == Path("/r/shot.variance.exr")
    # one rule for every view: the first keeps -o, the others add their name (then the frame)
    jobs = plan("/s.usda", out, [View("A", "/A"), View("B", "/B")], [1, 2], png=True)
    assert [j.output.name for j in jobs] == [
        "shot.0001.exr",
        "shot.0002.exr",
        "shot.B.0001.exr",
        "shot.B.0002.exr",
    ]
    assert jobs[0].png == Path("/r/shot.0001.png") and jobs[3].time == 2.0
    # without -o: the first view's productName, the others' beside it, else STAGE.exr
    views = [View("Main", None, "/R/Main", "main.exr"), View("Wide", None, "/R/Wide", "wide.exr")]
    assert view_outputs("/s.usda", None, views) == [Path("main.exr"), Path("wide.exr")]
    assert view_outputs("/s.usda", None, [View("A"), View("B")]) == [Path("s.exr"), Path("s.B.exr")]
    twins = [View("Main", None, "/R/Main", "x.exr"), View("Main", None, "/S/Main", "x.exr")]
    assert view_outputs("/s.usda", out, twins) == [out, Path("/r/shot.Main.exr")]
    assert view_outputs("/s.usda", None, twins) == [Path("x.exr"), Path("x.Main.exr")]


def test_samples_split_evenly_with_independent_seeds():
    assert split_samples(10, 4) == [3, 3, 2, 2] and split_samples(3, 8) == [1, 1, 1]
    seeds = {shard_seed(s, k) for s in range(20) for k in range(1, 16)}
    assert len(seeds) == 20 * 15 and shard_seed(5, 0) == 5


def test_merging_shards_is_exact():
    """The merged mean and variance equal those of all samples pooled (synthetic pixels)."""
    rng = np.random.default_rng(3)
    samples = rng.gamma(2.0, 0.3, size=(24, 6, 5, 3))  # 24 samples per pixel
    counts = [8, 8, 4, 4]
    starts = np.cumsum([0, *counts])
    means, variances = [], []
    for a, b in itertools.pairwise(starts):
        shard = samples[a:b]
        means.append(shard.mean(axis=0))
        variances.append(shard.var(axis=0, ddof=1) / len(shard))  # variance of the shard mean
    merged = merge_means(means, counts)
    assert np.allclose(merged, samples.mean(axis=0), rtol=1e-6)
    # the variance of the merged mean: Σ (n_k/N)² Var(m_k), here with the true per-sample σ²
    sigma2 = 2.0 * 0.3**2
    expected = sum((n / 24) ** 2 * sigma2 / n for n in counts)
    assert np.isclose(sigma2 / 24, expected)
    pooled = merge_variances(variances, counts)
    assert np.isclose(pooled.mean(), sigma2 / 24, rtol=0.1)


def animated_stage(path: Path) -> Path:
    """A grey quad lit by a distant light whose intensity is the time code; cameras moving in x."""
    stage = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageUpAxis(stage, "Y")
    mesh = UsdGeom.Mesh.Define(stage, "/Quad")
    mesh.CreatePointsAttr([(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)])
    mesh.CreateFaceVertexCountsAttr([4])
    mesh.CreateFaceVertexIndicesAttr([0, 1, 2, 3])
    light = UsdLux.DistantLight.Define(stage, "/Light")  # shines along −Z onto the quad
    for t in (1.0, 2.0, 3.0):
        light.CreateIntensityAttr().Set(float(t), t)
    for name, x in (("CamA", 0.0), ("CamB", 0.4)):
        cam = UsdGeom.Camera.Define(stage, f"/{name}")
        op = cam.AddTranslateOp()
        op.Set(Gf.Vec3d(x, 0, 5), 1.0)
        op.Set(Gf.Vec3d(x + 0.3, 0, 5), 3.0)
    settings = UsdRender.Settings.Define(stage, "/Render/Settings")
    settings.CreateResolutionAttr(Gf.Vec2i(24, 16))
    settings.CreateCameraRel().SetTargets(["/CamA"])
    wide = UsdRender.Product.Define(stage, "/Render/Wide")
    wide.CreateResolutionAttr(Gf.Vec2i(32, 16))
    tall = UsdRender.Product.Define(stage, "/Render/Tall")
    tall.CreateResolutionAttr(Gf.Vec2i(16, 24))
    tall.CreateCameraRel().SetTargets(["/CamB"])
    settings.CreateProductsRel().SetTargets(["/Render/Wide", "/Render/Tall"])
    stage.GetRootLayer().Save()
    return path


def run(*args: str):
    result = CliRunner().invoke(cli, ["render", *args, "--spp", "4", "-q"])
    assert result.exit_code == 0, result.output
    return result


@pytest.mark.render
def test_frames_follow_animated_lights_and_cameras(tmp_path):
    stage = animated_stage(tmp_path / "anim.usda")
    run(str(stage), "-o", str(tmp_path / "f.exr"), "--frames", "1-3", "--workers", "0")
    images = [read_exr(tmp_path / f"f.000{t}.exr")[0][..., :3] for t in (1, 2, 3)]
    brightness = [float(img.mean()) for img in images]
    assert brightness[1] / brightness[0] == pytest.approx(2.0, rel=0.05)  # intensity = time
    assert brightness[2] / brightness[0] == pytest.approx(3.0, rel=0.05)
    single = tmp_path / "t2.exr"
    run(str(stage), "-o", str(single), "--time", "2")
    assert np.array_equal(read_exr(single)[0], read_exr(tmp_path / "f.0002.exr")[0])
    attrs = read_exr(tmp_path / "f.0003.exr")[1]
    assert attrs["pavonine:time"] == 3.0 and attrs["pavonine:camera"] == "/CamA"


@pytest.mark.render
def test_several_cameras_and_products_in_one_call(tmp_path):
    stage = animated_stage(tmp_path / "anim.usda")
    run(
        str(stage),
        "-o",
        str(tmp_path / "c.exr"),
        "--camera",
        "/CamA",
        "--camera",
        "/CamB",
        "--workers",
        "0",
    )
    a, b = (read_exr(tmp_path / name) for name in ("c.exr", "c.CamB.exr"))
    assert a[1]["pavonine:camera"] == "/CamA" and b[1]["pavonine:camera"] == "/CamB"
    run(str(stage), "-o", str(tmp_path / "p.exr"), "--workers", "0", "--png")  # every product
    wide, tall = (read_exr(tmp_path / name) for name in ("p.exr", "p.Tall.exr"))
    assert wide[0].shape[:2] == (16, 32) and wide[1]["pavonine:camera"] == "/CamA"
    assert tall[0].shape[:2] == (24, 16) and tall[1]["pavonine:camera"] == "/CamB"
    assert (tmp_path / "p.Tall.png").is_file()


@pytest.mark.render
def test_turntable_orbits_the_bounds(tmp_path):
    eye = REPO / "assets" / "scenes" / "eye_feather_sun.usda"
    run(
        str(eye),
        "-o",
        str(tmp_path / "t.exr"),
        "--turntable",
        "4",
        "--resolution",
        "24x36",
        "--workers",
        "0",
    )
    layer = Usd.Stage.Open(str(tmp_path / "t.turntable.usda"))
    cams = [UsdGeom.Camera(layer.GetPrimAtPath(f"/Turntable/Camera_000{i}")) for i in range(4)]
    eyes = [np.array(c.ComputeLocalToWorldTransform(Usd.TimeCode.Default()))[3, :3] for c in cams]
    centre = np.mean(eyes, axis=0)
    radii = [np.linalg.norm((e - centre)[[0, 2]]) for e in eyes]
    assert np.ptp(radii) < 1e-6 * max(radii) and np.allclose([e[1] for e in eyes], eyes[0][1])
    assert cams[0].GetFocalLengthAttr().Get() == 50  # the shipped camera's lens, kept
    frames = [read_exr(tmp_path / f"t.000{i}.exr")[0] for i in range(4)]
    assert not np.allclose(frames[0], frames[1])
    assert not list(tmp_path.glob(".*"))  # nothing half-written left behind


@pytest.mark.mitsuba  # `render` checks that Mitsuba loads before it reads its options
def test_batch_input_errors_are_one_line(tmp_path):
    stage = REPO / "assets" / "scenes" / "eye_feather_sun.usda"
    cases = [
        (["--frames", "3-1"], "--frames: the range ends before it starts"),
        (["--turntable", "4", "--frames", "1-2"], "--turntable: orbits one camera"),
        (["--workers", "2", "--scheduler", "tcp://127.0.0.1:1"], "give --workers"),
        (["--product", "/Nope", "--workers", "0"], "--product: no RenderProduct at /Nope"),
        (["--frames", "1-2", "--png-out", str(tmp_path / "x.png")], "--png-out: names one file"),
    ]
    for extra, message in cases:
        result = CliRunner().invoke(
            cli, ["render", str(stage), "-o", str(tmp_path / "o.exr"), *extra]
        )
        assert result.exit_code == 2, (extra, result.output)
        assert message in result.output and result.output.count("\n") == 1, result.output
    assert not list(tmp_path.iterdir())


def test_workers_do_not_log_input_errors_but_do_log_bugs():
    import logging

    from pavonine.apps.farm.tasks import quiet_input_errors

    quiet_input_errors()
    quiet_input_errors()  # once only
    logger = logging.getLogger("distributed.worker")
    assert len(logger.filters) == 1

    def record(exception_text: str) -> logging.LogRecord:
        args = ("key", "executing", "<Task>", exception_text, "Traceback: ...")
        return logging.LogRecord("distributed.worker", logging.ERROR, "", 0, "Compute Failed\n"
                                 "Key: %s\nState: %s\nTask: %s\nException: %r\nTraceback: %r\n",
                                 args, None)  # fmt: skip

    assert not logger.filter(record("InputError('a.usda: x: is NaN')"))
    assert not logger.filter(record("ParameterError('radius: must be positive')"))
    assert logger.filter(record("ZeroDivisionError('division by zero')"))
    assert logger.filter(logging.LogRecord("distributed.worker", 30, "", 0, "other", (), None))


def test_every_image_line_says_how_long_it_took(capsys):
    """Per-frame time (issue 35's rattle shot): each image's record carries its render time
    (on the farm, its tasks' summed time) and its line on stdout ends with it."""
    from pavonine.apps.cli.render import _show
    from pavonine.apps.farm.render import image_record

    metadata = {"resolution": [512, 384], "spp": 8, "variant": "llvm_ad_spectral", "time": 3.0,
                "seconds": 61.2345}  # fmt: skip
    record = image_record(metadata, exr=Path("rattle.0003.exr"), png=Path("rattle.0003.png"))
    assert record["seconds"] == 61.234 and record["time"] == 3.0
    _show(record)
    line = capsys.readouterr().out.strip()
    assert line.startswith("rattle.0003.exr + rattle.0003.png: 512×384, 8 spp")
    assert line.endswith(", 61.2 s"), line
    del metadata["seconds"]
    assert image_record(metadata, exr=Path("x.exr"))["seconds"] is None
