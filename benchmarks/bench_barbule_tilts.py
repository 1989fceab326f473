"""What if a barbule's blocks shared part of their tilt? (issue 34, the 3 cm sparkle item)

The glitter model (``pavonine.materials.glitter``) draws every 25 µm block's tilt along the
barbule independently, ``σ_block`` = 8°. The proposal weighed here: part of that spread is the
barbule's own (its attachment angle and twist, shared by all its blocks), the rest per block,

    z = √s · z_barbule + √(1 − s) · z_block,     z_barbule, z_block ~ N(0, 1) (hashes)

so a block's tilt is still ``√g tan σ_block · z`` with ``z ~ N(0, 1)``: the average over blocks
(the smooth lobe) is unchanged for every share ``s``, only the correlation between the blocks of
one barbule (``s``) is new. A barbule is a row of ``--segment`` blocks (24: 600 µm; a 3 cm
pixel, 117 µm, lies within one).

1. **Explicit pixel sums** (NumPy, the independent method of
   ``tests/materials/test_glitter_footprint.py``): a square pixel of ``--pixel`` µm at a random
   place on the block grid holds the area-weighted mean of its blocks' lobes
   (:func:`glitter.block_ndf`, each block's tilt and speckle grains from
   :func:`glitter.block_state`), at 550 nm, at the lobe's peak and 1 σ and 2 σ out along the
   barbule: mean over the smooth lobe's, deviation / mean and p99.9/median over pixels.
2. ``--render``: the 3 cm close-up of ``bench_glints.py`` (the eye in the sun, 256 px) with one
   block per sample (the footprint's level forced below 0, so each pixel converges to the explicit
   sum of the blocks it holds, at the cost of Monte Carlo noise), per share, against glitter 0
   and the counting model (as shipped) at the same samples: p99.9/median luminance; with
   ``--level-shifts``, the counting model again with cells 4^shift times smaller than the
   footprint (its level lowered by ``shift``).

Usage: python benchmarks/bench_barbule_tilts.py [--shares 0,0.5,0.7,0.9,1] [--render --spp 256]
[--level-shifts 1,2]
"""

from __future__ import annotations

import argparse
import math
import sys
import tempfile
from pathlib import Path

import numpy as np

from pavonine.materials import barbule, glitter
from pavonine.materials.brdf import MaterialConstants
from pavonine.materials.parameters import preset

TABLE1 = preset("paper-table1").with_(glitter=1.0, glitter_seed=3)
CONSTANTS = MaterialConstants.from_parameters(TABLE1)
LAMBDA = 550.0
BARBULE_SALT = 0x5BD1E995


def correlated(block_state, share: float, segment: int):
    """``block_state`` with the tilt's deviate ``√s z_barbule + √(1 − s) z_block``: the barbule's
    ``z_barbule`` a hash of (barbule, block // segment, seed), the same for its blocks."""

    def state(g, sigma, barbule_index, block_index, seed, grains, ops=glitter.NUMPY):
        block = block_state(g, sigma, barbule_index, block_index, seed, grains, ops)
        if share == 0.0:
            return block
        run = ops.to_uint32(ops.floor(ops.to_float(block_index) * (1.0 / segment)))
        z = glitter.block_normal(barbule_index, run, glitter.lowbias32(seed ^ BARBULE_SALT), ops)
        shared = math.sqrt(share) * math.sqrt(g) * math.tan(sigma) * z
        return block._replace(tilt=shared + math.sqrt(1.0 - share) * block.tilt)

    return state


def lobe():
    """``(within s_w, speckle p, total tan σ_along, alpha_y)`` at 550 nm (slopes)."""
    along = barbule.along_sigma(CONSTANTS.block_sigma, CONSTANTS.rod_length_nm, LAMBDA)
    speckle, within = glitter.grain_split(CONSTANTS, 1.0, along, LAMBDA)
    alpha_y = barbule.SQRT2 * math.tan(CONSTANTS.crescent_sigma)
    return float(within), float(speckle), math.tan(along), alpha_y


def overlap(start: np.ndarray, index: np.ndarray, size: float, pixel: float) -> np.ndarray:
    """Length (µm) of ``[start, start + pixel]`` inside cell ``index`` of width ``size``."""
    lo = np.maximum(start, index * size)
    hi = np.minimum(start + pixel, (index + 1) * size)
    return np.maximum(hi - lo, 0.0)


