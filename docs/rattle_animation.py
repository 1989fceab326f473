"""Draw docs/images/peacock_rattle.png (an animated PNG) and peacock_rattle_diff.png from the
frames of the rattle shot:

    pavonine render assets/shots/peacock_rattle.usda -o FOLDER/rattle.exr --png --frames 1-6 \
        --workers 2 --spp 64
    .venv/bin/python docs/rattle_animation.py FOLDER

(64 spp: as many time slices of the shot's shutter, −0.25…0.25 of a frame, as its motion
needs by default: 5, for 4.1–4.4 px of reach.) The frames shown come from
``benchmarks/bench_motion.py --spp 64 -o FOLDER``'s blurred EXRs, written as display PNGs.

The animation: the whole train halved (left, the close-up's box drawn) and the box four times
(right, nearest neighbour: one block a pixel), 2 frames a second. The difference: |frame 2 −
frame 1| summed over the display PNG's RGB, ×2 (the same seed every frame, so the sampling noise
is shared and what differs is what moved).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

IMAGES = Path(__file__).parent / "images"
BOX = (296, 150, 424, 246)  # 128 × 96 pixels of the 512 × 384 frame: the inner rows' eyes


def main(folder: Path) -> None:
    frames = [Image.open(folder / f"rattle.{i:04d}.png").convert("RGB") for i in range(1, 7)]
    sheets = []
    for i, frame in enumerate(frames, start=1):
        sheet = Image.new("RGB", (768, 384), (24, 24, 24))
        small = frame.resize((256, 192), Image.LANCZOS)
        ImageDraw.Draw(small).rectangle(tuple(v // 2 for v in BOX), outline=(255, 255, 255))
        sheet.paste(small, (0, 96))
        sheet.paste(frame.crop(BOX).resize((512, 384), Image.NEAREST), (256, 0))
        draw = ImageDraw.Draw(sheet)
        draw.text((8, 8), f"frame {i}", fill=(255, 255, 255))
        draw.text((8, 24), f"t = {i / 24:.4f} s", fill=(200, 200, 200))
        draw.text((8, 300), "25.6 Hz at 24 fps,", fill=(200, 200, 200))
        draw.text((8, 316), "shutter -0.25..0.25", fill=(200, 200, 200))
        draw.text((8, 332), "frame: motion blur", fill=(200, 200, 200))
        sheets.append(sheet)
    out = IMAGES / "peacock_rattle.png"
    sheets[0].save(out, save_all=True, append_images=sheets[1:], duration=500, loop=0,
                   optimize=True)  # fmt: skip
    a, b = (np.asarray(f, dtype=np.float64) for f in frames[:2])
    diff = np.clip(2.0 * np.abs(b - a).sum(axis=2), 0, 255).astype(np.uint8)
    Image.fromarray(diff).save(IMAGES / "peacock_rattle_diff.png", optimize=True)
    print(out, out.stat().st_size)


if __name__ == "__main__":
    main(Path(sys.argv[1]))
