"""Render the public USD test suites with Pavonine's delegate and check every render.

Usage::

    python benchmarks/usd_suites.py /work/suites/google+hdmitsuba/hdmitsuba/test_assets \\
        /work/suites/usd-wg+assets/test_assets -o out/suites [--size 128] [--spp 16] [--only TEXT]

Every ``.usd``/``.usda``/``.usdc``/``.usdz`` file under each suite folder is a stage. Each is rendered
in its own worker process (``--worker``), so that a crash or a traceback is recorded against that
stage and the run goes on. Per stage the worker measures, and the parent checks:

* ``runs``: the render finished (no exception, no traceback, no crash, within the time limit);
* ``coverage``: geometry is seen where the stage has geometry (fraction of pixels whose camera ray
  hits a shape, from Mitsuba's ``aov`` depth), none where it has none;
* ``lit``: where geometry is seen, it is not black (the stage's lights, or the default sun and sky,
  reach it); through an irradiance meter (hdmitsuba's ``mitsuba:sensor:type``), whose pixels are
  each an estimate of the irradiance its mesh receives, their mean is not 0 (its geometry's
  coverage is then seen through the camera's lens);
* ``texture``: where a shader names an image file that exists and OpenImageIO reads, the render
  differs from the same stage with those files blanked (so the texture really reaches the image);
* ``silhouette``: where the suite ships a ``usdrecord`` screenshot (whose framing camera is known:
  ``UsdAppUtilsFrameRecorder``'s 50 mm camera fitted to the stage bounds), the intersection over
  union of our coverage and the screenshot's alpha, with one pixel of tolerance, is at least 0.85;
  for stages with subdivision surfaces (which usdrecord draws as their control cage) at least
  95 % of our silhouette lies inside the screenshot's;
* ``supported``: the delegate did not warn that anything in the stage is "not supported" (bad
  data that is warned about and rendered around is fine: that is the expected behaviour);
* ``products``: on a stage with several RenderProducts, every one renders, each to its own image
  (``render_products`` at 16×12, 1 spp).

Stages without a camera are rendered through the renderer's own default view, which is that same
``usdrecord`` framing camera (``pavonine.render.camera.usd_view_camera``), at usdrecord's aspect
ratio, so that silhouettes are comparable. The suites are read,
never modified, and never copied into the repository.

Prints a table and the pass rate (overall and per suite); writes ``report.json``, one PNG per stage
and ``contact_sheet.png`` (green frame: all checks passed; red: a check failed) into ``-o``.
"""

from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
import time
import warnings
from pathlib import Path

import numpy as np

STAGE_SUFFIXES = {".usd", ".usda", ".usdc", ".usdz"}
SCREENSHOT_PATTERNS = ("screenshots/{stem}_usdrecord_22.08.png",)
# GfCamera's defaults (the camera usdrecord frames a stage with): 50 mm lens, 35 mm academy aperture
SILHOUETTE_IOU = 0.85
INSIDE_CAGE = 0.95
LIT_LUMINANCE = 0.01
TEXTURE_DIFFERENCE = 0.01
WORKER_TIMEOUT_S = 900
LAYER_METADATA = (
    "upAxis",
    "metersPerUnit",
    "startTimeCode",
    "endTimeCode",
    "timeCodesPerSecond",
    "framesPerSecond",
    "renderSettingsPrimPath",
)


# -- the stage: what it describes ------------------------------------------------------------------


def find_stages(suite: Path) -> list[Path]:
    """Every USD file under ``suite``, sorted."""
    return sorted(p for p in suite.rglob("*") if p.suffix.lower() in STAGE_SUFFIXES and p.is_file())


def reference_screenshot(stage_path: Path) -> Path | None:
    """The suite's ``usdrecord`` screenshot of this stage, if it ships one."""
    for pattern in SCREENSHOT_PATTERNS:
        candidate = stage_path.parent / pattern.format(stem=stage_path.stem)
        if candidate.is_file():
            return candidate
    return None


