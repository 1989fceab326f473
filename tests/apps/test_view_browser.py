"""Acceptance of ``pavonine view``: the page in headless Chromium (software WebGL) against
``pavonine render`` of the same camera and sun, per ocellus zone, in three views.

``pavonine view`` serves the shipped eye scene; the page is opened with the view in its URL
(face-on: the scene's camera and sun; tilted 40° about the vertical through the feather; the sun
from the other side), a frame is read off its canvas, and the page's own "Render this view"
(``POST /api/render`` → ``pavonine render``) renders the same camera and sun. Zones are the
ocellar classes each pixel sees (a Mitsuba ray cast through the same camera, as in
``test_preview_delta_e.py``), alpha above 0.9, one pixel in from every boundary. Each zone's mean
colour must agree within ΔE2000 5 in every view, and must move with the view in both images
(a view-independent bake could not follow the tilt). The page's frame time at 1280×720 (the
median of 15 frames after 3 of warm-up) is measured and printed (``benchmarks/bench_view.py``
compares it against a yardstick). One Chromium serves both tests of this file.

    pytest tests/apps/test_view_browser.py -s   # prints the table; writes the frames to its tmp_path
"""

from __future__ import annotations

import base64
import io
import math
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from browser import Browser, Firefox, chromium, firefox, start_view, stop

REPO = Path(__file__).resolve().parents[2]
SCENE = REPO / "assets" / "scenes" / "eye_feather_sun.usda"
MAPS = REPO / "assets" / "feathers" / "eye_feather" / "maps"
WIDTH, HEIGHT = 160, 240
SPP = 32
MAX_DELTA_E = 5.0
MIN_PIXELS = 20
#: The scene's camera and sun (assets/scenes/eye_feather_sun.usda).
EYE = np.array([0.0, 17.0, 36.0])
SUN_DEG = 25.0

pytestmark = [
    pytest.mark.browser,
    pytest.mark.render,
    pytest.mark.skipif(chromium() is None, reason="no chromium on PATH"),
]


def _views(target: np.ndarray) -> dict[str, dict]:
    turn = math.radians(40.0)
    offset = EYE - target
    tilted = target + np.array(
        [
            offset[0] * math.cos(turn) + offset[2] * math.sin(turn),
            offset[1],
            -offset[0] * math.sin(turn) + offset[2] * math.cos(turn),
        ]
    )
    sun = np.array([math.sin(math.radians(SUN_DEG)), 0.0, math.cos(math.radians(SUN_DEG))])
    other = sun * np.array([-1.0, 1.0, 1.0])
    return {
        "face-on": {"eye": EYE, "sun": sun},
        "tilted 40°": {"eye": tilted, "sun": sun},
        "sun other side": {"eye": EYE, "sun": other},
    }


def _png(data_url: str) -> np.ndarray:
    """Linear RGB of an sRGB PNG data URL (the page and the render both encode plain sRGB)."""
    from PIL import Image

    from pavonine.materials.display import srgb_decode

    raw = base64.b64decode(data_url.split(",", 1)[1])
    rgb = np.asarray(Image.open(io.BytesIO(raw)).convert("RGB"), dtype=np.float64) / 255.0
    return srgb_decode(rgb)


def _zones(view: dict, scene_camera: dict, folder: Path) -> np.ndarray:
    """Ocellar class per pixel (−1: not the vane or alpha ≤ 0.9), eroded by one pixel."""
    from ocellus_zones import zone_masks

    from pavonine.apps.view.viewpoint import write_view_layer

    stub = SimpleNamespace(
        stage_path=SCENE.resolve(),
        camera={"path": "/World/Camera", "radius": scene_camera["radius"]},
        sun={"path": "/World/Sun"},
        sky={"path": "/World/Sky"},
    )
    folder.mkdir(parents=True, exist_ok=True)
    layer, _ = write_view_layer(stub, view, folder)
    out = np.full((HEIGHT, WIDTH), -1)
    for k, mask in zone_masks(layer, MAPS, WIDTH, HEIGHT).items():
        out[mask] = k
    return out


