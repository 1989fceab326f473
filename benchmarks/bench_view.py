"""``pavonine view``'s frame time: the page drawing the shipped eye at 1280×720 in headless
Chromium with software WebGL (SwiftShader), milliseconds per frame: the median of ``--frames``
frames after two of warm-up, each drawn and read back (``window.pavonine.benchmark``).

Yardstick, measured in the same run and page: the same meshes drawn in one unlit colour
(``MeshBasicMaterial``: the rasterisation every viewer pays). Prints both and their ratio, for
the face-on and the tilted view. Target: ≤ 200 ms a frame for the eye feather (interactive).

    python benchmarks/bench_view.py [--stage assets/scenes/eye_feather_sun.usda] [--frames 10]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "tests"))

from browser import Browser, start_view, stop  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--stage", default=str(REPO / "assets/scenes/eye_feather_sun.usda"))
    parser.add_argument("--frames", type=int, default=10)
    parser.add_argument("--size", default="1280x720")
    args = parser.parse_args()
    width, height = (int(v) for v in args.size.split("x"))
    process, url = start_view(args.stage)
    try:
        with Browser(f"{url}?hud=0", width, height) as browser:
            browser.wait_for("window.pavonine !== undefined")
            browser.evaluate("window.pavonine.ready")
            for view, turn in (("face-on", 0.0), ("tilted 40°", 40.0)):
                browser.evaluate(
                    f"(() => {{ const p = window.pavonine; return p.orbit({turn}); }})()"
                )
                feather = browser.evaluate(f"window.pavonine.benchmark({args.frames})")
                flat = browser.evaluate(f"window.pavonine.benchmark({args.frames}, true)")
                print(
                    f"{view:<11} {width}x{height}: feather {feather:7.1f} ms/frame, "
                    f"flat yardstick {flat:7.1f} ms/frame, ratio {feather / flat:5.2f}"
                )
    finally:
        stop(process)


if __name__ == "__main__":
    main()
