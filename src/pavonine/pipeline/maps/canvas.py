"""The painter's canvas and brushes: pixel-centre coordinates in feather units with seeded noise
(:class:`Canvas`), barbs as ridges, the fringe, the melanin fade, the gradation drift and the
barbule angle, shared by every feather kind (:mod:`.paint`, :mod:`.fishtail`)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from pavonine.pipeline.maps.encoding import angle_grey


def smoothstep(e0: float, e1: float, x: np.ndarray) -> np.ndarray:
    """Hermite step from 0 at ``e0`` to 1 at ``e1``: ``3t² − 2t³``, ``t`` clipped to [0, 1]."""
    t = np.clip((x - e0) / (e1 - e0), 0.0, 1.0)
    return t * t * (3.0 - 2.0 * t)


@dataclass
class Canvas:
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


def ridges(phase: np.ndarray, sharpness: float = 3.0) -> np.ndarray:
    """Streak profile: 1 on a barb's crest (integer ``phase``), falling to 0 between barbs."""
    return (0.5 + 0.5 * np.cos(2.0 * np.pi * phase)) ** sharpness


#: Mean of the streak profile over one period, ∫ ((1 + cos)/2)³ = 5/16.
RIDGE_MEAN = 5.0 / 16.0


def resolvable(period_px: np.ndarray) -> np.ndarray:
    """Weight of streaks whose period falls below ~3 pixels (anti-aliasing): 0 → their mean."""
    return np.clip((period_px - 2.5) / 2.0, 0.0, 1.0)


def filtered(ridge: np.ndarray, weight: np.ndarray) -> np.ndarray:
    """Streaks where they are resolvable, their mean value where they are not."""
    return weight * ridge + (1.0 - weight) * RIDGE_MEAN


def straight_barbs(
    cv: Canvas, angle_deg: np.ndarray | float, spacing: float, wobble: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Streaks of straight barbs leaving the rachis (x = 0) at ``angle_deg`` from it, apex-ward.

    A point (x, y) lies on the barb that left the rachis at ``y0 = y - |x| cot(angle)``; barbs
    are ``spacing`` feather units apart along the rachis. Returns (ridge height, fade).
    """
    alpha = np.radians(angle_deg)
    y0 = cv.y - np.abs(cv.x) / np.tan(alpha)
    ridge = ridges(y0 / spacing + wobble)
    period_px = spacing * np.sin(alpha) / cv.pixel
    return ridge, resolvable(np.asarray(period_px) + np.zeros_like(cv.x))


def radial_barbs(
    cv: Canvas, centre: tuple[float, float], count: int, wobble: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Streaks of ``count`` barbs radiating from ``centre`` (the eye: paper §3.3.4)."""
    dx = cv.x - centre[0]
    dy = cv.y - centre[1]
    theta = np.arctan2(dx, dy)
    radius = np.hypot(dx, dy)
    ridge = ridges(theta * count / (2 * np.pi) + wobble)
    period_px = 2 * np.pi * radius / count / cv.pixel
    return ridge, resolvable(period_px)


def edge_distance(alpha: np.ndarray, pixel: float) -> np.ndarray:
    """Distance (feather units) from each inside pixel to the silhouette edge."""
    return ndimage.distance_transform_edt(alpha > 0.5).astype(np.float32) * pixel


def fringe(cv: Canvas, ridge: np.ndarray, inside: np.ndarray, depth: float) -> np.ndarray:
    """Opacity gaps between barb tips within ``depth`` of the edge (the feathery margin)."""
    edge = edge_distance(inside, cv.pixel)
    weight = 1.0 - smoothstep(0.0, depth, edge)
    return inside * (1.0 - weight * (1.0 - np.clip(ridge * 1.6, 0.0, 1.0)))


def melanin_fade(
    cv: Canvas, alpha: np.ndarray, width: float, floor: float, noise: np.ndarray
) -> np.ndarray:
    """Structural share fading to ``floor`` within ``width`` of the edge (paper §3.3.6)."""
    edge = edge_distance(alpha, cv.pixel)
    share = floor + (1.0 - floor) * smoothstep(0.0, width, edge * (1.0 + 0.25 * noise))
    return np.where(alpha > 0.0, share, floor).astype(np.float32)


#: Gradation-map value of a class's measured structure: the literature preset puts each
#: region's measurement at t = ½ and its size variation at the ends (docs/model.md, "Gradation in
#: freyer2020"), so the painted maps stay near ½ and drift from base to apex (paper §3.3.3).
MEASURED_GRADATION = 0.5


def gradation_drift(
    cv: Canvas, slope: float, centre_y: float, noise: float, scale: float
) -> np.ndarray:
    """Gradation ``½ + slope·(y − centre_y)`` plus noise of amplitude ``noise`` and feature size
    ``scale``: the measured structure at ``centre_y``, a subtle drift from the feather's base to
    its apex (paper §3.3.3), clipped to [0, 1]."""
    drift = MEASURED_GRADATION + slope * (cv.y - centre_y)
    return np.clip(drift + noise * cv.noise(scale), 0.0, 1.0)


def barbule_angle(
    cv: Canvas,
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
    width = 0.006 + 0.25 * smoothstep(rachis_tip - 0.02, rachis_tip + 0.1, cv.y)
    side = 2.0 * smoothstep(-width, width, cv.x) - 1.0
    side = side + (1.0 - side) * unmirrored
    return angle_grey(90.0 - (90.0 - magnitude) * side)