@pytest.fixture(scope="module")
def view_server():
    process, url = start_view(str(SCENE))
    yield url
    if process.poll() is None:
        stop(process)


@pytest.fixture(scope="module")
def chrome(view_server):
    """One headless Chromium on the page (its first view: the scene's), for the whole file."""
    with Browser(f"{view_server}?hud=0", WIDTH, HEIGHT) as browser:
        browser.wait_for("window.pavonine !== undefined")
        browser.evaluate("window.pavonine.ready")
        yield browser


def _open(browser: Browser, url: str) -> None:
    """Navigate the page to ``url`` (at the tests' frame size) and wait until it has drawn."""
    browser.size(WIDTH, HEIGHT)
    browser.call("Page.navigate", url=url)
    browser.wait_for("window.pavonine !== undefined && document.readyState === 'complete'")
    browser.evaluate("window.pavonine.ready")


def test_page_matches_pavonine_render_per_zone_in_three_views(view_server, chrome, tmp_path):
    from PIL import Image

    from pavonine.materials.colour import delta_e2000, linear_srgb_to_lab
    from pavonine.materials.display import srgb_encode

    results: dict[str, dict[int, tuple]] = {}
    means: dict[str, dict[int, tuple[np.ndarray, np.ndarray]]] = {}
    browser = chrome
    scene_camera = browser.evaluate("fetch('/api/scene.json').then(r => r.json())")["camera"]
    target = np.asarray(scene_camera["target"])
    for name, v in _views(target).items():
        query = "&".join(
            [
                "hud=0",
                "eye=" + ",".join(f"{c:.6f}" for c in v["eye"]),
                "target=" + ",".join(f"{c:.6f}" for c in target),
                "sun=" + ",".join(f"{c:.6f}" for c in v["sun"]),
            ]
        )
        _open(browser, f"{view_server}?{query}")
        page = _png(browser.evaluate("window.pavonine.frame()"))
        state = browser.evaluate("window.pavonine.view()")
        rendered = _png(
            browser.evaluate(
                f"window.pavonine.renderView({WIDTH}, {HEIGHT}, {SPP}).then(b => new Promise("
                "r => { const f = new FileReader(); f.onload = () => r(f.result); "
                "f.readAsDataURL(b); }))",
                timeout_s=900,
            )
        )
        assert page.shape == rendered.shape == (HEIGHT, WIDTH, 3)
        zone = _zones(
            {**state, "width": WIDTH, "height": HEIGHT, "spp": 1},
            scene_camera,
            tmp_path / name.replace(" ", "_"),
        )
        slug = name.replace(" ", "_").replace("°", "")
        side = np.concatenate([page, rendered], axis=1)
        Image.fromarray((srgb_encode(side) * 255 + 0.5).astype(np.uint8)).save(
            tmp_path / f"{slug}.png"
        )
        results[name], means[name] = {}, {}
        for k in range(6):
            mask = zone == k
            if mask.sum() < MIN_PIXELS:
                continue
            a, b = page[mask].mean(axis=0), rendered[mask].mean(axis=0)
            de = float(delta_e2000(linear_srgb_to_lab(a), linear_srgb_to_lab(b)))
            results[name][k] = (int(mask.sum()), de, a, b)
            means[name][k] = (a, b)
    browser.size(1280, 720)
    browser.evaluate("window.dispatchEvent(new Event('resize'))")
    browser.evaluate("new Promise(r => setTimeout(r, 300))")
    frame_ms = browser.evaluate("window.pavonine.benchmark(15, false, 3)")
    frames = browser.evaluate("window.pavonine.frameTimes")  # sorted by the page

    print(f"\nframes: {tmp_path}")
    print("view             zone  pixels  ΔE2000  page (linear)          render (linear)")
    for name, zones in results.items():
        for k, (pixels, de, a, b) in zones.items():
            print(
                f"{name:<16} {k:>4}  {pixels:>6}  {de:6.2f}  "
                f"{np.array2string(a, precision=3):<22} {np.array2string(b, precision=3)}"
            )
    print(
        f"page frame time at 1280x720 (software WebGL): median {frame_ms:.1f} ms of "
        f"{len(frames)} frames (fastest {frames[0]:.1f}, slowest {frames[-1]:.1f})"
    )

    for name, zones in results.items():
        assert set(zones) >= {1, 2, 3, 4, 5}, (name, sorted(zones))
        assert all(de < MAX_DELTA_E for _, de, _, _ in zones.values()), (name, zones)
    # The colour moves with the view, in the page and in the render alike.
    lab = {
        n: {k: (linear_srgb_to_lab(a), linear_srgb_to_lab(b)) for k, (a, b) in z.items()}
        for n, z in means.items()
    }
    for side in (0, 1):
        moved = [
            float(delta_e2000(lab["face-on"][k][side], lab["tilted 40°"][k][side]))
            for k in lab["face-on"]
            if k in lab["tilted 40°"]
        ]
        assert max(moved) > 3 * MAX_DELTA_E, (side, moved)
    assert len(frames) == 15 and frames[0] > 0


