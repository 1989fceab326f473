"""Image comparison: the noise-aware Z-test, FLIP, image input and ``pavonine compare``."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from pavonine.apps.cli import cli
from pavonine.apps.compare.methods import (
    compare_arrays,
    display_decode,
    display_encode,
    estimate_noise_variance,
    read_image,
    sidak_alpha,
    stat_test,
)
from pavonine.render.imageio import write_display_png as write_png
from pavonine.render.imageio import write_exr

SIZE = 64


def smooth_image(size: int = SIZE) -> np.ndarray:
    """A smooth, coloured, strictly positive scene-linear image."""
    y, x = np.mgrid[0:size, 0:size] / size
    return np.stack([0.2 + 0.6 * x, 0.25 + 0.2 * np.sin(4 * y), 0.1 + 0.5 * x * y], axis=-1).astype(
        np.float32
    )


def noisy(truth: np.ndarray, seed: int, relative_sigma: float) -> tuple[np.ndarray, np.ndarray]:
    """A Monte Carlo-like estimate of ``truth``: Gaussian noise, and the variance of the estimate."""
    rng = np.random.default_rng(seed)
    variance = (relative_sigma * truth) ** 2
    image = truth + rng.normal(size=truth.shape) * np.sqrt(variance)
    return image.astype(np.float32), variance.astype(np.float32)


def shifted(truth: np.ndarray, factor: float, box=(slice(16, 48), slice(16, 48))) -> np.ndarray:
    out = truth.copy()
    out[box] *= factor
    return out


# ------------------------------------------------------------------------------------ statistics
def test_sidak_level_gives_family_wise_significance():
    assert sidak_alpha(0.01, 1) == pytest.approx(0.01)
    alpha = sidak_alpha(0.01, 12288)
    assert (1 - alpha) ** 12288 == pytest.approx(0.99, rel=1e-9)
    assert alpha < 0.01 / 12288 * 1.01


@pytest.mark.parametrize("seed", range(1, 13))
def test_other_seed_passes_stat(seed):
    truth = smooth_image()
    ref, ref_var = noisy(truth, 0, 0.05)
    test, test_var = noisy(truth, seed, 0.05)
    result = stat_test(test, ref, test_var, ref_var)
    assert result.passed, result.numbers


def test_two_percent_shift_in_a_region_fails_stat_and_heatmap_shows_where():
    truth = smooth_image()
    ref, ref_var = noisy(truth, 0, 0.05)
    test, test_var = noisy(shifted(truth, 1.02), 1, 0.05)
    result = stat_test(test, ref, test_var, ref_var)
    assert not result.passed
    per_pixel = result.scales[0]
    assert per_pixel.block == 1 and per_pixel.passed  # invisible pixel by pixel ...
    assert any(not s.passed for s in result.scales[1:])  # ... caught by block means
    brightness = result.heatmap.sum(axis=2)
    assert brightness[20:44, 20:44].mean() > 2 * brightness[:8, :].mean()


def test_noise_is_not_mistaken_for_a_shift_when_variance_is_ignored():
    """Without the variance, a 2 % shift and seed-to-seed noise of 5 % look alike per pixel."""
    truth = smooth_image()
    ref, _ = noisy(truth, 0, 0.05)
    other_seed, _ = noisy(truth, 1, 0.05)
    changed, _ = noisy(shifted(truth, 1.02), 1, 0.05)
    rms = [float(np.sqrt(np.mean((img - ref) ** 2))) for img in (other_seed, changed)]
    assert rms[1] == pytest.approx(rms[0], rel=0.1)


def test_a_few_outlier_pixels_pass_within_the_pass_ratio():
    truth = smooth_image()
    ref, ref_var = noisy(truth, 0, 0.05)
    test, test_var = noisy(truth, 1, 0.05)
    test[5, 7] += 0.5  # one firefly: 1 of 12288 per-pixel tests
    result = stat_test(test, ref, test_var, ref_var, blocks=(1,))
    assert result.passed
    assert result.scales[0].failures >= 1


def test_nonfinite_test_pixel_fails():
    truth = smooth_image()
    ref, ref_var = noisy(truth, 0, 0.05)
    test, test_var = noisy(truth, 1, 0.05)
    test[10, 10, 1] = np.nan
    result = stat_test(test, ref, test_var, ref_var)
    assert not result.passed
    assert result.numbers["nonfinite_pixels"] == 1


def test_identical_noise_free_images_pass_and_tiny_bias_on_flat_background_passes():
    flat = np.full((32, 32, 3), 0.5, np.float32)
    zero = np.zeros_like(flat)
    assert stat_test(flat, flat, zero, zero).passed
    assert stat_test(flat * (1 + 1e-5), flat, zero, zero).passed
    assert not stat_test(flat * 1.01, flat, zero, zero).passed


def test_noise_variance_estimate_recovers_known_sigma():
    rng = np.random.default_rng(3)
    sigma = 0.03
    image = smooth_image(128) + rng.normal(scale=sigma, size=(128, 128, 3)).astype(np.float32)
    estimate = estimate_noise_variance(image)
    assert np.median(estimate) == pytest.approx(sigma**2, rel=0.15)


def test_stat_without_variances_estimates_them():
    truth = smooth_image()
    ref, _ = noisy(truth, 0, 0.05)
    same, _ = noisy(truth, 1, 0.05)
    different, _ = noisy(shifted(truth, 1.3), 1, 0.05)
    assert compare_arrays(same, ref, "stat").passed
    assert not compare_arrays(different, ref, "stat").passed


# ------------------------------------------------------------------------------------------ FLIP
def test_display_encoding_is_the_srgb_curve_and_inverts():
    linear = np.array([[[0.0, 0.0031308, 0.18], [0.5, 1.0, 2.0]]], np.float32)
    encoded = display_encode(linear)
    expected = np.where(linear <= 0.0031308, 12.92 * linear, 1.055 * linear ** (1 / 2.4) - 0.055)
    assert encoded == pytest.approx(np.clip(expected, 0, 1), abs=2e-4)
    inside = linear[linear <= 1.0]
    assert display_decode(encoded)[linear <= 1.0] == pytest.approx(inside, abs=1e-4)


def test_png_is_decoded_with_the_view_it_was_written_with(tmp_path):
    from pavonine.materials.display import REFERENCE_DISPLAY
    from pavonine.render.imageio import write_png as write_render_png

    aces = replace(REFERENCE_DISPLAY, view="ACES 2.0 - SDR 100 nits (Rec.709)")
    linear = smooth_image(16) * 0.8
    write_render_png(tmp_path / "aces.png", linear, aces)
    image = read_image(tmp_path / "aces.png")
    assert image.display == aces
    assert image.rgb == pytest.approx(linear, abs=0.03)  # back to scene-linear, 8-bit rounding
    untonemapped = read_image(tmp_path / "aces.png", {"view": "Un-tone-mapped"})
    assert untonemapped.rgb != pytest.approx(linear, abs=0.03)
    result = CliRunner().invoke(
        cli, ["compare", str(tmp_path / "aces.png"), str(tmp_path / "aces.png"), "--view", "Nope"]
    )
    assert result.exit_code == 2 and "--view" in result.output


def test_flip_passes_noise_and_fails_a_swapped_image():
    truth = smooth_image()
    ref, _ = noisy(truth, 0, 0.05)
    test, _ = noisy(truth, 1, 0.05)
    assert compare_arrays(test, ref, "flip").passed
    swapped = test[:, ::-1, ::-1].copy()
    result = compare_arrays(swapped, ref, "flip")
    assert not result.passed
    assert result.numbers["mean_flip"] > 0.1
    assert result.heatmap.shape == (SIZE, SIZE, 3)


# ------------------------------------------------------------------------------------- the CLI
@pytest.fixture
def images(tmp_path: Path) -> Path:
    truth = smooth_image()
    ref, ref_var = noisy(truth, 0, 0.05)
    same, same_var = noisy(truth, 1, 0.05)
    changed, changed_var = noisy(shifted(truth, 1.02), 1, 0.05)
    for name, image, variance in (
        ("ref", ref, ref_var),
        ("same", same, same_var),
        ("changed", changed, changed_var),
    ):
        write_exr(tmp_path / f"{name}.exr", image)
        write_exr(tmp_path / f"{name}_var.exr", variance)
        write_png(tmp_path / f"{name}.png", display_encode(image))
    rgba = np.concatenate([display_encode(ref), np.ones((SIZE, SIZE, 1))], axis=2)
    write_png(tmp_path / "rgba.png", rgba)
    write_png(tmp_path / "small.png", display_encode(ref[:32, :48]))
    (tmp_path / "corrupt.exr").write_bytes((tmp_path / "ref.exr").read_bytes()[:400])
    (tmp_path / "text.png").write_text("not an image")
    return tmp_path


def run(*args: str):
    return CliRunner().invoke(cli, ["compare", *args], catch_exceptions=False)


def test_cli_agree_exits_0_and_writes_heatmaps_and_json(images: Path):
    d = images
    out = d / "out"
    result = run(
        str(d / "same.exr"), str(d / "ref.exr"), "--method", "all",
        "--ref-variance", str(d / "ref_var.exr"), "--test-variance", str(d / "same_var.exr"),
        "-o", str(out), "--json", str(d / "numbers.json"),
    )  # fmt: skip
    assert result.exit_code == 0, result.output
    assert "agree" in result.output
    for method in ("stat", "flip"):
        heatmap = read_image(out / f"same.{method}-diff.png")
        assert heatmap.size == (SIZE, SIZE)
    report = json.loads((d / "numbers.json").read_text())
    assert report["passed"] is True and report["test"] == str(d / "same.exr")
    numbers = report["methods"]
    assert numbers["stat"]["passed"] is True and numbers["flip"]["passed"] is True


def test_cli_shift_exits_1(images: Path):
    d = images
    result = run(
        str(d / "changed.exr"), str(d / "ref.exr"),
        "--ref-variance", str(d / "ref_var.exr"), "--test-variance", str(d / "changed_var.exr"),
    )  # fmt: skip
    assert result.exit_code == 1, result.output
    assert "DIFFER" in result.output
    assert (d / "changed.stat-diff.png").is_file()


def test_cli_png_inputs_fall_back_to_estimated_variance(images: Path):
    d = images
    assert run(str(d / "same.png"), str(d / "ref.png"), "--method", "all").exit_code == 0
    flipped = display_encode(read_image(d / "same.exr").rgb)[::-1]
    write_png(d / "upside_down.png", flipped)
    assert run(str(d / "upside_down.png"), str(d / "ref.png")).exit_code == 1


@pytest.mark.parametrize(
    ("test", "ref", "reason"),
    [
        ("small.png", "ref.png", "different sizes: 48x32 vs 64x64"),
        ("corrupt.exr", "ref.exr", "corrupt"),
        ("text.png", "ref.png", "cannot read image"),
        ("missing.exr", "ref.exr", "no such file"),
        ("ref_var.exr", "ref.txt", "unsupported image type"),
    ],
)
def test_cli_bad_input_exits_2_with_one_line(images: Path, test: str, ref: str, reason: str):
    (images / "ref.txt").write_text("x")
    result = CliRunner().invoke(cli, ["compare", str(images / test), str(images / ref)])
    assert result.exit_code == 2, result.output
    lines = result.output.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ")
    assert reason in lines[0]
    assert not list(images.glob(f"{Path(test).stem}.*-diff.png"))


def write_plain(path: Path, pixels: np.ndarray) -> None:
    """Channels pavonine's own writers do not make (grey EXR, grey + alpha PNG), with OpenImageIO:
    float EXR, 8-bit PNG with the colour stored unassociated (as PNG defines it)."""
    import OpenImageIO as oiio

    height, width, channels = pixels.shape
    png = path.suffix == ".png"
    spec = oiio.ImageSpec(width, height, channels, oiio.UINT8 if png else oiio.FLOAT)
    spec.attribute("oiio:UnassociatedAlpha", 1)
    data = np.round(pixels * 255).astype(np.uint8) if png else pixels.astype(np.float32)
    out = oiio.ImageOutput.create(str(path))
    out.open(str(path), spec)
    out.write_image(np.ascontiguousarray(data))
    out.close()


@pytest.mark.parametrize("method", ["stat", "flip", "all"])
def test_cli_grey_is_replicated_and_alpha_dropped_for_every_method(images: Path, method: str):
    """docs/compare.md: grey images are replicated to RGB; alpha is not compared (a PNG's colour
    as stored, not multiplied by a translucent alpha)."""
    d = images
    ref = read_image(d / "ref.exr").rgb
    grey = np.repeat(ref[:, :, :1], 3, axis=2)
    write_exr(d / "grey_rgb.exr", grey)
    write_plain(d / "grey.exr", grey[:, :, :1])
    write_png(d / "grey_rgb.png", display_encode(grey))
    write_png(d / "grey.png", display_encode(grey)[:, :, :1])
    alpha = np.linspace(0.0, 1.0, SIZE * SIZE, dtype=np.float32).reshape(SIZE, SIZE, 1)
    unassociated = {"oiio:UnassociatedAlpha": 1}  # colour stored as given, as PNG defines it
    write_png(d / "translucent.png", np.concatenate([display_encode(ref), alpha], axis=2),
              attributes=unassociated)  # fmt: skip
    grey_alpha = np.concatenate([display_encode(grey)[:, :, :1], alpha], axis=2)
    write_plain(d / "grey_alpha.png", grey_alpha)
    for test, ref_file in (
        ("grey.png", "grey_rgb.png"), ("grey_rgb.png", "grey.png"), ("grey.exr", "grey_rgb.exr"),
        ("grey.png", "grey_rgb.exr"), ("rgba.png", "ref.png"), ("ref.png", "rgba.png"),
        ("translucent.png", "ref.png"), ("grey_alpha.png", "grey_rgb.png"),
    ):  # fmt: skip
        result = run(str(d / test), str(d / ref_file), "--method", method)
        assert result.exit_code == 0, (test, ref_file, result.output)
    assert read_image(d / "grey_alpha.png").rgb.shape == (SIZE, SIZE, 3)


def test_cli_variance_of_wrong_size_exits_2(images: Path):
    d = images
    write_exr(d / "small_var.exr", np.zeros((8, 8, 3), np.float32))
    result = CliRunner().invoke(
        cli, ["compare", str(d / "same.exr"), str(d / "ref.exr"), "--ref-variance", str(d / "small_var.exr")]
    )  # fmt: skip
    assert result.exit_code == 2
    assert "variance is 8x8, image is 64x64" in result.output


def baseline_folder(tmp_path: Path) -> Path:
    """A baseline folder ``eye`` (256 spp, checked at 64) and ``test.exr``, a 64-spp render."""
    truth = smooth_image()
    folder = tmp_path / "eye"
    folder.mkdir()
    ref, ref_var = noisy(truth, 0, 0.02)  # 256 spp
    test, _ = noisy(truth, 1, 0.04)  # 64 spp: twice the standard deviation
    write_exr(folder / "mean.exr", ref)
    write_exr(folder / "variance.exr", ref_var)
    (folder / "baseline.json").write_text(json.dumps(BASELINE_RECORD))
    write_exr(tmp_path / "test.exr", test)
    return folder


BASELINE_RECORD = {
    "baseline": {"resolution": [64, 64], "spp": 256, "seed": 0},
    "check": {"resolution": [64, 64], "spp": 64, "seed": 1},
    "flip_threshold": 0.2,
}


def test_cli_baseline_folder_as_ref_scales_variance_by_spp(tmp_path: Path):
    """A baseline folder knows its spp and the check's: a 4x noisier TEST is expected."""
    baseline_folder(tmp_path)
    folder = tmp_path / "eye"
    result = run(str(tmp_path / "test.exr"), str(folder), "--method", "all")
    assert result.exit_code == 0, result.output
    assert "REF variance x 4" in result.output and "0.2" in result.output
    result = run(str(tmp_path / "test.exr"), str(folder), "--test-spp", "256")
    assert result.exit_code == 1, result.output  # claimed as clean as the baseline: it is not


