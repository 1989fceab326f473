"""Issue 33's two measures of how the barbs read (tests/render/test_barbs_eye.py,
benchmarks/bench_barbs_eye.py).

* **Local contrast** of an image region: its luminance (Rec. 709 weights of linear RGB) cut into
  square windows of ``window`` pixels (a few barb spacings), each window's ``std / mean``, and the
  median over the windows that lie wholly on the feather (the sheet's film alpha above 0.99)
  and are lit (mean above 0), of the part two seeds share (:func:`local_contrast`). The median
  ignores the few windows a ring boundary crosses; sheet and barbs are compared with the same
  camera, spp, seeds and glitter.
* **Whole pixels of background in the lower vane's outline**: the outline is the pixels whose
  centre ray, through the scene's camera, hits the *sheet's* vane (``geometry = sheet``) where the
  ocellar map says class 0 (the loose lower vane) and the alpha map (bilinear) is at least 0.05;
  a pixel shows the background whole when the barbs' film alpha there is below 0.05 (under 5 % of
  its samples hit a barb: no brightness threshold).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
ASSET = REPO / "assets" / "feathers" / "eye_feather" / "eye_feather.usd"
HERO = REPO / "assets" / "scenes" / "eye_feather_sun.usda"
#: The hero view's resolution (assets/scenes/eye_feather_sun.usda) and its camera's apertures (mm).
HERO_RESOLUTION, HERO_APERTURE_MM = (512, 768), (24.0, 36.0)
#: Film alpha below this: the pixel shows the background whole.
EMPTY_ALPHA = 0.05
#: The alpha map's level that bounds the lower vane's outline.
OUTLINE_ALPHA = 0.05


def luminance(rgb: np.ndarray) -> np.ndarray:
    """Rec. 709 luminance of linear RGB (the last axis)."""
    return rgb[..., :3] @ np.array([0.2126, 0.7152, 0.0722])


def shared_windows(
    seeds: tuple[np.ndarray, np.ndarray],
    window: int,
    inside: np.ndarray | None = None,
    detail: tuple[np.ndarray, np.ndarray] | None = None,
) -> list[tuple[float, float]]:
    """Per ``window``-pixel square (wholly inside ``inside`` when given, with a positive mean):
    (the covariance of the two seeds' ``detail`` images, their luminances unless given; the mean
    of the two luminances). Two renders of one view with different seeds: sampling noise is
    independent between them and drops out of the covariance; what is fixed to the scene stays."""
    a, b = seeds
    da, db = detail if detail is not None else seeds
    rows, cols = a.shape[0] // window, a.shape[1] // window
    values = []
    for i in range(rows):
        for j in range(cols):
            cut = np.s_[i * window : (i + 1) * window, j * window : (j + 1) * window]
            mean = 0.5 * (a[cut].mean() + b[cut].mean())
            if (inside is not None and not np.all(inside[cut])) or mean <= 0.0:
                continue
            cov = np.mean((da[cut] - da[cut].mean()) * (db[cut] - db[cut].mean()))
            values.append((float(cov), float(mean)))
    return values


def local_contrast(
    seeds: tuple[np.ndarray, np.ndarray], on_feather: np.ndarray, window: int
) -> tuple[float, int]:
    """(median over the ``window``-pixel squares wholly inside ``on_feather`` of the luminance's
    static contrast, the number of such squares): two renders of one view with different seeds,
    per square ``sqrt(max(cov(L0, L1), 0)) / mean(L0, L1)``: the standard deviation of what both
    seeds show over the mean (:func:`shared_windows`). The barbs, the ring boundaries and the
    glitter's grains (fixed to the feather) stay; sampling noise drops out."""
    luma = tuple(luminance(rgb) for rgb in seeds)
    values = [
        np.sqrt(max(cov, 0.0)) / mean for cov, mean in shared_windows(luma, window, on_feather)
    ]
    return (float(np.median(values)) if values else float("nan")), len(values)


def hero_stage(
    folder: Path,
    geometry: str,
    window: tuple[int, int, int, int] | None = None,
    sky: bool = True,
) -> Path:
    """The README's hero scene with the feather's ``geometry`` variant; ``window``
    ``(x0, y0, width, height)`` in the hero's 512x768 pixels: the camera's apertures and offsets
    narrowed to that window (the same rays at the same pixel size; render it at width x height).
    ``sky=False``: without the dome light, so that the film alpha is 0 where rays miss (Mitsuba
    counts an environment's rays as hits)."""
    text = HERO.read_text().replace("@../feathers/eye_feather/eye_feather.usd@", f"@{ASSET}@")
    selection = f'@{ASSET}@\n        variants = {{ string geometry = "{geometry}" }}'
    text = text.replace(f"@{ASSET}@", selection, 1)
    name = f"hero_{geometry}"
    if not sky:
        start = text.index('    def DomeLight "Sky"')
        end = text.index("}", start) + 1
        text = text[:start] + text[end:]
        name += "_nosky"
    if window is not None:
        x0, y0, w, h = window
        full_w, full_h = HERO_RESOLUTION
        mm = HERO_APERTURE_MM[0] / full_w  # one pixel on the film (square pixels)
        # Offsets move the window's centre from the film's (y up on the film, rows down).
        dx = (x0 + 0.5 * w - 0.5 * full_w) * mm
        dy = (0.5 * full_h - (y0 + 0.5 * h)) * mm
        camera = (
            f"float horizontalAperture = {w * mm:.6f}\n"
            f"        float horizontalApertureOffset = {dx:.6f}\n"
            f"        float verticalAperture = {h * mm:.6f}\n"
            f"        float verticalApertureOffset = {dy:.6f}"
        )
        text = text.replace(
            "float horizontalAperture = 24\n        float verticalAperture = 36", camera
        )
        text = text.replace("int2 resolution = (512, 768)", f"int2 resolution = ({w}, {h})")
        name += f"_{x0}_{y0}_{w}x{h}"
    path = folder / f"{name}.usda"
    path.write_text(text)
    return path