def _xvfb():
    """An X display for Firefox: ``$DISPLAY``, else a private Xvfb (None without either)."""
    import os
    import shutil
    import subprocess

    if os.environ.get("DISPLAY"):
        return None, os.environ["DISPLAY"]
    if shutil.which("Xvfb") is None:
        return None, None
    display = f":{90 + os.getpid() % 100}"
    process = subprocess.Popen(
        ["Xvfb", display, "-screen", "0", "1280x1024x24", "-nolisten", "tcp"],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    return process, display


@pytest.mark.skipif(firefox() is None, reason="no firefox-esr on PATH")
def test_page_draws_the_same_in_firefox(view_server, chrome, tmp_path, monkeypatch):
    """Firefox (windowed on Xvfb: headless Firefox has no WebGL without a GPU) draws the
    face-on view as Chromium does: per zone within ΔE2000 2 of Chromium's frame."""
    import time

    from pavonine.materials.colour import delta_e2000, linear_srgb_to_lab

    xvfb, display = _xvfb()
    if display is None:
        pytest.skip("no X display and no Xvfb for Firefox")
    monkeypatch.setenv("DISPLAY", display)
    time.sleep(1.0 if xvfb else 0.0)
    try:
        url = f"{view_server}?hud=0"
        frames = {}
        _open(chrome, url)
        frames["chromium"] = _png(chrome.evaluate("window.pavonine.frame()"))
        state = chrome.evaluate("window.pavonine.view()")
        scene_camera = chrome.evaluate("fetch('/api/scene.json').then(r => r.json())")["camera"]
        with Firefox(url, WIDTH, HEIGHT) as fox:
            fox.wait_for("window.pavonine !== undefined")
            fox.evaluate("window.pavonine.ready")
            size = fox.evaluate("innerWidth + 'x' + innerHeight")  # BiDi: strings as they are
            assert size == f"{WIDTH}x{HEIGHT}", size
            frames["firefox"] = _png(fox.evaluate("window.pavonine.frame()"))
    finally:
        if xvfb is not None:
            xvfb.terminate()
            xvfb.wait()
    zone = _zones({**state, "width": WIDTH, "height": HEIGHT, "spp": 1}, scene_camera, tmp_path)
    worst = {}
    for k in range(6):
        mask = zone == k
        if mask.sum() >= MIN_PIXELS:
            a, b = (linear_srgb_to_lab(frames[n][mask].mean(axis=0)) for n in frames)
            worst[k] = float(delta_e2000(a, b))
    print(f"\nFirefox vs Chromium, ΔE2000 per zone: {worst}")
    assert set(worst) >= {1, 2, 3, 4, 5} and max(worst.values()) < 2.0, worst
