"""The exported ``.glb`` in three.js against ``pavonine render``, per ocellus zone, for any feather
asset: what tests/pipeline/test_gltf_threejs.py asserts on the 256-px test eye, here on the shipped eye
by default (1024² textures, 99k triangles) and at any resolution (by default the scene's own,
512×768). It exports the asset, renders the shipped scene (assets/scenes/eye_feather_sun.usda:
its camera, sun and sky) face-on and turned 40°, draws the ``.glb`` with three.js 0.187 in
headless Chromium (software WebGL; needs ``.ci/node_modules``, installed by ``.ci/setup``) and
prints ΔE2000 of each zone's mean colour; the side-by-side frames go to ``--out``.
``--fit-eye scene`` (the default) exports the look fitted for the scene's camera
(``pavonine export --eye``), as the test does; ``framing`` for the export's default viewer
(where ``pavonine view`` frames the asset).

    python benchmarks/gltf_threejs.py [--asset assets/feathers/eye_feather] [--resolution 512x768]
        [--fit-eye scene|framing]
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "tests"))

from gltf_browser import compare_zones, scene_eye  # noqa: E402
from ocellus_zones import ZONE_NAMES  # noqa: E402


def main() -> None:
    from pavonine.pipeline.export.iridescence import TILT_DEG

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--asset", type=Path, default=REPO / "assets/feathers/eye_feather")
    parser.add_argument(
        "--resolution", default="512x768", help="WIDTHxHEIGHT [default: the scene's own]"
    )
    parser.add_argument("--spp", type=int, default=32)
    parser.add_argument("--out", type=Path, default=None, help="folder for the frames")
    parser.add_argument("--fit-eye", choices=("scene", "framing"), default="scene")
    args = parser.parse_args()
    resolution = tuple(int(v) for v in args.resolution.split("x"))
    out = args.out or Path(tempfile.mkdtemp(prefix="pavonine-gltf-threejs-"))
    out.mkdir(parents=True, exist_ok=True)
    asset = args.asset.resolve()
    glb = out / f"{asset.name}.glb"
    start = time.perf_counter()
    command = [sys.executable, "-m", "pavonine.apps.cli", "export", str(asset), "-o", str(glb)]
    if args.fit_eye == "scene":
        command += ["--eye", *(str(v) for v in scene_eye())]
    subprocess.run([*command, "-q"], check=True)
    print(f"export: {time.perf_counter() - start:.1f} s wall")
    rows = {}
    for tilt in (0.0, TILT_DEG):
        found = compare_zones(glb, asset / f"{asset.name}.usd", tilt, out, resolution, args.spp)
        rows[tilt] = found
    zones = [k for k in (5, 4, 3, 2, 1) if all(k in r.delta_e for r in rows.values())]
    print(
        f"{args.resolution}, {args.spp} spp, look fitted for the {args.fit_eye} eye: ΔE2000 per zone"
    )
    print(f"{'zone':>16}  " + "  ".join(f"{t:+.0f}°".rjust(7) for t in rows))
    for k in zones:
        cells = "  ".join(f"{r.delta_e[k]:7.2f}" for r in rows.values())
        print(f"{ZONE_NAMES[k]:>16}  {cells}")
    worst = max(r.delta_e[k] for r in rows.values() for k in zones)
    print(f"worst zone: {worst:.2f} (the issue's bound: 5); frames in {out}")


if __name__ == "__main__":
    main()