def lower_vane_outline(sheet_stage: Path, width: int, height: int) -> np.ndarray:
    """The lower vane's outline seen through ``sheet_stage``'s camera (module docstring)."""
    from ocellus_zones import feather_hits

    from pavonine.base.map_files import read_map, sample_bilinear, sample_nearest
    from pavonine.pipeline.maps.paint import ocellar_class

    maps = ASSET.parent / "maps"
    uv, on_vane = feather_hits(sheet_stage, width, height)
    outline = np.zeros((height, width), dtype=bool)
    alpha = sample_bilinear(read_map(maps / "alpha.png", "alpha"), uv[on_vane])
    zone = ocellar_class(sample_nearest(read_map(maps / "ocellar.png", "o"), uv[on_vane]))
    outline[on_vane] = (zone == 0) & (alpha >= OUTLINE_ALPHA)
    return outline


def whole_pixel_share(alpha: np.ndarray, outline: np.ndarray) -> float:
    """The share of ``outline``'s pixels whose film ``alpha`` is below :data:`EMPTY_ALPHA`."""
    return float(np.mean(alpha[outline] < EMPTY_ALPHA))


def with_alpha(path: Path) -> Path:
    """``path``'s stage with its render settings' one product giving ``color`` and ``alpha``."""
    from pxr import Usd
    from render_helpers import render_product

    stage = Usd.Stage.Open(str(path))
    render_product(stage, {"color": "color3f", "alpha": "float"}, path="/Render/ColorAlpha")
    stage.GetRootLayer().Save()
    return path


def render_color_alpha(path: Path, spp: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """(linear RGB, film alpha) of ``path`` rendered at ``spp``."""
    from pavonine.render.api import render_stage

    images = render_stage(with_alpha(path), spp=spp, seed=seed, progress=False).images
    return images["color"][..., :3], images["alpha"][..., 0]


#: The rachis tip of the shipped eye feather (cm, the asset's space): where its 240 barbs per turn
#: radiate from (the least-squares meeting point of the eye's barbs, measured on the barbs layer).
TIP_CM = (0.0, 22.20)


def radial_line_contrast(
    seeds: tuple[np.ndarray, np.ndarray],
    on_feather: np.ndarray,
    centre_cm: tuple[float, float],
    field_cm: float,
    radii_cm: tuple[float, float] = (1.0, 2.0),
    per_turn: int = 240,
    along_cm: float = 0.1,
) -> float:
    """The RMS contrast of fine radial lines round :data:`TIP_CM` in a view straight down the
    vane (``field_cm`` across, centred on ``centre_cm``): the luminance resampled in polar
    coordinates about the tip (radii ``radii_cm``), averaged along the radius over ``along_cm``
    (radial lines keep their contrast, the grains of pixel size do not), high-passed along the
    angle (minus its Gaussian blur, σ one barb period ``2π/per_turn``: the rings and the shading
    go), the two seeds' product (sampling noise drops out), its root mean over the
    pixels on the feather, over the mean luminance there."""
    from scipy import ndimage

    height, width = on_feather.shape
    px_per_cm = width / field_cm
    period = 2.0 * np.pi / per_turn
    radii = np.arange(radii_cm[0], radii_cm[1], 0.5 / px_per_cm)
    # The angles the view spans at the middle radius, sampled 12 per barb period.
    corners_x = centre_cm[0] + np.array([-0.5, 0.5]) * field_cm - TIP_CM[0]
    corners_y = centre_cm[1] + np.array([-0.5, 0.5]) * field_cm - TIP_CM[1]
    angles = np.arctan2(corners_y[:, None], corners_x[None, :]).ravel()
    thetas = np.arange(angles.min(), angles.max(), period / 12.0)
    r, t = np.meshgrid(radii, thetas, indexing="ij")
    x = TIP_CM[0] + r * np.cos(t)
    y = TIP_CM[1] + r * np.sin(t)
    cols = (x - centre_cm[0]) * px_per_cm + 0.5 * width - 0.5
    rows = (centre_cm[1] - y) * px_per_cm + 0.5 * height - 0.5
    inside = (cols >= 0) & (cols <= width - 1) & (rows >= 0) & (rows <= height - 1)
    coords = np.stack([rows, cols])
    valid = inside & (ndimage.map_coordinates(on_feather.astype(float), coords, order=0) > 0.5)
    along = max(round(along_cm * px_per_cm * 2.0), 1)  # rows of half a pixel
    valid = ndimage.minimum_filter1d(valid.astype(np.uint8), along, axis=0) > 0
    bands, means = [], []
    for rgb in seeds:
        polar = ndimage.map_coordinates(luminance(rgb), coords, order=1)
        polar = ndimage.uniform_filter1d(polar, along, axis=0)
        high = polar - ndimage.gaussian_filter1d(polar, 12.0, axis=1)
        bands.append(high)
        means.append(polar[valid].mean())
    shared = float(np.mean(bands[0][valid] * bands[1][valid]))
    return float(np.sqrt(max(shared, 0.0)) / (0.5 * (means[0] + means[1])))
