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

from pavonine.materials import barbule
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


def grain_split(
    constants: Any, glitter: float, along_sigma: Any, wavelength_nm: Any, ops: Any = NUMPY
) -> tuple[Any, Any]:
    """:func:`speckle_split` of a material's ``constants`` at ``wavelength_nm``: the rod ends'
    envelope and one block's grain are the Fraunhofer widths of its rod and block lengths
    (:func:`pavonine.materials.barbule.diffraction_sigma`); ``along_sigma`` the smooth lobe's
    spread along the barbule at that wavelength (radians)."""
    return speckle_split(
        glitter,
        constants.block_sigma,
        along_sigma,
        barbule.diffraction_sigma(constants.rod_length_nm, wavelength_nm),
        barbule.diffraction_sigma(constants.block_length_nm, wavelength_nm),
        ops,
    )


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


# -- The pixel's footprint: counts of glinting grains per cell (level of detail) ----------------
#
# A pixel that covers n blocks holds the *average* of their lobes, D_n(h) = (1/n) Σ_i D_i(h). One
# block per sample (above) is an unbiased but noisy estimate of it: at the hero view a pixel holds
# hundreds of blocks. The discrete-microfacet renderers (Jakob et al. 2014, "Discrete stochastic
# microfacet models", ACM TOG 33(4); Zirr & Kaplanyan 2016, "Real-time rendering of procedural
# multiscale materials", I3D; Chermain et al. 2020, "Procedural physically based BRDF for
# real-time rendering of glints", CGF 39(7); Deliot & Belcour 2023, "Real-time rendering of
# glinty appearances using distributed binomial laws on anisotropic grids", HPG) evaluate D_n
# directly: the footprint is approximated by a cell of a grid whose cells hold about as many
# facets as the footprint (the level of detail from the ray differentials), and the *number* of a cell's facets whose normals
# fall in a small bin of directions is drawn deterministically, from a hash of the cell and the
# bin, from its binomial law (Poisson for a rare bin). Here a facet is a speckle grain, the bins
# are slices of the grains' places along the barbule, and the bins are blended by the posterior
# weight of a grain at each place given the half-vector, which keeps the lobe continuous in h and
# its expectation over cells exactly the smooth lobe (module docstring: places ~ N(0, σ_μ²),
# σ_μ² = g tan² σ_block + p², each grain a Gaussian of s_w², σ_μ² + s_w² = tan² σ_along):
#
#     N(x; 0, σ_t²) = Σ_b ∫_b N(μ; 0, σ_μ²) N(x; μ, s_w²) dμ = N(x; 0, σ_t²) Σ_b ω_b(x)
#     ω_b(x) = Φ((c_b+1 − u*)/r) − Φ((c_b − u*)/r),   u* = x σ_μ / σ_t²,  r = s_w / σ_t
#
# (the product of two Gaussians; bins in units of σ_μ, edges c_b = b Δu). With X_b = N_b / (M P_b)
# the cell's count in bin b over its expectation (P_b = Φ(c_b+1) − Φ(c_b), M grains in the cell),
# the cell's lobe along the barbule is N(x; 0, σ_t²) Σ_b ω_b(x) X_b, and E[X_b] = 1 gives the smooth
# lobe on average over cells. M = n m for a cell of n blocks, m the independent, equal grains a
# block counts as for the variance of the sum over its blocks (:func:`count_model`: 1.7 for the
# 5 grains of a 25 µm block of 5 µm rods).

#: Finest cell above one block: 2 × 2 blocks (level 1); the coarsest, 2^MAX_LEVEL blocks a side.
MAX_LEVEL = 12
#: Bins of grain places counted around the half-vector's (one each side).
COUNT_BINS = 3
#: Below this expected count a bin's count is drawn from its Poisson law (inversion over
#: :data:`POISSON_TERMS` terms: P(N > 28) < 2·10⁻⁵ at the switch); from it on, from a normal law
#: (Zirr & Kaplanyan 2016 and Deliot & Belcour 2023 approximate the binomial law by a normal one
#: throughout; a rare bin's count is far from normal). The normal deviate is Irwin–Hall's sum of
#: four uniforms (|z| ≤ √12), so ``mean + √mean z`` is never negative from the switch on and the
#: count's mean is exact without clamping.
POISSON_SWITCH = 12.0
POISSON_TERMS = 28
#: A bin expected to hold fewer grains than this (the far tail of the lobe) keeps its mean, X = 1.
TINY_MEAN = 1.0e-4
LN2 = math.log(2.0)
INV_SQRT2 = 1.0 / math.sqrt(2.0)
SQRT3 = math.sqrt(3.0)


