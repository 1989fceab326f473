"""What a Blender user sees when importing the barbs: the portable USD
(``pavonine export ASSET -o X.usdc --geometry barbs``) through Blender's own USD importer
(``bpy.ops.wm.usd_import``) and Cycles, against Pavonine's render of the same USD, per ocellus
zone.

The shipped eye feather (or ``--asset``) is exported as a portable USD; the shipped scene
``assets/scenes/eye_feather_sun.usda`` (camera, sun from the right, sky) is pointed at it, and
Blender imports that scene file itself: camera, sun (``light_intensity_scale`` 0.25 undoes the
importer's ×4), the barbs and the rachis. Blender 5.3's importer makes no world of the scene's
untextured ``DomeLight``: the child sets the same uniform sky by hand (and says so). Cycles
renders it at the test size (128×192, ``--cycles-samples``, a one-pixel box filter as Pavonine's),
Pavonine renders the same scene (``--spp``), and the scene on the asset's own ``barbs`` level (the
curves with their barbules and the feather BSDF: what the portable preview stands in for). Each
view of ``--tilts`` (default face-on and the camera turned 60° about +Y: flat ribbons
foreshorten, round tubes do not) is rendered so.

Printed: what the importer made of the barbs (object type, material, what feeds the Principled
BSDF's Base Color: it must be the ``displayColor`` attribute, not the default grey), of the
camera and sun; per zone (tests/ocellus_zones.py on the sheet's silhouette: the barbs cover the
same vane) ΔE2000 between the zone means of Cycles and Pavonine on the portable USD, and of
each against Pavonine on the native barbs; the share of the feather's pixels each draws.
For comparison Blender also imports the scene on the asset's own ``barbs`` level (the curves,
as the issue found them). A PNG (Pavonine portable | Cycles portable | Cycles on the curves |
Pavonine native barbs) goes to the output folder.

Blender's Python module is not a project dependency: bpy 5.3 needs CPython 3.13, in a virtual
environment of its own whose python is ``--bpy-python`` (default ``$PAVONINE_BPY_PYTHON``):

    python3.13 -m venv .venv-bpy313 && .venv-bpy313/bin/pip install bpy
    PAVONINE_BPY_PYTHON=.venv-bpy313/bin/python .venv/bin/python benchmarks/blender_barbs.py
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(REPO / "tests"), str(REPO / "tests" / "pipeline")]
CHILD = Path(__file__).with_name("blender_render_barbs.py")
EYE = REPO / "assets" / "feathers" / "eye_feather"
INSTALL = "python3.13 -m venv .venv-bpy313 && .venv-bpy313/bin/pip install bpy"
SKY = [0.05 * c for c in (0.55, 0.7, 1.0)]  # the scene's DomeLight: intensity × colour


def _bpy_python(given: str | None) -> str:
    """The bpy venv's python, or exit saying how to make one."""
    python = given or os.environ.get("PAVONINE_BPY_PYTHON")
    if not python:
        raise SystemExit(f"error: no --bpy-python or $PAVONINE_BPY_PYTHON; make one:\n  {INSTALL}")
    probe = subprocess.run(
        [python, "-c", "import bpy"], capture_output=True, text=True, timeout=300, check=False
    )
    if probe.returncode != 0:
        why = (probe.stderr.strip().splitlines() or ["?"])[-1]
        raise SystemExit(f"error: {python} cannot import bpy ({why}); make one:\n  {INSTALL}")
    return python


def _scene(root: Path, folder: Path, name: str, geometry: str | None, tilt: float) -> Path:
    """The shipped sun scene on ``root`` (its ``geometry`` variant selected), its camera turned
    by ``tilt`` degrees about the world's +Y (gltf_browser.tilted_scene), as ``folder/name``."""
    from gltf_browser import tilted_scene

    written = tilted_scene(root, tilt, folder)
    text = written.read_text()
    if geometry:
        select = f'@{root}@\n        variants = {{ string geometry = "{geometry}" }}'
        text = text.replace(f"@{root}@", select)
    written.unlink()
    path = folder / f"{name}_{tilt:+.0f}.usda"
    path.write_text(text)
    return path


