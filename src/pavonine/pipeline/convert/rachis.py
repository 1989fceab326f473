"""The rachis (the feather's shaft): a tapering tube with conical end caps above the vane's
centre line, kept in *tube coordinates* so that refinement interpolates them linearly and
:func:`rachis_positions` turns them into round points.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pavonine.pipeline.convert.surface import FeatherFrame, normalise

#: Length (cm) of the cone in which the shaft ends past its top ring: it tapers to a point
#: (a rachis narrows to its tip, Lucas & Stettenheim 1972, *Avian Anatomy: Integument*;
#: the length is an estimate). A cone 1.5 tip radii long (0.045 cm on the eye) read as a
#: blunt, square end in close-ups of the eye's heart.
TIP_TAPER_CM = 0.6


@dataclass
class RachisSpec:
    """The shaft: from ``-calamus`` below the vane to ``top`` (feather-space v), tapering."""

    calamus_cm: float
    top: float
    radius_cm: float
    tip_radius_cm: float


def _rachis_centre(frame: FeatherFrame, s: np.ndarray, lift: np.ndarray) -> np.ndarray:
    uv = np.column_stack([np.full_like(s, 0.5), s])
    return frame.position(uv) + lift[:, None] * frame.normal(uv)


def rachis_radius(spec: RachisSpec, frame: FeatherFrame, s: np.ndarray) -> np.ndarray:
    """The shaft radius (cm) at feather-space heights ``s``, tapering from base to tip."""
    bottom = -spec.calamus_cm / frame.length
    t = np.clip((s - bottom) / (spec.top - bottom), 0.0, 1.0)
    return spec.radius_cm + (spec.tip_radius_cm - spec.radius_cm) * t**0.7


def base_rachis(
    spec: RachisSpec, frame: FeatherFrame, rings: int = 48, sides: int = 8
) -> tuple[np.ndarray, np.ndarray]:
    """Coarse rachis tube with conical end caps as *tube coordinates* ``(s, cos φ, sin φ, w)``.

    ``s`` is the feather-space ``v`` along the shaft, ``φ`` the angle around it and ``w`` the
    share of the radius (1 on the tube, 0 at the end-cap apexes). :func:`rachis_positions`
    turns linearly interpolated tube coordinates into points.
    """
    bottom = -spec.calamus_cm / frame.length
    s = np.linspace(bottom, spec.top, rings)
    phi = 2 * np.pi * np.arange(sides) / sides
    ss, pp = np.meshgrid(s, phi, indexing="ij")
    coords = np.column_stack([ss.ravel(), np.cos(pp).ravel(), np.sin(pp).ravel(), np.ones(ss.size)])
    idx = np.arange(rings * sides).reshape(rings, sides)
    nxt = np.roll(idx, -1, axis=1)
    a, b, c, d = idx[:-1], nxt[:-1], nxt[1:], idx[1:]
    faces = np.concatenate(
        [np.stack([a, b, c], -1).reshape(-1, 3), np.stack([a, c, d], -1).reshape(-1, 3)]
    )
    cap_len = 0.6 * spec.radius_cm / frame.length
    tip_len = max(TIP_TAPER_CM, 1.5 * spec.tip_radius_cm) / frame.length
    apex = np.array([[bottom - cap_len, 0.0, 0.0, 0.0], [spec.top + tip_len, 0.0, 0.0, 0.0]])
    base_apex, top_apex = len(coords), len(coords) + 1
    ring0, ring1 = idx[0], idx[-1]
    cap0 = np.stack([np.full(sides, base_apex), np.roll(ring0, -1), ring0], -1)
    cap1 = np.stack([np.full(sides, top_apex), ring1, np.roll(ring1, -1)], -1)
    return np.concatenate([coords, apex]), np.concatenate([faces, cap0, cap1])


def rachis_positions(
    spec: RachisSpec, frame: FeatherFrame, coords: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Object-space points and the shaft direction of tube coordinates (:func:`base_rachis`);
    the interpolated direction around the shaft is renormalised so the tube stays round."""
    s = coords[:, 0]
    ring = coords[:, 1:3]
    norm = np.linalg.norm(ring, axis=1)
    ring = ring / np.where(norm > 1e-12, norm, 1.0)[:, None]
    bottom = -spec.calamus_cm / frame.length
    s_in = np.clip(s, bottom, spec.top)
    radius = rachis_radius(spec, frame, s_in) * np.clip(coords[:, 3], 0.0, 1.0)
    lift = 0.35 * rachis_radius(spec, frame, s_in)
    centre = _rachis_centre(frame, s, lift)
    ds = 1e-4
    tangent = normalise(_rachis_centre(frame, s + ds, lift) - _rachis_centre(frame, s - ds, lift))
    e1 = np.tile(np.array([1.0, 0.0, 0.0]), (len(s), 1))
    e2 = normalise(np.cross(tangent, e1))
    e1 = np.cross(e2, tangent)
    points = centre + radius[:, None] * (ring[:, :1] * e1 + ring[:, 1:2] * e2)
    return points, tangent