BAD_RECORDS = [
    # (change to BASELINE_RECORD: dotted field -> value, or None to delete it), expected message
    ({"flip_threshold": "nan"}, 'flip_threshold: must be a positive number, got "nan"'),
    ({"flip_threshold": float("nan")}, "flip_threshold: must be a positive number, got NaN"),
    ({"flip_threshold": -1}, "flip_threshold: must be a positive number, got -1"),
    ({"flip_threshold": 0}, "flip_threshold: must be a positive number, got 0"),
    ({"flip_threshold": "abc"}, 'flip_threshold: must be a positive number, got "abc"'),
    ({"flip_threshold": True}, "flip_threshold: must be a positive number, got true"),
    ({"flip_threshold": None}, "flip_threshold: missing; run 'pavonine baseline update eye'"),
    ({"check": None}, "check: missing; run 'pavonine baseline update eye'"),
    ({"baseline": None}, "baseline: missing; run 'pavonine baseline update eye'"),
    ({"check": [64, 1]}, "check: must be an object with resolution, spp and seed, got [64, 1]"),
    ({"check.spp": float("nan")}, "check.spp: must be a positive whole number, got NaN"),
    ({"check.spp": -16}, "check.spp: must be a positive whole number, got -16"),
    ({"check.spp": "64"}, 'check.spp: must be a positive whole number, got "64"'),
    ({"check.spp": 64.5}, "check.spp: must be a positive whole number, got 64.5"),
    ({"check.spp": None}, "check.spp: missing"),
    ({"check.seed": -1}, "check.seed: must be a whole number in [0, 4294967295], got -1"),
    ({"check.seed": "1"}, "check.seed: must be a whole number in [0, 4294967295], got '1'"),
    ({"check.resolution": [64]}, "check.resolution: must be [width, height], got [64]"),
    ({"check.resolution": None}, "check.resolution: missing"),
    ({"check.resolution": [64, -64]}, "check.resolution: must be a positive whole number, got -64"),
    ({"baseline.spp": "abc"}, 'baseline.spp: must be a positive whole number, got "abc"'),
    ({"baseline.spp": 0}, "baseline.spp: must be a positive whole number, got 0"),
    ({"baseline.resolution": [32, 32]}, "baseline.resolution: 32x32 differs from mean.exr's 64x64"),
    ({"format": 2}, "format: 2 is newer than this Pavonine reads (1); update Pavonine"),
    ({"format": "1"}, 'format: must be a whole number >= 1, got "1"'),
]


