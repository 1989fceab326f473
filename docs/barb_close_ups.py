"""Draw docs/images/barb_close_ups.png: the shipped eye feather's barbs 1 cm and 4 mm across, on the
vane and at the edge of the heart and the blue-green ring, in the README hero's sun:

    .venv/bin/python docs/barb_close_ups.py [--size 320] [--spp 64]

The views are ``tests/barbule_views.py``'s (the barbule tests' close-ups: a 50 mm lens looking
straight down the feather's normal at a point found on the asset's own barbs), so the figure
shows what those tests measure. Each panel is rendered with ``geometry = barbs`` and written
through the current display transform; the labels give the field and the place.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

ROOT = Path(__file__).resolve().parents[1]
IMAGES = Path(__file__).parent / "images"
VIEWS = (("vane", 1.0), ("vane", 0.4), ("heart_edge", 1.0), ("heart_edge", 0.4))
LABELS = {"vane": "vane", "heart_edge": "heart | blue-green ring"}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, default=320, help="pixels of each square panel")
    parser.add_argument("--spp", type=int, default=64)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    sys.path.insert(0, str(ROOT / "tests"))
    import barbule_views

    from pavonine.render.imageio import write_png

    places = barbule_views.targets()
    panels = []
    with tempfile.TemporaryDirectory() as scratch:
        folder = Path(scratch)
        for place, field_cm in VIEWS:
            name = f"{place}_{field_cm:g}cm"
            stage = barbule_views.close_up(folder, name, places[place], field_cm, args.size)
            rgb = barbule_views.render(stage, args.spp, args.seed)
            png = folder / f"{name}.png"
            write_png(png, rgb)
            panel = Image.open(png).convert("RGB")
            field = f"{field_cm * 10:g} mm" if field_cm < 1 else f"{field_cm:g} cm"
            ImageDraw.Draw(panel).text((6, 4), f"{LABELS[place]}, {field} across", fill="white")
            panels.append(np.asarray(panel))
            print(f"{name}: mean linear luminance {barbule_views.luminance(rgb).mean():.4f}")
    rows = [np.concatenate(panels[i : i + 2], axis=1) for i in (0, 2)]
    out = IMAGES / "barb_close_ups.png"
    Image.fromarray(np.concatenate(rows, axis=0)).save(out)
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
