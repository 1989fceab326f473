"""What a Blender user sees when importing our ``.glb``: Blender's own glTF importer
(``bpy.ops.import_scene.gltf``) and Cycles (and EEVEE where it starts headless) against Pavonine's
render of the same camera and sun, per ocellus zone, face-on and tilted 40°.

The setup is tests/pipeline/test_gltf_threejs.py's, with Blender in place of three.js: the test eye
(256-px maps, seed 4, as tests/conftest.py ``convert_eye`` builds it) exported with
``pavonine export --eye`` (the scene's camera); ``assets/scenes/eye_feather_sun.usda`` pointed at it, its camera turned by
``pipeline.export.iridescence.TILT_DEG`` about +Y for the tilted view; Pavonine's render at
128×192, 32 spp (``render_stage``). Blender gets the USD camera (position, turn, vertical field
of view, clip range; placed in Blender's Z-up frame as the importer converts glTF's Y-up one), a
Sun lamp of π W/m² from the scene's sun direction (25° to the right, 0.53° wide), the sky as a
uniform world colour 0.05·(0.55, 0.7, 1) of strength 1, the "Standard" view transform and linear
float EXRs. Printed per view and zone: ΔE2000 of the zone means (tests/ocellus_zones.py, the
render clipped to the gamut as in the test), how well Blender's alpha matches the feather's
silhouette in Pavonine's frame, and what the importer connected to the Principled BSDF. PNGs
(render | Cycles | EEVEE) go to the output folder.

Blender's Python module is not a project dependency: it runs in a virtual environment of its own
(CPython 3.11), whose python is ``--bpy-python`` (default ``$PAVONINE_BPY_PYTHON``, else
``.venv-bpy/bin/python`` in the checkout):

    python3.11 -m venv .venv-bpy && .venv-bpy/bin/pip install bpy==5.0.1
    .venv/bin/python benchmarks/blender_gltf.py [--asset ASSET | --glb X.glb --asset ASSET]

Measured with bpy 5.0.1 (Blender 5.0.1, io_scene_gltf2 5.0.21), Cycles 64 spp CPU, EEVEE 64
samples (it starts headless on Mesa's EGL, printing EGL_BAD_MATCH, and draws within ~1 ΔE of
Cycles). The importer reads KHR_materials_specular (Specular IOR Level 0.5·specularFactor,
Specular Tint = specularColorTexture × specularColorFactor through an unclamped Multiply, so 12.5
is kept) but not KHR_materials_iridescence (Thin Film Thickness stays 0): Blender draws the base
and the bare substrate. ΔE2000 on the test eye (heart, blue-green, bronze, outer ring, vane):

    Cycles as imported      face-on  9.0 / 16.2 / 7.7 /  9.9 /  8.3   tilted 15.7 / 21.6 / 7.0 / 16.4 / 20.5
    EEVEE as imported       face-on  9.5 / 16.2 / 8.1 / 10.0 /  8.4   tilted 14.7 / 22.4 / 7.6 / 16.3 / 20.0
    Cycles, film by hand    face-on  9.6 /  9.9 / 6.5 /  7.5 /  5.2   tilted  9.2 / 11.1 / 5.1 /  8.1 /  3.1

("film by hand": ``cycles_film``, see blender_render_gltf.wire_film.) The flat quads of
tests/pipeline/test_gltf_threejs.py, printed last, show that as imported Cycles draws what
pipeline/export/iridescence.py says a viewer draws with the film's weight at 0.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "tests"))
CHILD = Path(__file__).with_name("blender_render_gltf.py")
BPY_VERSION = "5.0.1"
INSTALL = f"python3.11 -m venv .venv-bpy && .venv-bpy/bin/pip install bpy=={BPY_VERSION}"
#: ``cycles_film``: Cycles again after the child wires by hand the film the importer leaves out
#: (what Blender could draw if it read KHR_materials_iridescence; blender_render_gltf.wire_film).
ENGINES = ("cycles", "eevee", "cycles_film")


def _bpy_python(given: str | None) -> str:
    """The bpy venv's python, or exit saying how to make one."""
    python = given or os.environ.get("PAVONINE_BPY_PYTHON") or str(REPO / ".venv-bpy/bin/python")
    probe = "import bpy; print(bpy.app.version_string)"
    try:
        found = subprocess.run([python, "-c", probe], capture_output=True, text=True, timeout=120)
    except OSError as exc:
        found = None
        why = str(exc)
    else:
        why = (found.stderr.strip().splitlines() or ["?"])[-1]
    if found is None or found.returncode != 0:
        raise SystemExit(
            f"error: no Blender Python module at {python} ({why}).\n"
            f"Install it in a venv of its own (CPython 3.11; measured with bpy {BPY_VERSION}):\n"
            f"    {INSTALL}\n"
            "then pass --bpy-python .venv-bpy/bin/python (or set PAVONINE_BPY_PYTHON)."
        )
    return python


