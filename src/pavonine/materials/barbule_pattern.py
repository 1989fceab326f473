"""The structure under a barb: its ramus and the barbules on both sides, as a pattern over the
barb's own coordinate (procedural: nothing is stored per barbule).

A barb ribbon (:mod:`pavonine.render.curves.ribbons`) knows, at every point, its length along
the barb ``s``, its place across it ``a`` (signed, counter-clockwise of the barb seen from the
front), its half width ``h`` and the barb's id. From those and the barbule angle ``θ`` (the angle
map, from the barb) :func:`barbule_pattern` says what lies there:

* **Ramus** (the barb's shaft): ``|a| < r(s)``, a strip of half width
  ``r(s) = r_tip + (r_base − r_tip)·exp(−s/ℓ)`` (tapered from the rachis out), never more than
  :data:`RAMUS_MAX_SHARE` of the ribbon's half width (the sheet and the coarse levels carry no
  ramus, so its share is kept small enough that the barbs' average stays the sheet's colour).
  It is melanin-brown (the material's melanin pigment: ``pavonine.render.barbules`` shades it
  with the structural share 0) and round: the place across it ``t = a/r`` tilts its normal by
  ``asin(t)`` across the barb, so one flank is lit and the other is in shade.
* **Barbules** on both sides, leaving the ramus towards the barb's tip at ``φ`` = the barbule
  angle folded into [10°, 80°] (paper §3.3.4: "30°–40° like fish bones"; the fold makes the two
  sides mirror images, a fishbone, where the angle map holds one axis for both). Their axes lie
  :data:`BARBULE_PITCH_UM` apart (perpendicular to the axes), each :data:`BARBULE_WIDTH_UM` wide
  where it leaves the ramus, tapering by :data:`BARBULE_TAPER` to its tip; the strip between two
  neighbours is a gap (the background shows). A barbule is a chain of blocks
  :data:`BLOCK_LENGTH_UM` long (paper §2.1: "connected blocks, typically measuring 20–30 µm
  length"), narrowed by :data:`NECK_DEPTH` at each joint over :data:`NECK_UM`. Each barbule has
  its own length (its tip between ``1 − TIP_JITTER`` and 1 of the way to the ribbon's edge: a
  ragged edge, not a straight cut), its own phase of blocks, and its own twist about its axis, a
  normal tilt drawn from N(0, :data:`TWIST_SIGMA_DEG`) (paper §2.1: the barbules are "twisted at
  the root"), so neighbouring barbules catch the light differently.

All random choices come from an integer hash of (barb id, side, barbule index): the same barb
shows the same barbules in every render, whatever the sampler's seed.

Sizes not in the paper and not found in the sources searched (the barbule pitch, the ramus
widths) are parameters, chosen so that in a closed vane the barbules cover most of the area
(:data:`BARBULE_WIDTH_UM` / :data:`BARBULE_PITCH_UM`) and the ramus reads as a thin line.
"""

from __future__ import annotations

import math
from typing import Any, NamedTuple

from pavonine.materials import glitter

