"""Issue 33's measures of the barbs at full size (tests/barb_measures.py defines them).

1. **Eye 3 cm across** (tests/glint_scene.py's close-up: the camera 3 cm above the boundary of the
   heart and its first ring, ``--eye-res`` pixels, 117 µm a pixel at 256): the local contrast of
   barbs and sheet, glitter 0 and 1, same camera, spp and seed; their ratio (target >= 1.5x).
2. **Hero view** (assets/scenes/eye_feather_sun.usda, 512x768): the share of the lower vane's
   outline where the barbs show the background in whole pixels (target >= 25 %).

Usage: python benchmarks/bench_barbs_eye.py [--spp 32] [--eye-res 256] [--window 16] [--out DIR]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parents[1] / "tests"))
from barb_measures import (
    HERO_RESOLUTION,
    hero_stage,
    local_contrast,
    lower_vane_outline,
    radial_line_contrast,
    render_color_alpha,
    whole_pixel_share,
)
from glint_scene import TARGET, closeup_stage


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--spp", type=int, default=32)
    parser.add_argument("--hero-spp", type=int, default=16, help="alpha only: few suffice")
    parser.add_argument("--eye-res", type=int, default=256)
    parser.add_argument("--eye-cm", type=float, default=3.0, help="the eye view's width")
    parser.add_argument("--window", type=int, default=16, help="contrast window, pixels")
    parser.add_argument("--skip-hero", action="store_true")
    parser.add_argument("--out", type=Path, default=None, help="keep the PNGs here")
    args = parser.parse_args()
    from pavonine.render.imageio import write_png

    with tempfile.TemporaryDirectory(prefix="bench-barbs-eye-") as tmp:
        folder = Path(tmp)
        out = args.out or folder
        out.mkdir(parents=True, exist_ok=True)
        for glitter in (0.0, 1.0):
            images = {}
            for geometry in ("sheet", "barbs"):
                path = closeup_stage(
                    folder / f"eye_{geometry}_{glitter:g}.usda",
                    glitter,
                    field_mm=10.0 * args.eye_cm,
                    resolution=args.eye_res,
                    geometry=geometry,
                )
                images[geometry] = [render_color_alpha(path, args.spp, seed) for seed in (0, 1)]
                name = f"eye_{args.eye_cm:g}cm_{geometry}_glitter{glitter:g}.png"
                write_png(out / name, images[geometry][0][0])
                if args.out is not None:  # both seeds' colour and alpha, to measure again
                    (rgb0, alpha0), (rgb1, _) = images[geometry]
                    np.savez(
                        out / name.replace(".png", ".npz"), rgb0=rgb0, rgb1=rgb1, alpha0=alpha0
                    )
            # The same windows for both: wholly on the sheet (its alpha map's outline).
            on_feather = images["sheet"][0][1] > 0.99
            (cs, n), (cb, _) = (
                local_contrast((images[g][0][0], images[g][1][0]), on_feather, args.window)
                for g in ("sheet", "barbs")
            )
            print(
                f"eye {args.eye_cm:g} cm, {args.eye_res} px, {args.spp} spp, glitter {glitter:g}: "
                f"local contrast sheet {cs:.3f}, barbs {cb:.3f} ({n} windows of {args.window} px)"
                f", ratio {cb / cs:.2f}x (target >= 1.5x)"
            )
            rs, rb = (
                radial_line_contrast(
                    (images[g][0][0], images[g][1][0]), on_feather, TARGET[:2], args.eye_cm
                )
                for g in ("sheet", "barbs")
            )
            print(
                f"    radial lines (1-2 cm from the tip): sheet {rs:.4f}, barbs {rb:.4f}, "
                f"ratio {rb / rs:.2f}x"
            )
        if not args.skip_hero:
            width, height = HERO_RESOLUTION
            outline = lower_vane_outline(hero_stage(folder, "sheet", sky=False), width, height)
            rgb, alpha = render_color_alpha(hero_stage(folder, "barbs", sky=False), args.hero_spp)
            write_png(out / "hero_barbs.png", rgb)
            share = whole_pixel_share(alpha, outline)
            mean_alpha = float(np.mean(alpha[outline]))
            print(
                f"hero {width}x{height}, {args.hero_spp} spp: the lower vane's outline "
                f"({int(outline.sum())} px) shows the background in whole pixels on {share:.1%} "
                f"(target >= 25 %); its mean film alpha {mean_alpha:.3f}"
            )


if __name__ == "__main__":
    main()