def normal_cdf(x: Any, ops: Any = NUMPY) -> Any:
    """Φ(x) = (1 + erf(x/√2)) / 2."""
    return 0.5 + 0.5 * ops.erf(x * INV_SQRT2)


class CountModel(NamedTuple):
    """Material-wide numbers of the counts: the bin width ``Δu`` (units of σ_μ, twice a grain's
    posterior deviation ``r`` at 550 nm, so a grain's light spans about three bins) and the
    independent, equal grains a block counts as (:func:`count_model`)."""

    bin_width: float
    grains_per_block: float


def count_model(
    spread_550: float, within_550: float, speckle_550: float, grains: int
) -> CountModel:
    """The :class:`CountModel` for the grains' places' deviation ``spread_550`` (σ_μ), one grain's
    ``within_550`` (s_w) and the grains' deviation about their block's tilt ``speckle_550`` (p),
    slopes at 550 nm, and ``grains`` (G) per block.

    The counts must vary from cell to cell as the sum over the cell's blocks does. For a sum of
    Gaussian grains of deviation s_w at density ρ(x) the variance at x is
    ``E[w²] ρ(x) / (2√π s_w)`` per grain (Campbell's theorem); a block's G grains share its tilt,
    so per block it is ``ρ(x) / (2√π s_w) · c`` with
    ``c = Σ_k E[w_k²] + Σ_{k≠l} E[w_k w_l] s_w / √(s_w² + p²)
    = 2/(G + 1) + (G − 1)/(G + 1) · s_w/√(s_w² + p²)`` (Dirichlet(1, …, 1) shares: E[w_k²] =
    2/(G(G + 1)), E[w_k w_l] = 1/(G(G + 1)); two grains of a block lie a normal of variance 2p²
    apart). Counting in bins of width Δ blended by the posterior weights (:data:`COUNT_BINS` of
    them, the outer two taking the tails) gives
    ``Σ_b ω_b² / (M Δ ρ)``, which is ``1 / (2√π r M ρ)`` times ``f``, the mean of ``Σ_b ω_b²``
    over where the grain falls in its bin divided by its continuum value ``Δ/(2√π r)``. So a block
    counts as ``f / c`` independent, equal grains."""
    r = within_550 / math.hypot(spread_550, within_550)
    width = 2.0 * r
    c = 2.0 / (grains + 1) + (grains - 1) / (grains + 1) * within_550 / math.hypot(
        within_550, speckle_550
    )
    offsets = (NUMPY.asarray(range(200)) + 0.5) / 200.0  # the posterior's place in its bin
    # the inner edges of the COUNT_BINS bins about it, in bins; the outer bins take the tails
    edges = NUMPY.asarray(range(1 - COUNT_BINS // 2, COUNT_BINS // 2 + 1))[:, None] - offsets
    mass = normal_cdf(edges * (width / r))
    zero, one = 0.0 * offsets[None, :], 1.0 + 0.0 * offsets[None, :]
    cumulative = NUMPY.asarray([*zero, *mass, *one])
    omega2 = ((cumulative[1:] - cumulative[:-1]) ** 2).sum(axis=0).mean()
    f = float(omega2 / (width / (2.0 * math.sqrt(math.pi) * r)))
    return CountModel(width, f / c)


def footprint_level(area_um2: Any, block_length_um: float, barbule_width_um: float, ops=NUMPY):
    """Level of detail ``½ log₂(n)`` of a footprint of ``area_um2`` (µm²) holding ``n`` blocks:
    a cell of level ℓ is 2^ℓ blocks along by 2^ℓ barbules across; ≤ 0 is one block. An unknown
    footprint (area 0: no ray differentials) gives a level far below 0."""
    n = ops.maximum(area_um2, 1e-20) / (block_length_um * barbule_width_um)
    return (0.5 / LN2) * ops.log(n)


def irwin_hall(h: Any, ops: Any = NUMPY) -> Any:
    """A normal deviate (mean 0, variance 1 up to 2·10⁻⁵, |z| ≤ √12) from the four bytes of the
    32-bit hash ``h``: ``(Σ u_i − 2) √3`` for the four uniforms ``u_i = (byte_i + ½)/256``."""
    total = 0.0
    for k in range(4):
        total = total + ops.to_float((h >> (8 * k)) & 0xFF)
    return ((total + 2.0) * (1.0 / 256.0) - 2.0) * SQRT3


def count_ratio(mean: Any, u: Any, z: Any, ops: Any = NUMPY) -> Any:
    """``X = N / mean`` for a count ``N`` with expectation ``mean``: Poisson by inversion of the
    uniform ``u`` below :data:`POISSON_SWITCH`, else ``mean + √mean z`` (``z``: :func:`irwin_hall`,
    never below −√12, so never negative here), ``E[X] = 1`` in both; ``X = 1`` below
    :data:`TINY_MEAN`."""
    m = ops.maximum(mean, TINY_MEAN)
    p = ops.exp(-m)
    cdf = p
    n = 0.0
    for k in range(1, POISSON_TERMS + 1):
        n = n + ops.select(u > cdf, 1.0, 0.0)
        p = p * m * (1.0 / k)
        cdf = cdf + p
    ratio = ops.select(m < POISSON_SWITCH, n / m, 1.0 + z / ops.sqrt(m))
    return ops.select(mean < TINY_MEAN, 1.0, ratio)


class CellCounts(NamedTuple):
    """The cell under a point at one level: its share of the point's lobe (0 or 1, the level
    chosen per block: :func:`footprint_at`) and its gain ``Σ_b ω_b X_b`` over the smooth lobe."""

    weight: Any
    gain: Any


def cell_counts(
    model: CountModel,
    level: Any,
    weight: Any,
    along_um: Any,
    across_um: Any,
    block_length_um: float,
    barbule_width_um: float,
    seed: Any,
    slope_x: Any,
    spread: Any,
    total: Any,
    ops: Any = NUMPY,
) -> CellCounts:
    """The counts of the level-``level`` cell holding the point (``along_um``, ``across_um``) in
    the :data:`COUNT_BINS` bins around the half-vector's slope ``slope_x`` along the barbule,
    blended by the posterior weights of a grain's place at 550 nm (``spread`` σ_μ, ``total``
    σ_t; the outermost bins take the tails, so the weights sum to 1 and the cell's lobe averages
    to the smooth one at every wavelength). Counts are of integers only (cell, level, bin, seed):
    the same on every process and sample split."""
    side = ops.floor(ops.exp(level * LN2) + 0.5)  # 2^level, exactly
    cell_along = ops.to_uint32(ops.floor(along_um / (block_length_um * side)))
    cell_across = ops.to_uint32(ops.floor(across_um / (barbule_width_um * side)))
    total2 = total * total
    u_star = slope_x * (spread / total2)
    inv_r = total / ops.sqrt(ops.maximum(total2 - spread * spread, 1e-20))
    first = ops.floor(u_star / model.bin_width) - (COUNT_BINS // 2)
    grains = model.grains_per_block * side * side
    level_salt = lowbias32(seed ^ ((ops.to_uint32(level) * 0x632BE5AB) & MASK32))
    gain = 0.0
    lower_place = normal_cdf(first * model.bin_width, ops)
    lower_weight = 0.0
    for j in range(COUNT_BINS):
        edge = (first + (j + 1)) * model.bin_width
        upper_place = normal_cdf(edge, ops)
        upper_weight = 1.0 if j == COUNT_BINS - 1 else normal_cdf((edge - u_star) * inv_r, ops)
        bin_salt = lowbias32(level_salt ^ ((ops.to_uint32(first + j) * 0x9E3779B1) & MASK32))
        h1 = block_hash(cell_across, cell_along, bin_salt)
        u = (ops.to_float(h1) + 0.5) * (1.0 / 4294967296.0)
        z = irwin_hall(lowbias32(h1 ^ 0x68E31DA4), ops)
        ratio = count_ratio(grains * (upper_place - lower_place), u, z, ops)
        gain = gain + (upper_weight - lower_weight) * ratio
        lower_place, lower_weight = upper_place, upper_weight
    return CellCounts(weight, gain)


class Footprint(NamedTuple):
    """What a pixel's footprint holds at a point: its block (weight ``block_weight``) or the cell
    of the chosen level (:class:`CellCounts`), the weights summing to 1."""

    block: Block
    block_weight: Any
    cells: tuple[CellCounts, ...]


def level_choice(
    level: Any,
    along_um: Any,
    across_um: Any,
    block_length_um: float,
    barbule_width_um: float,
    seed: Any,
    ops: Any = NUMPY,
) -> tuple[Any, Any]:
    """``(chosen, is_block)``: the whole level a point's block takes for a continuous level ℓ,
    k ≤ ℓ < k + 1: k + 1 with probability ℓ − k, else k (level 0 is the block itself,
    ``is_block``), drawn from a hash of the block's integer place, so over the blocks of a cell
    the lobe is the linear blend of the two levels (as Zirr & Kaplanyan 2016 blend their levels
    of detail) at the cost of one level, and a block keeps its choice while ℓ moves a little."""
    clamped = ops.minimum(ops.maximum(level, 0.0), MAX_LEVEL - 1e-3)
    k = ops.floor(clamped)
    barbule_index, block_index = block_cell(
        along_um, across_um, block_length_um, barbule_width_um, ops
    )
    h = block_hash(barbule_index, block_index, lowbias32(seed ^ 0x3C6EF372))
    u = (ops.to_float(h) + 0.5) * (1.0 / 4294967296.0)
    chosen = ops.select(u < clamped - k, k + 1.0, k)
    return chosen, chosen < 0.5


def footprint_block_weight(
    level, along_um, across_um, block_length_um, barbule_width_um, seed, ops: Any = NUMPY
) -> Any:
    """1 where the point's block is its own lobe (:func:`level_choice`), else 0."""
    _, is_block = level_choice(
        level, along_um, across_um, block_length_um, barbule_width_um, seed, ops
    )
    return ops.select(is_block, 1.0, 0.0)


def footprint_ndf(
    hx: Any,
    hy: Any,
    hz: Any,
    alpha_x: Any,
    alpha_y: Any,
    within: Any,
    speckle: Any,
    constants: Any,
    footprint: Footprint,
    ops: Any = NUMPY,
) -> Any:
    """The normal distribution a footprint holds at one wavelength: its block's
    (:func:`block_ndf`, weight ``block_weight``) plus the smooth Beckmann lobe (``alpha_x`` =
    √2 tan σ_along) times the cell's gain. ``within`` and ``speckle`` are :func:`speckle_split`'s
    at this wavelength (``constants``: the material's, unused but for the signature's sake)."""
    d_block = block_ndf(hx, hy, hz, barbule.SQRT2 * within, alpha_y, footprint.block, speckle, ops)
    smooth = barbule.beckmann_ndf(hx, hy, hz, alpha_x, alpha_y, ops)
    gain = 0.0
    for cell in footprint.cells:
        gain = gain + cell.weight * cell.gain
    return footprint.block_weight * d_block + smooth * gain


def footprint_at(
    block: Block,
    level: Any,
    along_um: Any,
    across_um: Any,
    seed: Any,
    slope_x: Any,
    model: CountModel,
    spread: Any,
    total: Any,
    block_length_um: float,
    barbule_width_um: float,
    ops: Any = NUMPY,
) -> Footprint:
    """The :class:`Footprint` of level ``level`` (:func:`footprint_level`) at a point of the
    block grid (``along_um``, ``across_um``, its ``block``), for the half-vector's slope
    ``slope_x`` along the barbule (``spread``, ``total``: σ_μ and σ_t at 550 nm)."""
    chosen, is_block = level_choice(
        level, along_um, across_um, block_length_um, barbule_width_um, seed, ops
    )
    block_weight = ops.select(is_block, 1.0, 0.0)
    cell = cell_counts(
        model,
        ops.maximum(chosen, 1.0),
        1.0 - block_weight,
        along_um,
        across_um,
        block_length_um,
        barbule_width_um,
        seed,
        slope_x,
        spread,
        total,
        ops,
    )
    return Footprint(block, block_weight, (cell,))
