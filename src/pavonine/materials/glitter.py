"""Discrete barbule blocks: which block a shading point lies on, its tilt and its speckle.

The smooth BRDF (:mod:`pavonine.materials.brdf`) spreads the layer normals along the barbule by
``σ_along = σ_block ⊕ σ_d`` (:func:`pavonine.materials.barbule.along_sigma`): the saddle blocks'
spread ``σ_block`` and the diffraction envelope of the rods' ends, ``σ_d = 0.376 λ/ℓ`` (a slit of
the rod length ℓ, "several µm": 2.4° at 550 nm for 5 µm), averaged over all blocks of a barbule
and all barbules in a footprint. A barbule is a row of blocks 20–30 µm long (paper §2.1,
Figure 3B). With glitter ``g`` ∈ [0, 1] the average comes apart in two ways:

* **tilt**: a block's mean slope along the barbule is offset by
  ``√g · tan σ_block · z``, ``z ~ N(0, 1)`` from a hash of (barbule, block, seed);
* **speckle**: the rod ends of one block are lit coherently (sunlight's transverse coherence
  diameter is ``0.61 λ/α`` ≈ 70 µm at 550 nm for the sun's angular radius α = 0.265°: the van
  Cittert–Zernike theorem, Born & Wolf, *Principles of Optics*, §10.4.2), so the block does not
  reflect the smooth envelope ``σ_d`` but a speckle pattern under it: grains as wide as the
  block's own aperture, ``σ_c = 0.376 λ/L`` (0.47° for L = 25 µm), about ``L/ℓ`` of them
  (:func:`grain_count`) at random places in the envelope, each with a negative-exponential
  share of the light (fully developed speckle; Goodman 2007, *Speckle Phenomena in Optics*,
  ch. 3 for the intensity statistics, ch. 4 for the grain size ≈ λ/L). Grain ``k`` sits at slope ``tilt + z_k · √(g (tan² σ_d − tan² σ_c))``; the
  slope scales with λ (a Fraunhofer pattern is a function of ``sin θ / λ``), ``z_k`` does not.

Each grain's lobe keeps the rest of the slope variance,

    s_w² = tan² σ_along(λ) − g · tan² σ_block − g · (tan² σ_d − tan² σ_c)      (slope space)

(≈ tan² σ_c at g = 1, up to the tangent's curvature), so a Gaussian of tilts and grain places
convolved with a grain's Gaussian lobe is the smooth lobe's Gaussian of variance
``tan² σ_along`` at every wavelength, whatever the grains' shares: over a footprint of many
blocks the BRDF is the smooth one for every ``g``; over a few, the grains that face the
half-vector glint, and a 1° turn of the half-vector (the sun turned by 2°) moves them. ``g = 0``
is exactly the smooth BRDF. The crescent's spread across the barbule (Eq. 6) is each block's own
cross-section shape and stays within it. Slopes are Beckmann slopes (``α = √2 s``, Walter et al.
2007 Eq. 25); a grain's distribution is that Beckmann slope density shifted along ``x``.
The sun's own disc (0.53°) is the renderer's light, not part of the BSDF.

The block a point lies on comes from its position along and across the barbule (µm): on a vane
sheet the feather coordinate turned into the barbule's axis (:func:`sheet_coordinates`), on a
barb ribbon the ribbon's own coordinate. The hash is of integers only (never of a sample), so every
process, worker and sample split sees the same blocks.
"""

from __future__ import annotations

import math
from typing import Any, NamedTuple

from pavonine.materials.arraymath import NUMPY

