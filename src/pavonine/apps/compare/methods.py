"""Render comparison: a Monte Carlo-aware Z-test (``stat``) and NVIDIA FLIP (``flip``).

``stat`` follows Mitsuba 3's own render tests (``src/render/tests/test_renders.py``): each pixel's
difference to the reference is divided by the standard deviation of the estimates, the two-sided
p-value is compared with a Šidák-corrected significance level, and the image passes when the share
of passing tests reaches a pass ratio. Because a small systematic shift (a 2 % change of a layer
interval) hides under per-pixel noise at CI sample counts, the same test is also run on block means
(2×2 up to 32×32 pixels): averaging ``n`` pixels divides the noise by ``√n`` but not the shift. All
tests of all scales form one family for the Šidák correction.

``flip`` runs the LDR FLIP metric (Andersson et al. 2020, "FLIP: A Difference Evaluator for
Alternating Images", HPG) on display-referred images and thresholds its mean.

Images are held scene-linear (Rec.709 primaries) in memory. PNG files are display-referred and are
decoded with the inverse of the display transform recorded in the PNG (OCIO config, display, view
and exposure, written by :mod:`pavonine.render.imageio`; the current display transform when the PNG
records none), each field overridable. FLIP always sees both images through the pinned reference
transform (:data:`pavonine.materials.display.REFERENCE_DISPLAY`), so ``$OCIO`` cannot move its
verdict. Images are written by :mod:`pavonine.render.imageio`.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from pavonine.base.errors import InputError
from pavonine.base.limits import image_error, open_image
from pavonine.materials.display import (
    REFERENCE_DISPLAY,
    DisplayError,
    DisplayTransform,
    current_display,
    with_overrides,
)

METHODS = ("stat", "flip")

#: Family-wise false-alarm probability of ``stat`` (Mitsuba's render tests use the same value).
SIGNIFICANCE = 0.01
#: Share of tests per scale that must pass (Mitsuba's render tests use the same value).
PASS_RATIO = 0.9975
#: Block edges (pixels) at which ``stat`` tests block means; 1 is the per-pixel test.
BLOCK_SIZES = (1, 2, 4, 8, 16, 32)
#: Differences below ``ABS_TOLERANCE·scale + REL_TOLERANCE·|reference|`` (``scale`` the reference's
#: mean absolute value, so the floor follows the scene's exposure) are numerically meaningless:
#: they floor the standard deviation so noise-free pixels (background) do not fail on rounding.
ABS_TOLERANCE = 1e-3
REL_TOLERANCE = 1e-3
#: Mean FLIP above which two display-referred images differ; measured from seed-to-seed noise of the
#: shipped scenes at CI size (see docs/compare.md for the measurement).
FLIP_THRESHOLD = 0.10

_EXR = (".exr",)
_PNG = (".png",)


# --------------------------------------------------------------------------------------- images
@dataclass(frozen=True)
class LoadedImage:
    """An image read for comparison: ``rgb`` is H×W×3 float32 scene-linear (grey replicated, alpha
    dropped); ``channels`` is how many the file has."""

    path: Path
    rgb: np.ndarray
    display_referred: bool
    channels: int
    display: DisplayTransform | None = None  # what a display-referred image was encoded with

    @property
    def size(self) -> tuple[int, int]:
        """(width, height) in pixels."""
        return self.rgb.shape[1], self.rgb.shape[0]


def _read_pixels(path: Path) -> tuple[np.ndarray, dict[str, object]]:
    """All channels of ``path`` as H×W×C float32 and its header attributes, or :class:`InputError`."""

    from pavonine.base.groups import check_group

    if not os.path.lexists(path):
        raise InputError(str(path), "no such file")
    check_group(path)  # a render's EXR, variance and PNG: all from one write
    # a regular file within the pixel budget (pavonine.base.limits); a PNG's colour as stored, since
    # alpha is dropped (_as_rgb) and must not darken it
    with open_image(path, unassociated_alpha=True) as inp:
        attributes = {a.name: a.value for a in inp.spec().extra_attribs}
        pixels = inp.read_image("float")
        error = inp.geterror() if pixels is None else ""
    if pixels is None or not isinstance(pixels, np.ndarray) or pixels.size == 0:
        raise InputError(str(path), f"corrupt or truncated image ({image_error(error)})")
    pixels = np.asarray(pixels, dtype=np.float32)
    if pixels.ndim == 2:
        pixels = pixels[:, :, None]
    return pixels, attributes


def _as_rgb(pixels: np.ndarray, path: Path) -> np.ndarray:
    """RGB: grey (and grey + alpha) replicated to three channels, alpha dropped (not compared)."""
    channels = pixels.shape[2]
    if channels in (1, 2):
        return np.repeat(pixels[:, :, :1], 3, axis=2)
    if channels in (3, 4):
        return pixels[:, :, :3]
    raise InputError(str(path), f"has {channels} channels; expected 1 (grey), 3 (RGB) or 4 (RGBA)")


def read_image(path: str | Path, overrides: Mapping[str, Any] | None = None) -> LoadedImage:
    """Read an EXR (scene-linear) or PNG (display-referred, decoded to linear) for comparison.

    A PNG is decoded with the display transform recorded in it by
    :func:`pavonine.render.imageio.write_png` (else the current one), with the fields in
    ``overrides`` (``config``, ``display``, ``view``, ``exposure``) replaced.
    """
    from pavonine.render.imageio import png_display

    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in _EXR + _PNG:
        raise InputError(str(path), f"unsupported image type '{suffix}'; expected .exr or .png")
    pixels, attributes = _read_pixels(path)
    rgb = _as_rgb(pixels, path)
    display = None
    if suffix in _PNG:
        try:
            display = with_overrides(
                (png_display(attributes) or current_display()).check(), **(overrides or {})
            )
        except DisplayError as exc:
            raise InputError(str(path), f"{exc.field}: {exc.message}") from None
        rgb = display.decode(rgb)
    rgb = np.ascontiguousarray(rgb, dtype=np.float32)
    return LoadedImage(path, rgb, suffix in _PNG, pixels.shape[2], display)


def read_variance(path: str | Path, size: tuple[int, int]) -> np.ndarray:
    """Per-pixel variance of an estimate (EXR, H×W×1 or ×3, scene-linear units²)."""
    path = Path(path)
    if path.suffix.lower() not in _EXR:
        raise InputError(str(path), "variance must be an EXR file (scene-linear units squared)")
    pixels, _ = _read_pixels(path)
    if (pixels.shape[1], pixels.shape[0]) != size:
        raise InputError(
            str(path),
            f"variance is {pixels.shape[1]}x{pixels.shape[0]}, image is {size[0]}x{size[1]}",
        )
    variance = _as_rgb(pixels, path)
    if not np.all(np.isfinite(variance)) or np.any(variance < 0):
        raise InputError(str(path), "variance has negative, NaN or infinite values")
    return np.ascontiguousarray(variance, dtype=np.float32)


def display_encode(linear: np.ndarray, display: DisplayTransform | None = None) -> np.ndarray:
    """Scene-linear Rec.709 → display values in [0, 1], exactly as PNGs are encoded.

    ``display`` defaults to the pinned reference transform (``sRGB - Display``,
    ``Un-tone-mapped``); non-finite values become 0 first.
    """
    rgb = np.nan_to_num(np.asarray(linear, np.float32), nan=0.0, posinf=0.0, neginf=0.0)
    return (display or REFERENCE_DISPLAY).encode(rgb)


def display_decode(encoded: np.ndarray, display: DisplayTransform | None = None) -> np.ndarray:
    """Display values in [0, 1] → scene-linear Rec.709 (inverse of :func:`display_encode`)."""
    return (display or REFERENCE_DISPLAY).decode(encoded)


def match_display_range(test: LoadedImage, ref: LoadedImage) -> tuple[LoadedImage, LoadedImage]:
    """When one image is display-referred (PNG), clip the other to what a PNG can hold.

    A PNG has lost out-of-gamut and over-range values (the spectral renderer makes both); the
    scene-linear image goes through the same display encoding and back so that only noise and
    rounding separate them.
    """
    if test.display_referred == ref.display_referred:
        return test, ref

    display = test.display if test.display_referred else ref.display

    def clipped(image: LoadedImage) -> LoadedImage:
        if image.display_referred:
            return image
        rgb = display_decode(display_encode(image.rgb, display), display).astype(np.float32)
        return LoadedImage(image.path, rgb, image.display_referred, image.channels, display)

    return clipped(test), clipped(ref)


def quantization_variance(image: LoadedImage) -> np.ndarray:
    """Variance that 8-bit rounding adds to a display-referred image, in scene-linear units².

    Rounding to 1/255 steps is uniform error of variance ``(1/255)²/12`` in display values; the
    decoding curve scales it by its slope squared (first-order propagation of error).
    """
    if not image.display_referred:
        return np.zeros_like(image.rgb)
    display = image.display
    encoded = display_encode(image.rgb, display)
    step = 0.5 / 255.0
    slope = (
        display_decode(np.clip(encoded + step, 0, 1), display)
        - display_decode(np.clip(encoded - step, 0, 1), display)
    ) * 255.0
    return (slope**2 * (1.0 / 255.0) ** 2 / 12.0).astype(np.float32)


def estimate_noise_variance(rgb: np.ndarray) -> np.ndarray:
    """Per-pixel noise variance estimated from one image, for inputs without a variance image.

    Immerkær's operator (J. Immerkær 1996, "Fast Noise Variance Estimation", CVIU 64(2)) — the
    difference of two Laplacians, ``[[1,-2,1],[-2,4,-2],[1,-2,1]]`` — cancels smooth image content;
    on i.i.d. noise of variance σ² its response has variance 36σ². Its squared response averaged over
    a 5×5 window, divided by 36, is the local σ². Edges inflate it, which errs towards passing.
    """
    from scipy.ndimage import convolve, uniform_filter

    kernel = np.array([[1, -2, 1], [-2, 4, -2], [1, -2, 1]], dtype=np.float64)
    variance = np.empty(rgb.shape, dtype=np.float64)
    for c in range(rgb.shape[2]):
        response = convolve(rgb[:, :, c].astype(np.float64), kernel, mode="reflect")
        variance[:, :, c] = uniform_filter(response**2, size=5, mode="reflect") / 36.0
    return variance  # float64: the variance of float32 values beyond 1.8e19 overflows float32


def check_same_shape(test: LoadedImage, ref: LoadedImage) -> None:
    """Raise :class:`InputError` unless both images have the same size (both are RGB: grey is
    replicated and alpha dropped when read) and the reference is finite."""
    if test.size != ref.size:
        raise InputError(
            f"{test.path} vs {ref.path}",
            f"different sizes: {test.size[0]}x{test.size[1]} vs {ref.size[0]}x{ref.size[1]}",
        )
    if not np.all(np.isfinite(ref.rgb)):
        raise InputError(str(ref.path), "reference has NaN or infinite pixels")


# ------------------------------------------------------------------------------------- stat test
@dataclass(frozen=True)
class ScaleOutcome:
    """The Z-tests of one block size."""

    block: int
    tests: int
    failures: int
    allowed: int
    max_z: float

    @property
    def passed(self) -> bool:
        return self.failures <= self.allowed


@dataclass
class ComparisonResult:
    """Outcome of one method: ``passed``, printable ``numbers`` and an RGB heat-map (H×W×3 in [0,1])."""

    method: str
    passed: bool
    numbers: dict[str, float | int | str]
    heatmap: np.ndarray
    scales: list[ScaleOutcome] = field(default_factory=list)


def _block_sums(values: np.ndarray, block: int) -> np.ndarray:
    """Sums over ``block``×``block`` tiles (partial tiles at the right/bottom edges included)."""
    if block == 1:
        return values
    rows = np.arange(0, values.shape[0], block)
    cols = np.arange(0, values.shape[1], block)
    return np.add.reduceat(np.add.reduceat(values, rows, axis=0), cols, axis=1)


def _expand(blocks: np.ndarray, block: int, shape: tuple[int, int]) -> np.ndarray:
    """Each tile's value repeated over its pixels (inverse layout of :func:`_block_sums`)."""
    if block == 1:
        return blocks
    full = np.repeat(np.repeat(blocks, block, axis=0), block, axis=1)
    return full[: shape[0], : shape[1]]


