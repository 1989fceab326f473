"""IES LM-63 photometric files → a luminous-intensity profile over the light's directions.

The file format (ANSI/IESNA LM-63-2002, "IESNA Standard File Format for the Electronic Transfer
of Photometric Data and Related Information"; the 1986, 1991, 1995 and 2019 editions share the
numeric block read here):

1. an optional first line ``IESNA:LM-63-…`` and ``[KEYWORD] text`` lines, up to
2. ``TILT=NONE``, ``TILT=INCLUDE`` (then: lamp-to-luminaire geometry, the number of tilt
   angles N, N angles, N multiplying factors) or ``TILT=<file>``: tilt data describe how lamp
   output changes with the lamp's tilt in its luminaire, which a fixed light does not have: read
   and not applied;
3. ten numbers: number of lamps, lumens per lamp (−1: absolute photometry), candela multiplier,
   number of vertical angles, number of horizontal angles, photometric type (1 = C, 2 = B,
   3 = A), units (1 feet, 2 metres), luminous opening width, length, height;
4. three numbers: ballast factor, ballast-lamp photometric factor (LM-63-1991; "future use" in
   2002, 1), input watts;
5. the vertical angles (increasing), the horizontal angles (increasing), then for each
   horizontal angle the candela value at each vertical angle.

Numbers are separated by blanks, line ends or commas. Candela values are multiplied by the
candela multiplier, the ballast factor and the ballast-lamp factor (LM-63-2002 §3.12, §3.14).

Type C photometry (the one every luminaire file in practice uses, and the only one UsdLux's
shaping describes): vertical angle 0° is the nadir, the luminaire's axis, which is the light's
emission axis, −Z; horizontal angle 0° is the luminaire's length axis (+X here), 90° is
counter-clockwise from it seen from above (+Y). Horizontal angles ending at 0° mean a profile
symmetric about the axis; ending at 90°, symmetric in each quadrant; at 180°, about the 0–180°
plane; starting at 90° and ending at 270°, about the 90–270° plane (LM-63-2002 §3.18). Outside
the vertical range the file covers (0–90° covers the lower hemisphere only) the intensity is 0.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

PHOTOMETRIC_TYPES = {1: "C", 2: "B", 3: "A"}


class IesError(ValueError):
    """An IES file that cannot be read: the message names the file and what is wrong."""


@dataclass(frozen=True)
class IesProfile:
    """A type C luminous-intensity distribution (candela, multipliers applied)."""

    vertical_deg: np.ndarray  # (V,) increasing, within 0..180
    horizontal_deg: np.ndarray  # (H,) increasing
    candela: np.ndarray  # (H, V)
    lumens_per_lamp: float  # −1: absolute photometry
    photometric_type: int

    def intensity(self, theta: np.ndarray, phi: np.ndarray) -> np.ndarray:
        """Candela towards polar angle ``theta`` off the axis (rad, 0 = nadir) and azimuth ``phi``
        (rad, counter-clockwise from +X), linearly interpolated; 0 outside the vertical range."""
        theta_deg = np.degrees(np.asarray(theta, dtype=np.float64))
        phi_deg = _fold_azimuth(np.degrees(np.asarray(phi, dtype=np.float64)), self.horizontal_deg)
        theta_deg, phi_deg = np.broadcast_arrays(theta_deg, phi_deg)
        v, h = self.vertical_deg, self.horizontal_deg
        per_slice = np.stack(
            [np.interp(theta_deg, v, row, left=0.0, right=0.0) for row in self.candela], axis=-1
        )
        if len(h) == 1:
            value = per_slice[..., 0]
        else:
            j = np.clip(np.searchsorted(h, phi_deg, side="right") - 1, 0, len(h) - 2)
            t = np.clip((phi_deg - h[j]) / (h[j + 1] - h[j]), 0.0, 1.0)
            lo = np.take_along_axis(per_slice, j[..., None], axis=-1)[..., 0]
            hi = np.take_along_axis(per_slice, j[..., None] + 1, axis=-1)[..., 0]
            value = lo * (1.0 - t) + hi * t
        inside = (theta_deg >= v[0] - 1e-9) & (theta_deg <= v[-1] + 1e-9)
        return np.where(inside, value, 0.0)

    def flux(self, samples: int = 1024) -> float:
        """Luminous flux, lm: ∫ I dΩ over the sphere (midpoint rule on a θ×φ grid)."""
        return sphere_integral(self.intensity(*texel_angles(samples, 2 * samples)))


def texel_angles(n_theta: int, n_phi: int) -> tuple[np.ndarray, np.ndarray]:
    """Polar angle θ (rows, 0..π) and azimuth φ (columns, 0..2π) at the centres of a grid."""
    theta = (np.arange(n_theta) + 0.5) / n_theta * math.pi
    phi = (np.arange(n_phi) + 0.5) / n_phi * 2.0 * math.pi
    return theta[:, None], phi[None, :]


def sphere_integral(grid: np.ndarray) -> float:
    """∫ f dΩ of values at :func:`texel_angles` centres: Σ f sin θ Δθ Δφ (midpoint rule)."""
    n_theta, n_phi = grid.shape
    theta = (np.arange(n_theta) + 0.5) / n_theta * math.pi
    return float(
        (grid * np.sin(theta)[:, None]).sum() * (math.pi / n_theta) * (2 * math.pi / n_phi)
    )


def scaled_theta(theta: np.ndarray, angle_scale: float) -> np.ndarray:
    """``shaping:ies:angleScale`` (UsdLux ShapingAPI): the profile's θ for the light's θ (rad):
    θ / s for s > 0, θ for s = 0, (θ − π) / −s + π for s < 0."""
    if angle_scale > 0:
        return theta / angle_scale
    if angle_scale < 0:
        return (theta - math.pi) / -angle_scale + math.pi
    return theta


def profile_table(
    profile: IesProfile, angle_scale: float, normalize: bool, n_theta: int, n_phi: int
) -> np.ndarray:
    """The factor UsdLux scales a shaped light's radiance by, per direction (``n_theta`` rows of θ
    from the light's −Z axis, ``n_phi`` columns of azimuth from +X, at texel centres).

    The profile's candela towards the direction (θ mapped by :func:`scaled_theta`; beyond 0..π
    nothing), divided when ``normalize`` by its mean over the sphere, ``Φ / 4π`` of the profile as
    emitted: the light then sends out the power it would unshaped (UsdLux: "preserving the
    overall energy output")."""
    theta, phi = texel_angles(n_theta, n_phi)
    mapped = scaled_theta(theta, angle_scale)
    table = np.where((mapped >= 0) & (mapped <= math.pi), profile.intensity(mapped, phi), 0.0)
    table = np.broadcast_to(table, (n_theta, n_phi))
    if normalize:
        mean = sphere_integral(table) / (4.0 * math.pi)
        table = table / mean if mean > 0 else table
    return np.ascontiguousarray(table)


def read_ies(path: str | Path) -> IesProfile:
    """Parse an IES LM-63 file; :class:`IesError` (naming the file and field) if it is malformed."""
    path = Path(path)
    try:
        text = path.read_text(encoding="latin-1")
    except OSError as exc:
        raise IesError(f"{path}: cannot read the IES file ({exc.strerror or exc})") from None
    return parse_ies(text, str(path))


def parse_ies(text: str, where: str = "IES file") -> IesProfile:
    """Parse the text of an IES LM-63 file (see the module docstring for the layout)."""
    lines = text.splitlines()
    tilt_at = next(
        (i for i, line in enumerate(lines) if line.strip().upper().startswith("TILT")), None
    )
    if tilt_at is None:
        raise IesError(f"{where}: no TILT= line: not an IES LM-63 file")
    tilt = lines[tilt_at].split("=", 1)[-1].strip().upper()
    numbers = _numbers(" ".join(lines[tilt_at + 1 :]), where)
    at = 0
    if tilt == "INCLUDE":
        if len(numbers) < 2:
            raise IesError(f"{where}: TILT=INCLUDE: the tilt block is cut short")
        pairs = int(numbers[1])
        at = 2 + 2 * pairs
    head = numbers[at : at + 13]
    if len(head) < 13:
        raise IesError(f"{where}: the photometric header (13 numbers after TILT) is cut short")
    lamps_lumens, multiplier = head[1], head[2]
    n_vertical, n_horizontal, kind = int(head[3]), int(head[4]), int(head[5])
    ballast, ballast_lamp = head[10], head[11]
    if n_vertical < 2 or n_horizontal < 1:
        raise IesError(
            f"{where}: number of vertical angles = {n_vertical}, horizontal = {n_horizontal}: "
            "needs at least 2 and 1"
        )
    if kind not in PHOTOMETRIC_TYPES:
        raise IesError(f"{where}: photometric type = {kind}: must be 1 (C), 2 (B) or 3 (A)")
    body = numbers[at + 13 :]
    expected = n_vertical + n_horizontal + n_vertical * n_horizontal
    if len(body) < expected:
        raise IesError(
            f"{where}: {len(body)} angle and candela values, the header announces {expected}: "
            "the file is cut short"
        )
    vertical = np.asarray(body[:n_vertical])
    horizontal = np.asarray(body[n_vertical : n_vertical + n_horizontal])
    candela = np.asarray(body[n_vertical + n_horizontal : expected]).reshape(
        n_horizontal, n_vertical
    )
    for name, angles, top in (("vertical", vertical, 180.0), ("horizontal", horizontal, 360.0)):
        if np.any(np.diff(angles) <= 0) or angles[0] < 0 or angles[-1] > top:
            raise IesError(f"{where}: {name} angles must increase within 0..{top:g}°")
    if not np.all(np.isfinite(candela)) or np.any(candela < 0):
        raise IesError(f"{where}: candela values must be finite and not negative")
    scale = multiplier * ballast * ballast_lamp
    if not math.isfinite(scale) or scale < 0:
        raise IesError(f"{where}: candela multiplier × ballast factors = {scale:g}: not usable")
    return IesProfile(vertical, horizontal, candela * scale, float(lamps_lumens), kind)


def _numbers(text: str, where: str) -> list[float]:
    values = []
    for token in re.split(r"[\s,]+", text.strip()):
        if not token:
            continue
        try:
            values.append(float(token))
        except ValueError:
            raise IesError(f"{where}: {token!r} is not a number") from None
    return values


def _fold_azimuth(phi_deg: np.ndarray, horizontal: np.ndarray) -> np.ndarray:
    """Azimuth (deg) folded into the range the file covers, by its symmetry (LM-63-2002 §3.18)."""
    phi = np.mod(phi_deg, 360.0)
    first, last = float(horizontal[0]), float(horizontal[-1])
    if len(horizontal) == 1:
        return np.zeros_like(phi)
    if first == 0.0 and last == 90.0:  # quadrant symmetry
        phi = np.mod(phi, 180.0)
        return np.where(phi > 90.0, 180.0 - phi, phi)
    if first == 0.0 and last == 180.0:  # symmetric about the 0–180° plane
        return np.where(phi > 180.0, 360.0 - phi, phi)
    if first == 90.0 and last == 270.0:  # symmetric about the 90–270° plane
        return np.where(phi < 90.0, 180.0 - phi, np.where(phi > 270.0, 540.0 - phi, phi))
    return phi