def describe(stage) -> dict:
    """What the stage describes: geometry bounds, cameras, lights, image files bound to materials."""
    from pxr import Sdf, Usd, UsdGeom, UsdLux, UsdShade

    from pavonine.render.delegate import render_time

    time_code = render_time(stage, None)
    cache = UsdGeom.BBoxCache(time_code, [UsdGeom.Tokens.default_, UsdGeom.Tokens.render])
    box = cache.ComputeWorldBound(stage.GetPseudoRoot()).ComputeAlignedRange()
    cameras, lights, texture_inputs = [], 0, []
    gprims, subdivided = 0, 0
    it = iter(Usd.PrimRange(stage.GetPseudoRoot(), Usd.TraverseInstanceProxies()))
    for prim in it:
        imageable = UsdGeom.Imageable(prim)
        if imageable and (
            imageable.ComputeVisibility(time_code) == UsdGeom.Tokens.invisible
            or imageable.ComputePurpose() in (UsdGeom.Tokens.guide, UsdGeom.Tokens.proxy)
        ):
            it.PruneChildren()
            continue
        if prim.IsA(UsdGeom.Gprim):
            points = (
                prim.GetAttribute("points").Get(time_code) if prim.IsA(UsdGeom.PointBased) else [0]
            )
            gprims += bool(hasattr(points, "__len__") and len(points))
            if (
                prim.IsA(UsdGeom.Mesh)
                and UsdGeom.Mesh(prim).GetSubdivisionSchemeAttr().Get() != "none"
            ):
                subdivided += 1
        if prim.IsA(UsdGeom.Camera):
            cameras.append(str(prim.GetPath()))
        elif prim.HasAPI(UsdLux.LightAPI) or prim.IsA(UsdLux.BoundableLightBase):
            lights += 1
        elif prim.IsA(UsdShade.Shader) and not prim.IsInstanceProxy():
            for shader_input in UsdShade.Shader(prim).GetInputs():
                value = shader_input.Get(time_code)
                if isinstance(value, Sdf.AssetPath) and readable_image(value.resolvedPath):
                    texture_inputs.append(shader_input.GetAttr().GetPath())
    bound = [] if box.IsEmpty() else [list(box.GetMin()), list(box.GetMax())]
    return {
        "bounds": bound,
        "gprims": gprims,
        "subdivided": subdivided,
        "cameras": sorted(cameras),
        "lights": lights,
        "texture_inputs": [str(p) for p in texture_inputs],
        "up_axis": str(UsdGeom.GetStageUpAxis(stage)),
    }


def readable_image(resolved: str) -> bool:
    """True when a resolved asset path (file or package member) is an image OpenImageIO reads:
    a texture the stage really provides, as opposed to a deliberately missing or corrupt one."""
    import OpenImageIO as oiio

    from pavonine.base.asset_io import local_file

    if not resolved:
        return False
    try:
        image = oiio.ImageInput.open(local_file(resolved))
    except Exception:
        return False
    if image is None:
        return False
    image.close()
    return True


def write_wrapper(
    stage_path: Path, stage, facts: dict, out: Path, blank_textures: bool
) -> tuple[Path, str | None]:
    """A layer that sublayers the stage and (``blank_textures``) blanks every image file bound to a
    shader input."""
    from pxr import Sdf, Usd

    layer_path = out / ("wrapper_blank.usda" if blank_textures else "wrapper.usda")
    wrapper = Usd.Stage.CreateNew(str(layer_path))
    root = stage.GetRootLayer()
    wrapper.GetRootLayer().subLayerPaths.append(str(stage_path.resolve()))
    for key in LAYER_METADATA:
        if root.pseudoRoot.HasInfo(key):
            wrapper.GetRootLayer().pseudoRoot.SetInfo(key, root.pseudoRoot.GetInfo(key))
    if blank_textures:
        for attr_path in facts["texture_inputs"]:
            path = Sdf.Path(attr_path)
            over = wrapper.OverridePrim(path.GetPrimPath())
            attr = over.CreateAttribute(path.name, Sdf.ValueTypeNames.Asset)
            attr.Set(Sdf.AssetPath(""))
    wrapper.GetRootLayer().Save()
    return layer_path