def sidak_alpha(significance: float, tests: int) -> float:
    """Per-test level so that ``tests`` independent tests have family-wise level ``significance``.

    Šidák (1967): ``α = 1 − (1 − significance)^(1/m)``.
    """
    return -math.expm1(math.log1p(-significance) / tests)


def stat_test(
    test: np.ndarray,
    ref: np.ndarray,
    test_variance: np.ndarray,
    ref_variance: np.ndarray,
    *,
    significance: float = SIGNIFICANCE,
    pass_ratio: float = PASS_RATIO,
    blocks: Sequence[int] = BLOCK_SIZES,
) -> ComparisonResult:
    """Z-test of ``test`` against ``ref`` given the variance of each estimate (scene-linear).

    ``z = |Δ̄| / √(σ̄²_test + σ̄²_ref)`` per channel and block (``Δ̄`` the block's mean difference,
    ``σ̄² = Σσ²/n²`` its variance, assuming independent pixels); a test fails when its two-sided
    p-value ``erfc(z/√2)`` is below the Šidák level for all tests of all block sizes. A scale passes
    when at most ``⌊(1 − pass_ratio)·tests⌋`` of its tests fail; the image passes when every scale does.
    Non-finite test pixels always fail.
    """
    from scipy.special import ndtri

    shape = test.shape[:2]
    finite = np.isfinite(test)
    diff = np.where(finite, test.astype(np.float64) - ref, 0.0)
    variance = np.asarray(test_variance, np.float64) + np.asarray(ref_variance, np.float64)
    counts = np.ones((*shape, 1), dtype=np.float64)
    bad = (~finite).astype(np.float64)

    sizes = [b for b in sorted(set(blocks)) if b >= 1 and (b == 1 or b <= max(shape))]
    n_tests = sum(_block_sums(counts, b).size * 3 for b in sizes)
    alpha = sidak_alpha(significance, n_tests)
    z_critical = float(ndtri(1.0 - alpha / 2.0))

    scale = float(np.mean(np.abs(ref), dtype=np.float64)) or 1.0
    scales: list[ScaleOutcome] = []
    ratios: list[np.ndarray] = []
    for b in sizes:
        n = _block_sums(counts, b)
        mean_diff = _block_sums(diff, b) / n
        mean_var = _block_sums(variance, b) / n**2
        mean_ref = _block_sums(ref.astype(np.float64), b) / n
        floor = (ABS_TOLERANCE * scale + REL_TOLERANCE * np.abs(mean_ref)) ** 2
        z = np.abs(mean_diff) / np.sqrt(np.maximum(mean_var, floor))
        z = np.where(_block_sums(bad, b) > 0, np.inf, z)
        failures = int(np.count_nonzero(z > z_critical))
        allowed = math.floor((1.0 - pass_ratio) * z.size + 1e-9)
        scales.append(ScaleOutcome(b, int(z.size), failures, allowed, float(np.max(z))))
        ratios.append(_expand(np.max(z, axis=2), b, shape) / z_critical)

    passed = all(s.passed for s in scales)
    # The heat-map shows the finest failing scale: fine enough to say where, coarse enough to see.
    shown = next((i for i, s in enumerate(scales) if not s.passed), 0)
    ratio = ratios[shown]
    numbers: dict[str, float | int | str] = {
        "z_critical": round(z_critical, 3),
        "tests": n_tests,
        "failed_tests": sum(s.failures for s in scales),
        "failed_pixels": int(np.count_nonzero(ratio > 1.0)),
        "max_z_ratio": _rounded(max(s.max_z for s in scales) / z_critical),
        "heatmap_scale": f"{scales[shown].block}x{scales[shown].block}",
        "nonfinite_pixels": int(np.count_nonzero(~np.all(finite, axis=2))),
    }
    for s in scales:
        numbers[f"fail_{s.block}x{s.block}"] = f"{s.failures}/{s.tests} (≤{s.allowed})"
    return ComparisonResult("stat", passed, numbers, significance_heatmap(ratio), scales)