#: Block length along a barbule (µm): paper §2.1, "typically 20–30 µm"; the middle
#: (:data:`pavonine.materials.glitter.BLOCK_LENGTH_UM`).
BLOCK_LENGTH_UM = glitter.BLOCK_LENGTH_UM
#: Barbule width where it leaves the ramus (µm): the blocks of the paper's Figure 3B are about as
#: wide as long; the glitter's barbule width (:data:`pavonine.materials.glitter.BARBULE_WIDTH_UM`).
BARBULE_WIDTH_UM = glitter.BARBULE_WIDTH_UM
#: Distance between neighbouring barbules' axes, perpendicular to them (µm). Not found in the
#: sources searched; a parameter: below the barbules' width, so that they overlap at their roots
#: like shingles (a closed vane), and the gaps between them open as they taper.
BARBULE_PITCH_UM = 14.0
#: A barbule's width at its tip as a share of its root's is ``1 − BARBULE_TAPER``.
BARBULE_TAPER = 0.25
#: The barbule narrows by this share of its width at each joint between two blocks ...
NECK_DEPTH = 0.45
#: ... over this length either side of the joint (µm).
NECK_UM = 3.0
#: Barbule tips end between ``1 − TIP_JITTER`` and ``1 + BARBULE_OVERLAP`` of the way from the
#: ramus to the ribbon's authored edge: a ragged edge that interleaves with the neighbouring
#: barb's barbules (the renderer tessellates barbs ``1 + BARBULE_OVERLAP`` wider than authored).
TIP_JITTER = 0.2
BARBULE_OVERLAP = 0.8
#: Each barbule's twist about its own axis (degrees, standard deviation of its normal's tilt):
#: paper §2.1, barbules "twisted at the root". A parameter (the paper gives no angle); taken out
#: of the crescent's spread θ0 = 15° (:func:`split_crescent`), which keeps 6.5° within a barbule.
TWIST_SIGMA_DEG = 13.5
#: The share of that twist's variance that is the same for every barbule on one side of a barb
#: and opposite on the other (``side·√share·σ``; the rest ``√(1 − share)·σ`` is each barbule's own
#: draw): the two sides are mirror images (a fishbone), so a twist at the root of one hand tilts
#: them opposite ways across the barb, and under a directional light the two halves of a barb
#: differ in brightness: fine lines along the barbs, at the barb spacing, where a pixel holds
#: many barbules. The tilts' variance is still ``σ²`` (a mixture of ``N(±√share·σ, (1 − share)σ²)``),
#: so the barbules' average stays the smooth BSDF's to second order. A parameter (the paper gives
#: no angle).
SIDE_TWIST_SHARE = 0.65
#: Ramus half width at the rachis and towards the barb's tip (µm), and the length over which it
#: tapers (e-folding, µm). Not found in the sources searched; parameters.
RAMUS_BASE_UM = 45.0
RAMUS_TIP_UM = 8.0
RAMUS_TAPER_UM = 20_000.0
#: The ramus never takes more than this share of the ribbon's half width (the barbs' average
#: colour stays the sheet's: the coarse levels have no ramus).
RAMUS_MAX_SHARE = 0.03
#: How much of the ramus' round cross-section shows in its shading normal (1: a cylinder).
RAMUS_ROUNDNESS = 0.8
#: Thickness of the layer of barbules (µm): overlapping barbules of neighbouring barbs lie in it
#: and do not shadow each other (their real shadows are a few µm across, within a block). About a
#: block's width (paper §2.1, Figure 3B); a parameter.
LAYER_UM = 20.0
#: The barbules droop from the ramus by this angle (degrees; the renderer drops a barb ribbon's
#: edges by its tangent): overlapping barbules of neighbouring barbs lie at different heights,
#: and a ray through a gap in one reaches the other (in one plane, a ray leaving the first starts
#: past the second: Mitsuba offsets it by ~9e-5 of the coordinates' size, 17 µm at 18 cm). A
#: parameter: a closed vane is nearly flat.
DROOP_DEG = 8.0
#: Barbule angles (from the barb) are folded into this range (degrees).
MIN_ANGLE_DEG, MAX_ANGLE_DEG = 10.0, 80.0

_MASK = glitter.MASK32
_INV32 = 1.0 / 4294967296.0