def _eye(work: Path) -> Path:
    """The test eye, built as tests/conftest.py ``convert_eye(work, "eye_feather")`` builds it."""
    from pavonine.pipeline.convert.batch import convert_recipe
    from pavonine.pipeline.maps.paint import MAP_NAMES, generate_maps, write_maps

    name = "eye_feather"
    if not (work / "m").is_dir():
        write_maps(generate_maps("eye", 256, seed=4), work / "m")
    maps = "\n".join(f'{map_name} = "m/{map_name}.png"' for map_name in MAP_NAMES)
    (work / f"{name}.toml").write_text(
        f'name = "{name}"\n[maps]\n{maps}\n[material]\npreset = "freyer2020"\n'
        "[geometry]\nlength_cm = 20\nrachis_length = 0.74\n"
        "[geometry.lod]\nhigh = 12000\nmedium = 4000\nlow = 1000\n"
        "[bake]\nresolution = 256\n"
    )
    return convert_recipe(work / f"{name}.toml", work / "out").root


def _asset_usd(asset: str) -> Path:
    """An asset folder's root layer (``<folder>/<folder name>.usd``), or the layer given."""
    path = Path(asset).resolve()
    if path.is_dir():
        path = path / f"{path.name}.usd"
    if not path.is_file():
        raise SystemExit(f"error: {path}: no such asset layer")
    return path


def _silhouette(scene: Path, maps: Path, width: int, height: int) -> np.ndarray:
    """Pixels whose centre sees the vane where its alpha map passes glTF's cutoff, or the rachis
    (Pavonine's frame)."""
    from ocellus_zones import feather_hits

    from pavonine.base.map_files import read_map, sample_bilinear

    uv, on_vane = feather_hits(scene, width, height)
    _, on_rachis = feather_hits(scene, width, height, mesh="Rachis")
    alpha = np.zeros((height, width))
    alpha[on_vane] = sample_bilinear(read_map(maps / "alpha.png", "alpha"), uv[on_vane])
    return (alpha >= 0.5) | on_rachis


def _mask_match(expected: np.ndarray, alpha: np.ndarray) -> str:
    drawn = alpha >= 0.5
    union = (expected | drawn).sum()
    iou = (expected & drawn).sum() / max(union, 1)
    shift = ""
    if drawn.any() and expected.any():
        centre = [np.argwhere(m).mean(axis=0) for m in (expected, drawn)]
        dy, dx = centre[1] - centre[0]
        shift = f", centroid moved ({dx:+.2f}, {dy:+.2f}) px (x right, y down)"
    return f"{int(expected.sum())} px expected, {int(drawn.sum())} drawn, IoU {iou:.3f}{shift}"


