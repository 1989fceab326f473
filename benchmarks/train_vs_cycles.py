"""Pavonine against Blender Cycles on the same train USD: CPU time and peak memory, alternating.

Both sides render ``assets/scenes/peacock_train.usda`` (whatever it holds when run) at the same
resolution and the same samples per pixel, each render a fresh process from start to exit, so
each side's figures include its own start-up, the scene's load (Pavonine: open the stage, sync,
build the Mitsuba scene, compile the kernels; Blender: ``bpy`` start-up and
``bpy.ops.wm.usd_import``) and writing the image. The rounds alternate (Pavonine, Cycles,
Pavonine, Cycles, ...), round ``k`` with seed ``k`` on both sides. Each child is reaped with
``os.wait4``, whose resource usage is that process's own: CPU = user + system seconds, peak
memory = ``ru_maxrss``.

What each side renders: Pavonine its own scene (the prototypes' ``medium`` LOD with the
spectral feather BSDF, the sun and the sky). Blender imports the same file with its USD importer
(``light_intensity_scale`` 0.25 undoes the importer's ×4 on lights): the PointInstancer as a point
cloud instancing the prototypes' meshes, which carry their ``UsdPreviewSurface`` (a Principled
BSDF fed by the baked base-colour texture), the camera and the sun; it makes no world of an
untextured ``DomeLight``, so the child sets the same uniform sky (the dome's intensity × colour,
read from the stage) by hand. Cycles on CPU, both CPU threads, adaptive sampling and denoising
off, Pavonine's one-pixel box filter.

Samples: equal samples per pixel. So that "comparable noise" is a measured claim, the two rounds
of each side (different seeds) give each image's noise: the RMS of the difference of the two
images over sqrt(2), relative to the image's mean (per channel, averaged).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
CYCLES_CHILD = HERE / "blender_render_barbs.py"


def dome_sky(scene: Path) -> list[float]:
    """The stage's untextured dome lights as one uniform linear-RGB sky: intensity × colour."""
    from pxr import Usd, UsdLux

    stage = Usd.Stage.Open(str(scene))
    sky = np.zeros(3)
    for prim in stage.Traverse():
        if prim.IsA(UsdLux.DomeLight):
            light = UsdLux.DomeLight(prim)
            colour = light.GetColorAttr().Get() or (1.0, 1.0, 1.0)
            sky += (light.GetIntensityAttr().Get() or 1.0) * np.asarray(colour, dtype=float)
    return [float(c) for c in sky]


def measured(argv: list[str], log: Path) -> dict:
    """Run ``argv`` to its end; its own wall, CPU (user + sys) seconds and peak RSS (MiB)."""
    started = time.perf_counter()
    with log.open("w") as out:
        child = subprocess.Popen(argv, stdout=out, stderr=subprocess.STDOUT)
        _, status, usage = os.wait4(child.pid, 0)
    child.returncode = os.waitstatus_to_exitcode(status)
    if child.returncode != 0:
        raise SystemExit(f"error: {argv[0]} {argv[1]} failed ({child.returncode}); log: {log}")
    return {
        "seconds": time.perf_counter() - started,
        "cpu_seconds": usage.ru_utime + usage.ru_stime,
        "peak_mib": usage.ru_maxrss / 1024,
        "load": os.getloadavg()[0],
    }


def pavonine_round(scene: Path, size: tuple[int, int], spp: int, seed: int, out: Path) -> dict:
    """One Pavonine render of ``scene`` in a fresh process; its figures and image (H×W×3)."""
    image = out / f"pavonine_{seed}.npy"
    argv = [sys.executable, __file__, "--pavonine", str(scene), f"{size[0]}x{size[1]}", str(spp),
            str(seed), str(image)]  # fmt: skip
    report = measured(argv, out / f"pavonine_{seed}.log")
    return {**report, "image": np.load(image)}


def cycles_round(bpy_python: str, job: dict, seed: int, out: Path) -> dict:
    """One Cycles render (import + render) in a fresh bpy process; its figures and image over
    the sky (H×W×3)."""
    from pavonine.render.imageio import read_exr

    folder = out / f"cycles_{seed}"
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "job.json").write_text(json.dumps({**job, "seed": seed, "out": str(folder)}))
    report = measured([bpy_python, str(CYCLES_CHILD), str(folder / "job.json")], folder / "log")
    rgba = read_exr(folder / "cycles.exr")[0]
    over = rgba[..., :3] + (1.0 - rgba[..., 3:4]) * np.asarray(job["sky"], dtype=np.float32)
    described = json.loads((folder / "blender.json").read_text())
    return {**report, "image": over, "objects": described["objects"]}


def noise(first: np.ndarray, second: np.ndarray) -> float:
    """Relative noise of one image from two of different seeds: RMS(a - b) / sqrt(2) / mean."""
    diff = (first - second).reshape(-1, 3)
    mean = 0.5 * (first + second).reshape(-1, 3).mean(axis=0)
    return float(np.mean(np.sqrt((diff**2).mean(axis=0) / 2.0) / np.maximum(mean, 1e-12)))