def _child(bpy_python: str, job: dict, folder: Path) -> dict:
    """Run the bpy child on ``job`` in ``folder``; its report."""
    folder.mkdir(parents=True, exist_ok=True)
    job = {**job, "out": str(folder)}
    (folder / "job.json").write_text(json.dumps(job, indent=1))
    child = subprocess.run(
        [bpy_python, str(CHILD), str(folder / "job.json")],
        capture_output=True,
        text=True,
        check=False,
    )
    (folder / "blender.log").write_text(child.stdout + child.stderr)
    if child.returncode != 0:
        raise SystemExit(f"error: Blender failed (log: {folder / 'blender.log'}):\n{child.stderr}")
    return json.loads((folder / "blender.json").read_text())


def _importer(report: dict) -> bool:
    """Print what the importer made of each object; True when every barb mesh has a material
    whose Base Color is the ``displayColor`` attribute."""
    print(f"Blender {report['blender']}: the import of the scene")
    good = True
    for name, entry in sorted(report["objects"].items()):
        if entry["type"] in ("MESH", "CURVES"):
            base = entry.get("base_color", {})
            feed = base.get("attribute") or base.get("node") or base.get("value")
            print(
                f"  {name:>8}: {entry['type']}, {entry.get('faces', entry.get('curves'))} "
                f"{'faces' if entry['type'] == 'MESH' else 'curves'}, materials "
                f"{entry['materials']}, Base Color <- {feed}, colour attributes "
                f"{entry['color_attributes']}"
            )
            if name == "Barbs":
                good &= entry["type"] == "MESH" and base.get("attribute") == "displayColor"
        elif entry["type"] in ("LIGHT", "CAMERA"):
            shown = {k: v for k, v in entry.items() if k != "type"}
            print(f"  {name:>8}: {entry['type']} {shown}")
    print(f"  added by hand: {report.get('added')}")
    return good


def main() -> None:
    from click.testing import CliRunner

    from pavonine.apps.cli import cli

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--asset", default=str(EYE), help="asset folder [the shipped eye]")
    parser.add_argument(
        "--out", default=str(Path(tempfile.gettempdir()) / "pavonine_blender_barbs")
    )
    parser.add_argument("--bpy-python", help="python of the venv with bpy")
    parser.add_argument("--cycles-samples", type=int, default=64)
    parser.add_argument("--spp", type=int, default=32, help="Pavonine's samples per pixel")
    parser.add_argument(
        "--tilts", default="0,60", help="camera turns about +Y, degrees, comma-separated"
    )
    args = parser.parse_args()
    out = Path(args.out).resolve()
    out.mkdir(parents=True, exist_ok=True)
    bpy_python = _bpy_python(args.bpy_python)
    asset = Path(args.asset).resolve()
    root = asset / f"{asset.name}.usd" if asset.is_dir() else asset

    portable = out / f"{root.stem}_barbs.usdc"
    started = time.perf_counter()
    result = CliRunner().invoke(
        cli, ["export", str(root), "-o", str(portable), "--geometry", "barbs", "--json", "-"]
    )
    if result.exit_code != 0:
        raise SystemExit(f"error: pavonine export failed:\n{result.output}")
    exported = json.loads(result.stdout)
    print(
        f"pavonine export: {portable.name}, {exported['meshes'][0]['triangles']:,} ribbon "
        f"triangles, {exported['bytes']:,} bytes, {time.perf_counter() - started:.1f} s"
    )
    bound = True
    for k, tilt in enumerate(float(t) for t in args.tilts.split(",")):
        bound &= _view(tilt, root, portable, out, bpy_python, args, first=k == 0)
    print(f"barbs bound to their displayColor in Blender: {'yes' if bound else 'NO'}")
    if not bound:
        raise SystemExit(1)