def pixel_lobes(state, slope: float, pixel: float, count: int, seed: int = 11) -> np.ndarray:
    """Each of ``count`` pixels' lobe at the half-vector of slope ``slope`` along the barbule
    (0.05 across): the mean of its blocks' :func:`glitter.block_ndf`, weighted by their area in
    the pixel."""
    within, speckle, _, alpha_y = lobe()
    length, width = TABLE1.block_length_um, TABLE1.barbule_width_um
    grains = glitter.grain_count(TABLE1.block_length_um, TABLE1.rod_length_um)
    rng = np.random.default_rng(0)
    x0, y0 = rng.uniform(0.0, 1e5, size=(2, count))
    first_block, first_barbule = np.floor(x0 / length), np.floor(y0 / width)
    h = np.array([-slope, -0.05, 1.0]) / math.hypot(slope, 0.05, 1.0)
    total, weights = np.zeros(count), np.zeros(count)
    for b in range(int(pixel // width) + 2):
        across = overlap(y0, first_barbule + b, width, pixel)
        for a in range(int(pixel // length) + 2):
            area = across * overlap(x0, first_block + a, length, pixel)
            block = state(
                1.0,
                CONSTANTS.block_sigma,
                (first_barbule + b).astype(np.uint64),
                (first_block + a).astype(np.uint64),
                seed,
                grains,
            )
            d = glitter.block_ndf(*h, barbule.SQRT2 * within, alpha_y, block, speckle)
            total, weights = total + area * d, weights + area
    return total / weights


def ratio(values: np.ndarray) -> float:
    return float(np.percentile(values, 99.9) / np.median(values))


def explicit(shares: list[float], segment: int, pixel: float, count: int) -> None:
    _, _, total, alpha_y = lobe()
    print(
        f"explicit sums: {pixel:.0f} um pixels (~{pixel**2 / 500:.0f} blocks), {count} each, "
        "550 nm; mean/smooth, deviation/mean, p99.9/median"
    )
    for share in shares:
        state = correlated(glitter.block_state, share, segment)
        row = []
        for k in (0.0, 1.0, 2.0):
            d = pixel_lobes(state, k * total, pixel, count)
            h = np.array([-k * total, -0.05, 1.0]) / math.hypot(k * total, 0.05, 1.0)
            smooth = barbule.beckmann_ndf(*h, barbule.SQRT2 * total, alpha_y)
            row.append(
                f"{k:.0f} sigma {d.mean() / smooth:.3f} {d.std() / d.mean():.2f} {ratio(d):.1f}"
            )
        print(f"  share {share:.1f}: " + "; ".join(row), flush=True)


def rendered(shares: list[float], shifts: list[float], segment: int, spp: int, seed: int) -> None:
    sys.path.insert(0, str(Path(__file__).parent))
    import bench_glints as bench

    tmp = Path(tempfile.mkdtemp(prefix="bench_barbule_tilts_"))

    def close_up(g: float) -> tuple[float, np.ndarray]:
        rgb, uv = bench.render(bench.closeup(tmp / "c.usda", g, 30.0, 256, sun_deg=25.0), spp, seed)
        feather = bench.zones(uv) >= 0
        return bench.glint_ratio(rgb, feather), feather

    base, _ = close_up(0.0)
    counted, _ = close_up(1.0)
    print(
        f"3 cm close-up, 256 px, {spp} spp, seed {seed}: p99.9/median glitter 0 {base:.2f}; "
        f"glitter 1 counted (as shipped) {counted:.2f} ({counted / base:.2f}x)",
        flush=True,
    )
    original_state, original_level = glitter.block_state, glitter.footprint_level
    try:
        for shift in shifts:
            glitter.footprint_level = lambda *args, d=shift: original_level(*args) - d
            value, _ = close_up(1.0)
            print(
                f"  counted, cells 4^{shift:g} times smaller than the footprint: {value:.2f} "
                f"({value / base:.2f}x glitter 0)",
                flush=True,
            )
    finally:
        glitter.footprint_level = original_level
    glitter.footprint_level = lambda area, *args: 0.0 * area - 100.0  # one block per sample
    try:
        for share in shares:
            glitter.block_state = correlated(original_state, share, segment)
            value, _ = close_up(1.0)
            print(
                f"  one block per sample, barbule share {share:.1f}: {value:.2f} "
                f"({value / base:.2f}x glitter 0)",
                flush=True,
            )
    finally:
        glitter.block_state, glitter.footprint_level = original_state, original_level


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--shares", default="0,0.5,0.7,0.9,1")
    parser.add_argument("--segment", type=int, default=24, help="blocks per barbule")
    parser.add_argument("--pixel", type=float, default=117.0, help="pixel side, um")
    parser.add_argument("--count", type=int, default=20000, help="pixels per explicit sum")
    parser.add_argument("--render", action="store_true")
    parser.add_argument("--level-shifts", default="", help="e.g. 1,2 (with --render)")
    parser.add_argument("--spp", type=int, default=256)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    shares = [float(s) for s in args.shares.split(",") if s]
    shifts = [float(s) for s in args.level_shifts.split(",") if s]
    explicit(shares, args.segment, args.pixel, args.count)
    if args.render:
        rendered(shares, shifts, args.segment, args.spp, args.seed)


if __name__ == "__main__":
    main()
