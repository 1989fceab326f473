"""Procedural scale-C maps (paper §3.3) for the feather kinds Pavonine ships.

The paper's own map images are not available (MODEL-NOTES, "Maps"), so Pavonine paints its
own: an eye feather of the peacock's train with its ocellus, a blue body feather, a yellow
covert and a fishtail (T-shaped) feather from the edge of the train. Each kind yields the six maps of §3.3 as float arrays in [0, 1], ``[row, column]`` with
row 0 at the top (the feather's apex); see ``docs/pipeline.md`` for every encoding:

=============  ==============================================================================
alpha          opacity (silhouette), anti-aliased over about one pixel
ocellar        class ``k`` in 0 (white) … 5 (black) stored as grey ``1 - k/5``; read back as
               ``k = round(5 * (1 - grey))``
gradation      0 = a class's black end … 1 = its white end (Table 1 "black/white"); painted
               near ½, the literature preset's measured structure (:data:`MEASURED_GRADATION`)
angle          barbule long axis relative to its barb, ``grey = (angle_deg mod 180) / 180``
               (counter-clockwise seen from the front); barbules sit 30–40° off the barb
displacement   barb-streak height, 0 = vane surface, 1 = full height
melanin        share of structural colour: 1 = fully structural, 0 = melanin brown only
=============  ==============================================================================

Shapes are drawn in *feather units*: ``x`` across (0 on the rachis, ``±aspect/2`` at the image
edges) and ``y`` along, 0 at the base (bottom row) and 1 at the apex (top row), so one unit is
the feather's length and pixels are square.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy import ndimage

from pavonine.base.map_files import write_map
from pavonine.pipeline.maps.canvas import (
    MEASURED_GRADATION,
    Canvas,
    barbule_angle,
    filtered,
    fringe,
    gradation_drift,
    melanin_fade,
    radial_barbs,
    smoothstep,
    straight_barbs,
)
from pavonine.pipeline.maps.encoding import (
    CLASS_COUNT,
    MAP_NAMES,
    angle_degrees,
    angle_grey,
    ocellar_class,
    ocellar_grey,
)
from pavonine.pipeline.maps.fishtail import (
    FISHTAIL_RACHIS_TIP,
    FISHTAIL_SPACING,
    paint_fishtail,
)

__all__ = [
    "CLASS_COUNT",
    "CLASS_DISPLAY_COLOURS",
    "FISHTAIL_RACHIS_TIP",
    "FISHTAIL_SPACING",
    "KINDS",
    "MAP_NAMES",
    "MEASURED_GRADATION",
    "FeatherKind",
    "angle_degrees",
    "angle_grey",
    "generate_maps",
    "ocellar_class",
    "ocellar_grey",
    "write_contact_sheet",
    "write_maps",
]


# --------------------------------------------------------------------------- kinds

#: The eye's fringe (its barb tips beyond the outer ring): the structural share falls to this
#: share of the vane's at the silhouette, within this width (feather units) of it.
EYE_FRINGE_FLOOR = 0.8
EYE_FRINGE_WIDTH = 0.02


def _eye(cv: Canvas) -> dict[str, np.ndarray]:
    """Train eye feather: ocellus near the apex, loose barbs below (paper §2.1, §3.3)."""
    x, y = cv.x, cv.y
    cy = 0.74  # eye centre = apex of the rachis
    edge_noise = cv.noise(0.04)
    # Silhouette: the eye's disc (soft union) with the narrowing loose-barbed lower vane.
    disc = (1.0 - np.hypot(x / 0.215, (y - 0.735) / 0.245)) * 0.215
    lower_half_width = 0.035 + 0.12 * np.clip(y / 0.62, 0.0, 1.0) ** 0.9
    lower = np.minimum(np.minimum(lower_half_width - np.abs(x), y - 0.004), 0.72 - y)
    k = 0.012
    signed = k * np.logaddexp(disc / k, lower / k) + 0.006 * edge_noise
    signed = np.minimum(signed, np.minimum(y - 0.004, 0.996 - y))
    solid = cv.coverage(signed)

    # Barbs: straight from the rachis below the eye, radial around it (paper §3.3.4).
    wobble = 0.35 * cv.noise(0.05)
    barb_angle = 38.0 + 30.0 * smoothstep(0.2, 0.7, y)
    straight, straight_fade = straight_barbs(cv, barb_angle, 0.0075, wobble)
    radial, radial_fade = radial_barbs(cv, (0.0, cy), 240, wobble)
    to_eye = np.hypot(x, y - cy)
    radial_weight = np.maximum(smoothstep(cy - 0.32, cy - 0.12, y), smoothstep(0.2, 0.1, to_eye))
    ridge = radial_weight * filtered(radial, radial_fade) + (1 - radial_weight) * filtered(
        straight, straight_fade
    )
    loose = 1.0 - smoothstep(0.3, 0.5, y)  # loose, separate barbs low on the feather
    alpha = fringe(cv, ridge, solid, 0.02 + 0.03 * loose)
    alpha = alpha * (1.0 - 0.4 * loose * (1.0 - np.clip(ridge * 1.8, 0, 1)))

    # Ocellus: classes 5 (heart) … 2 as nested, slightly rising rings; 1 vane; 0 lower vane.
    ring_noise = cv.noise(0.03)
    theta = np.arctan2(x, y - cy)
    notch = 1.0 - 0.28 * np.exp(-(((np.abs(theta) - np.pi) / 0.45) ** 2))  # heart's notch
    klass = np.where(y > 0.40 + 0.03 * edge_noise, 1, 0)
    for cls, (dy, ax, ay) in zip(
        (2, 3, 4, 5),
        ((0.012, 0.142, 0.176), (0.010, 0.125, 0.153), (0.005, 0.088, 0.106), (0.0, 0.053, 0.063)),
        strict=True,
    ):
        shape = notch if cls == 5 else 1.0
        rho = np.hypot(x / ax, (y - cy - dy) / ay) / shape
        klass = np.where(rho + 0.025 * ring_noise < 1.0, cls, klass)
    klass = np.where(solid > 0, klass, 0)

    # Measured structure at the eye's centre; ±0.1 across the rings, lower at the base.
    gradation = gradation_drift(cv, 0.55, cy, 0.04, 0.08)
    angle = barbule_angle(cv, 32.0, 6.0, cv.noise(0.06), cy, radial_weight)
    grain = cv.noise(0.01)
    displacement = solid * np.clip(0.78 * ridge + 0.12 + 0.05 * grain + 0.05 * edge_noise, 0, 1)
    # The lower vane's loose barbs fade to melanin brown at the edge (paper §3.3.6). The eye's
    # fringe, the barb tips beyond its outer ring, is the metallic brass-green of the vane
    # (Freyer & Stavenga 2020's class-1 region) right out to the tips: there the share only
    # dips to EYE_FRINGE_FLOOR of the vane's within EYE_FRINGE_WIDTH. The full fade
    # there (floor 0.15 within 0.05) mixed the tips into tan (docs/model.md, "The eye's fringe").
    noise = cv.noise(0.05)
    lower_fade = melanin_fade(cv, solid, 0.05, 0.15, noise)
    fringe_fade = melanin_fade(cv, solid, EYE_FRINGE_WIDTH, EYE_FRINGE_FLOOR, noise)
    disc = smoothstep(0.40, 0.50, y)
    melanin = disc * fringe_fade + (1.0 - disc) * lower_fade
    melanin = melanin * (1.0 - 0.35 * loose)
    # The heart keeps the full structural share, like the rings: its black-violet is the dark
    # 443 nm band of Freyer & Stavenga's structure itself. Lowering the share there mixed in the
    # melanin brown, which is lighter than that violet and lit the heart (docs/model.md, "The
    # heart's lightness against Freyer & Stavenga 2020").
    # The vane around the eye is brass-green, duller than the rings: less structural colour.
    vane = ndimage.gaussian_filter((klass <= 1).astype(np.float32), 3.0 * cv.height / 1024)
    melanin = melanin * (1.0 - 0.3 * vane)
    return {
        "alpha": alpha,
        "ocellar": ocellar_grey(klass),
        "gradation": gradation,
        "angle": angle,
        "displacement": displacement,
        "melanin": melanin,
    }


def _contour_feather(
    cv: Canvas,
    half_width: Callable[[np.ndarray], np.ndarray],
    barb_angle_deg: float,
    spacing: float,
    downy_until: float,
    melanin_floor: float,
) -> dict[str, np.ndarray]:
    """A body/covert feather: a vane of straight barbs, downy melanin base (one ocellar class)."""
    x, y = cv.x, cv.y
    edge_noise = cv.noise(0.05)
    signed = half_width(y) - np.abs(x) + 0.004 * edge_noise
    signed = np.minimum(signed, np.minimum(y - 0.004, 0.996 - y))
    solid = cv.coverage(signed)
    wobble = 0.3 * cv.noise(0.06)
    ridge, fade = straight_barbs(cv, barb_angle_deg + 8.0 * y, spacing, wobble)
    ridge = filtered(ridge, fade)
    downy = 1.0 - smoothstep(downy_until - 0.08, downy_until + 0.08, y + 0.03 * edge_noise)
    alpha = fringe(cv, ridge, solid, 0.025 + 0.08 * downy)
    gradation = gradation_drift(cv, 0.5, 0.55, 0.04, 0.1)
    angle = barbule_angle(cv, 34.0, 5.0, cv.noise(0.06), 0.9)
    grain = cv.noise(0.012)
    displacement = solid * np.clip(0.75 * ridge + 0.15 + 0.06 * grain, 0.0, 1.0)
    melanin = melanin_fade(cv, solid, 0.06, melanin_floor, cv.noise(0.05))
    melanin = melanin * (1.0 - 0.9 * downy)
    return {
        "alpha": alpha,
        "ocellar": ocellar_grey(np.zeros_like(y, dtype=np.int32)),
        "gradation": gradation,
        "angle": angle,
        "displacement": displacement,
        "melanin": melanin,
    }


def _blue(cv: Canvas) -> dict[str, np.ndarray]:
    """Blue body (neck/breast) feather: short, broad, rounded tip, downy dark base."""

    def half_width(y: np.ndarray) -> np.ndarray:
        # Rounded tip: an ellipse over the upper part, tapering to the quill at the base.
        t = np.clip(y, 0.0, 1.0)
        return (
            0.33
            * np.sqrt(np.clip(1.0 - ((t - 0.55) / 0.45) ** 2, 0.0, 1.0))
            * (0.35 + 0.65 * smoothstep(0.0, 0.45, t))
        )

    return _contour_feather(cv, half_width, 48.0, 0.011, 0.32, 0.2)


def _yellow(cv: Canvas) -> dict[str, np.ndarray]:
    """Yellow (bronze) covert: long and lanceolate, barbs at a steep angle to the rachis."""

    def half_width(y: np.ndarray) -> np.ndarray:
        t = np.clip(y, 0.0, 1.0)
        return 0.16 * np.sin(np.pi * np.clip(t, 0.0, 1.0) ** 0.75) ** 0.8 + 0.008

    return _contour_feather(cv, half_width, 32.0, 0.009, 0.18, 0.25)


@dataclass(frozen=True)
class FeatherKind:
    """A shipped feather kind: width/height of its maps and the painter."""

    name: str
    aspect: float
    paint: Callable[[Canvas], dict[str, np.ndarray]]
    description: str


KINDS: dict[str, FeatherKind] = {
    "eye": FeatherKind("eye", 0.5, _eye, "train eye feather with its ocellus (6 classes)"),
    "blue": FeatherKind("blue", 0.72, _blue, "blue body feather (one class)"),
    "yellow": FeatherKind("yellow", 0.36, _yellow, "yellow covert feather (one class)"),
    "fishtail": FeatherKind(
        "fishtail", 0.42, paint_fishtail, "fishtail (T-shaped) train-edge feather, no ocellus"
    ),
}


def generate_maps(kind: str, size: int = 1024, seed: int = 0) -> dict[str, np.ndarray]:
    """The six maps of ``kind`` at ``size`` pixels along the feather (height), as float32 [0, 1].

    The width is ``round(size * aspect)``. Deterministic for a given ``(kind, size, seed)``.
    """
    if kind not in KINDS:
        raise KeyError(f"unknown feather kind {kind!r}; known: {sorted(KINDS)}")
    if size < 16:
        raise ValueError(f"map size must be at least 16 pixels, got {size}")
    spec = KINDS[kind]
    width = max(8, round(size * spec.aspect))
    canvas = Canvas(size, width, np.random.default_rng(seed))
    maps = spec.paint(canvas)
    return {name: np.clip(maps[name], 0.0, 1.0).astype(np.float32) for name in MAP_NAMES}


def write_maps(
    maps: dict[str, np.ndarray],
    outdir: str | os.PathLike,
    extension: str = ".png",
    group_id: str | None = None,
) -> dict[str, Path]:
    """Write each map as ``OUTDIR/<name><extension>``; returns the paths by map name.

    The six are marked as one group (``pavonine:group``, :mod:`pavonine.base.groups`) so
    that readers refuse a set mixed from two writes. Its id is ``group_id``, by default a hash
    of the maps' contents: the same maps give the same bytes (``--seed`` reproduces a set)."""
    from pavonine.base.groups import GROUP_ATTRIBUTE, content_group_id, group_marks

    outdir = Path(outdir)
    paths = {name: outdir / f"{name}{extension}" for name in MAP_NAMES}
    if group_id is None:
        parts: list = [extension.encode()]
        for name in MAP_NAMES:
            parts += [f"{name}{np.shape(maps[name])}".encode(), maps[name]]
        group_id = content_group_id(parts)
    marks = group_marks(group_id, paths.values())
    for name, path in paths.items():
        description = f"pavonine {name} map (paper section 3.3)"
        write_map(
            path, maps[name], description=description, attributes={GROUP_ATTRIBUTE: marks[path]}
        )
    return paths