# -- the worker: one stage ----------------------------------------------------------------------


def coverage_mask(stage_path: Path, camera: str | None, size: tuple[int, int]) -> np.ndarray:
    """Per pixel, the fraction of 4 camera rays that hit a shape (Mitsuba ``aov`` depth > 0)."""
    import mitsuba as mi

    from pavonine.render import camera as camera_translator
    from pavonine.render import displacement
    from pavonine.render.api import scene_objects
    from pavonine.render.delegate import StageDelegate, open_stage, render_time
    from pavonine.render.diagnostics import Diagnostics
    from pavonine.render.settings import read_render_settings

    diag = Diagnostics()
    stage = open_stage(stage_path, diag)
    time_code = render_time(stage, None)
    delegate = StageDelegate(stage, time_code, diag)
    synced = delegate.sync()
    settings = read_render_settings(stage, diag)
    if camera is not None:
        prim = synced.cameras[camera]
        sensor = camera_translator.translate_camera(
            prim,
            delegate.xforms.world(prim),
            time_code,
            size,
            1.0,
            settings.conform,
            diag,
            lens_only=True,  # an irradiance meter's geometry is seen through its camera's lens
        )
    else:
        sensor = camera_translator.default_view(
            stage, time_code, synced, "usd", size, (1.0, settings.conform), diag
        )
    film = {"type": "hdrfilm", "width": size[0], "height": size[1], "rfilter": {"type": "box"}}
    shapes = scene_objects(synced.shapes, {})
    view = displacement.view_of(sensor.sensor, sensor.to_world, size)
    displacement.resolve(shapes, [view], synced.bounds, diag)
    scene_dict = {
        "type": "scene",
        "integrator": {"type": "aov", "aovs": "depth:depth"},
        "sensor": {**sensor.sensor, "film": film, "sampler": {"type": "stratified"}},
        **shapes,
    }
    hits = [
        np.asarray(mi.render(mi.load_dict(scene_dict), spp=1, seed=s))[..., 0] for s in range(4)
    ]
    return np.mean([h > 0 for h in hits], axis=0)


def run_worker(stage_path: Path, out: Path, size: int, spp: int) -> dict:
    """Render one stage (and its texture-blanked twin) and measure; returns the metrics dict."""
    from pxr import Usd

    from pavonine.base.errors import InputError
    from pavonine.render.api import render_stage
    from pavonine.render.camera import usd_view_resolution
    from pavonine.render.diagnostics import Diagnostics, StageWarning
    from pavonine.render.imageio import write_png
    from pavonine.render.settings import read_render_settings

    warnings.simplefilter("ignore", StageWarning)
    out.mkdir(parents=True, exist_ok=True)
    result: dict = {"stage": str(stage_path)}
    try:
        stage = Usd.Stage.Open(str(stage_path))
    except Exception:  # usd-core refuses the layer: the renderer must say so in one line
        try:
            render_stage(stage_path, spp=1, resolution=(8, 8), progress=False)
        except InputError as exc:
            return {**result, "status": "error", "detail": str(exc)}
        raise
    facts = describe(stage)
    result.update(facts)
    settings = read_render_settings(stage, Diagnostics())
    wrapper = write_wrapper(stage_path, stage, facts, out, blank_textures=False)
    camera = None
    if facts["cameras"]:
        camera = settings.camera if settings.camera in facts["cameras"] else facts["cameras"][0]
    if camera is None:  # the renderer's default view: usdrecord's camera, at its aspect ratio
        resolution = usd_view_resolution(size)
    elif settings.resolution:
        w, h = settings.resolution
        resolution = (size, max(1, round(size * h / w)))
    else:
        resolution = (size, size)
    result["camera"] = camera
    result["resolution"] = list(resolution)
    started = time.perf_counter()
    rendered = render_stage(wrapper, spp=spp, resolution=resolution, camera=camera, progress=False)
    result["seconds"] = round(time.perf_counter() - started, 2)
    result["warnings"] = rendered.warnings
    write_png(out / "render.png", rendered.rgb)
    rgb = np.nan_to_num(rendered.rgb.astype(np.float64))
    luminance = rgb @ [0.2126, 0.7152, 0.0722]
    covered = coverage_mask(wrapper, camera, resolution)
    np.save(out / "coverage.npy", covered)
    result["coverage"] = float((covered > 0).mean())
    mask = covered > 0.5
    seen = covered > 0
    # brightness of what is seen, per unit coverage (objects smaller than a pixel count too); an
    # irradiance meter's pixels are each one estimate of the mesh's irradiance: their mean
    result["meter"] = "irradiancemeter" in rendered.metadata.get("sensor", "")
    if result["meter"]:
        result["lit_luminance"] = float(luminance.mean())
    else:
        result["lit_luminance"] = (
            float(np.percentile(luminance[seen] / covered[seen], 90)) if seen.any() else 0.0
        )
    if facts["texture_inputs"] and mask.any():
        blank = write_wrapper(stage_path, stage, facts, out, blank_textures=True)
        plain = render_stage(blank, spp=spp, resolution=resolution, camera=camera, progress=False)
        diff = np.abs(np.nan_to_num(plain.rgb.astype(np.float64)) - rgb).mean(axis=2)
        result["texture_difference"] = float(diff[mask].mean() / max(luminance[mask].mean(), 1e-3))
    if len(settings.products) > 1:  # every product, each to its own image (issue 35's twins)
        from pavonine.render.api import render_products

        try:
            every = render_products(stage_path, spp=1, resolution=(16, 12), progress=False)
            result["products"] = [len(every), len(settings.products)]
        except Exception as exc:  # recorded against the stage
            result["products"] = [0, len(settings.products)]
            result["products_error"] = f"{type(exc).__name__}: {exc}"[:300]
    screenshot = reference_screenshot(stage_path)
    if screenshot is not None and camera is None:
        result["screenshot"] = str(screenshot)
        agreement = silhouette_agreement(covered, screenshot)
        result["silhouette_iou"], result["inside_reference"], result["reference_coverage"] = (
            agreement
        )
    return result


