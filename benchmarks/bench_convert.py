"""Benchmark ``pavonine convert`` on an eye feather with a 1 M-triangle high LOD.

Prints the seconds of each stage (maps, mesh, atlas, refine+displace, lods, bake, write) and
the total, beside the yardstick: the time to merely write the same high-LOD mesh to ``.usdc``.
Target (issue 4): total ≤ 20 s on the project's 2-core machine; the bake (issue 11, 1024²
textures by default) is reported beside it as its ratio to the yardstick.

    python benchmarks/bench_convert.py [--triangles 1000000] [--map-size 2048] [--bake 1024]
"""

from __future__ import annotations

import argparse
import shutil
import tempfile
import time
from pathlib import Path

RECIPE = """\
name = "bench_eye_feather"
[maps]
alpha = "m/alpha.png"
ocellar = "m/ocellar.png"
gradation = "m/gradation.png"
angle = "m/angle.png"
displacement = "m/displacement.png"
melanin = "m/melanin.png"
[material]
preset = "paper-table1"
[geometry]
rachis_length = 0.74
[geometry.lod]
high = {high}
medium = {medium}
low = {low}
[bake]
resolution = {bake}
"""


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--triangles", type=int, default=1_000_000, help="high-LOD target")
    parser.add_argument("--map-size", type=int, default=2048, help="map height in pixels")
    parser.add_argument("--bake", type=int, default=1024, help="baked texture resolution")
    parser.add_argument("--keep", type=Path, help="keep the asset in this folder")
    args = parser.parse_args()

    from rich.console import Console
    from rich.table import Table

    from pavonine.pipeline.convert.asset import write_geometry_layer
    from pavonine.pipeline.convert.batch import convert_recipe
    from pavonine.pipeline.maps.paint import generate_maps, write_maps

    work = Path(tempfile.mkdtemp(prefix="pavonine-bench-"))
    try:
        start = time.perf_counter()
        write_maps(generate_maps("eye", args.map_size, seed=0), work / "m")
        paint = time.perf_counter() - start
        high = args.triangles
        recipe = work / "eye.toml"
        recipe.write_text(
            RECIPE.format(high=high, medium=high // 5, low=high // 25, bake=args.bake)
        )
        outdir = args.keep or (work / "out")
        result = convert_recipe(recipe, outdir, force=True, keep_meshes=True)
        seconds = dict(result.seconds)
        seconds["maps"] += paint  # painting + writing the maps, then reading them back

        # Yardstick: write the same high-LOD meshes to a crate file, nothing else.
        meshes = result.meshes["high"]
        start = time.perf_counter()
        write_geometry_layer(work / "yardstick.usdc", "bench", meshes)
        yardstick = time.perf_counter() - start

        table = Table(title=f"pavonine convert: eye feather, {args.map_size}px maps")
        table.add_column("stage")
        table.add_column("seconds", justify="right")
        for stage in ("maps", "mesh", "atlas", "refine+displace", "lods", "bake", "write"):
            table.add_row(stage, f"{seconds.get(stage, 0.0):.2f}")
        total = sum(seconds.values())
        table.add_row("[bold]total", f"[bold]{total:.2f}")
        table.add_row("yardstick: write high LOD to .usdc", f"{yardstick:.2f}")
        console = Console()
        console.print(table)
        tris = ", ".join(f"{k} {v:,}" for k, v in result.triangles.items())
        console.print(f"triangles: {tris}")
        verdict = "meets" if total <= 20.0 else "MISSES"
        console.print(f"total {total:.2f} s {verdict} the 20 s target")
        bake = seconds.get("bake", 0.0)
        console.print(
            f"bake {bake:.2f} s = {bake / yardstick:.1f}x the yardstick "
            f"({args.bake}x{args.bake} textures)"
        )
    finally:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