#: Block length along the barbule (µm): "typically 20–30 µm" (paper §2.1); the middle.
BLOCK_LENGTH_UM = 25.0
#: Barbule width on the vane (µm): the spacing of neighbouring barbules across their axis. Not
#: given by the paper (its Figure 3B shows blocks about as wide as long); a parameter.
BARBULE_WIDTH_UM = 20.0
#: Barbule-axis directions are snapped to this many steps over 180° before the feather
#: coordinate is turned into the axis: a smoothly turning axis would otherwise shear the block
#: grid (a 1 mrad turn moves a point 15 cm from the origin by 150 µm, six blocks). Within a step the
#: grid is rigid; between steps the blocks change, as they do between barbules.
AXIS_STEPS = 32
MASK32 = 0xFFFFFFFF
#: At most this many speckle grains per block (:func:`grain_count`).
MAX_GRAINS = 8


def lowbias32(x: Any) -> Any:
    """Chris Wellons' ``lowbias32`` integer hash (bias 0.17, github.com/skeeto/hash-prospector).

    ``x`` holds unsigned 32-bit values: NumPy ``uint64`` arrays (products stay below 2⁶⁴ and are
    masked), Dr.Jit ``UInt32`` (wraps by itself) or Python ints.
    """
    x = x ^ (x >> 16)
    x = (x * 0x7FEB352D) & MASK32
    x = x ^ (x >> 15)
    x = (x * 0x846CA68B) & MASK32
    return x ^ (x >> 16)


def block_hash(barbule: Any, block: Any, seed: Any) -> Any:
    """One 32-bit hash of a block's integer coordinates and the seed (all unsigned 32-bit)."""
    h = lowbias32(seed ^ 0x9E3779B9)
    h = lowbias32(h ^ barbule)
    return lowbias32(h ^ ((block * 0x85EBCA6B) & MASK32))


def block_normal(barbule: Any, block: Any, seed: Any, ops: Any = NUMPY) -> Any:
    """A standard normal deviate per block (Box–Muller on two hashes of its coordinates)."""
    h1 = block_hash(barbule, block, seed)
    h2 = lowbias32(h1 ^ 0x68E31DA4)
    u1 = (ops.to_float(h1) + 0.5) * (1.0 / 4294967296.0)
    u2 = ops.to_float(h2) * (1.0 / 4294967296.0)
    return ops.sqrt(-2.0 * ops.log(u1)) * ops.cos((2.0 * math.pi) * u2)


def block_cell(
    along_um: Any,
    across_um: Any,
    block_length_um: float = BLOCK_LENGTH_UM,
    barbule_width_um: float = BARBULE_WIDTH_UM,
    ops: Any = NUMPY,
) -> tuple[Any, Any]:
    """``(barbule, block)`` indices (unsigned 32-bit) of a point ``across_um`` across and
    ``along_um`` along the barbules (µm, any origin)."""
    return (
        ops.to_uint32(ops.floor(across_um / barbule_width_um)),
        ops.to_uint32(ops.floor(along_um / block_length_um)),
    )


def sheet_coordinates(
    u_um: Any, v_um: Any, axis_angle: Any, ops: Any = NUMPY
) -> tuple[Any, Any, Any]:
    """``(along, across, step)``: a point of the vane sheet at feather coordinate ``(u, v)``
    (µm) in the frame of a barbule axis at ``axis_angle`` (radians from ``u``), the angle snapped
    to :data:`AXIS_STEPS` steps over 180°; ``step`` (unsigned) goes into the seed."""
    k = ops.floor(axis_angle * (AXIS_STEPS / math.pi) + 0.5)
    snapped = k * (math.pi / AXIS_STEPS)
    c, s = ops.cos(snapped), ops.sin(snapped)
    step = ops.to_uint32(k - AXIS_STEPS * ops.floor(k / AXIS_STEPS))
    return u_um * c + v_um * s, v_um * c - u_um * s, step


def grain_count(block_length: float, rod_length: float) -> int:
    """Speckle grains under one block's diffraction envelope: ``L / ℓ`` (the envelope is
    ``λ/ℓ`` wide, a grain ``λ/L``), rounded, 1 to :data:`MAX_GRAINS`."""
    return int(min(max(round(block_length / rod_length), 1), MAX_GRAINS))