def silhouette_agreement(covered: np.ndarray, screenshot: Path) -> tuple[float, float, float]:
    """IoU of our coverage and the screenshot's alpha (box-resampled), one pixel of tolerance; the
    fraction of our silhouette inside the screenshot's; the screenshot's coverage.

    A pixel counts as a disagreement only when the other mask has no pixel within one pixel of it,
    so that anti-aliased edges and a half-pixel framing difference do not count.
    """
    import OpenImageIO as oiio

    image = oiio.ImageBuf(str(screenshot))
    spec = image.spec()
    pixels = image.get_pixels(oiio.FLOAT).reshape(spec.height, spec.width, spec.nchannels)
    alpha = pixels[..., 3] if spec.nchannels == 4 else (pixels[..., :3].max(axis=2) > 0)
    h, w = covered.shape
    ref = _box_resample(alpha.astype(np.float64), h, w) > 0.5
    ours = covered > 0.5
    union = ours | ref
    if not union.any():
        return 1.0, 1.0, 0.0
    near_ref, near_ours = _dilate(ref), _dilate(ours)
    disagree = (ours & ~near_ref) | (ref & ~near_ours)
    inside = float((ours & near_ref).sum() / max(ours.sum(), 1))
    return float(1.0 - disagree.sum() / union.sum()), inside, float(ref.mean())


def _box_resample(image: np.ndarray, h: int, w: int) -> np.ndarray:
    """Mean of the source pixels under each target pixel (nearest pixel when upsampling)."""
    H, W = image.shape
    ys = np.minimum(np.linspace(0, H, h + 1).astype(int), H - 1)
    xs = np.minimum(np.linspace(0, W, w + 1).astype(int), W - 1)
    return np.array(
        [
            [
                image[ys[i] : max(ys[i + 1], ys[i] + 1), xs[j] : max(xs[j + 1], xs[j] + 1)].mean()
                for j in range(w)
            ]
            for i in range(h)
        ]
    )


def _dilate(mask: np.ndarray) -> np.ndarray:
    padded = np.pad(mask, 1)
    out = np.zeros_like(mask)
    for dy in (0, 1, 2):
        for dx in (0, 1, 2):
            out |= padded[dy : dy + mask.shape[0], dx : dx + mask.shape[1]]
    return out


