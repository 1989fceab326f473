"""Displacement at render time: tessellation time and memory against the undisplaced render.

Usage::

    python benchmarks/bench_displacement.py [--size 256] [--spp 4] [--target 1.0]

Renders, each in a fresh process (so peak memory is the render's own), a 2×2 quad displaced by a
texture (UsdPreviewSurface ``displacement``, ``render/displacement.py``) seen at 30° from above,
and the same stage with its displacement removed, in the same run. Prints, per render, the wall
time, the tessellation time, triangles before and after, and the peak resident memory; then the
ratios against the undisplaced render and the memory per displaced triangle (the figure behind
``render/displacement.py``'s ``BYTES_PER_TRIANGLE``).
"""

from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path


def write_stage(folder: Path, displaced: bool) -> Path:
    """The benchmark stage: a quad with a texture of random bumps, camera 30° above it."""
    import numpy as np
    import OpenImageIO as oiio
    from pxr import Gf, Sdf, Usd, UsdGeom, UsdLux, UsdShade

    rng = np.random.default_rng(1)
    heights = np.zeros((256, 256), np.float32)
    rows, cols = np.mgrid[0:256, 0:256]
    for r, c, radius in zip(
        rng.uniform(0, 256, 40), rng.uniform(0, 256, 40), rng.uniform(6, 30, 40), strict=False
    ):
        heights = np.maximum(heights, np.clip(1.0 - np.hypot(rows - r, cols - c) / radius, 0, 1))
    file = folder / "bumps.exr"
    oiio.ImageBuf(np.ascontiguousarray(heights[..., None])).write(str(file))
    path = folder / ("displaced.usda" if displaced else "flat.usda")
    stage = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
    mesh = UsdGeom.Mesh.Define(stage, "/Quad")
    mesh.CreatePointsAttr([(-1, 0, -1), (-1, 0, 1), (1, 0, 1), (1, 0, -1)])
    mesh.CreateFaceVertexCountsAttr([4])
    mesh.CreateFaceVertexIndicesAttr([0, 1, 2, 3])
    mesh.CreateSubdivisionSchemeAttr("none")
    UsdGeom.PrimvarsAPI(mesh).CreatePrimvar(
        "st", Sdf.ValueTypeNames.TexCoord2fArray, UsdGeom.Tokens.vertex
    ).Set([(0, 0), (0, 1), (1, 1), (1, 0)])
    material = UsdShade.Material.Define(stage, "/Looks/M")
    surface = UsdShade.Shader.Define(stage, "/Looks/M/Surface")
    surface.SetShaderId("UsdPreviewSurface")
    surface.CreateInput("diffuseColor", Sdf.ValueTypeNames.Color3f).Set(Gf.Vec3f(0.7))
    material.CreateSurfaceOutput().ConnectToSource(surface.ConnectableAPI(), "surface")
    if displaced:
        reader = UsdShade.Shader.Define(stage, "/Looks/M/St")
        reader.SetShaderId("UsdPrimvarReader_float2")
        reader.CreateInput("varname", Sdf.ValueTypeNames.String).Set("st")
        texture = UsdShade.Shader.Define(stage, "/Looks/M/Bumps")
        texture.SetShaderId("UsdUVTexture")
        texture.CreateInput("file", Sdf.ValueTypeNames.Asset).Set(str(file))
        texture.CreateInput("scale", Sdf.ValueTypeNames.Float4).Set(Gf.Vec4f(0.3))
        texture.CreateInput("st", Sdf.ValueTypeNames.Float2).ConnectToSource(
            reader.ConnectableAPI(), "result"
        )
        surface.CreateInput("displacement", Sdf.ValueTypeNames.Float).ConnectToSource(
            texture.ConnectableAPI(), "r"
        )
        material.CreateDisplacementOutput().ConnectToSource(
            surface.ConnectableAPI(), "displacement"
        )
    UsdShade.MaterialBindingAPI.Apply(mesh.GetPrim()).Bind(material)
    camera = UsdGeom.Camera.Define(stage, "/Camera")
    camera.AddTranslateOp().Set(Gf.Vec3d(0, 2.0, 3.46))
    camera.AddRotateXOp().Set(-30.0)
    sun = UsdLux.DistantLight.Define(stage, "/Sun")
    sun.CreateIntensityAttr(3.14159)
    sun.AddRotateXOp().Set(-50.0)
    stage.Save()
    return path


def worker(stage: Path, size: int, spp: int, target: float) -> dict:
    """Render ``stage`` once; times, triangle counts and peak memory (this process)."""
    from pavonine.render import displacement
    from pavonine.render.api import render_stage

    reports = []
    resolve = displacement.resolve

    def measured(*args, **kwargs):
        reports.append(resolve(*args, **{**kwargs, "target_px": target}))
        return reports[-1]

    displacement.resolve = measured
    started = time.perf_counter()
    render_stage(stage, spp=spp, resolution=(size, size), progress=False)
    wall = time.perf_counter() - started
    report = reports[0]
    return {
        "wall_s": wall,
        "tessellation_s": report.seconds,
        "triangles_in": report.triangles_in,
        "triangles_out": report.triangles_out,
        "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0,
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--size", type=int, default=256)
    parser.add_argument("--spp", type=int, default=4)
    parser.add_argument("--target", type=float, default=1.0, help="edge target, pixels")
    parser.add_argument("--worker", type=Path, help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.worker:
        print(json.dumps(worker(args.worker, args.size, args.spp, args.target)))
        return 0
    results = {}
    with tempfile.TemporaryDirectory() as tmp:
        for name in ("flat", "displaced"):
            stage = write_stage(Path(tmp), name == "displaced")
            cmd = [sys.executable, __file__, "--worker", str(stage), "--size", str(args.size)]
            cmd += ["--spp", str(args.spp), "--target", str(args.target)]
            out = subprocess.run(cmd, capture_output=True, text=True, check=True).stdout
            results[name] = json.loads(out.strip().splitlines()[-1])
    for name, r in results.items():
        print(
            f"{name:10} wall {r['wall_s']:7.2f} s  tessellation {r['tessellation_s']:6.2f} s  "
            f"triangles {r['triangles_in']:>9,} -> {r['triangles_out']:>9,}  "
            f"peak RSS {r['peak_rss_mb']:8.1f} MB"
        )
    flat, moved = results["flat"], results["displaced"]
    added = max(moved["triangles_out"] - flat["triangles_out"], 1)
    extra_mb = moved["peak_rss_mb"] - flat["peak_rss_mb"]
    print(
        f"displaced / undisplaced: wall x{moved['wall_s'] / flat['wall_s']:.2f}, "
        f"peak memory x{moved['peak_rss_mb'] / flat['peak_rss_mb']:.2f} "
        f"(+{extra_mb:.1f} MB = {extra_mb * 2**20 / added:.0f} bytes per added triangle), "
        f"tessellation {100 * moved['tessellation_s'] / moved['wall_s']:.0f} % of the render"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
