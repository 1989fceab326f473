"""The barb direction over the vane, estimated from the displacement map's streaks.

The converter knows the feather only through its maps, and the barbs show in one of them: the
displacement map's streaks run along the barbs. Their direction is an *axis* (no sign) and is
handled as a doubled angle ``(cos 2φ, sin 2φ)`` throughout, so that ``φ`` and ``φ + 180°`` are
the same value and averaging never cancels an axis against itself.

1. **Measure** where the streaks are: the structure tensor ``J = G_σ * (∇d ∇dᵀ)`` of the map at
   its own resolution (a streak pattern finer than two texels aliases into moiré if the map is
   reduced first; the smooth tensor is reduced afterwards), its eigenvector of the smaller
   eigenvalue being the streak direction (Bigün & Granlund 1987; Jähne, *Digital Image
   Processing*, §13.3).
2. **Trust** a texel by its *coherence* ``√((J₁₁−J₂₂)² + 4J₁₂²) / (J₁₁+J₂₂)`` (1 for parallel
   streaks, 0 for isotropic texture) and by its *streak energy* ``J₁₁+J₂₂`` against the map's
   typical energy: fine grain noise has a direction of its own on the scale of a few texels, but
   a thousandth of the barbs' energy.
3. **Fill** untrusted texels (barbs too fine to resolve, as near the centre of an eye feather
   where 240 radial barbs meet; texels with no streaks) from the trusted ones by push-pull
   (normalised pyramid interpolation, Gortler et al. 1996, *The Lumigraph*, §3.4.2): the smooth
   continuation of the measured field. Inside a ring of radial barbs it continues them radially
   (the doubled angle of the ring's directions turns twice around the centre; every symmetric
   average of it points along the radius). With no streaks anywhere the field is the shaft
   direction ``(0, 1)``.

Vertex tangents need one sign per axis that neighbours agree on (a triangle interpolates them:
``v`` and ``−v`` would cancel and draw a line): :func:`sample_direction` points every barb away
from the rachis, as barbs grow.
"""

from __future__ import annotations

import math

import numpy as np
from scipy import ndimage

from pavonine.base.map_files import area_reduce, sample_bilinear

#: Streak-orientation scale, as a fraction of the map's height (about 6 texels at 1024).
ORIENTATION_SCALE = 0.006
#: Coherence from which a texel's direction counts (ramping to full trust 0.3 above it).
MIN_COHERENCE = 0.2
#: Streak energy, relative to the map's typical (90th percentile) energy, from which a texel's
#: direction counts (full trust at 4× this).
MIN_ENERGY = 0.02
#: Mean trust at which a pyramid cell's direction is taken as it is (push-pull).
PULL_TRUST = 0.25


def streak_tensor(displacement: np.ndarray, max_size: int = 1024):
    """Smoothed structure tensor ``(J₁₁, J₁₂, J₂₂)`` of the map (x right, y up), reduced to at
    most ``max_size`` texels along its longer side after smoothing."""
    factor = max(1, math.ceil(max(displacement.shape) / max_size))
    # A map reduced afterwards is differentiated in float32: a map is 16-bit at most, and the
    # float64 gradient of 33 M texels (8192) cost 3 s of CPU of the 0.3 s float32 takes.
    d = np.asarray(displacement, dtype=np.float64 if factor == 1 else np.float32)
    gy_rows, gx = np.gradient(d)
    gy = -gy_rows  # rows grow downward; v grows upward
    sigma = max(1.5, ORIENTATION_SCALE * d.shape[0])
    if factor == 1:
        return tuple(
            ndimage.gaussian_filter(g, sigma, mode="nearest") for g in (gx * gx, gx * gy, gy * gy)
        )
    # Both orders apply the same Gaussian and the same box: reducing the products first (they
    # are formed at full resolution, so the streaks do not alias) and smoothing the reduced map
    # with σ / factor costs factor² times less (49-texel σ at 8192: 33 M texels, 395 taps).
    return tuple(
        ndimage.gaussian_filter(
            area_reduce(g, factor).astype(np.float64), sigma / factor, mode="nearest"
        )
        for g in (gx * gx, gx * gy, gy * gy)
    )


def _trust(jxx: np.ndarray, jxy: np.ndarray, jyy: np.ndarray) -> np.ndarray:
    """Per-texel trust in [0, 1]: coherent streaks with a barb's share of energy."""
    trace = jxx + jyy
    coherence = np.hypot(jxx - jyy, 2.0 * jxy) / np.maximum(trace, 1e-30)
    coherent = np.clip((coherence - MIN_COHERENCE) / 0.3, 0.0, 1.0)
    typical = np.percentile(trace, 90.0)
    if typical <= 1e-12:
        return np.zeros_like(trace)
    strong = np.clip((trace / typical - MIN_ENERGY) / (3.0 * MIN_ENERGY), 0.0, 1.0)
    return coherent * strong


