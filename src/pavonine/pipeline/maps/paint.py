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

import math
import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy import ndimage

from pavonine.base.map_files import write_map

MAP_NAMES = ("alpha", "ocellar", "gradation", "angle", "displacement", "melanin")
CLASS_COUNT = 6


def ocellar_grey(ocellar_class: np.ndarray | int, classes: int = CLASS_COUNT) -> np.ndarray:
    """Grey level of ocellar class ``k`` of ``n`` classes: ``1 - k/(n-1)`` (0 = white, n-1 = black).

    With the paper's six classes: ``1 - k/5``. A one-class material reads every grey as class 0
    and is painted white.
    """
    if classes <= 1:
        return np.ones_like(np.asarray(ocellar_class, dtype=np.float32))
    return 1.0 - np.asarray(ocellar_class, dtype=np.float32) / (classes - 1)


def ocellar_class(grey: np.ndarray, classes: int = CLASS_COUNT) -> np.ndarray:
    """Class of an ocellar grey level: the nearest level, ``k = round((1 - g)(n - 1))``."""
    k = np.rint((1.0 - np.asarray(grey, dtype=np.float64)) * max(classes - 1, 0))
    return np.clip(k, 0, max(classes - 1, 0)).astype(np.int32)


def angle_grey(angle_deg: np.ndarray) -> np.ndarray:
    """Angle-map grey of a barbule axis at ``angle_deg`` counter-clockwise from its barb
    (seen from the front): ``(angle mod 180°) / 180°`` (an axis: 180° is the same line as 0°)."""
    return (np.mod(np.asarray(angle_deg, dtype=np.float64), 180.0) / 180.0).astype(np.float32)


def angle_degrees(grey: np.ndarray) -> np.ndarray:
    """Inverse of :func:`angle_grey`: the barbule axis angle in degrees in [0, 180]."""
    return np.asarray(grey, dtype=np.float32) * 180.0


# --------------------------------------------------------------------------- helpers


def _smoothstep(e0: float, e1: float, x: np.ndarray) -> np.ndarray:
    t = np.clip((x - e0) / (e1 - e0), 0.0, 1.0)
    return t * t * (3.0 - 2.0 * t)


@dataclass
class _Canvas:
    """Pixel-centre coordinates of a map in feather units, and a seeded noise source."""

    height: int
    width: int
    rng: np.random.Generator

    def __post_init__(self) -> None:
        self.aspect = self.width / self.height
        cols = (np.arange(self.width, dtype=np.float32) + 0.5) / self.width
        rows = (np.arange(self.height, dtype=np.float32) + 0.5) / self.height
        self.x = (cols[None, :] - 0.5) * self.aspect + np.zeros((self.height, 1), np.float32)
        self.y = (1.0 - rows[:, None]) + np.zeros((1, self.width), np.float32)
        self.pixel = 1.0 / self.height  # one pixel in feather units

    def noise(self, scale: float) -> np.ndarray:
        """Smooth zero-mean noise (≈ unit variance) with feature size ``scale`` feather units.

        Drawn on a grid fixed in feather units, so the pattern does not depend on the map size.
        """
        ny = math.ceil(1.0 / scale) + 4
        nx = math.ceil(self.aspect / scale) + 4
        grid = self.rng.standard_normal((ny, nx)).astype(np.float32)
        rows = self.y / scale + 2.0
        cols = (self.x + self.aspect / 2) / scale + 2.0
        return ndimage.map_coordinates(grid, [rows, cols], order=3, mode="nearest").astype(
            np.float32
        )

    def coverage(self, signed: np.ndarray) -> np.ndarray:
        """Anti-aliased inside-ness of a signed distance (feather units, > 0 inside)."""
        return np.clip(signed / self.pixel + 0.5, 0.0, 1.0)


