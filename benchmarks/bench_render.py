"""Render-time benchmark of the feather BSDF on the shipped eye-feather scene.

1. 512×512 at 64 spp twice in one process: with the feather BSDF, then with Mitsuba's
   ``roughconductor`` substituted for every feather material; prints the ratio (target ≤ 1.25).
2. 1024×1024 at 256 spp with the feather BSDF; prints seconds (target ≤ 60 s on 2 cores).

Each configuration is rendered once to warm the JIT kernel cache, then timed.
Usage: python benchmarks/bench_render.py [--quick]
"""

from __future__ import annotations

import argparse
import time
import warnings
from contextlib import contextmanager
from pathlib import Path

from pavonine.render import materials
from pavonine.render.api import render_stage
from pavonine.render.diagnostics import StageWarning

SCENE = Path(__file__).parents[1] / "assets" / "scenes" / "eye_feather_sun.usda"


@contextmanager
def roughconductor_instead_of_feather():
    """Substitute Mitsuba's ``roughconductor`` (gold, α = 0.2) for every feather material."""
    original = materials.feather_bsdf

    def substitute(material, time_code, diag):
        return materials.MaterialSpec(
            str(material.GetPath()) + "#roughconductor",
            {
                "type": "twosided",
                "bsdf": {"type": "roughconductor", "material": "Au", "alpha": 0.2},
            },
            materials.FEATHER_UV,
            two_sided=True,
        )

    materials.feather_bsdf = substitute
    try:
        yield
    finally:
        materials.feather_bsdf = original


def timed(resolution: tuple[int, int], spp: int) -> float:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", StageWarning)
        render_stage(SCENE, spp=min(spp, 4), resolution=resolution, progress=False)  # warm-up
        start = time.perf_counter()
        render_stage(SCENE, spp=spp, resolution=resolution, progress=False)
        return time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="skip the 1024×1024 × 256 spp render")
    args = parser.parse_args()
    feather = timed((512, 512), 64)
    with roughconductor_instead_of_feather():
        conductor = timed((512, 512), 64)
    print(
        f"512x512 @ 64 spp: feather {feather:.2f} s, roughconductor {conductor:.2f} s, "
        f"ratio {feather / conductor:.2f} (target <= 1.25)"
    )
    if not args.quick:
        big = timed((1024, 1024), 256)
        print(f"1024x1024 @ 256 spp: feather {big:.1f} s (target <= 60 s)")


if __name__ == "__main__":
    main()
