"""``pavonine view``'s HTTP server: the page, its bundled scripts, the opened stage's data.

Stdlib only (:class:`http.server.ThreadingHTTPServer`), bound to 127.0.0.1. What it serves is a
closed list, looked up by name, never a path joined from the request:

* ``/`` the page; ``/static/<name>`` the files of :data:`STATIC` (``static/`` in the package);
* ``/api/scene.json?lod=…&geometry=…`` the stage read for those variant selections
  (:mod:`pavonine.apps.view.scene`), whose JSON names the URLs below;
* ``/api/<key>/mesh/<i>.bin``, ``/api/<key>/table/<i>.bin``, ``/api/<key>/albedo/<i>.bin``
  its meshes, BRDF tables and their sky albedo;
* ``/api/<key>/files/<n>/<name>`` the map files the stage's feather materials use (each inside
  the folder of the layer naming it; a symlink out of it is not served);
* ``POST /api/render`` "render this view" (:mod:`pavonine.apps.view.viewpoint`): runs
  ``pavonine render`` on the page's camera and sun and answers the PNG.

Anything else is 404. A request whose ``Host`` is not the printed ``127.0.0.1:PORT`` gets 403
(DNS rebinding), and so does a POST from another origin. A client that goes away mid-transfer
only ends its own thread.
"""

from __future__ import annotations

import copy
import json
import logging
import subprocess
import sys
import tempfile
import threading
from http import HTTPStatus
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from urllib.parse import parse_qs, urlsplit

from pavonine import LOGGER_NAME
from pavonine.apps.view.scene import VIEW_VARIANT_SETS, ViewScene, read_scene
from pavonine.base.errors import InputError

LOG = logging.getLogger(f"{LOGGER_NAME}.view")
LOOPBACK = "127.0.0.1"
STATIC_DIR = Path(__file__).resolve().parent / "static"
#: Every file the page may load (relative to ``static/``) and its media type.
STATIC = {
    "index.html": "text/html; charset=utf-8",
    "view.css": "text/css; charset=utf-8",
    "main.js": "text/javascript; charset=utf-8",
    "feather.js": "text/javascript; charset=utf-8",
    "loader.js": "text/javascript; charset=utf-8",
    "vendor/three.min.js": "text/javascript; charset=utf-8",
}
MAP_TYPES = {".png": "image/png", ".jpg": "image/jpeg", ".jpeg": "image/jpeg"}
CHUNK = 64 * 1024
MAX_BODY = 64 * 1024
RENDER_TIMEOUT_S = 600


class ViewState:
    """The opened stage, read once per variant selection (thread-safe)."""

    def __init__(self, path: Path, render_spp: int = 16):
        self.path = path
        self.render_spp = render_spp
        self.lock = threading.Lock()
        self.render_lock = threading.Lock()
        self.scenes: list[ViewScene] = []
        self.keys: dict[tuple, int] = {}

    def scene(self, selections: dict[str, str]) -> tuple[int, ViewScene]:
        key = tuple(sorted(selections.items()))
        with self.lock:
            if key not in self.keys:
                self.scenes.append(read_scene(self.path, selections))
                self.keys[key] = len(self.scenes) - 1
            index = self.keys[key]
            return index, self.scenes[index]


class ViewServer(ThreadingHTTPServer):
    """The server (module docstring); :attr:`url` is what it printed."""

    daemon_threads = True
    allow_reuse_address = False

    def __init__(self, state: ViewState, port: int = 0):
        super().__init__((LOOPBACK, port), ViewHandler)
        self.state = state
        self.host_header = f"{LOOPBACK}:{self.server_address[1]}"
        self.url = f"http://{self.host_header}/"

    def handle_error(self, request, client_address) -> None:
        LOG.debug("request from %s failed", client_address, exc_info=True)


