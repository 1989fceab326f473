"""``pavonine view`` tested as a server: loopback only, a closed list of files, the Host check,
concurrency, clients that go away, and its bad input (missing asset, unreadable map, port in use).

One real ``pavonine view`` process serves a copy of the shipped eye whose melanin map is a
symlink to a file outside the asset folder.
"""

from __future__ import annotations

import http.client
import json
import os
import shutil
import socket
import struct
import subprocess
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from urllib.parse import urlsplit

import pytest
from browser import COMMAND, start_view, stop

REPO = Path(__file__).resolve().parents[2]
EYE = REPO / "assets" / "feathers" / "eye_feather"


def copy_eye(folder: Path) -> Path:
    target = folder / "eye_feather"
    shutil.copytree(EYE, target)
    return target


@pytest.fixture(scope="module")
def server(tmp_path_factory):
    folder = tmp_path_factory.mktemp("view")
    asset = copy_eye(folder)
    outside = folder / "outside"
    outside.mkdir()
    shutil.move(asset / "maps" / "melanin.png", outside / "melanin.png")
    os.symlink(outside / "melanin.png", asset / "maps" / "melanin.png")
    process, url = start_view(str(asset))
    parts = urlsplit(url)
    yield {"process": process, "url": url, "host": parts.hostname, "port": parts.port}
    if process.poll() is None:
        process.kill()
        process.wait()


def get(server, path: str, host: str | None = None, method: str = "GET", body=None, headers=None):
    conn = http.client.HTTPConnection(server["host"], server["port"], timeout=60)
    conn.putrequest(method, path, skip_host=True, skip_accept_encoding=True)
    conn.putheader("Host", f"{server['host']}:{server['port']}" if host is None else host)
    for k, v in (headers or {}).items():
        conn.putheader(k, v)
    if body is not None:
        conn.putheader("Content-Length", str(len(body)))
    conn.endheaders(body)
    response = conn.getresponse()
    data = response.read()
    conn.close()
    return response.status, data


def test_prints_a_loopback_url_and_listens_on_loopback_only(server):
    assert server["host"] == "127.0.0.1" and server["port"] > 0
    port_hex = f"{server['port']:04X}"
    listening = [
        line.split()[1]
        for line in Path("/proc/net/tcp").read_text().splitlines()[1:]
        if line.split()[1].endswith(f":{port_hex}") and line.split()[3] == "0A"
    ]
    assert listening == [f"0100007F:{port_hex}"], listening  # 127.0.0.1 only
    assert not [
        line
        for line in Path("/proc/net/tcp6").read_text().splitlines()[1:]
        if line.split()[1].endswith(f":{port_hex}") and line.split()[3] == "0A"
    ]


def test_serves_the_page_its_scripts_and_the_stage(server):
    status, page = get(server, "/")
    assert status == 200 and b"/static/main.js" in page
    for name in ("main.js", "feather.js", "loader.js", "view.css", "vendor/three.min.js"):
        assert get(server, f"/static/{name}")[0] == 200, name
    status, body = get(server, "/api/scene.json")
    scene = json.loads(body)
    assert status == 200 and {m["path"].rsplit("/", 1)[1] for m in scene["meshes"]} >= {"Vane"}
    feather = next(m for m in scene["materials"] if m["kind"] == "feather")
    assert set(feather["maps"]) == {"alpha", "ocellar", "gradation", "angle", "displacement"}
    for mesh in scene["meshes"]:
        status, data = get(server, mesh["url"])
        end = max(o + n * 4 for o, n in mesh["layout"].values())
        assert status == 200 and len(data) == end
    status, table = get(server, feather["table"])
    meta = feather["tableMeta"]
    cells = meta["axes"] * meta["classes"] * meta["gradations"] * meta["thetaSteps"]
    assert status == 200 and len(table) == cells * meta["slopeSteps"] * 4 * 2
    for url in feather["maps"].values():
        status, data = get(server, url)
        assert status == 200 and data[:8] == b"\x89PNG\r\n\x1a\n"
    assert any("melanin map" in w and "outside its asset" in w for w in scene["warnings"])


@pytest.mark.parametrize(
    "path",
    [
        "/../etc/passwd",
        "/static/../server.py",
        "/static/%2e%2e/server.py",
        "/static/vendor/../../scene.py",
        "/static/vendor/build.sh",
        "//etc/passwd",
        "/etc/passwd",
        "/api/0/files/../../eye_feather.usd",
        "/api/0/files/0/../../../eye_feather.usd",
        "/api/0/files/0/melanin.png",
        "/api/0/files/99/alpha.png",
        "/api/0/mesh/7.bin",
        "/api/1/mesh/0.bin",
        "/api/0/table/0.bin/../..",
        "/eye_feather.usd",
        "/maps/alpha.png",
        "/static/",
    ],
)
def test_anything_else_is_404(server, path):
    assert get(server, path)[0] == 404