def push_pull(values: np.ndarray, weight: np.ndarray, fallback: np.ndarray) -> np.ndarray:
    """Fill ``values`` (``H × W × C``) where ``weight`` (in [0, 1]) is low by normalised pyramid
    interpolation of the weighted values: each level averages ``weight·value`` and ``weight`` over
    2 × 2 blocks; going back up, a texel keeps its own value in proportion to its trust and takes
    the coarser level's value for the rest. Where no texel is trusted: ``fallback`` (``C``)."""
    levels = [(values * weight[..., None], weight)]
    while max(levels[-1][1].shape) > 2:
        weighted, w = levels[-1]
        levels.append((area_reduce(weighted, 2), area_reduce(w, 2)))
    weighted, w = levels[-1]
    filled = np.where((w > 1e-9)[..., None], weighted / np.maximum(w, 1e-9)[..., None], fallback)
    for weighted, w in reversed(levels[:-1]):
        zoom = (w.shape[0] / filled.shape[0], w.shape[1] / filled.shape[1], 1)
        coarse = ndimage.zoom(filled, zoom, order=1, mode="nearest", grid_mode=True)
        own = weighted / np.maximum(w, 1e-9)[..., None]
        keep = np.clip(w / PULL_TRUST, 0.0, 1.0)[..., None]
        filled = keep * own + (1.0 - keep) * coarse
    return filled


def barb_direction_field(displacement: np.ndarray, max_size: int = 1024) -> np.ndarray:
    """Barb direction per texel from the displacement map's streaks, as unit 2-D vectors
    ``(du, dv)`` in square-pixel feather units (``u`` right, ``v`` up), ``dv ≥ 0`` (an axis; see
    :func:`sample_direction` for a consistent sign). At most ``max_size`` texels along the longer
    side. Module docstring: measure, trust, fill."""
    jxx, jxy, jyy = streak_tensor(displacement, max_size)
    norm = np.maximum(np.hypot(jxx - jyy, 2.0 * jxy), 1e-30)
    # The streaks run across the gradient: the barb's doubled angle is the gradient's + 180°.
    doubled = np.stack([-(jxx - jyy) / norm, -2.0 * jxy / norm], axis=-1)
    shaft = np.array([-1.0, 0.0])  # (0, 1) doubled: 2·90° = 180°
    doubled = push_pull(doubled, _trust(jxx, jxy, jyy), shaft)
    phi = 0.5 * np.arctan2(doubled[..., 1], doubled[..., 0])
    phi = np.where(np.hypot(doubled[..., 0], doubled[..., 1]) > 1e-9, phi, 0.5 * math.pi)
    field = np.stack([np.cos(phi), np.sin(phi)], axis=-1)
    field *= np.where(field[..., 1:] < 0.0, -1.0, 1.0)
    return field.astype(np.float32)


def sample_direction(
    field: np.ndarray, uv: np.ndarray, outward: np.ndarray | None = None
) -> np.ndarray:
    """Bilinear lookup of a 2-D axis field at feather-space points, as unit vectors.

    Interpolated as the doubled angle ``(cos 2φ, sin 2φ)`` (interpolating the vectors would
    average ``v`` and ``−v`` to nothing where the axis turns through horizontal). The sign:
    ``outward`` (per point, any length) is the direction away from the rachis, and each vector is
    turned to point along it (barbs grow away from the shaft), so neighbouring vertices agree
    wherever the barbs leave the rachis or its tip; without it, or where ``outward`` is zero,
    ``dv ≥ 0``.
    """
    du, dv = field[..., 0].astype(np.float64), field[..., 1].astype(np.float64)
    c2 = sample_bilinear(du * du - dv * dv, uv)
    s2 = sample_bilinear(2.0 * du * dv, uv)
    phi = 0.5 * np.arctan2(s2, c2)
    out = np.stack([np.cos(phi), np.sin(phi)], axis=1)
    side = out[:, 1]
    if outward is not None:
        along = np.sum(out * outward, axis=1)
        side = np.where(np.abs(along) > 1e-9, along, side)
    out *= np.where(side < 0.0, -1.0, 1.0)[:, None]
    return np.where(np.hypot(c2, s2)[:, None] > 1e-6, out, np.array([[0.0, 1.0]]))


def away_from_rachis(uv: np.ndarray, aspect: float, rachis_top: float) -> np.ndarray:
    """From the nearest point of the rachis (feather space ``u = ½``, ``v ≤ rachis_top``) to each
    point, in square feather units: across the vane beside the shaft, radial above its tip."""
    x = (uv[:, 0] - 0.5) * aspect
    return np.stack([x, np.maximum(uv[:, 1] - rachis_top, 0.0)], axis=1)