def _rounded(value: float) -> float | str:
    return round(value, 3) if math.isfinite(value) else "inf"


def significance_heatmap(ratio: np.ndarray) -> np.ndarray:
    """Colour ``|z|/z_critical`` with magma: 0 black, 1 (the failing edge) red, ≥ 2 pale yellow."""
    from matplotlib import colormaps

    value = np.clip(np.nan_to_num(ratio, nan=2.0, posinf=2.0) / 2.0, 0.0, 1.0)
    return colormaps["magma"](value)[:, :, :3].astype(np.float32)


# ------------------------------------------------------------------------------------- flip test
def flip_test(
    test_display: np.ndarray, ref_display: np.ndarray, *, threshold: float = FLIP_THRESHOLD
) -> ComparisonResult:
    """LDR FLIP of two sRGB-encoded images in [0, 1]; passes when the mean error ≤ ``threshold``."""
    import flip_evaluator

    ref = np.ascontiguousarray(ref_display, dtype=np.float32)
    test = np.ascontiguousarray(test_display, dtype=np.float32)
    error, mean, _ = flip_evaluator.evaluate(ref, test, "LDR", inputsRGB=True, applyMagma=False)
    error = np.asarray(error, dtype=np.float32)[:, :, 0]
    numbers: dict[str, float | int | str] = {
        "mean_flip": round(float(mean), 4),
        "threshold": threshold,
        "median_flip": round(float(np.median(error)), 4),
        "p99_flip": round(float(np.percentile(error, 99)), 4),
        "max_flip": round(float(np.max(error)), 4),
    }
    from matplotlib import colormaps

    heatmap = colormaps["magma"](np.clip(error, 0.0, 1.0))[:, :, :3].astype(np.float32)
    return ComparisonResult("flip", bool(mean <= threshold), numbers, heatmap)