def test_a_symlinked_map_out_of_the_asset_is_not_served(server):
    scene = json.loads(get(server, "/api/scene.json")[1])
    urls = [u for m in scene["materials"] if m["kind"] == "feather" for u in m["maps"].values()]
    assert not [u for u in urls if "melanin" in u]
    for n in range(8):
        assert get(server, f"/api/0/files/{n}/melanin.png")[0] == 404


@pytest.mark.parametrize(
    "host", ["evil.example:80", "localhost:{port}", "127.0.0.1", "127.0.0.1:1", "", "[::1]:{port}"]
)
def test_a_foreign_host_header_is_refused(server, host):
    status, _ = get(server, "/", host=host.format(port=server["port"]))
    assert status == 403
    assert get(server, "/api/scene.json", host=host.format(port=server["port"]))[0] == 403


def test_render_post_from_another_origin_or_not_json_is_refused(server):
    body = b"{}"
    assert (
        get(
            server,
            "/api/render",
            method="POST",
            body=body,
            headers={"Origin": "http://evil.example", "Content-Type": "application/json"},
        )[0]
        == 403
    )
    assert (
        get(
            server, "/api/render", method="POST", body=body, headers={"Content-Type": "text/plain"}
        )[0]
        == 415
    )
    status, text = get(
        server,
        "/api/render",
        method="POST",
        body=b'{"eye": [0, 0]}',
        headers={"Content-Type": "application/json"},
    )
    assert status == 400 and b"view.eye" in text


def test_a_hundred_concurrent_requests(server):
    size = len(get(server, "/static/vendor/three.min.js")[1])
    paths = ["/static/vendor/three.min.js", "/api/scene.json", "/", "/nothing"] * 25
    with ThreadPoolExecutor(max_workers=100) as pool:
        results = list(pool.map(lambda p: (p, *get(server, p)), paths))
    for path, status, data in results:
        if path == "/nothing":
            assert status == 404
        else:
            assert status == 200, path
        if path.endswith("three.min.js"):
            assert len(data) == size
    assert get(server, "/")[0] == 200


def test_clients_that_disconnect_mid_transfer_leave_it_serving(server):
    for reset in (False, True, False, True, True):
        sock = socket.create_connection((server["host"], server["port"]), timeout=30)
        host = f"{server['host']}:{server['port']}"
        sock.sendall(f"GET /static/vendor/three.min.js HTTP/1.1\r\nHost: {host}\r\n\r\n".encode())
        assert sock.recv(1024).startswith(b"HTTP/1.1 200")
        if reset:  # RST instead of FIN
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
        sock.close()
    half = socket.create_connection((server["host"], server["port"]), timeout=30)
    half.sendall(b"GET / HTTP/1.1\r\nHo")  # a request that never ends, left open
    assert get(server, "/")[0] == 200
    assert len(get(server, "/static/vendor/three.min.js")[1]) > 100_000
    half.close()


def test_port_in_use_is_one_line_and_nonzero(server):
    done = subprocess.run(
        [*COMMAND, str(EYE), "--port", str(server["port"])],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 2
    assert done.stderr.strip().count("\n") == 0
    assert f"--port: {server['port']} is in use" in done.stderr


def test_ctrl_c_stops_it_cleanly(server):
    code, out = stop(server["process"])
    assert code == 0 and "stopped" in out


def test_missing_asset_is_one_line_and_nonzero(tmp_path):
    done = subprocess.run(
        [*COMMAND, str(tmp_path / "nowhere")], capture_output=True, text=True, timeout=120
    )
    assert done.returncode == 2
    assert done.stderr.strip() == f"error: {tmp_path / 'nowhere'}: no such USD file"


def test_unreadable_map_is_one_line_and_nonzero(tmp_path):
    asset = copy_eye(tmp_path)
    (asset / "maps" / "ocellar.png").write_bytes(b"not a png at all")
    done = subprocess.run([*COMMAND, str(asset)], capture_output=True, text=True, timeout=240)
    assert done.returncode == 2, done.stderr
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and "ocellar.png" in lines[0] and "ocellar map" in lines[0], lines
