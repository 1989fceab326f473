"""Benchmark the NumPy meshing fallback against pymeshlab (the yardstick), in the same run.

Converts the shipped eye feather (``assets/recipes/eye_feather.toml``) once with each backend
(``PAVONINE_MESHING``) and prints, per backend: the convert time, its ``mesh`` (clean-up) and
``lods`` (decimation) stages, the triangles per LOD, and how far the decimated vanes are from
the high LOD (the distance, at every high-LOD vertex, to the LOD's surface at the same feather
coordinate). Ratios are NumPy / pymeshlab.

    python benchmarks/bench_meshing.py [--repeat 2]
"""

from __future__ import annotations

import argparse
import os
import shutil
import tempfile
import time
from pathlib import Path

import numpy as np

BACKENDS = ("pymeshlab", "numpy")


def deviation(high, lod) -> tuple[float, float]:
    """RMS and largest distance (cm) from ``high``'s vertices to ``lod``'s surface at the same
    feather coordinate (``lod``'s triangles located in feather space)."""
    from matplotlib.tri import Triangulation

    finder = Triangulation(lod.feather_uv[:, 0], lod.feather_uv[:, 1], lod.faces).get_trifinder()
    uv = high.feather_uv
    face = finder(uv[:, 0], uv[:, 1])
    inside = face >= 0
    corners = lod.faces[face[inside]]
    a, b, c = (lod.feather_uv[corners[:, k]] for k in range(3))
    weights = np.linalg.solve(np.stack([b - a, c - a], axis=2), (uv[inside] - a)[..., None])[..., 0]
    bary = np.column_stack([1.0 - weights.sum(axis=1), weights])
    surface = np.einsum("nk,nkd->nd", bary, lod.points[corners])
    distance = np.linalg.norm(surface - high.points[inside], axis=1)
    return float(np.sqrt(np.mean(distance**2))), float(distance.max())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=2, help="conversions per backend (best)")
    args = parser.parse_args()

    from rich.console import Console
    from rich.table import Table

    from pavonine.base.shipped import assets_dir
    from pavonine.pipeline.convert import meshing
    from pavonine.pipeline.convert.batch import convert_recipe

    recipe = assets_dir() / "recipes" / "eye_feather.toml"
    work = Path(tempfile.mkdtemp(prefix="pavonine-bench-"))
    best: dict[str, dict[str, float]] = {}
    results = {}
    try:
        for _ in range(args.repeat):
            for name in BACKENDS:  # interleaved, so both see the same load
                os.environ[meshing.MESHING_ENV] = name
                meshing.meshing_backend.cache_clear()
                start = time.perf_counter()
                result = convert_recipe(recipe, work / name, force=True, keep_meshes=True)
                seconds = dict(result.seconds, total=time.perf_counter() - start)
                keep = best.setdefault(name, seconds)
                for stage, value in seconds.items():
                    keep[stage] = min(keep[stage], value)
                results[name] = result
    finally:
        os.environ.pop(meshing.MESHING_ENV, None)
        meshing.meshing_backend.cache_clear()
        shutil.rmtree(work, ignore_errors=True)

    console = Console()
    table = Table(title=f"eye feather: meshing backends (best of {args.repeat})")
    table.add_column("")
    for name in BACKENDS:
        table.add_column(name, justify="right")
    table.add_column("ratio", justify="right")
    for stage in ("total", "mesh", "lods"):
        a, b = best["pymeshlab"][stage], best["numpy"][stage]
        table.add_row(f"{stage} (s)", f"{a:.2f}", f"{b:.2f}", f"{b / a:.2f}")
    for lod in ("high", "medium", "low"):
        a, b = results["pymeshlab"].triangles[lod], results["numpy"].triangles[lod]
        table.add_row(f"{lod} triangles", f"{a:,}", f"{b:,}", "")
    high = {name: results[name].meshes["high"][0] for name in BACKENDS}
    for lod in ("medium", "low"):
        cells = []
        for name in BACKENDS:
            rms, worst = deviation(high[name], results[name].meshes[lod][0])
            cells.append(f"{rms * 1e4:.1f} / {worst * 1e4:.1f}")
        table.add_row(f"{lod} vane from high, RMS / max (µm)", *cells, "")
    console.print(table)
    same = np.array_equal(high["pymeshlab"].points, high["numpy"].points)
    console.print(f"high LOD (refined, not decimated) identical with both: {same}")


if __name__ == "__main__":
    main()