def _ridges(phase: np.ndarray, sharpness: float = 3.0) -> np.ndarray:
    """Streak profile: 1 on a barb's crest (integer ``phase``), falling to 0 between barbs."""
    return (0.5 + 0.5 * np.cos(2.0 * np.pi * phase)) ** sharpness


#: Mean of the streak profile over one period, ∫ ((1 + cos)/2)³ = 5/16.
_RIDGE_MEAN = 5.0 / 16.0


def _resolvable(period_px: np.ndarray) -> np.ndarray:
    """Weight of streaks whose period falls below ~3 pixels (anti-aliasing): 0 → their mean."""
    return np.clip((period_px - 2.5) / 2.0, 0.0, 1.0)


def _filtered(ridge: np.ndarray, weight: np.ndarray) -> np.ndarray:
    """Streaks where they are resolvable, their mean value where they are not."""
    return weight * ridge + (1.0 - weight) * _RIDGE_MEAN


def _straight_barbs(
    cv: _Canvas, angle_deg: np.ndarray | float, spacing: float, wobble: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Streaks of straight barbs leaving the rachis (x = 0) at ``angle_deg`` from it, apex-ward.

    A point (x, y) lies on the barb that left the rachis at ``y0 = y - |x| cot(angle)``; barbs
    are ``spacing`` feather units apart along the rachis. Returns (ridge height, fade).
    """
    alpha = np.radians(angle_deg)
    y0 = cv.y - np.abs(cv.x) / np.tan(alpha)
    ridge = _ridges(y0 / spacing + wobble)
    period_px = spacing * np.sin(alpha) / cv.pixel
    return ridge, _resolvable(np.asarray(period_px) + np.zeros_like(cv.x))


def _radial_barbs(
    cv: _Canvas, centre: tuple[float, float], count: int, wobble: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Streaks of ``count`` barbs radiating from ``centre`` (the eye: paper §3.3.4)."""
    dx = cv.x - centre[0]
    dy = cv.y - centre[1]
    theta = np.arctan2(dx, dy)
    radius = np.hypot(dx, dy)
    ridge = _ridges(theta * count / (2 * np.pi) + wobble)
    period_px = 2 * np.pi * radius / count / cv.pixel
    return ridge, _resolvable(period_px)


def _edge_distance(alpha: np.ndarray, pixel: float) -> np.ndarray:
    """Distance (feather units) from each inside pixel to the silhouette edge."""
    return ndimage.distance_transform_edt(alpha > 0.5).astype(np.float32) * pixel


def _fringe(cv: _Canvas, ridge: np.ndarray, inside: np.ndarray, depth: float) -> np.ndarray:
    """Opacity gaps between barb tips within ``depth`` of the edge (the feathery margin)."""
    edge = _edge_distance(inside, cv.pixel)
    weight = 1.0 - _smoothstep(0.0, depth, edge)
    return inside * (1.0 - weight * (1.0 - np.clip(ridge * 1.6, 0.0, 1.0)))


def _melanin_fade(
    cv: _Canvas, alpha: np.ndarray, width: float, floor: float, noise: np.ndarray
) -> np.ndarray:
    """Structural share fading to ``floor`` within ``width`` of the edge (paper §3.3.6)."""
    edge = _edge_distance(alpha, cv.pixel)
    share = floor + (1.0 - floor) * _smoothstep(0.0, width, edge * (1.0 + 0.25 * noise))
    return np.where(alpha > 0.0, share, floor).astype(np.float32)


#: Gradation-map value of a class's measured structure: the literature preset puts each
#: region's measurement at t = ½ and its size variation at the ends (docs/model.md, "Gradation in
#: freyer2020"), so the painted maps stay near ½ and drift from base to apex (paper §3.3.3).
MEASURED_GRADATION = 0.5


def _gradation(
    cv: _Canvas, slope: float, centre_y: float, noise: float, scale: float
) -> np.ndarray:
    """Gradation ``½ + slope·(y − centre_y)`` plus noise of amplitude ``noise`` and feature size
    ``scale``: the measured structure at ``centre_y``, a subtle drift from the feather's base to
    its apex (paper §3.3.3), clipped to [0, 1]."""
    drift = MEASURED_GRADATION + slope * (cv.y - centre_y)
    return np.clip(drift + noise * cv.noise(scale), 0.0, 1.0)


def _barbule_angle(
    cv: _Canvas,
    base_deg: float,
    spread_deg: float,
    noise: np.ndarray,
    rachis_tip: float,
    unmirrored: np.ndarray | float = 0.0,
):
    """Barbules 30–40° off their barb (paper §3.3.4), mirrored across the rachis.

    The mirror turns the angle ``θ`` into ``180° − θ``; the turn is continuous (a smooth ramp
    through 90° within a rachis width of the centre line, hidden under the shaft; never through
    0°/180°, where the grey level would wrap and bilinear filtering would draw a line), and above
    the rachis tip, where no shaft covers the centre line, it widens so no line is drawn through
    the vane. ``unmirrored`` (0…1) keeps one side's angle where barbs radiate from a centre (the
    eye), so the angle turns with them and shows no seam at all.
    """
    across = np.clip(np.abs(cv.x) / (cv.aspect / 2), 0.0, 1.0)
    magnitude = base_deg + spread_deg * across + 1.5 * noise
    width = 0.006 + 0.25 * _smoothstep(rachis_tip - 0.02, rachis_tip + 0.1, cv.y)
    side = 2.0 * _smoothstep(-width, width, cv.x) - 1.0
    side = side + (1.0 - side) * unmirrored
    return angle_grey(90.0 - (90.0 - magnitude) * side)


# --------------------------------------------------------------------------- kinds

#: The eye's fringe (its barb tips beyond the outer ring): the structural share falls to this
#: share of the vane's at the silhouette, within this width (feather units) of it.
EYE_FRINGE_FLOOR = 0.8
EYE_FRINGE_WIDTH = 0.02


def _eye(cv: _Canvas) -> dict[str, np.ndarray]:
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
    barb_angle = 38.0 + 30.0 * _smoothstep(0.2, 0.7, y)
    straight, straight_fade = _straight_barbs(cv, barb_angle, 0.0075, wobble)
    radial, radial_fade = _radial_barbs(cv, (0.0, cy), 240, wobble)
    to_eye = np.hypot(x, y - cy)
    radial_weight = np.maximum(_smoothstep(cy - 0.32, cy - 0.12, y), _smoothstep(0.2, 0.1, to_eye))
    ridge = radial_weight * _filtered(radial, radial_fade) + (1 - radial_weight) * _filtered(
        straight, straight_fade
    )
    loose = 1.0 - _smoothstep(0.3, 0.5, y)  # loose, separate barbs low on the feather
    alpha = _fringe(cv, ridge, solid, 0.02 + 0.03 * loose)
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
    gradation = _gradation(cv, 0.55, cy, 0.04, 0.08)
    angle = _barbule_angle(cv, 32.0, 6.0, cv.noise(0.06), cy, radial_weight)
    grain = cv.noise(0.01)
    displacement = solid * np.clip(0.78 * ridge + 0.12 + 0.05 * grain + 0.05 * edge_noise, 0, 1)
    # The lower vane's loose barbs fade to melanin brown at the edge (paper §3.3.6). The eye's
    # fringe, the barb tips beyond its outer ring, is the metallic brass-green of the vane
    # (Freyer & Stavenga 2020's class-1 region) right out to the tips: there the share only
    # dips to EYE_FRINGE_FLOOR of the vane's within EYE_FRINGE_WIDTH. The full fade
    # there (floor 0.15 within 0.05) mixed the tips into tan (docs/model.md, "The eye's fringe").
    noise = cv.noise(0.05)
    lower_fade = _melanin_fade(cv, solid, 0.05, 0.15, noise)
    fringe_fade = _melanin_fade(cv, solid, EYE_FRINGE_WIDTH, EYE_FRINGE_FLOOR, noise)
    disc = _smoothstep(0.40, 0.50, y)
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
    cv: _Canvas,
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
    ridge, fade = _straight_barbs(cv, barb_angle_deg + 8.0 * y, spacing, wobble)
    ridge = _filtered(ridge, fade)
    downy = 1.0 - _smoothstep(downy_until - 0.08, downy_until + 0.08, y + 0.03 * edge_noise)
    alpha = _fringe(cv, ridge, solid, 0.025 + 0.08 * downy)
    gradation = _gradation(cv, 0.5, 0.55, 0.04, 0.1)
    angle = _barbule_angle(cv, 34.0, 5.0, cv.noise(0.06), 0.9)
    grain = cv.noise(0.012)
    displacement = solid * np.clip(0.75 * ridge + 0.15 + 0.06 * grain, 0.0, 1.0)
    melanin = _melanin_fade(cv, solid, 0.06, melanin_floor, cv.noise(0.05))
    melanin = melanin * (1.0 - 0.9 * downy)
    return {
        "alpha": alpha,
        "ocellar": ocellar_grey(np.zeros_like(y, dtype=np.int32)),
        "gradation": gradation,
        "angle": angle,
        "displacement": displacement,
        "melanin": melanin,
    }


def _blue(cv: _Canvas) -> dict[str, np.ndarray]:
    """Blue body (neck/breast) feather: short, broad, rounded tip, downy dark base."""

    def half_width(y: np.ndarray) -> np.ndarray:
        # Rounded tip: an ellipse over the upper part, tapering to the quill at the base.
        t = np.clip(y, 0.0, 1.0)
        return (
            0.33
            * np.sqrt(np.clip(1.0 - ((t - 0.55) / 0.45) ** 2, 0.0, 1.0))
            * (0.35 + 0.65 * _smoothstep(0.0, 0.45, t))
        )

    return _contour_feather(cv, half_width, 48.0, 0.011, 0.32, 0.2)


def _yellow(cv: _Canvas) -> dict[str, np.ndarray]:
    """Yellow (bronze) covert: long and lanceolate, barbs at a steep angle to the rachis."""

    def half_width(y: np.ndarray) -> np.ndarray:
        t = np.clip(y, 0.0, 1.0)
        return 0.16 * np.sin(np.pi * np.clip(t, 0.0, 1.0) ** 0.75) ** 0.8 + 0.008

    return _contour_feather(cv, half_width, 32.0, 0.009, 0.18, 0.25)


#: The fishtail's rachis tip (feather units, = its recipe's ``rachis_length``): the notch between
#: its two lobes, where the barbs of both sides end.
FISHTAIL_RACHIS_TIP = 0.8
#: Barb spacing along the fishtail's rachis (feather units; 0.225 cm of its 30 cm, the
#: converter's default ``spacing_cm``), so that sheet streaks and traced barbs agree.
FISHTAIL_SPACING = 0.0075
#: A fishtail barb's angle to the rachis: ``_FISHTAIL_SHAFT_DEG`` on the narrow shaft; in the
#: lobes it leaves at ``_FISHTAIL_ROOT_DEG`` and curves apex-ward to ``_FISHTAIL_LOBE_DEG`` over
#: ``_FISHTAIL_CURVE`` feather units from the rachis (the swallow-tail: its lobes trail past the
#: notch).
_FISHTAIL_SHAFT_DEG = 40.0
_FISHTAIL_ROOT_DEG = 70.0
_FISHTAIL_LOBE_DEG = 36.0
_FISHTAIL_CURVE = 0.12


def _fishtail_opening(root: np.ndarray) -> np.ndarray:
    """0 on the narrow shaft … 1 in the lobes, by a barb's root height (feather units)."""
    return _smoothstep(0.5, 0.76, root)


def _fishtail_reach(root: np.ndarray) -> np.ndarray:
    """How far across (feather units) a barb rooted at ``root`` reaches: 0.022–0.035 along the
    shaft, lengthening to 0.18 (the lobes' tips) just below the notch."""
    shaft = 0.022 + 0.013 * np.clip(root / 0.45, 0.0, 1.0)
    return shaft + (0.18 - shaft) * _fishtail_opening(root) ** 0.8


def _ramp_integral(x: np.ndarray, width: float) -> np.ndarray:
    """``∫₀ˣ smoothstep(0, width, ξ) dξ`` in closed form: ``width·(s³ − s⁴/2)`` for ``s = x/width
    ≤ 1``, then ``width/2 + (x − width)``."""
    s = np.clip(x / width, 0.0, 1.0)
    return width * (s**3 - 0.5 * s**4) + np.clip(x - width, 0.0, None)


def _fishtail_barbs(cv: _Canvas) -> tuple[np.ndarray, np.ndarray]:
    """Per pixel, the root height ``t`` on the rachis of the barb through it and that barb's
    local cotangent ``dy/d|x|`` (its direction: ``atan(1/cot)`` from the rachis).

    A barb is the curve ``y = t + |x|·c₀(t) + u(t)·Δc·R(|x|)``: ``c₀`` the cotangent it leaves the
    rachis at, ``u`` the opening (:func:`_fishtail_opening`), ``Δc`` the lobe barbs' curving toward
    the apex and ``R`` :func:`_ramp_integral` (the cotangent ramps over ``_FISHTAIL_CURVE``).
    ``y`` grows with ``t`` at every ``|x|`` on the vane, so ``t`` is found by bisection.
    """
    ax = np.abs(cv.x).astype(np.float64)
    y = cv.y.astype(np.float64)
    shaft_cot = 1.0 / math.tan(math.radians(_FISHTAIL_SHAFT_DEG))
    root_cot = 1.0 / math.tan(math.radians(_FISHTAIL_ROOT_DEG))
    lobe_cot = 1.0 / math.tan(math.radians(_FISHTAIL_LOBE_DEG))
    ramp = _ramp_integral(ax, _FISHTAIL_CURVE)

    def height(t: np.ndarray) -> np.ndarray:
        u = _fishtail_opening(t)
        return t + ax * (shaft_cot + u * (root_cot - shaft_cot)) + u * (lobe_cot - root_cot) * ramp

    low, high = np.full_like(y, -1.0), np.full_like(y, 1.5)
    for _ in range(32):
        mid = 0.5 * (low + high)
        above = height(mid) > y
        high = np.where(above, mid, high)
        low = np.where(above, low, mid)
    t = 0.5 * (low + high)
    u = _fishtail_opening(t)
    curve = _smoothstep(0.0, _FISHTAIL_CURVE, ax)
    cot = shaft_cot + u * (root_cot - shaft_cot) + u * (lobe_cot - root_cot) * curve
    return t.astype(np.float32), cot.astype(np.float32)


def _fishtail(cv: _Canvas) -> dict[str, np.ndarray]:
    """Fishtail (T-shaped) train feather from the fan's edge: a long narrow shaft of short loose
    barbs whose barbs lengthen toward the rachis tip into two trailing lobes, the notch between
    them at the tip (a swallow-tail), and no ocellus.

    Every pixel belongs to one barb (:func:`_fishtail_barbs`): barbs leave the rachis straight
    at 40° on the shaft and, in the lobes, at 70° curving apex-ward to 36°, so the lobes' tips
    reach past the notch; the silhouette is where the barbs end (their reach, each barb's own
    length drawn ragged), the notch the last barbs below the rachis tip. The barbs hang loose
    along much of their length, no hooked barbules holding them (Dakin et al. 2016, PLoS ONE 11:
    e0152759: only the eyespot's barbs lock together; a fishtail has none): loose everywhere on
    the shaft and on the outer part of every lobe barb, so the outline is a fringe of separate
    barbs. Classes from the eye feather's material (Table 1): 1 (green-gold) near the rachis,
    2 (gold) then 3 (bronze) toward the lobe barbs' tips, the metallic green-bronze of the
    train's sides (paper §2.1); 0 (the loose lower vane) low on the shaft.
    """
    x, y = cv.x, cv.y
    tip = FISHTAIL_RACHIS_TIP
    root, cot = _fishtail_barbs(cv)
    reach = _fishtail_reach(root)
    # Each barb its own length: up to 22 % shorter (the ragged, feathery outline).
    barb = np.clip(np.floor(root / FISHTAIL_SPACING).astype(np.int64), 0, None)
    jitter = cv.rng.uniform(0.0, 1.0, int(tip / FISHTAIL_SPACING) + 2).astype(np.float32)
    reach = reach * (1.0 - 0.22 * jitter[np.clip(barb, 0, len(jitter) - 1)])
    sin_a = 1.0 / np.sqrt(1.0 + cot * cot)  # sine of the barb's angle to the rachis
    across = np.abs(x)
    # Signed distance (feather units, > 0 inside): to the barb tips, to the notch (the top
    # barbs, root at the rachis tip), to the base.
    signed = np.minimum(reach - across, (tip - root) * sin_a)
    signed = np.minimum(signed, np.minimum(y - 0.004, 0.996 - y))
    solid = cv.coverage(signed)

    wobble = 0.3 * cv.noise(0.06)
    ridge = _ridges(root / FISHTAIL_SPACING + wobble)
    ridge = _filtered(ridge, _resolvable(FISHTAIL_SPACING * sin_a / cv.pixel))
    share = np.clip(across / np.maximum(reach, 1e-6), 0.0, 1.0)  # along the barb, 0 → 1
    loose = np.maximum(1.0 - _smoothstep(0.4, 0.6, root), _smoothstep(0.3, 0.6, share))
    alpha = _fringe(cv, ridge, solid, 0.015 + 0.025 * loose)
    alpha = alpha * (1.0 - 0.6 * loose * (1.0 - np.clip(ridge * 1.8, 0.0, 1.0)))

    opening = _fishtail_opening(root)
    band = share + 0.04 * cv.noise(0.03)
    klass = np.where(root > 0.3, 1, 0)
    klass = np.where((opening > 0.3) & (band > 0.45), 2, klass)
    klass = np.where((opening > 0.3) & (band > 0.72), 3, klass)
    klass = np.where(solid > 0, klass, 0)

    gradation = _gradation(cv, 0.5, 0.6, 0.04, 0.08)
    angle = _barbule_angle(cv, 33.0, 6.0, cv.noise(0.06), tip)
    grain = cv.noise(0.012)
    displacement = solid * np.clip(0.76 * ridge + 0.14 + 0.05 * grain, 0.0, 1.0)
    melanin = _melanin_fade(cv, solid, 0.03, 0.2, cv.noise(0.05)) * (1.0 - 0.4 * loose)
    maps = (alpha, ocellar_grey(klass), gradation, angle, displacement, melanin)
    return dict(zip(MAP_NAMES, maps, strict=True))


@dataclass(frozen=True)
class FeatherKind:
    """A shipped feather kind: width/height of its maps and the painter."""

    name: str
    aspect: float
    paint: Callable[[_Canvas], dict[str, np.ndarray]]
    description: str


KINDS: dict[str, FeatherKind] = {
    "eye": FeatherKind("eye", 0.5, _eye, "train eye feather with its ocellus (6 classes)"),
    "blue": FeatherKind("blue", 0.72, _blue, "blue body feather (one class)"),
    "yellow": FeatherKind("yellow", 0.36, _yellow, "yellow covert feather (one class)"),
    "fishtail": FeatherKind(
        "fishtail", 0.42, _fishtail, "fishtail (T-shaped) train-edge feather, no ocellus"
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
    canvas = _Canvas(size, width, np.random.default_rng(seed))
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