#: Approximate appearance of each ocellar class (display only, for contact sheets).
CLASS_DISPLAY_COLOURS = (
    (0.55, 0.60, 0.35),  # 0 white end: pale green-gold lower vane
    (0.45, 0.55, 0.15),  # 1 green-gold vane
    (0.70, 0.60, 0.20),  # 2 gold ring
    (0.60, 0.35, 0.15),  # 3 bronze ring
    (0.05, 0.55, 0.55),  # 4 blue-green ring
    (0.10, 0.05, 0.40),  # 5 dark blue-violet heart
)


def write_contact_sheet(maps: dict[str, np.ndarray], path: str | os.PathLike, title: str) -> None:
    """A labelled PNG of the six maps side by side (the ocellar map in display colours)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.colors import ListedColormap

    height, width = maps["alpha"].shape
    panel = 2.0
    fig, axes = plt.subplots(
        1,
        len(MAP_NAMES),
        figsize=(panel * len(MAP_NAMES), panel * height / width + 0.7),
        dpi=120,
    )
    checker = (
        (np.add.outer(np.arange(height) // 16, np.arange(width) // 16) % 2) * 0.15 + 0.7
    ).astype(np.float32)
    for ax, name in zip(axes, MAP_NAMES, strict=True):
        values = maps[name]
        if name == "ocellar":
            ax.imshow(
                ocellar_class(values),
                cmap=ListedColormap(CLASS_DISPLAY_COLOURS),
                vmin=-0.5,
                vmax=5.5,
                interpolation="nearest",
            )
        elif name == "angle":
            ax.imshow(angle_degrees(values), cmap="twilight", vmin=0, vmax=180)
        elif name == "alpha":
            ax.imshow(checker * (1 - values) + values * 0.05, cmap="gray", vmin=0, vmax=1)
        else:
            ax.imshow(values, cmap="gray", vmin=0, vmax=1)
        ax.set_title(name, fontsize=10)
        ax.set_xticks([])
        ax.set_yticks([])
    fig.suptitle(title, fontsize=11)
    fig.tight_layout()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.stem}.tmp{os.getpid()}.png")
    fig.savefig(tmp)
    plt.close(fig)
    os.replace(tmp, path)
