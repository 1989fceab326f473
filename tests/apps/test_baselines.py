"""Baselines and ``pavonine check-renders``: with a stand-in renderer, then for real (``render``)."""

from __future__ import annotations

import json
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from pavonine.apps.cli import cli
from pavonine.apps.compare import baselines
from pavonine.apps.compare.baselines import (
    CheckSettings,
    SceneRender,
    baseline_for,
    check_stage,
    shipped_scenes,
    update_baseline,
)
from pavonine.apps.compare.methods import read_image

pytestmark = pytest.mark.mitsuba  # the CLI checks that Mitsuba loads first


# ------------------------------------------------------------ stand-in renderer (fast, no Mitsuba)
def fake_render(
    stage, settings: CheckSettings, *, progress: bool = False, limits=None
) -> SceneRender:
    """A smooth image whose brightness is read from the 'stage' text, with Monte Carlo-like noise.

    The per-sample relative spread is 50 %, so the estimate's variance is ``(0.5·truth)²/spp``;
    ``noise-lies`` in the stage makes the reported variance 100x too small.
    """
    text = Path(stage).read_text()
    gain = float(text.split("gain=")[1].split()[0]) if "gain=" in text else 1.0
    width, height = settings.resolution
    y, x = np.mgrid[0:height, 0:width] / max(width, height)
    truth = np.stack([0.2 + 0.6 * x, 0.3 + 0.2 * y, 0.1 + 0.3 * x * y], axis=-1)
    truth[height // 4 : 3 * height // 4, width // 4 : 3 * width // 4] *= gain
    variance = (0.5 * truth) ** 2 / settings.spp
    rng = np.random.default_rng(settings.seed)
    rgb = truth + rng.normal(size=truth.shape) * np.sqrt(variance)
    if "noise-lies" in text:
        variance = variance / 100
    return SceneRender(rgb.astype(np.float32), variance.astype(np.float32), {"fake": True})


def scene_text(comment: str) -> str:
    return f'#usda 1.0\n(\n    renderSettingsPrimPath = "/Render/Settings"\n)\n# {comment}\n'


@pytest.fixture
def fake_repo(tmp_path: Path, monkeypatch) -> Path:
    monkeypatch.setattr(baselines, "render_scene", fake_render)
    scenes = tmp_path / "scenes"
    scenes.mkdir()
    for name in ("eye", "blue"):
        (scenes / f"{name}.usda").write_text(scene_text("gain=1.0"))
    (scenes / "component.usda").write_text("#usda 1.0\n")  # referenced asset, not a scene
    return tmp_path


def invoke(*args: str):
    return CliRunner().invoke(cli, list(args), catch_exceptions=False)


def dirs(repo: Path) -> list[str]:
    return ["--scenes-dir", str(repo / "scenes"), "--baselines-dir", str(repo / "baselines")]


def test_baseline_update_writes_mean_variance_preview_and_record(fake_repo: Path):
    result = invoke(
        "baseline", "update", "eye", "--resolution", "96x96", "--spp", "256", "--check-spp", "64",
        *dirs(fake_repo),
    )  # fmt: skip
    assert result.exit_code == 0, result.output
    folder = fake_repo / "baselines" / "eye"
    assert sorted(p.name for p in folder.iterdir()) == [
        "baseline.json", "mean.exr", "preview.png", "variance.exr",
    ]  # fmt: skip
    info = json.loads((folder / "baseline.json").read_text())
    assert info["baseline"] == {"resolution": [96, 96], "spp": 256, "seed": 0}
    assert info["check"] == {"resolution": [96, 96], "spp": 64, "seed": 1}
    assert info["versions"]["numpy"] == np.__version__
    assert len(info["stage_sha256"]) == 64
    assert info["calibration"]["seeds"] == [2, 3]
    assert info["flip_threshold"] >= max(info["calibration"]["flip_mean"])
    assert "pavonine baseline update eye" in info["command"]
    assert read_image(folder / "mean.exr").size == (96, 96)
    from pavonine.render.imageio import read_exr

    for name in ("mean.exr", "variance.exr"):  # both say which space their values are in
        assert read_exr(folder / name)[1]["oiio:ColorSpace"] == "lin_rec709_scene"
    assert not (fake_repo / "baselines" / "blue").exists()  # nothing updated implicitly
    listing = invoke("baseline", "list", *dirs(fake_repo))
    assert "eye" in listing.output and "missing" in listing.output


def test_baseline_update_refuses_a_scene_whose_noise_it_cannot_trust(fake_repo: Path):
    (fake_repo / "scenes" / "eye.usda").write_text(scene_text("noise-lies"))
    result = invoke("baseline", "update", "eye", *dirs(fake_repo))
    assert result.exit_code == 2
    assert "fails 'stat'" in result.output and "--check-spp" in result.output
    assert not (fake_repo / "baselines" / "eye").exists()


def test_baseline_update_rejects_unknown_scene_and_equal_seeds(fake_repo: Path):
    result = invoke("baseline", "update", "nope", *dirs(fake_repo))
    assert result.exit_code == 2 and "no such scene (shipped scenes: blue, eye)" in result.output
    result = invoke("baseline", "update", "eye", "--check-seed", "0", *dirs(fake_repo))
    assert result.exit_code == 2 and "--check-seed" in result.output
    missing = fake_repo / "nowhere"
    result = invoke("check-renders", "eye", "--scenes-dir", str(missing))
    assert (
        result.exit_code == 2 and f"error: --scenes-dir {missing}: no such folder" in result.output
    )
    result = invoke("baseline", "update", "eye", "--check-spp", "0", *dirs(fake_repo))
    assert (
        result.exit_code == 2
        and "error: --check-spp: samples per pixel must be positive, got 0" in result.output
    )


def test_check_renders_passes_then_catches_a_change_and_reports_it(fake_repo: Path):
    update = invoke("baseline", "update", "--all", "--resolution", "96x96", *dirs(fake_repo))
    assert update.exit_code == 0
    result = invoke("check-renders", *dirs(fake_repo), "--report", str(fake_repo / "report"))
    assert result.exit_code == 0, result.output
    assert "2 scene(s) match their baselines" in result.output
    assert (fake_repo / "report" / "index.html").is_file()

    (fake_repo / "scenes" / "eye.usda").write_text(scene_text("gain=1.03"))
    result = invoke("check-renders", *dirs(fake_repo), "--report", str(fake_repo / "report"))
    assert result.exit_code == 1, result.output
    assert "1 of 2 scene(s) differ from baseline: eye" in result.output
    assert "changed since the baseline" in result.output
    page = (fake_repo / "report" / "index.html").read_text()
    assert page.count(">FAIL<") >= 2 and "images/eye-stat-diff.png" in page
    heatmap = read_image(fake_repo / "report" / "images" / "eye-stat-diff.png").rgb
    inside, outside = heatmap[36:60, 36:60].mean(), heatmap[:12, :12].mean()
    assert inside > 2 * outside  # the heat-map shows where


def test_check_renders_without_baseline_exits_2_with_one_line(fake_repo: Path):
    result = CliRunner().invoke(cli, ["check-renders", *dirs(fake_repo)])
    assert result.exit_code == 2
    lines = result.output.strip().splitlines()
    assert len(lines) == 1 and "pavonine baseline update" in lines[0]


def test_corrupt_baseline_record_exits_2(fake_repo: Path):
    invoke("baseline", "update", "eye", *dirs(fake_repo))
    (fake_repo / "baselines" / "eye" / "baseline.json").write_text("{not json")
    result = CliRunner().invoke(cli, ["check-renders", "eye", *dirs(fake_repo)])
    assert result.exit_code == 2 and "baseline.json: invalid JSON" in result.output


# ----------------------------------------------------------------------- the real renderer
SCENES = shipped_scenes()
EYE = next((p for p in SCENES if p.stem == "eye_feather_sun"), None)
needs_eye = pytest.mark.skipif(EYE is None, reason="assets/scenes/eye_feather_sun.usda not shipped")


@pytest.mark.render
@pytest.mark.skipif(not SCENES, reason="no shipped scenes in assets/scenes")
def test_every_shipped_scene_matches_its_baseline(tmp_path: Path):
    """The CI suite itself: ``pavonine check-renders --report``."""
    result = invoke("check-renders", "--report", str(tmp_path / "report"))
    assert result.exit_code == 0, result.output
    page = tmp_path / "report" / "index.html"
    chromium = shutil.which("chromium")
    if chromium is None:
        pytest.skip("report written; Debian's chromium is not installed to open it")
    dom = subprocess.run(
        [
            chromium, "--headless", "--no-sandbox", "--disable-gpu",
            "--disable-background-networking", "--disable-component-update", "--disable-sync",
            "--no-first-run", f"--user-data-dir={tmp_path / 'profile'}",
            "--virtual-time-budget=5000", "--dump-dom", page.as_uri(),
        ],
        capture_output=True, text=True, timeout=120, check=True,
    ).stdout  # fmt: skip
    status = re.search(r'<pre id="image-status">(.*?)</pre>', dom, re.S)
    assert status, dom[-2000:]
    lines = status.group(1).strip().splitlines()
    assert len(lines) == 4 * len(SCENES)  # render, baseline, two heat-maps
    assert all(line.startswith("loaded ") for line in lines), lines


def _feather_material(stage):
    from pavonine.schemas.authoring import MAP_ATTRS

    for prim in stage.Traverse():
        if "PavonineFeatherAPI" in prim.GetAppliedSchemas():
            return prim, MAP_ATTRS
    raise AssertionError("no PavonineFeatherAPI material in the shipped eye feather scene")


def _override(tmp_path: Path, name: str, edit, base: Path | None = None) -> Path:
    """A new layer that sublayers ``base`` (the shipped scene) and overrides it with ``edit``."""
    from pxr import Sdf, Usd

    layer = Sdf.Layer.CreateNew(str(tmp_path / f"{name}.usda"))
    layer.subLayerPaths.append(str((base or EYE).resolve()))
    stage = Usd.Stage.Open(layer)
    stage.SetEditTarget(layer)
    edit(stage)
    layer.Save()
    return Path(layer.realPath)


def _dominant_class(material, map_attrs) -> int:
    """The ocellar class covering most of the feather (alpha-weighted), so the shift is visible."""
    from pavonine.pipeline.maps.paint import ocellar_class
    from pavonine.schemas.authoring import resolve_maps

    maps = resolve_maps(material)
    grey = read_image(maps["ocellar"]).rgb[:, :, 0] if maps.get("ocellar") else None
    if grey is None:
        return 0
    weight = np.ones_like(grey)
    if maps.get("alpha"):
        alpha = read_image(maps["alpha"]).rgb[:, :, 0]
        if alpha.shape == grey.shape:
            weight = alpha
    classes = np.asarray(ocellar_class(grey)).astype(int)
    return int(np.argmax(np.bincount(classes.ravel(), weights=weight.ravel(), minlength=6)))


def shift_interval(stage) -> None:
    """One class (the most visible), one axis (long): a 2 % longer layer interval at both ends."""
    material, map_attrs = _feather_material(stage)
    k = _dominant_class(material, map_attrs)
    attr = material.GetAttribute("pavonine:long:layerInterval")
    values = [tuple(v) for v in attr.Get()]
    values[k] = (values[k][0] * 1.02, values[k][1] * 1.02)
    attr.Set(values)


def rotate_sun(stage) -> None:
    from pxr import UsdGeom, UsdLux

    suns = [p for p in stage.Traverse() if p.IsA(UsdLux.DistantLight)]
    assert suns, "the eye feather scene has no DistantLight sun"
    UsdGeom.Xformable(suns[0]).AddRotateXOp(opSuffix="perturb").Set(5.0)


def swap_maps(stage) -> None:
    """The gradation and angle maps swapped (two grey maps a pipeline could mix up)."""
    material, map_attrs = _feather_material(stage)
    gradation, angle = (material.GetAttribute(map_attrs[k]) for k in ("gradation", "angle"))
    a, b = gradation.Get(), angle.Get()
    gradation.Set(b)
    angle.Set(a)


@pytest.mark.render
@needs_eye
def test_another_seed_passes_both_methods():
    baseline = baseline_for(EYE)
    check = check_stage(EYE, baseline, seed=baseline.check_settings.seed + 100)
    assert [r.method for r in check.results] == ["stat", "flip"]
    assert check.passed, [r.numbers for r in check.results]


@pytest.mark.render
@needs_eye
@pytest.mark.parametrize("perturb", [shift_interval, rotate_sun], ids=lambda f: f.__name__)
def test_a_look_change_fails_stat(tmp_path: Path, perturb):
    stage = _override(tmp_path, perturb.__name__, perturb)
    check = check_stage(stage, baseline_for(EYE), methods=("stat",))
    stat = check.results[0]
    assert not stat.passed, stat.numbers
    assert np.max(stat.heatmap) > 0.5  # the failing blocks are lit in the heat-map


@pytest.mark.render
@needs_eye
def test_a_swapped_map_fails_stat(tmp_path: Path):
    """The eye feather with the eye maps authored, baselined afresh; then two maps swapped."""
    from pavonine.pipeline.maps.paint import generate_maps, write_maps
    from pavonine.schemas.authoring import author_maps

    paths = write_maps(generate_maps("eye", size=96), tmp_path / "maps")

    def add_maps(stage) -> None:
        material, _ = _feather_material(stage)
        author_maps(material, {k: str(paths[k]) for k in ("ocellar", "gradation", "angle")})

    mapped = _override(tmp_path, "eye_mapped", add_maps)
    baseline = update_baseline(mapped, baselines_dir=tmp_path / "baselines")
    assert check_stage(mapped, baseline).passed  # another seed still agrees

    swapped = _override(tmp_path, "eye_swapped_maps", swap_maps, base=mapped)
    check = check_stage(swapped, baseline)
    assert not check.results[0].passed, check.results[0].numbers


def test_check_renders_junit_has_a_case_per_scene_failing_when_it_differs(fake_repo: Path):
    """--junit, read back with junitparser (what CI test-report plug-ins are built on)."""
    from junitparser import Failure, JUnitXml

    assert (
        invoke("baseline", "update", "--all", "--resolution", "64x64", *dirs(fake_repo)).exit_code
        == 0
    )
    (fake_repo / "scenes" / "eye.usda").write_text(scene_text("gain=1.05"))
    target = fake_repo / "renders.xml"
    result = invoke("check-renders", *dirs(fake_repo), "--junit", str(target))
    assert result.exit_code == 1, result.output
    [suite] = list(JUnitXml.fromfile(str(target)))
    assert suite.name == "pavonine check-renders"
    assert (suite.tests, suite.failures, suite.errors) == (2, 1, 0)
    cases = {case.name: case for case in suite}
    assert cases["blue"].is_passed
    failures = cases["eye"].result
    assert failures and all(isinstance(f, Failure) for f in failures)
    assert any(f.message.startswith("stat: differs") for f in failures)