# -- the parent: run, check, report ----------------------------------------------------------------


def checks(metrics: dict) -> dict[str, bool | None]:
    """Each check's outcome (``None``: not applicable to this stage)."""
    ran = metrics.get("status") == "ok"
    out: dict[str, bool | None] = {"runs": ran}
    if not ran:
        return out
    # the suite's screenshot, where it ships one, says whether anything is seen from its camera
    has_geometry = metrics.get("reference_coverage", metrics["gprims"]) > 0
    out["coverage"] = metrics["coverage"] > 0 if has_geometry else metrics["coverage"] == 0
    out["lit"] = metrics["lit_luminance"] > LIT_LUMINANCE if metrics["coverage"] > 0 else None
    if "texture_difference" in metrics:
        out["texture"] = metrics["texture_difference"] > TEXTURE_DIFFERENCE
    if "silhouette_iou" in metrics:
        if metrics["subdivided"]:
            # usdrecord draws subdivision surfaces at refine level 0 (the control cage); the limit
            # surface lies inside the cage's hull, so our silhouette must lie inside its image.
            out["silhouette"] = metrics["inside_reference"] >= INSIDE_CAGE
        else:
            out["silhouette"] = metrics["silhouette_iou"] >= SILHOUETTE_IOU
    unsupported = [w for w in metrics["warnings"] if "not supported" in w]
    out["supported"] = not unsupported
    if "products" in metrics:  # a stage with several RenderProducts: each one rendered
        rendered, wanted = metrics["products"]
        out["products"] = rendered == wanted
    return out


def run_one(stage: Path, out: Path, args) -> dict:
    """Run the worker for one stage in a fresh process; its metrics plus status and stderr tail."""
    report = out / "metrics.json"
    if getattr(args, "resume", False) and report.is_file():  # measured by an earlier run
        metrics = json.loads(report.read_text())
        metrics.setdefault("status", "ok")
        return metrics
    report.unlink(missing_ok=True)  # a stale report must not stand for a failed worker
    cmd = [sys.executable, __file__, "--worker", str(stage), "-o", str(out)]
    cmd += ["--size", str(args.size), "--spp", str(args.spp)]
    started = time.perf_counter()
    try:
        proc = subprocess.run(
            cmd, capture_output=True, text=True, timeout=WORKER_TIMEOUT_S, check=False
        )
    except subprocess.TimeoutExpired:
        return {"stage": str(stage), "status": "timeout", "detail": f">{WORKER_TIMEOUT_S} s"}
    wall = round(time.perf_counter() - started, 1)
    if proc.returncode == 0 and report.is_file() and "Traceback" not in proc.stderr:
        metrics = json.loads(report.read_text())
        metrics.setdefault("status", "ok")
        metrics["wall"] = wall
        return metrics
    tail = [line for line in proc.stderr.splitlines() if line.strip()][-1:] or [""]
    status = "traceback" if "Traceback" in proc.stderr else f"exit {proc.returncode}"
    return {"stage": str(stage), "status": status, "detail": tail[0][:200], "wall": wall}