def _describe(socket: dict) -> str:
    """One line for what feeds a Principled input (blender_render_gltf.py's report)."""
    if "node" not in socket:
        return f"constant {socket.get('value')}"
    parts = []
    while socket and "node" in socket:
        what = socket["node"].removeprefix("ShaderNode")
        if "image" in socket:
            what += f" '{socket['image']}' ({socket['colorspace']})"
        if "blend_type" in socket:
            what += f" {socket['blend_type']} clamp={socket['clamp_result']}"
            consts = [v["value"] for v in socket["inputs"].values() if "value" in v]
            what += f" by {consts[-1]}" if consts else ""
        if "operation" in socket:
            consts = [v["value"] for v in socket["inputs"].values() if "value" in v]
            what += f" {socket['operation']} {consts}"
        parts.append(f"{what}.{socket['output']}")
        linked = [v for v in socket.get("inputs", {}).values() if "node" in v]
        socket = linked[0] if linked else None
    return " <- ".join(parts)


def _child(bpy_python: str, job: dict, folder: Path) -> dict:
    """Run the bpy child on ``job`` in ``folder``; its report."""
    folder.mkdir(parents=True, exist_ok=True)
    job = {**job, "out": str(folder)}
    (folder / "job.json").write_text(json.dumps(job, indent=1))
    child = subprocess.run(
        [bpy_python, str(CHILD), str(folder / "job.json")], capture_output=True, text=True
    )
    (folder / "blender.log").write_text(child.stdout + child.stderr)
    if child.returncode != 0:
        raise SystemExit(f"error: Blender failed (log: {folder / 'blender.log'}):\n{child.stderr}")
    return json.loads((folder / "blender.json").read_text())


def quads(bpy_python: str, out: Path, samples: int) -> None:
    """tests/pipeline/test_gltf_threejs.py's flat quads (one material, 16×16 px, 1° field, no sky) in
    Cycles against ``pipeline/export/iridescence.py``'s model of what a glTF viewer draws: as
    imported (no film: the model at weight 0) and with the film wired by hand (the model)."""
    from gltf_browser import SUN
    from test_gltf_threejs import _quad

    from pavonine.pipeline.export import iridescence as irid
    from pavonine.render.imageio import read_exr

    base, ior, tilts = np.array([0.1, 0.2, 0.05]), 1.56, (0.0, irid.TILT_DEG)
    views = []
    for tilt in tilts:
        c = math.radians(tilt)
        views.append(
            {"name": f"{tilt:+.0f}", "position": [math.sin(c), 0.0, math.cos(c)],
             "rotate_y_deg": tilt, "fov_deg": 1.0, "near": 0.1, "far": 10.0}
        )  # fmt: skip
    print(
        "\nQuads (test_gltf_threejs): radiance at the centre, the model (iridescence.py) vs Cycles"
    )
    print(f"  {'weight, nm, roughness, F0':>28}  view  {'model, no film':>22}  "
          f"{'as imported':>22}  {'model':>22}  {'film wired':>22}")  # fmt: skip
    for k, (weight, thickness, roughness, f0) in enumerate(
        [
            (1.0, 400.0, 0.4, (0.0, 0.0, 0.0)),
            (0.8, 550.0, 0.6, (0.0, 0.0, 0.0)),
            (1.0, 300.0, 0.3, (0.2, 0.3, 0.1)),
            (0.5, 250.0, 0.5, (0.35, 0.12, 0.45)),
        ]
    ):
        folder = out / f"quad{k}"
        folder.mkdir(parents=True, exist_ok=True)
        _quad(folder / "quad.glb", base, weight, thickness, roughness, ior, f0)
        job = {"glb": str(folder / "quad.glb"), "resolution": [16, 16], "views": views,
               "sun": SUN, "sun_irradiance": math.pi, "sun_angle_deg": 0.53, "sky": [0, 0, 0],
               "engines": ["cycles", "cycles_film"], "cycles_samples": samples,
               "eevee_samples": 1, "threads": 2}  # fmt: skip
        report = _child(bpy_python, job, folder)
        light, seen = np.array([SUN]), irid.tilted_views(tilts)[None]
        model = {
            w: irid.glTF_reflectance(
                base[None], [w], [thickness], light, seen, [roughness], ior, [f0]
            )[0]
            * SUN[2]
            for w in (0.0, weight)
        }  # reflectance factor → radiance under E = π
        for j, view in enumerate(views):
            drawn = [
                read_exr(report["engines"][e]["files"][view["name"]])[0][8, 8, :3]
                for e in ("cycles", "cycles_film")
            ]
            cells = [model[0.0][j], drawn[0], model[weight][j], drawn[1]]
            text = "  ".join(f"{np.array2string(c, precision=3):>22}" for c in cells)
            case = f"{weight}, {thickness:.0f}, {roughness}, {f0}"
            print(f"  {case:>28}  {view['name']:>4}  {text}")


