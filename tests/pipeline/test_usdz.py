"""``pavonine package``: one ``.usdz`` by USD's own packaging, whose maps and textures
``pavonine validate`` and ``pavonine render`` read through USD's asset resolver."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from click.testing import CliRunner

from pavonine.apps.cli import cli

SCENE = Path(__file__).resolve().parents[2] / "assets" / "scenes" / "eye_feather_sun.usda"


def run(*args: str):
    return CliRunner().invoke(cli, [str(a) for a in args])


@pytest.fixture(scope="module")
def package(eye_asset, tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("usdz") / "eye_feather.usdz"
    result = run("package", eye_asset.parent, "-o", out, "--json", "-")
    assert result.exit_code == 0, result.output
    report = json.loads(result.stdout)
    assert report["output"] == str(out) and report["bytes"] == out.stat().st_size
    return out


def test_package_holds_every_layer_map_and_texture(package):
    from pxr import Sdf

    files = set(Sdf.ZipFile.Open(str(package)).GetFileNames())
    assert "eye_feather.usd" == Sdf.ZipFile.Open(str(package)).GetFileNames()[0]
    for lod in ("high", "medium", "low"):
        assert f"eye_feather_geo_{lod}.usdc" in files
    for name in ("alpha", "ocellar", "gradation", "angle", "displacement", "melanin"):
        assert f"maps/{name}.png" in files
    for name in ("basecolor", "roughness", "film_thickness", "film_ior", "film_weight"):
        assert f"textures/{name}.png" in files
    assert not any(f.endswith(".mtlx") for f in files)  # usdz holds layers, images, audio


def test_validate_reads_the_maps_inside_the_package(package):
    result = run("validate", package)
    assert result.exit_code == 0 and result.output == "1 file, no findings\n", result.output


def _scene(tmp_path: Path, asset: Path) -> Path:
    text = SCENE.read_text().replace("@../feathers/eye_feather/eye_feather.usd@", f"@{asset}@")
    path = tmp_path / f"scene_{asset.suffix[1:]}.usda"
    path.write_text(text)
    return path


@pytest.mark.render
def test_a_scene_renders_the_package_like_the_unpacked_asset(package, eye_asset, tmp_path):
    images = {}
    for asset, seed in ((package, 1), (eye_asset, 2)):
        out = tmp_path / f"{asset.suffix[1:]}.exr"
        result = run(
            "render", _scene(tmp_path, asset), "-o", out, "--spp", "32",
            "--resolution", "48x72", "--seed", seed, "-q",
        )  # fmt: skip
        assert result.exit_code == 0, result.output
        assert "not found" not in result.output and "warning" not in result.output
        images[asset.suffix] = out
    compare = run(
        "compare", images[".usdz"], images[".usd"], "--method", "stat",
        "--ref-spp", "32", "--test-spp", "32", "--json", tmp_path / "stat.json",
    )  # fmt: skip
    assert compare.exit_code == 0, compare.output
    stat = json.loads((tmp_path / "stat.json").read_text())["methods"]["stat"]
    assert stat["passed"] is True and stat["nonfinite_pixels"] == 0


@pytest.mark.parametrize("case", ["zip", "missing_asset", "unresolvable"])
def test_bad_input_is_one_line_and_writes_nothing(eye_asset, tmp_path, case):
    import shutil

    out = tmp_path / "x.usdz"
    asset = eye_asset.parent
    if case == "zip":
        out = tmp_path / "x.zip"
    elif case == "missing_asset":
        asset = tmp_path / "nothing_here.usd"
    else:
        asset = tmp_path / "broken"
        shutil.copytree(eye_asset.parent, asset)
        (asset / "textures" / "roughness.png").unlink()
        (asset / "broken.usd").write_text((asset / "eye_feather.usd").read_text())
        asset = asset / "broken.usd"
    result = run("package", asset, "-o", out)
    assert result.exit_code == 2, result.output
    assert result.stderr.startswith("error: ") and result.stderr.count("\n") == 1
    if case == "unresolvable":
        assert "roughness.png" in result.stderr
    assert not out.exists()
