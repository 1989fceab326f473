"""Discrete barbule blocks: which block a shading point lies on, and that block's own tilt.

The smooth BRDF (:mod:`pavonine.materials.brdf`) spreads the layer normals along the barbule by
``σ_along = σ_block ⊕ σ_diffraction`` (:func:`pavonine.materials.barbule.along_sigma`): the
average over all blocks of a barbule and over all barbules in a footprint. A barbule is a row of
blocks 20–30 µm long, each curved like a saddle (paper §2.1, Figure 3B), so the part ``σ_block``
of that spread is *between* blocks, not within one. With glitter ``g`` ∈ [0, 1] a block's mean
slope along the barbule is offset by

    μ = √g · tan σ_block · z,   z ~ N(0, 1) drawn from a hash of (barbule, block, seed)

and the lobe around it keeps the rest of the slope variance,

    s_w² = tan² σ_along(λ) − g · tan² σ_block                                 (slope space)

so a Gaussian of the offsets convolved with the block's Gaussian lobe is the smooth lobe's
Gaussian of variance ``tan² σ_along``: over a footprint of many blocks the BRDF is the smooth one
for every ``g``; over a few, the blocks that face the half-vector glint. ``g = 0`` is exactly the
smooth BRDF. The crescent's spread across the barbule (Eq. 6) is each block's own cross-section
shape and stays within the block. Slopes are Beckmann slopes (``α = √2 s``, Walter et al. 2007
Eq. 25); the block's distribution is that Beckmann slope density shifted by ``μ`` along ``x``.

The block a point lies on comes from its position along and across the barbule (µm): on a vane
sheet the feather coordinate turned into the barbule's axis (:func:`block_cell`), on a barb
ribbon the ribbon's own coordinate. The hash is of integers only (never of a sample), so every
process, worker and sample split sees the same blocks.
"""

from __future__ import annotations

import math
from typing import Any

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


def slope_split(
    glitter: float, block_sigma: float, along_sigma: Any, ops: Any = NUMPY
) -> tuple[float, Any]:
    """``(between, within)``: the slope deviation of the block offsets, ``√g tan σ_block``, and of
    the lobe within a block, ``√(tan² σ_along − g tan² σ_block)`` (radians in; slopes out)."""
    between2 = glitter * math.tan(block_sigma) ** 2
    t = ops.tan(along_sigma)
    return math.sqrt(between2), ops.sqrt(ops.maximum(t * t - between2, 1e-12))


def block_slope(
    glitter: float,
    block_sigma: float,
    barbule: Any,
    block: Any,
    seed: Any,
    ops: Any = NUMPY,
) -> Any:
    """A block's mean slope offset along the barbule, ``μ = √g tan σ_block z``."""
    between = math.sqrt(glitter) * math.tan(block_sigma)
    return between * block_normal(barbule, block, seed, ops)