def compare(
    scene: Path,
    size: tuple[int, int],
    spp: int,
    rounds: int,
    bpy_python: str,
    out: Path,
    cycles_spp: int | None = None,
) -> dict:
    """An unmeasured warm-up of each side, then alternating rounds (Pavonine, Cycles, ...);
    prints each and the ratios; the medians of each side."""
    from pavonine.render.imageio import write_png

    out.mkdir(parents=True, exist_ok=True)
    cycles_spp = cycles_spp or spp
    job = {"usd": str(scene), "resolution": list(size), "cycles_samples": cycles_spp,
           "threads": 2, "sky": dome_sky(scene)}  # fmt: skip
    # the warm-up: Pavonine's kernels go to Dr.Jit's on-disk cache (as for any second render)
    warm = {"pavonine": pavonine_round(scene, size, spp, 99, out)}
    warm["cycles"] = cycles_round(bpy_python, job, 99, out)
    for name, r in warm.items():
        print(
            f"  warm-up {name:<8}: {r['seconds']:6.1f} s wall, {r['cpu_seconds']:6.1f} s CPU, "
            f"peak RSS {r['peak_mib']:5.0f} MiB (not counted)",
            flush=True,
        )
    runs: dict[str, list[dict]] = {"pavonine": [], "cycles": []}
    for k in range(rounds):
        runs["pavonine"].append(pavonine_round(scene, size, spp, k, out))
        runs["cycles"].append(cycles_round(bpy_python, job, k, out))
        for name in runs:
            r = runs[name][-1]
            print(
                f"  round {k + 1} {name:<8}: {r['seconds']:6.1f} s wall, {r['cpu_seconds']:6.1f} s"
                f" CPU, peak RSS {r['peak_mib']:5.0f} MiB (load {r['load']:.1f})",
                flush=True,
            )
    kinds = sorted({e["type"] for e in runs["cycles"][0]["objects"].values()})
    print(f"  Blender imported: {', '.join(kinds)}; sky set by hand {job['sky']}")
    found = {}
    for name, done in runs.items():
        found[name] = {
            key: float(np.median([r[key] for r in done]))
            for key in ("seconds", "cpu_seconds", "peak_mib")
        }
        found[name]["noise"] = noise(done[0]["image"], done[1]["image"]) if rounds > 1 else None
        found[name]["mean"] = [float(c) for c in done[0]["image"].reshape(-1, 3).mean(axis=0)]
    for name, f in found.items():
        shown = f"{f['noise']:.3f}" if f["noise"] is not None else "-"
        print(
            f"  {name:<8} median of {rounds}: {f['seconds']:6.1f} s wall, {f['cpu_seconds']:6.1f} s "
            f"CPU, peak RSS {f['peak_mib']:5.0f} MiB; relative noise {shown}, mean RGB "
            f"{np.round(f['mean'], 4).tolist()}"
        )
    p, c = found["pavonine"], found["cycles"]
    if p["noise"] and c["noise"]:
        # noise ~ 1 / sqrt(samples): the Cycles samples whose noise would equal Pavonine's
        equal = cycles_spp * (c["noise"] / p["noise"]) ** 2
        print(f"  Cycles at Pavonine's noise would take ~{equal:.1f} spp (noise ~ 1/sqrt(spp))")
    print(
        f"train Pavonine {spp} spp / Cycles {cycles_spp} spp ({size[0]}x{size[1]}, whole "
        f"process with load): "
        f"CPU {p['cpu_seconds'] / c['cpu_seconds']:.2f}x, peak memory "
        f"{p['peak_mib'] / c['peak_mib']:.2f}x (targets <= 1x), wall "
        f"{p['seconds'] / c['seconds']:.2f}x"
    )
    side = np.concatenate([runs["pavonine"][0]["image"], runs["cycles"][0]["image"]], axis=1)
    write_png(out / "pavonine_cycles.png", side)
    print(f"  side by side (Pavonine | Cycles), round 1: {out / 'pavonine_cycles.png'}")
    return found


def _pavonine_child(scene: str, size: str, spp: str, seed: str, image: str) -> None:
    """In the child: render ``scene`` once and save its beauty as ``image`` (.npy)."""
    import warnings

    from pavonine.render.api import render_stage
    from pavonine.render.diagnostics import StageWarning

    width, height = (int(v) for v in size.split("x"))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", StageWarning)
        result = render_stage(
            scene, spp=int(spp), resolution=(width, height), seed=int(seed), progress=False
        )
    np.save(image, np.asarray(result.rgb[..., :3], dtype=np.float32))


if __name__ == "__main__" and sys.argv[1:2] == ["--pavonine"]:
    _pavonine_child(*sys.argv[2:7])
