"""Draw a .glb with three.js in headless Chromium (software WebGL) and read its pixels back.

``tests/threejs/gltf_view.html`` loads the file with GLTFLoader under the camera and lights it is
given, renders into a linear float target and POSTs the pixels to the small loopback server
here; three.js comes from ``.ci/node_modules`` (``.ci/package.json``, installed by ``.ci/setup``).
:func:`compare_zones` sets the shipped scene's camera, sun and sky on a feather asset, turned
about the vertical, and compares three.js' frame with ``pavonine render``'s per ocellus zone
(tests/pipeline/test_gltf_threejs.py, benchmarks/gltf_threejs.py).
"""

from __future__ import annotations

import json
import math
import shutil
import subprocess
import threading
import urllib.parse
from dataclasses import dataclass
from functools import partial
from http.server import SimpleHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
CI = REPO / ".ci"
SCENE = REPO / "assets" / "scenes" / "eye_feather_sun.usda"
#: The shipped scene's sun: from the right, 25° off the vane normal; E = π.
SUN = [math.sin(math.radians(25.0)), 0.0, math.cos(math.radians(25.0))]
THREE = CI / "node_modules" / "three"
PAGE = Path(__file__).resolve().parent / "threejs" / "gltf_view.html"


def chromium() -> str | None:
    """The Chromium executable on PATH, if any."""
    return next((p for n in ("chromium", "chromium-browser") if (p := shutil.which(n))), None)


class _Handler(SimpleHTTPRequestHandler):
    def __init__(self, *args, results: dict, **kwargs):
        self.results = results
        super().__init__(*args, **kwargs)

    def do_POST(self):
        body = self.rfile.read(int(self.headers["Content-Length"]))
        self.results[self.path] = body
        self.send_response(204)
        self.end_headers()
        self.results["done"].set()

    def log_message(self, *args):
        pass


def draw(glb: Path, view: dict, folder: Path, timeout: float = 240.0) -> np.ndarray:
    """``(height, width, 4)`` linear RGBA of ``glb`` drawn by three.js with ``view`` (the keys
    ``tests/threejs/gltf_view.html`` reads; ``resolution`` is ``(width, height)``)."""
    folder.mkdir(parents=True, exist_ok=True)
    shutil.copy(PAGE, folder / PAGE.name)
    shutil.copy(glb, folder / "asset.glb")
    if not (folder / "three").exists():
        (folder / "three").symlink_to(THREE, target_is_directory=True)
    results = {"done": threading.Event()}
    handler = partial(_Handler, directory=str(folder), results=results)
    server = ThreadingHTTPServer(("127.0.0.1", 0), handler)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    width, height = view["resolution"]
    query = urllib.parse.urlencode({"view": json.dumps({**view, "glb": "asset.glb"})})
    url = f"http://127.0.0.1:{server.server_address[1]}/{PAGE.name}?{query}"
    browser = subprocess.Popen(
        [
            chromium(),
            "--headless=new",
            "--no-sandbox",
            "--use-gl=angle",
            "--use-angle=swiftshader",
            "--enable-unsafe-swiftshader",
            "--ignore-gpu-blocklist",
            f"--user-data-dir={folder / 'profile'}",
            f"--window-size={width},{height}",
            url,
        ],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
    )
    try:
        if not results["done"].wait(timeout):
            raise TimeoutError(f"three.js page did not report within {timeout} s: {url}")
    finally:
        browser.terminate()
        try:
            browser.wait(20)
        except subprocess.TimeoutExpired:
            browser.kill()
            browser.wait()
        server.shutdown()
        server.server_close()
    if "/error" in results:
        raise RuntimeError(f"three.js page failed: {results['/error'].decode()}")
    pixels = np.frombuffer(results["/result"], dtype="<f4")
    return pixels.reshape(height, width, 4).astype(np.float64)


def page_view(tilt_deg: float, camera: tuple[float, float, float], **extra) -> dict:
    """A page view: the camera at ``camera`` (m) turned by ``tilt_deg`` about the world's +Y."""
    c = math.radians(tilt_deg)
    x, y, z = camera
    return {
        "camera_position": [
            x * math.cos(c) + z * math.sin(c),
            y,
            -x * math.sin(c) + z * math.cos(c),
        ],
        "camera_rotate_y_deg": tilt_deg,
        "sun_direction": SUN,
        "sun_intensity": math.pi,
        **extra,
    }


