"""The whole train against one feather: render seconds and peak memory, in the same run.

Renders ``assets/scenes/peacock_train.usda`` (220 feathers through one PointInstancer, four
prototypes at their medium LOD) and the single eye feather (``eye_feather_sun.usda``, its high
LOD) at the same size and samples, each in a fresh process (so each peak resident set is its
own): a warm-up that compiles the kernels, then the timed render. The warm-up is one pass of the
timed render (same resolution, same samples per pass), since the kernel depends on both: a
1-spp warm-up left the whole LLVM compile inside the timed render. Prints wall and CPU seconds
(the machine may be shared: CPU seconds move less with the load, whose average is printed),
peak RSS and the ratios (targets: memory <= 1.5x, time <= 3x the single feather), plus the
triangles the train would hold as plain meshes, to show what instancing saves.

``--profile`` splits each timed render, from Dr.Jit's kernel history, into kernel execution,
code generation, LLVM compilation and the rest (wall seconds): the rest is mostly tracing the
path tracer into Dr.Jit's IR, once per pass. It also prints the largest kernel's IR operation
count. The history keeps every kernel's IR, so peak RSS under ``--profile`` reads high.

``--flat`` adds a third render: the train with its instancer written out as plain meshes, every
copy of a prototype mesh merged into one world-space mesh (``flat_train.py``; no instances, 4.5 M
triangles held). It is the floor of what the train's geometry costs in Mitsuba, whatever the
instancing: compare its kernel seconds (``--flat`` implies ``--profile``; its wall seconds include
syncing 4.5 M triangles from USD, and its memory is not a target).

Usage: python benchmarks/bench_train.py [--resolution 1024x768] [--spp 64] [--profile] [--flat]
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
import warnings
from pathlib import Path

SCENES = Path(__file__).parents[1] / "assets" / "scenes"


def one(scene: str, resolution: tuple[int, int], spp: int, profile: bool = False) -> dict:
    """Run in the child: warm up, render, report wall and CPU seconds and peak RSS."""
    from pavonine.render.api import render_stage
    from pavonine.render.diagnostics import StageWarning
    from pavonine.render.passes import samples_per_pass

    if profile:
        import drjit as dr

        dr.set_flag(dr.JitFlag.KernelHistory, True)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", StageWarning)
        warm = samples_per_pass(spp, resolution[0] * resolution[1], False)
        render_stage(scene, spp=warm, resolution=resolution, progress=False)
        if profile:
            dr.kernel_history()  # drop the warm-up's kernels
        start, cpu = time.perf_counter(), _cpu_seconds()
        result = render_stage(scene, spp=spp, resolution=resolution, progress=False)
        seconds, cpu = time.perf_counter() - start, _cpu_seconds() - cpu
    peak_kib = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    report = {
        "seconds": seconds,
        "cpu_seconds": cpu,
        "peak_mib": peak_kib / 1024,
        "passes": result.metadata["passes"],
        "load": os.getloadavg()[0],
    }
    if profile:
        report.update(kernel_split(dr.kernel_history(), seconds))
    return report


def kernel_split(history: list[dict], seconds: float) -> dict:
    """Wall seconds of a render spent executing, generating and compiling kernels, and the rest."""
    total = {
        key: sum((k.get(f"{key}_time") or 0.0) for k in history) / 1000.0
        for key in ("execution", "codegen", "backend")
    }
    total["other"] = seconds - sum(total.values())
    total["largest_kernel_ops"] = max((k.get("operation_count") or 0 for k in history), default=0)
    total["kernels_compiled"] = sum(1 for k in history if k.get("cache_hit") == 0)
    return total


def _cpu_seconds() -> float:
    usage = resource.getrusage(resource.RUSAGE_SELF)
    return usage.ru_utime + usage.ru_stime


def triangles(scene: Path) -> tuple[int, int]:
    """(triangles held by Mitsuba, triangles if every instance were its own mesh).

    Counts what the delegate draws: meshes of the default and render purposes (a prototype's
    proxy LOD is not drawn) and instances not in ``invisibleIds``, each n-gon as n - 2 triangles.
    """
    from pxr import Usd, UsdGeom

    stage = Usd.Stage.Open(str(scene))
    held = flat = 0
    for prim in Usd.PrimRange(stage.GetPseudoRoot(), Usd.TraverseInstanceProxies()):
        if prim.IsA(UsdGeom.PointInstancer):
            instancer = UsdGeom.PointInstancer(prim)
            counts = [0] * len(instancer.GetPrototypesRel().GetTargets())
            for i, target in enumerate(instancer.GetPrototypesRel().GetTargets()):
                for child in Usd.PrimRange(stage.GetPrimAtPath(target)):
                    counts[i] += _drawn_triangles(child)
            indices = instancer.GetProtoIndicesAttr().Get()
            ids = instancer.GetIdsAttr().Get() or range(len(indices))
            hidden = set(instancer.GetInvisibleIdsAttr().Get() or [])
            shown = [k for k, i in zip(indices, ids, strict=True) if i not in hidden]
            held += sum(counts[k] for k in set(shown))
            flat += sum(counts[k] for k in shown)
        elif not _under_instancer(prim):
            n = _drawn_triangles(prim)
            held += n
            flat += n
    return held, flat


def _drawn_triangles(prim) -> int:
    """Triangles of ``prim`` if it is a mesh the delegate draws, else 0."""
    from pxr import UsdGeom

    if not prim.IsA(UsdGeom.Mesh):
        return 0
    imageable = UsdGeom.Imageable(prim)
    if imageable.ComputePurpose() not in (UsdGeom.Tokens.default_, UsdGeom.Tokens.render):
        return 0
    counts = UsdGeom.Mesh(prim).GetFaceVertexCountsAttr().Get() or []
    return sum(max(int(n) - 2, 0) for n in counts)


def _under_instancer(prim) -> bool:
    from pxr import UsdGeom

    parent = prim.GetParent()
    while parent:
        if parent.IsA(UsdGeom.PointInstancer):
            return True
        parent = parent.GetParent()
    return False


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--resolution", default="1024x768")
    parser.add_argument("--spp", type=int, default=64)
    parser.add_argument("--profile", action="store_true", help="split each render (see above)")
    parser.add_argument("--flat", action="store_true", help="also the train without instancing")
    parser.add_argument("--one", help=argparse.SUPPRESS)
    args = parser.parse_args()
    args.profile |= args.flat
    size = tuple(int(v) for v in args.resolution.split("x"))
    if args.one:
        print(json.dumps(one(args.one, size, args.spp, args.profile)))
        return
    with tempfile.TemporaryDirectory() as tmp:
        scenes = {name: SCENES / f"{name}.usda" for name in ("eye_feather_sun", "peacock_train")}
        if args.flat:
            # in a child too: a child's peak RSS starts at its parent's (Linux keeps it over exec)
            scenes["train, flat"] = Path(tmp) / "peacock_train_flat.usdc"
            flat_train = Path(__file__).with_name("flat_train.py")
            command = [sys.executable, flat_train, scenes["peacock_train"], scenes["train, flat"]]
            subprocess.run(command, check=True, stdout=subprocess.DEVNULL)
        results = {name: run(scene, args) for name, scene in scenes.items()}
    report(results, args)


def run(scene: Path, args) -> dict:
    """One scene's render in a child process, with its triangle counts."""
    done = subprocess.run(
        [sys.executable, __file__, "--one", str(scene), "--resolution", args.resolution,
         "--spp", str(args.spp)] + (["--profile"] if args.profile else []),
        capture_output=True, text=True, check=True,
    )  # fmt: skip
    result = json.loads(done.stdout.strip().splitlines()[-1])
    result["triangles"], result["flat_triangles"] = triangles(scene)
    return result


