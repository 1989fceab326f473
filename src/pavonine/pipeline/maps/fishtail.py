"""The fishtail feather's maps (paper §3.3): a narrow shaft of loose barbs lengthening into two
lobes that trail past the notch at the rachis tip (docs/pipeline.md, "The fishtail")."""

from __future__ import annotations

import math

import numpy as np

from pavonine.pipeline.maps.canvas import (
    Canvas,
    barbule_angle,
    filtered,
    fringe,
    gradation_drift,
    melanin_fade,
    resolvable,
    ridges,
    smoothstep,
)
from pavonine.pipeline.maps.encoding import MAP_NAMES, ocellar_grey

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
    return smoothstep(0.5, 0.76, root)


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


def _fishtail_barbs(cv: Canvas) -> tuple[np.ndarray, np.ndarray]:
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
    curve = smoothstep(0.0, _FISHTAIL_CURVE, ax)
    cot = shaft_cot + u * (root_cot - shaft_cot) + u * (lobe_cot - root_cot) * curve
    return t.astype(np.float32), cot.astype(np.float32)


def paint_fishtail(cv: Canvas) -> dict[str, np.ndarray]:
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
    ridge = ridges(root / FISHTAIL_SPACING + wobble)
    ridge = filtered(ridge, resolvable(FISHTAIL_SPACING * sin_a / cv.pixel))
    share = np.clip(across / np.maximum(reach, 1e-6), 0.0, 1.0)  # along the barb, 0 → 1
    loose = np.maximum(1.0 - smoothstep(0.4, 0.6, root), smoothstep(0.3, 0.6, share))
    alpha = fringe(cv, ridge, solid, 0.015 + 0.025 * loose)
    alpha = alpha * (1.0 - 0.6 * loose * (1.0 - np.clip(ridge * 1.8, 0.0, 1.0)))

    opening = _fishtail_opening(root)
    band = share + 0.04 * cv.noise(0.03)
    klass = np.where(root > 0.3, 1, 0)
    klass = np.where((opening > 0.3) & (band > 0.45), 2, klass)
    klass = np.where((opening > 0.3) & (band > 0.72), 3, klass)
    klass = np.where(solid > 0, klass, 0)

    gradation = gradation_drift(cv, 0.5, 0.6, 0.04, 0.08)
    angle = barbule_angle(cv, 33.0, 6.0, cv.noise(0.06), tip)
    grain = cv.noise(0.012)
    displacement = solid * np.clip(0.76 * ridge + 0.14 + 0.05 * grain, 0.0, 1.0)
    melanin = melanin_fade(cv, solid, 0.03, 0.2, cv.noise(0.05)) * (1.0 - 0.4 * loose)
    maps = (alpha, ocellar_grey(klass), gradation, angle, displacement, melanin)
    return dict(zip(MAP_NAMES, maps, strict=True))