def tilted_scene(root: Path, tilt_deg: float, folder: Path) -> Path:
    """The shipped scene (assets/scenes/eye_feather_sun.usda) on the feather asset ``root``, its
    camera turned by ``tilt_deg`` about the world's +Y, written into ``folder``."""
    text = SCENE.read_text().replace("@../feathers/eye_feather/eye_feather.usd@", f"@{root}@")
    if tilt_deg:
        old = (
            "double3 xformOp:translate = (0, 17, 36)\n"
            '        uniform token[] xformOpOrder = ["xformOp:translate"]'
        )
        assert old in text
        text = text.replace(
            old,
            f"float xformOp:rotateY = {tilt_deg}\n        double3 xformOp:translate = (0, 17, 36)\n"
            '        uniform token[] xformOpOrder = ["xformOp:rotateY", "xformOp:translate"]',
        )
    path = folder / f"scene_{tilt_deg:+.0f}.usda"
    path.write_text(text)
    return path


def scene_camera(scene: Path) -> dict:
    """The scene camera's vertical field of view and position in metres (metersPerUnit)."""
    from pxr import Usd, UsdGeom

    stage = Usd.Stage.Open(str(scene))
    camera = UsdGeom.Camera(stage.GetPrimAtPath("/World/Camera")).GetCamera()
    scale = UsdGeom.GetStageMetersPerUnit(stage)
    fov = 2.0 * math.degrees(math.atan(camera.verticalAperture / (2.0 * camera.focalLength)))
    translate = stage.GetPrimAtPath("/World/Camera").GetAttribute("xformOp:translate").Get()
    near, far = camera.clippingRange.min * scale, camera.clippingRange.max * scale
    return {"fov_deg": fov, "near": near, "far": far, "position": [v * scale for v in translate]}


def scene_eye(scene: Path = SCENE) -> list[float]:
    """The shipped scene camera's position in the scene's units, which are those of the feather
    asset it references at its origin: the viewer ``pavonine export --eye`` fits the look for."""
    from pxr import Usd

    stage = Usd.Stage.Open(str(scene))
    return list(stage.GetPrimAtPath("/World/Camera").GetAttribute("xformOp:translate").Get())


@dataclass
class ZoneComparison:
    """Per ocellus zone: ``delta_e`` (ΔE2000 of the mean colours), ``means`` (render's, three.js'
    linear RGB) and ``pixels``."""

    delta_e: dict
    means: dict
    pixels: dict


def compare_zones(glb: Path, asset: Path, tilt_deg: float, folder: Path, resolution, spp: int):
    """``glb`` drawn by three.js and ``asset`` (its ``.usd``) rendered by ``pavonine render`` in
    the shipped scene turned by ``tilt_deg`` (:func:`tilted_scene`) at ``resolution`` (width,
    height) and ``spp``, compared per zone (tests/ocellus_zones.py) as a display shows the render
    (negative components clipped, as ``pavonine render --png`` does); writes
    ``render_vs_threejs_<tilt>.png`` side by side into ``folder``."""
    from ocellus_zones import zone_delta_e, zone_masks

    from pavonine.render.api import render_stage
    from pavonine.render.imageio import write_png

    width, height = resolution
    scene = tilted_scene(asset, tilt_deg, folder)
    render = render_stage(scene, spp=spp, resolution=resolution, seed=0, progress=False)
    camera = scene_camera(scene)
    view = page_view(tilt_deg, camera["position"], resolution=[width, height])
    view |= {"fov_deg": camera["fov_deg"], "near": camera["near"], "far": camera["far"]}
    # The scene's sky: a uniform dome of radiance 0.05·(0.55, 0.7, 1); three.js' ambient light of
    # intensity I lights a Lambertian surface with radiance I·albedo/π.
    view |= {"sky_color": [0.55, 0.7, 1.0], "sky_intensity": 0.05 * math.pi}
    three = draw(glb, view, folder / f"page{tilt_deg:+.0f}")[..., :3]
    write_png(
        folder / f"render_vs_threejs_{tilt_deg:+.0f}.png", np.concatenate([render.rgb, three], 1)
    )
    masks = zone_masks(scene, asset.parent / "maps", width, height)
    shown = np.clip(render.rgb, 0.0, None)
    means = {k: (shown[m].mean(axis=0), three[m].mean(axis=0)) for k, m in masks.items()}
    pixels = {k: int(m.sum()) for k, m in masks.items()}
    return ZoneComparison(zone_delta_e(shown, three, masks), means, pixels)