class ViewHandler(BaseHTTPRequestHandler):
    server: ViewServer
    protocol_version = "HTTP/1.1"
    server_version = "pavonine-view"

    def log_message(self, format: str, *args) -> None:
        LOG.debug("%s %s", self.address_string(), format % args)

    # -- checks -------------------------------------------------------------------------------
    def _host_ok(self) -> bool:
        if self.headers.get("Host") != self.server.host_header:
            self._send(HTTPStatus.FORBIDDEN, b"wrong Host\n", "text/plain")
            return False
        return True

    def _send(self, status: int, body: bytes, content_type: str, extra: dict | None = None):
        try:
            self.send_response(status)
            self.send_header("Content-Type", content_type)
            self.send_header("Content-Length", str(len(body)))
            self.send_header("Cache-Control", "no-store")
            self.send_header("X-Content-Type-Options", "nosniff")
            for k, v in (extra or {}).items():
                self.send_header(k, v)
            self.end_headers()
            if self.command != "HEAD":
                for start in range(0, len(body), CHUNK):
                    self.wfile.write(body[start : start + CHUNK])
        except (BrokenPipeError, ConnectionResetError, TimeoutError):
            self.close_connection = True

    def _not_found(self) -> None:
        self._send(HTTPStatus.NOT_FOUND, b"not found\n", "text/plain")

    def _file(self, path: Path, content_type: str) -> None:
        try:
            body = path.read_bytes()
        except OSError:
            return self._not_found()
        self._send(HTTPStatus.OK, body, content_type)

    # -- GET ----------------------------------------------------------------------------------
    def do_HEAD(self) -> None:
        self.do_GET()

    def do_GET(self) -> None:
        if not self._host_ok():
            return
        url = urlsplit(self.path)
        parts = url.path.split("/")[1:]
        if url.path == "/":
            return self._file(STATIC_DIR / "index.html", STATIC["index.html"])
        if parts[0] == "static" and "/".join(parts[1:]) in STATIC:
            name = "/".join(parts[1:])
            return self._file(STATIC_DIR / name, STATIC[name])
        if url.path == "/api/scene.json":
            return self._scene(parse_qs(url.query))
        if len(parts) >= 4 and parts[0] == "api" and parts[1].isdigit():
            return self._scene_file(int(parts[1]), parts[2:])
        return self._not_found()

    def _scene(self, query: dict) -> None:
        selections = {k: v[0] for k, v in query.items() if k in VIEW_VARIANT_SETS and v}
        try:
            key, scene = self.server.state.scene(selections)
        except InputError as exc:
            body = json.dumps({"error": str(exc)}).encode()
            return self._send(HTTPStatus.UNPROCESSABLE_ENTITY, body, "application/json")
        data = copy.deepcopy(scene.description())
        prefix = f"/api/{key}"
        for mesh in data["meshes"]:
            mesh["url"] = f"{prefix}/mesh/{mesh['id']}.bin"
        for material in data["materials"]:
            if material["kind"] == "feather":
                for key in ("table", "albedo"):
                    material[key] = prefix + material[key].removeprefix("/api")
                material["maps"] = {k: prefix + v for k, v in material["maps"].items()}
        self._send(HTTPStatus.OK, json.dumps(data).encode(), "application/json")

    def _scene_file(self, key: int, parts: list[str]) -> None:
        scenes = self.server.state.scenes
        if key >= len(scenes):
            return self._not_found()
        scene = scenes[key]
        kind, rest = parts[0], "/".join(parts[1:])
        if kind in ("mesh", "table", "albedo") and len(parts) == 2 and rest.endswith(".bin"):
            index = rest.removesuffix(".bin")
            items = scene.meshes if kind == "mesh" else scene.tables
            if not index.isdigit() or int(index) >= len(items):
                return self._not_found()
            item = items[int(index)]
            if kind == "mesh":
                body = item.payload()[1]
            else:
                body = item.texture_bytes() if kind == "table" else item.albedo_bytes()
            return self._send(HTTPStatus.OK, body, "application/octet-stream")
        if kind == "files" and rest in scene.files:
            path = scene.files[rest]
            return self._file(path, MAP_TYPES.get(path.suffix.lower(), "application/octet-stream"))
        return self._not_found()

    # -- POST ---------------------------------------------------------------------------------
    def do_POST(self) -> None:
        if not self._host_ok():
            return
        origin = self.headers.get("Origin")
        if origin is not None and origin != self.server.url.rstrip("/"):
            return self._send(HTTPStatus.FORBIDDEN, b"wrong Origin\n", "text/plain")
        if urlsplit(self.path).path != "/api/render":
            return self._not_found()
        if self.headers.get("Content-Type", "").split(";")[0].strip() != "application/json":
            return self._send(HTTPStatus.UNSUPPORTED_MEDIA_TYPE, b"JSON only\n", "text/plain")
        try:
            length = int(self.headers.get("Content-Length", "0"))
        except ValueError:
            length = -1
        if not 0 < length <= MAX_BODY:
            return self._send(HTTPStatus.BAD_REQUEST, b"bad Content-Length\n", "text/plain")
        try:
            view = json.loads(self.rfile.read(length))
            png = render_view(self.server.state, view)
        except (ValueError, InputError) as exc:
            return self._send(HTTPStatus.BAD_REQUEST, f"{exc}\n".encode(), "text/plain")
        except RenderFailed as exc:
            return self._send(HTTPStatus.INTERNAL_SERVER_ERROR, f"{exc}\n".encode(), "text/plain")
        self._send(HTTPStatus.OK, png, "image/png")


class RenderFailed(RuntimeError):
    """``pavonine render`` exited non-zero (its last line of stderr)."""


def render_command(layer: Path, camera: str, view: dict, png: Path) -> list[str]:
    """The ``pavonine render`` command line for a view layer."""
    return [
        sys.executable,
        "-m",
        "pavonine.apps.cli",
        "render",
        str(layer),
        "-o",
        str(png.with_suffix(".exr")),
        "--png-out",
        str(png),
        "--camera",
        camera,
        "--resolution",
        f"{view['width']}x{view['height']}",
        "--spp",
        str(view["spp"]),
    ]


def render_view(state: ViewState, view: dict) -> bytes:
    """Render the page's view with ``pavonine render`` (one at a time); the PNG's bytes."""
    from pavonine.apps.view.viewpoint import check_view, write_view_layer

    if not isinstance(view, dict):
        raise InputError("view", "expected a JSON object")
    view.setdefault("spp", state.render_spp)
    checked = check_view(view)
    selections = {k: v for k, v in checked["variants"].items() if k in VIEW_VARIANT_SETS}
    _, scene = state.scene(selections)
    with state.render_lock, tempfile.TemporaryDirectory(prefix="pavonine-view-") as tmp:
        folder = Path(tmp)
        layer, camera = write_view_layer(scene, view, folder)
        png = folder / "view.png"
        done = subprocess.run(
            render_command(layer, camera, checked, png),
            capture_output=True,
            text=True,
            timeout=RENDER_TIMEOUT_S,
            check=False,
        )
        if done.returncode != 0 or not png.is_file():
            last = (done.stderr.strip().splitlines() or ["no output"])[-1]
            raise RenderFailed(f"pavonine render failed: {last}")
        return png.read_bytes()