def contact_sheet(rows: list[dict], path: Path, cell: int) -> None:
    """All renders in a grid, captioned, framed green (all checks passed) or red."""
    from PIL import Image, ImageDraw

    columns = 12
    caption = 22
    sheet = Image.new(
        "RGB",
        (columns * (cell + 4), math.ceil(len(rows) / columns) * (cell + caption + 4)),
        "white",
    )
    draw = ImageDraw.Draw(sheet)
    for i, row in enumerate(rows):
        x, y = (i % columns) * (cell + 4), (i // columns) * (cell + caption + 4)
        colour = (40, 160, 60) if row["passed"] else (210, 40, 40)
        draw.rectangle([x, y, x + cell + 3, y + cell + 3], fill=colour)
        png = Path(row["out"]) / "render.png"
        if png.is_file():
            image = Image.open(png).convert("RGB")
            image.thumbnail((cell, cell))
            sheet.paste(image, (x + 2, y + 2))
        name = row["name"]
        draw.text((x + 2, y + cell + 4), name[-24:], fill="black")
        draw.text((x + 2, y + cell + 13), ",".join(row["failed"])[:24], fill=(210, 40, 40))
    sheet.save(path)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("suites", nargs="+", type=Path, help="suite folders (test_assets/)")
    parser.add_argument("-o", "--output", type=Path, default=Path("out/usd_suites"))
    parser.add_argument("--size", type=int, default=128, help="image width (default 128)")
    parser.add_argument("--spp", type=int, default=16)
    parser.add_argument("--only", default=None, help="only stages whose path contains this")
    parser.add_argument(
        "--resume",
        action="store_true",
        help="reuse each stage's metrics.json left in -o by an earlier run (render only the rest)",
    )
    parser.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)

    if args.worker:
        metrics = run_worker(args.suites[0], args.output, args.size, args.spp)
        (args.output / "metrics.json").write_text(json.dumps(metrics, indent=1, default=str))
        return 0

    rows = []
    started = time.perf_counter()
    for suite in args.suites:
        suite = suite.resolve()
        if not suite.is_dir():
            print(f"error: {suite}: not a folder", file=sys.stderr)
            return 2
        stages = [s for s in find_stages(suite) if not args.only or args.only in str(s)]
        for n, stage in enumerate(stages, 1):
            rel = stage.relative_to(suite)
            out = args.output / "renders" / suite.parent.name / rel.with_suffix("")
            metrics = run_one(stage, out, args)
            outcome = checks(metrics)
            failed = [k for k, ok in outcome.items() if ok is False]
            row = {
                "suite": suite.parent.name if suite.name == "test_assets" else suite.name,
                "name": str(rel),
                "out": str(out),
                "checks": outcome,
                "failed": failed,
                "passed": not failed,
                "metrics": metrics,
            }
            rows.append(row)
            print(
                f"[{n:3d}/{len(stages)}] {'PASS' if not failed else 'FAIL'} {row['suite']}/{rel}"
                f" {' '.join(failed)} {metrics.get('detail', '')}",
                file=sys.stderr,
                flush=True,
            )
    print_table(rows)
    args.output.mkdir(parents=True, exist_ok=True)
    (args.output / "report.json").write_text(json.dumps(rows, indent=1, default=str))
    contact_sheet(rows, args.output / "contact_sheet.png", args.size)
    print(
        f"\n{len(rows)} stages in {time.perf_counter() - started:.0f} s; "
        f"contact sheet: {args.output / 'contact_sheet.png'}"
    )
    return 0


def print_table(rows: list[dict]) -> None:
    """One line per stage (checks: + pass, x fail, . not applicable), then pass rates."""
    names = ["runs", "coverage", "lit", "texture", "silhouette", "supported", "products"]
    print(f"{'suite':10} {'stage':70} " + " ".join(f"{n[:5]:>5}" for n in names) + "  notes")
    for row in rows:
        marks = []
        for name in names:
            ok = row["checks"].get(name)
            marks.append(f"{'.' if ok is None else '+' if ok else 'x':>5}")
        m = row["metrics"]
        note = m.get("detail", "")
        if "silhouette_iou" in m:
            note = f"IoU {m['silhouette_iou']:.2f} " + note
        unsupported = [w for w in m.get("warnings", []) if "not supported" in w]
        if unsupported:
            note += " " + unsupported[0][:90]
        print(f"{row['suite'][:10]:10} {row['name'][-70:]:70} " + " ".join(marks) + f"  {note}")
    print()
    for suite in sorted({r["suite"] for r in rows}):
        part = [r for r in rows if r["suite"] == suite]
        passed = sum(r["passed"] for r in part)
        print(f"{suite}: {passed}/{len(part)} passed ({100 * passed / len(part):.1f} %)")
    passed = sum(r["passed"] for r in rows)
    print(f"overall: {passed}/{len(rows)} passed ({100 * passed / max(len(rows), 1):.1f} %)")


if __name__ == "__main__":
    sys.exit(main())