def report(results: dict[str, dict], args) -> None:
    """Print each render and the ratios against the single feather."""
    eye, train = results["eye_feather_sun"], results["peacock_train"]
    for name, r in results.items():
        print(
            f"{name:<16} {args.resolution} @ {args.spp} spp: {r['seconds']:6.1f} s "
            f"({r['cpu_seconds']:.1f} s CPU, {r['passes']} passes, load {r['load']:.1f}), peak RSS "
            f"{r['peak_mib']:6.0f} MiB, {r['triangles']:,} triangles held "
            f"({r['flat_triangles']:,} as plain meshes)"
        )
        if args.profile:
            print(
                f"{'':<16} kernels {r['execution']:.1f} s, code generation {r['codegen']:.1f} s, "
                f"LLVM {r['backend']:.1f} s ({r['kernels_compiled']} compiled), other (tracing) "
                f"{r['other']:.1f} s; largest kernel {r['largest_kernel_ops']:,} IR operations"
            )
    print(
        f"train / single feather: time {train['seconds'] / eye['seconds']:.2f}x "
        f"(CPU {train['cpu_seconds'] / eye['cpu_seconds']:.2f}x; target <= 3), "
        f"memory {train['peak_mib'] / eye['peak_mib']:.2f}x (target <= 1.5)"
    )
    if args.profile:
        kernels = ", ".join(
            f"{name} {r['execution'] / eye['execution']:.2f}x"
            for name, r in results.items()
            if r is not eye
        )
        print(f"kernel execution / single feather's: {kernels}")


if __name__ == "__main__":
    main()