# ------------------------------------------------------------------------------------ front door
@dataclass(frozen=True)
class CompareOptions:
    """Thresholds shared by ``pavonine compare`` and ``pavonine check-renders``."""

    significance: float = SIGNIFICANCE
    pass_ratio: float = PASS_RATIO
    blocks: tuple[int, ...] = BLOCK_SIZES
    flip_threshold: float = FLIP_THRESHOLD


def compare_arrays(
    test: np.ndarray,
    ref: np.ndarray,
    method: str,
    *,
    test_variance: np.ndarray | None = None,
    ref_variance: np.ndarray | None = None,
    options: CompareOptions = CompareOptions(),
) -> ComparisonResult:
    """Compare two scene-linear H×W×3 images with ``method`` (``stat`` or ``flip``).

    ``stat`` without variances estimates them from the images (:func:`estimate_noise_variance`);
    with only ``ref_variance`` it assumes the test is as noisy as the reference.
    """
    if method == "flip":
        return flip_test(
            display_encode(test), display_encode(ref), threshold=options.flip_threshold
        )
    if method != "stat":
        raise InputError("--method", f"unknown method '{method}'; expected one of {METHODS}")
    if ref_variance is None:
        ref_variance = estimate_noise_variance(ref)
        if test_variance is None:
            test_variance = estimate_noise_variance(np.nan_to_num(test))
    if test_variance is None:
        test_variance = ref_variance
    return stat_test(
        test,
        ref,
        test_variance,
        ref_variance,
        significance=options.significance,
        pass_ratio=options.pass_ratio,
        blocks=options.blocks,
    )