def speckle_split(
    glitter: float,
    block_sigma: float,
    along_sigma: Any,
    diffraction_sigma: Any,
    grain_sigma: Any,
    ops: Any = NUMPY,
) -> tuple[Any, Any]:
    """``(speckle, within)``: the slope deviation of the grains' positions about the block's tilt,
    ``√(g (tan² σ_d − tan² σ_c))``, and of the lobe of one grain, ``√(tan² σ_along − g tan² σ_block
    − speckle²)`` (radians in, slopes out; σ_d the rod ends' envelope, σ_c one grain)."""
    td, tc = ops.tan(diffraction_sigma), ops.tan(grain_sigma)
    speckle2 = glitter * ops.maximum(td * td - tc * tc, 0.0)
    t = ops.tan(along_sigma)
    within2 = t * t - glitter * math.tan(block_sigma) ** 2 - speckle2
    return ops.sqrt(speckle2), ops.sqrt(ops.maximum(within2, 1e-12))


class Block(NamedTuple):
    """One block's tilt and speckle: the mean slope offset ``tilt = √g tan σ_block z`` and, per
    grain, its position deviate ``z_k`` ~ N(0, 1) and its share of the block's light ``w_k``."""

    tilt: Any
    grains: tuple[Any, ...]
    weights: tuple[Any, ...]


def block_state(
    glitter: float,
    block_sigma: float,
    barbule: Any,
    block: Any,
    seed: Any,
    grains: int,
    ops: Any = NUMPY,
) -> Block:
    """The block's tilt and its ``grains`` speckle grains, all from hashes of its coordinates.

    A grain's share is ``e_k / Σ e``, ``e_k`` negative-exponential: the intensity statistics of
    fully developed speckle (Goodman 2007, *Speckle Phenomena in Optics*, ch. 3)."""
    tilt = math.sqrt(glitter) * math.tan(block_sigma) * block_normal(barbule, block, seed, ops)
    positions, energies = [], []
    for k in range(grains):
        salt = (k + 1) * 0x27D4EB2F & MASK32
        positions.append(block_normal(barbule, block, lowbias32(seed ^ salt), ops))
        h = lowbias32(block_hash(barbule, block, seed ^ (salt * 3 & MASK32)) ^ 0xB5297A4D)
        energies.append(-ops.log((ops.to_float(h) + 0.5) * (1.0 / 4294967296.0)))
    total = energies[0]
    for e in energies[1:]:
        total = total + e
    return Block(tilt, tuple(positions), tuple(e / total for e in energies))


def block_ndf(
    hx: Any,
    hy: Any,
    hz: Any,
    alpha_x: Any,
    alpha_y: Any,
    block: Block,
    speckle: Any,
    ops: Any = NUMPY,
) -> Any:
    """The block's normal distribution: its grains' shifted Beckmann lobes (roughness ``alpha_x``
    along, ``alpha_y`` across), grain ``k`` at slope ``tilt + z_k · speckle``, weighted by its
    share: ``Σ_k w_k D_k`` with ``D_k`` :func:`pavonine.materials.barbule.shifted_beckmann_ndf`
    (``∫ D h_z dω = 1``), the factors the grains share computed once."""
    hz2 = hz * hz
    safe = ops.maximum(hz2, 1e-12)
    inv_z = 1.0 / ops.maximum(hz, 1e-6)
    sx = -hx * inv_z - block.tilt
    sy = hy * inv_z
    inv_ax2 = 1.0 / (alpha_x * alpha_x)
    shared = ops.exp(-(sy * sy) / (alpha_y * alpha_y)) / (math.pi * alpha_x * alpha_y * safe * safe)
    total = 0.0
    for z, w in zip(block.grains, block.weights, strict=True):
        d = sx - z * speckle
        total = total + w * ops.exp(-(d * d) * inv_ax2)
    return ops.select(hz > 0.0, shared * total, 0.0)