class BarbuleLayout(NamedTuple):
    """The pattern's sizes (µm; module constants by default)."""

    block_length_um: float = BLOCK_LENGTH_UM
    barbule_width_um: float = BARBULE_WIDTH_UM
    barbule_pitch_um: float = BARBULE_PITCH_UM
    barbule_taper: float = BARBULE_TAPER
    neck_depth: float = NECK_DEPTH
    neck_um: float = NECK_UM
    tip_jitter: float = TIP_JITTER
    twist_sigma_deg: float = TWIST_SIGMA_DEG
    ramus_base_um: float = RAMUS_BASE_UM
    ramus_tip_um: float = RAMUS_TIP_UM
    ramus_taper_um: float = RAMUS_TAPER_UM
    ramus_max_share: float = RAMUS_MAX_SHARE
    ramus_roundness: float = RAMUS_ROUNDNESS

    def validate(self) -> BarbuleLayout:
        """Every size finite and in its range; ``ValueError`` naming the field otherwise."""
        for name, value in self._asdict().items():
            if not isinstance(value, (int, float)) or isinstance(value, bool):
                raise ValueError(f"{name}: expected a number, got {value!r}")
            if not math.isfinite(value):
                raise ValueError(f"{name}: must be finite, got {value}")
        positive = (
            "block_length_um",
            "barbule_width_um",
            "barbule_pitch_um",
            "ramus_taper_um",
        )
        for name in positive:
            if getattr(self, name) <= 0.0:
                raise ValueError(f"{name}: must be positive, got {getattr(self, name)}")
        shares = ("barbule_taper", "neck_depth", "tip_jitter", "ramus_max_share", "ramus_roundness")
        for name in shares:
            if not 0.0 <= getattr(self, name) <= 1.0:
                raise ValueError(f"{name}: must lie in [0, 1], got {getattr(self, name)}")
        for name in ("neck_um", "twist_sigma_deg", "ramus_base_um", "ramus_tip_um"):
            if getattr(self, name) < 0.0:
                raise ValueError(f"{name}: must not be negative, got {getattr(self, name)}")
        return self


class BarbulePoint(NamedTuple):
    """What the pattern puts at a point (arrays of the point's shape)."""

    present: Any  # bool: ramus or barbule (else a gap: the ray passes)
    ramus: Any  # bool: on the ramus
    tilt_along: Any  # the shading normal's tilt, its in-plane direction's component along the barb
    tilt_across: Any  # ... and across it (counter-clockwise); |tilt| = sin of the tilt angle
    side: Any  # +1 left of the barb (a > 0), −1 right
    axis_deg: Any  # the barbule axis counter-clockwise from the barb: side·φ (a fishbone)


#: The twist takes at most this share of the crescent's spread (the rest stays within a barbule).
MAX_TWIST_SHARE = 0.9


def split_crescent(crescent_sigma_deg: float, twist_sigma_deg: float) -> tuple[float, float]:
    """``(twist, within)``: the crescent's spread across a barbule (paper Eq. 6, θ0, degrees) split
    into the barbules' twist and the spread within one barbule, ``θ0² = twist² + within²``; the
    twist at most :data:`MAX_TWIST_SHARE` of θ0 (normal tilts add as Gaussians do: their
    variances add, so the barbules' average is the smooth BSDF's)."""
    twist = min(float(twist_sigma_deg), MAX_TWIST_SHARE * float(crescent_sigma_deg))
    return twist, math.sqrt(max(crescent_sigma_deg**2 - twist**2, 0.0))


def _unit(h: Any, ops: Any) -> Any:
    """A hash as a uniform number in (0, 1)."""
    return (ops.to_float(h) + 0.5) * _INV32


def _hash(*keys: Any) -> Any:
    """One 32-bit hash of several unsigned keys."""
    h = keys[0]
    for k in keys[1:]:
        h = glitter.lowbias32(h ^ ((k * 0x9E3779B1) & _MASK))
    return glitter.lowbias32(h)


def ramus_half_width(s_um: Any, half_width_um: Any, layout: BarbuleLayout, ops: Any) -> Any:
    """The ramus' half width (µm) at ``s_um`` along a barb whose ribbon is ``half_width_um``."""
    r = layout.ramus_tip_um + (layout.ramus_base_um - layout.ramus_tip_um) * ops.exp(
        -ops.maximum(s_um, 0.0) / layout.ramus_taper_um
    )
    return ops.minimum(r, layout.ramus_max_share * ops.maximum(half_width_um, 0.0))