def _view(
    tilt: float,
    root: Path,
    portable: Path,
    out: Path,
    bpy_python: str,
    args: argparse.Namespace,
    first: bool,
) -> bool:
    """One view, the scene camera turned by ``tilt``: Blender on the portable layer and on the
    asset's own curves, Pavonine on both, compared per zone; True when Blender bound the barbs'
    colour."""
    from ocellus_zones import ZONE_NAMES, zone_delta_e, zone_masks
    from test_gltf_threejs import RESOLUTION

    from pavonine.render.api import render_stage
    from pavonine.render.imageio import read_exr, write_png

    scenes = {
        "portable": _scene(portable, out, "scene_portable", None, tilt),
        "native": _scene(root, out, "scene_native", "barbs", tilt),
        "sheet": _scene(root, out, "scene_sheet", "sheet", tilt),
    }
    width, height = RESOLUTION
    job = {
        "usd": str(scenes["portable"]),
        "resolution": [width, height],
        "cycles_samples": args.cycles_samples,
        "threads": 2,
        "sky": SKY,
    }
    print(f"\n=== camera turned {tilt:+.0f}° about +Y")
    started = time.perf_counter()
    report = _child(bpy_python, job, out / f"blender_{tilt:+.0f}")
    print(f"Cycles {args.cycles_samples} spp: {time.perf_counter() - started:.0f} s (with import)")
    bound = _importer(report) if first else True
    images = {"cycles": read_exr(report["cycles"])[0]}
    # what Blender makes of the asset's own barbs level (the curves), for comparison
    job["usd"] = str(scenes["native"])
    before = _child(bpy_python, job, out / f"blender_curves_{tilt:+.0f}")
    if first:
        print("\nThe same with the asset's own barbs (the curves, no portable export):")
        _importer(before)
    images["cycles_curves"] = read_exr(before["cycles"])[0]
    for name in ("portable", "native"):
        started = time.perf_counter()
        rendered = render_stage(
            scenes[name], spp=args.spp, resolution=RESOLUTION, seed=0, progress=False
        )
        print(f"Pavonine {name} {args.spp} spp: {time.perf_counter() - started:.0f} s")
        images[name] = rendered.rgb
    masks = zone_masks(scenes["sheet"], root.parent / "maps", width, height)
    shown = {k: np.clip(v[..., :3], 0.0, None) for k, v in images.items()}
    pairs = [
        ("cycles", "portable"),
        ("cycles", "native"),
        ("portable", "native"),
        ("cycles_curves", "native"),
    ]
    deltas = {p: zone_delta_e(shown[p[0]], shown[p[1]], masks) for p in pairs}
    print("\nΔE2000 of the zone means (linear Rec. 709, negative clipped)")
    header = "".join(f"  {a + ' vs ' + b:>20}" for a, b in pairs)
    print("  (cycles: Blender on the portable USD; cycles_curves: on the asset's own curves)")
    print(f"  {'zone':>16}  pixels{header}  {'Cycles mean RGB':>24}  {'Pavonine portable':>24}")
    for k in sorted(masks, reverse=True):
        cells = "".join(f"  {deltas[p][k]:20.2f}" for p in pairs)
        means = [shown[e][masks[k]].mean(axis=0) for e in ("cycles", "portable")]
        text = "".join(f"  {np.array2string(m, precision=3):>24}" for m in means)
        print(f"  {ZONE_NAMES[k]:>16}  {int(masks[k].sum()):>6}{cells}{text}")
    zones = [k for k in (5, 4, 3, 2, 1) if k in masks]
    print(
        f"  {'mean (5 zones)':>16}  {'':>6}"
        + "".join(f"  {np.mean([deltas[p][k] for k in zones]):20.2f}" for p in pairs)
    )
    feather = np.zeros((height, width), dtype=bool)
    for mask in masks.values():
        feather |= mask
    for name in ("cycles", "cycles_curves"):
        alpha = images[name][..., 3]
        print(
            f"Inside the zones ({int(feather.sum())} px) {name}: mean alpha "
            f"{alpha[feather].mean():.3f}, {np.mean(alpha[feather] >= 0.5):.1%} of them ≥ 0.5"
        )
    sky = np.array(SKY)
    over = {
        k: images[k][..., :3] + (1.0 - images[k][..., 3:]) * sky
        for k in ("cycles", "cycles_curves")
    }
    panels = [images["portable"], over["cycles"], over["cycles_curves"], images["native"]]
    png = out / f"portable_cycles_native_{tilt:+.0f}.png"
    write_png(png, np.concatenate(panels, axis=1))
    print(
        "side by side (Pavonine portable | Cycles portable | Cycles on the asset's curves | "
        f"Pavonine native barbs): {png}"
    )
    return bound


if __name__ == "__main__":
    main()