def main() -> None:
    from gltf_browser import SUN
    from gltf_browser import scene_camera as _camera
    from gltf_browser import tilted_scene as _scene
    from ocellus_zones import ZONE_NAMES, zone_delta_e, zone_masks
    from test_gltf_threejs import RESOLUTION, SPP

    from pavonine.apps.cli import cli
    from pavonine.materials.colour import delta_e2000, linear_srgb_to_lab
    from pavonine.pipeline.export import iridescence as irid
    from pavonine.render.api import render_stage
    from pavonine.render.imageio import read_exr, write_png

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--asset", help="asset folder (or its root .usd); default: the test eye")
    parser.add_argument("--glb", help="a .glb exported from --asset; default: export it")
    parser.add_argument("--out", default=str(Path(tempfile.gettempdir()) / "pavonine_blender_gltf"))
    parser.add_argument("--bpy-python", help="python of the venv with bpy")
    parser.add_argument("--cycles-samples", type=int, default=64)
    parser.add_argument("--eevee-samples", type=int, default=64)
    parser.add_argument("--engines", default=",".join(ENGINES), help="cycles,eevee,cycles_film")
    parser.add_argument("--no-quads", action="store_true", help="skip the flat-quad check")
    args = parser.parse_args()
    if args.glb and not args.asset:
        parser.error("--glb needs the --asset it was exported from (for the zones and reference)")
    out = Path(args.out).resolve()
    out.mkdir(parents=True, exist_ok=True)
    bpy_python = _bpy_python(args.bpy_python)
    engines = [e for e in args.engines.split(",") if e]

    usd = _asset_usd(args.asset) if args.asset else _eye(out / "eye")
    if args.glb:
        glb = Path(args.glb).resolve()
    else:
        from click.testing import CliRunner
        from gltf_browser import scene_eye

        glb = out / f"{usd.stem}.glb"
        eye = [str(v) for v in scene_eye()]  # fitted for the scene's camera, as the test does
        result = CliRunner().invoke(cli, ["export", str(usd.parent), "-o", str(glb), "--eye", *eye])
        if result.exit_code != 0:
            raise SystemExit(f"error: pavonine export failed:\n{result.output}")
    width, height = RESOLUTION
    views, refs = [], {}
    for tilt in (0.0, irid.TILT_DEG):
        name = f"{tilt:+.0f}"
        scene = _scene(usd, tilt, out)
        started = time.perf_counter()
        refs[name] = (scene, render_stage(scene, spp=SPP, resolution=RESOLUTION, seed=0,
                                          progress=False).rgb)  # fmt: skip
        print(f"Pavonine render {name}°: {time.perf_counter() - started:.0f} s")
        camera = _camera(scene)
        c = math.radians(tilt)
        x, y, z = camera["position"]
        views.append(
            {
                "name": name,
                "position": [
                    x * math.cos(c) + z * math.sin(c),
                    y,
                    -x * math.sin(c) + z * math.cos(c),
                ],
                "rotate_y_deg": tilt,
                "fov_deg": camera["fov_deg"],
                "near": camera["near"],
                "far": camera["far"],
            }
        )
    job = {
        "glb": str(glb),
        "resolution": [width, height],
        "views": views,
        "sun": SUN,
        "sun_irradiance": math.pi,
        "sun_angle_deg": 0.53,  # the scene's DistantLight inputs:angle
        "sky": [0.05 * c for c in (0.55, 0.7, 1.0)],
        "engines": engines,
        "cycles_samples": args.cycles_samples,
        "eevee_samples": args.eevee_samples,
        "threads": 2,
    }
    started = time.perf_counter()
    report = _child(bpy_python, job, out / "blender")
    print(f"Blender {report['blender']} (bpy): {time.perf_counter() - started:.0f} s")

    print("\nWhat the importer connected (Principled BSDF of each material):")
    for material, entry in report["materials"].items():
        print(f"  {material}: render method {entry.get('surface_render_method')}")
        for socket, feed in entry.get("principled", {}).items():
            print(f"    {socket:>20}: {_describe(feed)}")
    for engine in engines:
        if "error" in report["engines"][engine]:
            print(f"\n{engine}: did not render: {report['engines'][engine]['error']}")
    drawn = [e for e in engines if "files" in report["engines"][e]]

    seen = {}
    for view in views:
        name = view["name"]
        scene, rgb = refs[name]
        shown = np.clip(rgb, 0.0, None)
        images = {e: read_exr(report["engines"][e]["files"][name])[0] for e in drawn}
        silhouette = _silhouette(scene, usd.parent / "maps", width, height)
        masks = zone_masks(scene, usd.parent / "maps", width, height)
        seen[name] = (masks, images)
        print(f"\ntilt {name}°")
        for e in drawn:
            print(
                f"  {e} alpha vs Pavonine's silhouette: {_mask_match(silhouette, images[e][..., 3])}"
            )
        deltas = {e: zone_delta_e(shown, images[e][..., :3], masks) for e in drawn}
        header = "".join(f"  ΔE {e:>6}" for e in drawn)
        means = "".join(f"  {e + ' mean RGB':>24}" for e in drawn)
        print(f"  {'zone':>16}  pixels{header}  {'render mean RGB':>24}{means}")
        for k in masks:
            cells = "".join(f"  {deltas[e][k]:9.2f}" for e in drawn)
            rgbs = [shown[masks[k]].mean(axis=0)] + [images[e][masks[k]][:, :3].mean(axis=0)
                                                     for e in drawn]  # fmt: skip
            text = "".join(f"  {np.array2string(c, precision=3):>24}" for c in rgbs)
            print(f"  {ZONE_NAMES[k]:>16}  {int(masks[k].sum()):>6}{cells}{text}")
        zones = [k for k in (5, 4, 3, 2, 1) if k in masks]
        mean = "".join(f"  {np.mean([deltas[e][k] for k in zones]):9.2f}" for e in drawn)
        print(f"  {'mean (5 zones)':>16}  {'':>6}{mean}")
        sky = np.array(job["sky"])  # the film is transparent: show Blender's over the sky
        panels = [rgb] + [images[e][..., :3] + (1 - images[e][..., 3:]) * sky for e in drawn]
        png = out / f"render_vs_blender_{name}.png"
        write_png(png, np.concatenate(panels, axis=1))
        print(f"  side by side (render | {' | '.join(drawn)}): {png}")
    (face_masks, face), (tilted_masks, tilted) = seen.values()
    for e in drawn:  # the colour moves with the view, as in the render?
        moved = []
        for k in (2, 3, 4):
            if k in face_masks and k in tilted_masks:
                a = linear_srgb_to_lab(face[e][face_masks[k]][:, :3].mean(axis=0))
                b = linear_srgb_to_lab(tilted[e][tilted_masks[k]][:, :3].mean(axis=0))
                moved.append(f"{ZONE_NAMES[k]} {float(delta_e2000(a, b)):.1f}")
        print(f"{e}: ΔE2000 face-on -> tilted within each ring: {', '.join(moved)}")
    if not args.no_quads:
        quads(bpy_python, out / "quads", args.cycles_samples)


if __name__ == "__main__":
    main()