def barbule_pattern(
    s_um: Any,
    a_um: Any,
    half_width_um: Any,
    barb_id: Any,
    angle_deg: Any,
    layout: BarbuleLayout,
    ops: Any,
) -> BarbulePoint:
    """The ramus and barbules at ``(s, a)`` on a barb (module docstring).

    ``s_um``: length along the barb from its root; ``a_um``: place across it (counter-clockwise
    positive); ``half_width_um``: the ribbon's half width there; ``barb_id``: the barb's id
    (whole numbers); ``angle_deg``: the barbule axis from the barb (the angle map, any of the
    axis' two directions)."""
    side = ops.select(a_um < 0.0, -1.0, 1.0)
    dist = ops.abs(a_um)
    r = ramus_half_width(s_um, half_width_um, layout, ops)
    on_ramus = dist < r
    # The angle map's axis (a line: 180°-periodic) folded to the barbule's angle from the barb.
    folded = angle_deg - 180.0 * ops.floor(angle_deg / 180.0)
    folded = ops.minimum(folded, 180.0 - folded)
    phi = ops.minimum(ops.maximum(folded, MIN_ANGLE_DEG), MAX_ANGLE_DEG) * (math.pi / 180.0)
    sin_phi, cos_phi = ops.sin(phi), ops.cos(phi)
    # Out from the ramus' edge: along the barbule (ℓ), and where along the barb it is rooted.
    d = ops.maximum(dist - r, 0.0)
    ell = d / sin_phi
    root = s_um - d * cos_phi / sin_phi
    along_pitch = layout.barbule_pitch_um / sin_phi
    side_key = ops.to_uint32(side + 1.0)  # 0 right, 2 left
    barb = ops.to_uint32(barb_id)
    offset = _unit(_hash(barb, side_key, 7), ops)
    x = root / along_pitch + offset
    k = ops.floor(x)
    frac = x - k  # across the barbule's strip: 0 … 1 of the pitch
    key = _hash(barb, side_key, ops.to_uint32(k))
    u_len, u_phase = _unit(key, ops), _unit(_hash(key, 1), ops)
    u_twist1, u_twist2 = _unit(_hash(key, 2), ops), _unit(_hash(key, 3), ops)
    # Each barbule's own reach: from the ramus to 1 − jitter … 1 + overlap of the way to the
    # ribbon's authored edge.
    reach = ops.maximum(half_width_um - r, 0.0) / sin_phi
    tip = reach * (1.0 - layout.tip_jitter + (layout.tip_jitter + BARBULE_OVERLAP) * u_len)
    # Width: tapering to the tip, narrowed at every joint between blocks.
    t_len = ops.minimum(ell / ops.maximum(tip, 1e-6), 1.0)
    width = layout.barbule_width_um * (1.0 - layout.barbule_taper * t_len)
    blocks = ell / layout.block_length_um + u_phase
    to_joint = ops.abs(blocks - ops.floor(blocks + 0.5)) * layout.block_length_um
    neck = ops.maximum(1.0 - to_joint / max(layout.neck_um, 1e-6), 0.0)
    width = width * (1.0 - layout.neck_depth * neck)
    # The barbule's strip is centred in its pitch: |frac − ½| below half its width's share.
    inside = ops.abs(frac - 0.5) * layout.barbule_pitch_um < 0.5 * width
    on_barbule = inside & (ell < tip)
    present = on_ramus | on_barbule
    # Normal tilts: the ramus round across the barb; a barbule twisted about its own axis
    # (Box–Muller of two hashes: a Gaussian angle).
    t = ops.select(on_ramus, a_um / ops.maximum(r, 1e-6), 0.0) * layout.ramus_roundness
    gauss = ops.sqrt(-2.0 * ops.log(u_twist1)) * ops.cos(2.0 * math.pi * u_twist2)
    gauss = side * math.sqrt(SIDE_TWIST_SHARE) + gauss * math.sqrt(1.0 - SIDE_TWIST_SHARE)
    twist = ops.sin(gauss * (layout.twist_sigma_deg * math.pi / 180.0))
    # The twist tilts the normal across the barbule axis the BSDF uses (the angle map's, on both
    # sides: its crescent spread lies across that axis, and the twist takes its share of it),
    # towards the in-plane perpendicular (−sin θ, cos θ) in (along, across).
    theta = angle_deg * (math.pi / 180.0)
    tilt_along = ops.select(on_ramus, 0.0, -ops.sin(theta) * twist)
    tilt_across = ops.select(on_ramus, t, ops.cos(theta) * twist)
    axis = side * phi * (180.0 / math.pi)
    return BarbulePoint(present, on_ramus, tilt_along, tilt_across, side, axis)
