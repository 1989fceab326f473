"""The rattle shot: frames of the train with its feathers turning, sharp and motion-blurred, on
Dask workers; per-frame time and sync, and the two ratios issue 35 asks for, in the same run.

Usage::

    python benchmarks/bench_motion.py [--resolution 512x384] [--spp 16] [--frames 1-6]
        [--workers 2] [--slices 16] [--stage assets/shots/peacock_rattle.usda] [-o out/motion]

The stage is ``assets/shots/peacock_rattle.usda`` when it exists (``pavonine assemble train``'s
rattle keys); otherwise a stand-in written here: ``assets/scenes/peacock_train.usda`` with every
feather of its PointInstancer turned about its own axis by +6° and −6° on alternate frames
(``orientations`` time-sampled at every frame; USD interpolates them in between), and the camera's
shutter open from −0.25 to +0.25 of a frame. The same stage is rendered twice through
``pavonine render --frames … --workers N --json``: once sharp (a layer over it authors the
RenderSettings' ``disableMotionBlur``), once blurred (``--motion-slices``), both at the same spp
and seed. Printed:

* per frame and run: the worker, the task's seconds and its sync seconds (the first frame of a
  worker syncs the whole stage, its later frames only the feathers' instance transforms);
* **sync ratio**: the largest sync of a later frame over the first frame's sync on that worker
  (issue 35: ≤ 10 %);
* **blur cost**: the blurred frames' task seconds over the sharp frames', summed (≤ 1.5×).

Nothing here is a hard-coded result: every number is measured in the run that prints it.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
RATTLE = ROOT / "assets" / "shots" / "peacock_rattle.usda"
TRAIN = ROOT / "assets" / "scenes" / "peacock_train.usda"
TURN_DEG = 6.0
SHUTTER = (-0.25, 0.25)


def rattle_stand_in(folder: Path, frames: list[int]) -> Path:
    """The train with every feather turning ±6° about its own z from frame to frame, and the
    camera's shutter open (module docstring)."""
    from pxr import Gf, Sdf, Usd, UsdGeom

    path = folder / "rattle_stand_in.usda"
    stage = Usd.Stage.CreateNew(str(path))
    stage.GetRootLayer().subLayerPaths.append(str(TRAIN))
    copy_stage_metadata(Sdf.Layer.FindOrOpen(str(TRAIN)), stage.GetRootLayer())
    stage.SetStartTimeCode(frames[0])
    stage.SetEndTimeCode(frames[-1])
    instancer = None
    for prim in stage.Traverse():
        if prim.IsA(UsdGeom.PointInstancer):
            instancer = UsdGeom.PointInstancer(prim)
            break
    if instancer is None:
        raise SystemExit(f"{TRAIN}: no PointInstancer to rattle")
    base = instancer.GetOrientationsAttr().Get()
    orientations = instancer.GetOrientationsAttr()
    for frame in frames:
        sign = 1.0 if frame % 2 else -1.0
        turn = Gf.Rotation(Gf.Vec3d(0, 0, 1), sign * TURN_DEG).GetQuat()
        turned = [Gf.Quath(Gf.Quatd(q.GetReal(), Gf.Vec3d(q.GetImaginary())) * turn) for q in base]
        orientations.Set(turned, Usd.TimeCode(frame))
    for prim in stage.Traverse():
        if prim.IsA(UsdGeom.Camera):
            camera = UsdGeom.Camera(prim)
            camera.CreateShutterOpenAttr(SHUTTER[0])
            camera.CreateShutterCloseAttr(SHUTTER[1])
    stage.GetRootLayer().Save()
    return path


def copy_stage_metadata(source, target) -> None:
    """Stage metadata is read from the root layer only: carry the sublayer's over."""
    for key in ("upAxis", "metersPerUnit", "renderSettingsPrimPath", "timeCodesPerSecond"):
        if source.pseudoRoot.HasInfo(key):
            target.pseudoRoot.SetInfo(key, source.pseudoRoot.GetInfo(key))


def sharp_layer(folder: Path, stage_path: Path) -> Path:
    """A layer over ``stage_path`` whose RenderSettings disable motion blur."""
    from pxr import Sdf, Usd, UsdRender

    path = folder / "sharp.usda"
    stage = Usd.Stage.CreateNew(str(path))
    stage.GetRootLayer().subLayerPaths.append(str(stage_path))
    copy_stage_metadata(Sdf.Layer.FindOrOpen(str(stage_path)), stage.GetRootLayer())
    source = Usd.Stage.Open(str(stage_path))
    settings = UsdRender.Settings.GetStageRenderSettings(source)
    if not settings:
        raise SystemExit(f"{stage_path}: no RenderSettings to disable motion blur on")
    over = UsdRender.Settings(stage.OverridePrim(settings.GetPath()))
    over.CreateDisableMotionBlurAttr(True)
    stage.SetStartTimeCode(source.GetStartTimeCode())
    stage.SetEndTimeCode(source.GetEndTimeCode())
    stage.GetRootLayer().Save()
    return path