@pytest.mark.parametrize(("change", "reason"), BAD_RECORDS)
def test_cli_baseline_folder_with_a_bad_record_exits_2_naming_the_field(
    tmp_path: Path, change: dict, reason: str
):
    """A bad field of ``baseline.json`` is never replaced by a default (a looser FLIP threshold)."""
    folder = baseline_folder(tmp_path)
    record = json.loads(json.dumps(BASELINE_RECORD))
    for dotted, value in change.items():
        *parents, key = dotted.split(".")
        section = record
        for parent in parents:
            section = section[parent]
        if value is None:
            del section[key]
        else:
            section[key] = value
    (folder / "baseline.json").write_text(json.dumps(record))
    args = [str(tmp_path / "test.exr"), str(folder), "--method", "flip", "--test-spp", "16"]
    result = CliRunner().invoke(cli, ["compare", *args])
    assert result.exit_code == 2, result.output
    assert result.output == f"error: {folder / 'baseline.json'}: {reason}\n"
    assert not (tmp_path / "test.flip-diff.png").exists()


@pytest.mark.parametrize(
    ("content", "reason"),
    [
        (None, "missing; run 'pavonine baseline update eye'"),
        ("[1, 2]", "must be a JSON object, got [1, 2]"),
        ("{}", "baseline: missing; run 'pavonine baseline update eye'"),
        (b"\xff\xfe{}", "not UTF-8 text"),
    ],
)
def test_cli_baseline_folder_without_a_record_exits_2_with_one_line(
    tmp_path: Path, content: str | bytes | None, reason: str
):
    folder = baseline_folder(tmp_path)
    record = folder / "baseline.json"
    if content is None:
        record.unlink()
    elif isinstance(content, bytes):
        record.write_bytes(content)
    else:
        record.write_text(content)
    result = CliRunner().invoke(cli, ["compare", str(tmp_path / "test.exr"), str(folder)])
    assert result.exit_code == 2, result.output
    assert result.output == f"error: {record}: {reason}\n"


def test_cli_png_against_exr_with_out_of_range_values(tmp_path: Path):
    """A PNG cannot hold negatives or values above 1: the EXR is clipped the same way first."""
    truth = smooth_image() * 1.6 - 0.05  # over-range highlights and out-of-gamut negatives
    ref, ref_var = noisy(truth, 0, 0.02)
    test, _ = noisy(truth, 1, 0.02)
    write_exr(tmp_path / "ref.exr", ref)
    write_exr(tmp_path / "ref_var.exr", ref_var)
    write_png(tmp_path / "test.png", display_encode(test))
    args = [str(tmp_path / "test.png"), str(tmp_path / "ref.exr")]
    result = run(*args, "--ref-variance", str(tmp_path / "ref_var.exr"), "--method", "all")
    assert result.exit_code == 0, result.output
    write_png(tmp_path / "test.png", display_encode(test * 1.05))
    assert run(*args, "--ref-variance", str(tmp_path / "ref_var.exr")).exit_code == 1
