"""Render-time benchmark of the feather BSDF on the shipped eye-feather scene.

1. 512×512 at 64 spp twice in one process: with the feather BSDF, then with Mitsuba's
   ``roughconductor`` substituted for the feather BSDF inside the same alpha mask and bump map;
   prints the ratio (target ≤ 1.25).
2. 1024×1024 at 256 spp with the feather BSDF; prints seconds (target ≤ 60 s on 2 cores).

Each configuration is rendered once to warm the JIT kernel cache, then timed (best of 3 at
512×512; the machine is shared, so single timings scatter).
Usage: python benchmarks/bench_render.py [--quick]
"""

from __future__ import annotations

import argparse
import dataclasses
import time
import warnings
from contextlib import contextmanager
from pathlib import Path

from pavonine.render.api import render_stage
from pavonine.render.diagnostics import StageWarning
from pavonine.render.feather_bsdf import PLUGIN_NAME
from pavonine.render.shading import feather

SCENE = Path(__file__).parents[1] / "assets" / "scenes" / "eye_feather_sun.usda"


def _swap_innermost(bsdf: dict, replacement: dict) -> dict:
    """``bsdf`` with its innermost ``pavonine_feather`` node replaced (``mask``/``bumpmap`` kept)."""
    if bsdf.get("type") == PLUGIN_NAME:
        return replacement
    return {
        k: _swap_innermost(v, replacement) if isinstance(v, dict) else v for k, v in bsdf.items()
    }


@contextmanager
def roughconductor_instead_of_feather():
    """Substitute Mitsuba's ``roughconductor`` (gold, α = 0.2, two-sided) for the feather BSDF.

    Only the feather BSDF itself is swapped: the alpha ``mask`` and the displacement ``bumpmap``
    around it stay, so the ratio measures the BSDF and nothing else.
    """
    original = feather.feather_material
    conductor = {
        "type": "twosided",
        "bsdf": {"type": "roughconductor", "material": "Au", "alpha": 0.2},
    }

    def substitute(material, time_code, diag):
        spec = original(material, time_code, diag)
        return dataclasses.replace(
            spec, key=spec.key + "#roughconductor", bsdf=_swap_innermost(spec.bsdf, conductor)
        )

    feather.feather_material = substitute
    try:
        yield
    finally:
        feather.feather_material = original


def timed(resolution: tuple[int, int], spp: int, repeats: int = 3) -> float:
    """Best of ``repeats`` renders (seconds), after one warm-up that compiles the kernels."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", StageWarning)
        render_stage(SCENE, spp=min(spp, 4), resolution=resolution, progress=False)  # warm-up
        best = float("inf")
        for _ in range(repeats):
            start = time.perf_counter()
            render_stage(SCENE, spp=spp, resolution=resolution, progress=False)
            best = min(best, time.perf_counter() - start)
        return best


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
        big = timed((1024, 1024), 256, repeats=1)
        print(f"1024x1024 @ 256 spp: feather {big:.1f} s (target <= 60 s)")


if __name__ == "__main__":
    main()