def run(stage: Path, out: Path, args, extra: list[str], frames: str | None = None) -> dict:
    report = out.with_suffix(".json")
    command = [
        sys.executable, "-c", "import sys; from pavonine.console import main; sys.exit(main())",
        "render", str(stage), "-o", str(out),
        "--frames", frames or args.frames, "--resolution", args.resolution, "--spp", str(args.spp),
        "--seed", "1", "--workers", str(args.workers), "--json", str(report), "-q", *extra,
    ]  # fmt: skip
    started = time.perf_counter()
    done = subprocess.run(command, capture_output=True, text=True)
    if done.returncode != 0:
        raise SystemExit(f"{' '.join(command)}\n{done.stderr}")
    result = json.loads(report.read_text())
    result["wall"] = time.perf_counter() - started
    return result


def frames_table(name: str, result: dict) -> list[tuple[str, int, float, float]]:
    rows = []
    for task in sorted(result["tasks"], key=lambda t: t["job"]):
        seconds = task["seconds"]
        whole = bool(seconds["synced_all"])
        rows.append((task["worker"], task["job"], seconds["task"], seconds["sync"], whole))
        print(
            f"  {name:7s} frame {task['job']:2d}  {seconds['task']:8.2f} s  "
            f"sync {seconds['sync']:7.3f} s ({'full' if whole else 'time-varying prims only'})"
            f"  on {task['worker'].split(' ')[0]}"
        )
    return rows


def sync_ratio(rows) -> float:
    """The largest sync of a frame that moved only what varies, over the smallest full sync (a
    worker's first frame)."""
    full = [sync for _w, _j, _s, sync, whole in rows if whole]
    moved = [sync for _w, _j, _s, sync, whole in rows if not whole]
    return max(moved) / min(full) if moved and full else float("nan")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--resolution", default="512x384")
    parser.add_argument("--spp", type=int, default=16)
    parser.add_argument("--frames", default="1-6")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--slices", type=int, default=None, help="--motion-slices (default 16)")
    parser.add_argument("--stage", type=Path, default=None)
    parser.add_argument("-o", "--output", type=Path, default=None)
    args = parser.parse_args()
    from pavonine.apps.farm.jobs import parse_frames

    frames = parse_frames(args.frames)
    with tempfile.TemporaryDirectory() as tmp:
        folder = args.output or Path(tmp)
        folder.mkdir(parents=True, exist_ok=True)
        stage = args.stage or (RATTLE if RATTLE.is_file() else rattle_stand_in(folder, frames))
        print(f"stage {stage}: {args.frames} at {args.resolution}, {args.spp} spp, "
              f"{args.workers} workers")  # fmt: skip
        sharp_stage = sharp_layer(folder, stage)
        # Warm-up, untimed: the first render on this machine compiles the kernels into Dr.Jit's
        # disk cache, which both timed runs then find (else the first run would pay for both).
        run(sharp_stage, folder / "warm.exr", args, [], frames=args.frames.split("-")[0])
        sharp = run(sharp_stage, folder / "sharp.exr", args, [])
        slices = [] if args.slices is None else ["--motion-slices", str(args.slices)]
        blurred = run(stage, folder / "blurred.exr", args, slices)
        sharp_rows = frames_table("sharp", sharp)
        blurred_rows = frames_table("blurred", blurred)
        sharp_seconds = sum(r[2] for r in sharp_rows)
        blurred_seconds = sum(r[2] for r in blurred_rows)
        print(
            f"sync of later frames / first frame's sync: sharp {sync_ratio(sharp_rows):.1%}, "
            f"blurred {sync_ratio(blurred_rows):.1%} (target <= 10 %)"
        )
        print(
            f"blur cost: {blurred_seconds:.1f} s / {sharp_seconds:.1f} s of tasks = "
            f"{blurred_seconds / sharp_seconds:.2f}x at {args.spp} spp (target <= 1.5x); wall "
            f"{blurred['wall']:.0f} s / {sharp['wall']:.0f} s"
        )
        warnings = sorted({w for image in blurred["images"] for w in image["warnings"]})
        for warning in warnings:
            print(f"  warning: {warning}")


if __name__ == "__main__":
    main()
