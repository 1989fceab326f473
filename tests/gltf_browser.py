"""Draw a .glb with three.js in headless Chromium (software WebGL) and read its pixels back.

``tests/threejs/gltf_view.html`` loads the file with GLTFLoader under the camera and lights it is
given, renders into a linear float target and POSTs the pixels to the small loopback server
here; three.js comes from ``.ci/node_modules`` (``.ci/package.json``, installed by ``.ci/setup``).
"""

from __future__ import annotations

import json
import shutil
import subprocess
import threading
import urllib.parse
from functools import partial
from http.server import SimpleHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path

import numpy as np

CI = Path(__file__).resolve().parents[1] / ".ci"
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
