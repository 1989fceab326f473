"""Headless Chromium driven over the DevTools protocol, with the standard library only.

A minimal RFC 6455 client (text frames, client masking) is enough for the protocol's JSON
messages: :class:`Browser` starts ``chromium --headless=new`` with software WebGL
(SwiftShader), opens a URL and evaluates scripts in the page (promises awaited).
"""

from __future__ import annotations

import base64
import json
import os
import re
import shutil
import signal
import socket
import struct
import subprocess
import sys
import tempfile
import time
import urllib.request
from pathlib import Path
from urllib.parse import urlsplit

CHROMIUM_FLAGS = (
    "--headless=new",
    "--use-gl=swiftshader",
    "--enable-unsafe-swiftshader",
    "--ignore-gpu-blocklist",
    "--no-sandbox",
    "--no-first-run",
    "--no-default-browser-check",
    "--disable-extensions",
    "--disable-background-networking",
    "--hide-scrollbars",
    "--mute-audio",
)


#: ``pavonine view`` as the tests start it.
COMMAND = [sys.executable, "-m", "pavonine.apps.cli", "view"]


def start_view(*args: str, timeout: float = 240.0) -> tuple[subprocess.Popen, str]:
    """Start ``pavonine view ARGS``; the process and the URL it printed."""
    process = subprocess.Popen(
        [*COMMAND, *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        line = process.stdout.readline()
        if "http://" in line:
            return process, line.split("at ", 1)[1].split()[0]
        if not line and process.poll() is not None:
            raise AssertionError(f"pavonine view exited: {process.stderr.read()}")
    process.kill()
    raise AssertionError("pavonine view printed no URL")


def stop(process: subprocess.Popen) -> tuple[int, str]:
    """Ctrl-C the server; its exit status and the rest of its stdout."""
    process.send_signal(signal.SIGINT)
    out, _ = process.communicate(timeout=30)
    return process.returncode, out


def chromium() -> str | None:
    """The Chromium executable on PATH, if any."""
    return shutil.which("chromium") or shutil.which("chromium-browser")


class WebSocket:
    """Blocking text-frame WebSocket client (enough for the DevTools protocol)."""

    def __init__(self, url: str, timeout: float = 120.0):
        parts = urlsplit(url)
        self.sock = socket.create_connection((parts.hostname, parts.port), timeout=timeout)
        key = base64.b64encode(os.urandom(16)).decode()
        request = (
            f"GET {parts.path} HTTP/1.1\r\nHost: {parts.hostname}:{parts.port}\r\n"
            "Upgrade: websocket\r\nConnection: Upgrade\r\n"
            f"Sec-WebSocket-Key: {key}\r\nSec-WebSocket-Version: 13\r\n\r\n"
        )
        self.sock.sendall(request.encode())
        head = b""
        while b"\r\n\r\n" not in head:
            chunk = self.sock.recv(1)
            if not chunk:
                raise ConnectionError("websocket handshake: connection closed")
            head += chunk
        if b" 101 " not in head.split(b"\r\n", 1)[0]:
            raise ConnectionError(f"websocket handshake: {head[:80]!r}")

    def send(self, text: str) -> None:
        data = text.encode()
        header = bytes([0x81])
        n = len(data)
        if n < 126:
            header += bytes([0x80 | n])
        elif n < 1 << 16:
            header += bytes([0x80 | 126]) + struct.pack(">H", n)
        else:
            header += bytes([0x80 | 127]) + struct.pack(">Q", n)
        mask = os.urandom(4)
        self.sock.sendall(header + mask + bytes(b ^ mask[i % 4] for i, b in enumerate(data)))

    def _exact(self, n: int) -> bytes:
        out = bytearray()
        while len(out) < n:
            chunk = self.sock.recv(n - len(out))
            if not chunk:
                raise ConnectionError("websocket closed")
            out += chunk
        return bytes(out)

    def receive(self) -> str:
        message = b""
        while True:
            b0, b1 = self._exact(2)
            n = b1 & 0x7F
            if n == 126:
                n = struct.unpack(">H", self._exact(2))[0]
            elif n == 127:
                n = struct.unpack(">Q", self._exact(8))[0]
            payload = self._exact(n)
            opcode = b0 & 0x0F
            if opcode == 0x8:
                raise ConnectionError("websocket closed by the browser")
            if opcode in (0x9, 0xA):
                continue
            message += payload
            if b0 & 0x80:
                return message.decode()

    def close(self) -> None:
        self.sock.close()


class _Page:
    """What both browsers share: polling the page, and ending the browser and its profile."""

    process: subprocess.Popen
    profile: str
    ws: WebSocket

    next_id = 0

    @staticmethod
    def _failure(message: dict):
        """The error an answer carries (the protocols differ), else ``None``."""
        raise NotImplementedError

    def call(self, method: str, **params):
        """Send a command and wait for its answer (events in between are dropped)."""
        self.next_id += 1
        self.ws.send(json.dumps({"id": self.next_id, "method": method, "params": params}))
        while True:
            message = json.loads(self.ws.receive())
            if message.get("id") == self.next_id:
                failure = self._failure(message)
                if failure is not None:
                    raise RuntimeError(f"{method}: {failure}")
                return message.get("result", {})

    def evaluate(self, expression: str, timeout_s: float = 300.0):
        raise NotImplementedError

    def wait_for(self, expression: str, timeout_s: float = 120.0) -> None:
        """Poll until ``expression`` is truthy in the page (it may not exist yet)."""
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            try:
                if self.evaluate(expression):
                    return
            except RuntimeError:
                pass
            time.sleep(0.2)
        raise TimeoutError(expression)

    def close(self) -> None:
        try:
            self.ws.close()
        finally:
            self.process.terminate()
            try:
                self.process.wait(timeout=15)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait()
            shutil.rmtree(self.profile, ignore_errors=True)

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        self.close()


class Browser(_Page):
    """One headless Chromium with one page at ``url`` (a context manager)."""

    def __init__(self, url: str, width: int, height: int, executable: str | None = None):
        self.profile = tempfile.mkdtemp(prefix="pavonine-chromium-")
        exe = executable or chromium()
        if exe is None:
            raise FileNotFoundError("chromium")
        self.process = subprocess.Popen(
            [
                exe,
                *CHROMIUM_FLAGS,
                f"--user-data-dir={self.profile}",
                "--remote-debugging-port=0",
                f"--window-size={width},{height}",
                "about:blank",
            ],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.PIPE,
            text=True,
        )
        port = self._devtools_port()
        pages = json.load(urllib.request.urlopen(f"http://127.0.0.1:{port}/json/list", timeout=30))
        page = next(p for p in pages if p["type"] == "page")
        self.ws = WebSocket(page["webSocketDebuggerUrl"])
        self.next_id = 0
        self.call("Page.enable")
        self.call("Runtime.enable")
        self.size(width, height)
        self.call("Page.navigate", url=url)

    def _devtools_port(self) -> int:
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline:
            line = self.process.stderr.readline()
            found = re.search(r"DevTools listening on ws://[^:]+:(\d+)/", line)
            if found:
                return int(found.group(1))
            if not line and self.process.poll() is not None:
                break
        raise RuntimeError("chromium did not start its DevTools server")

    @staticmethod
    def _failure(message: dict):
        return message.get("error")

    def size(self, width: int, height: int) -> None:
        self.call(
            "Emulation.setDeviceMetricsOverride",
            width=width,
            height=height,
            deviceScaleFactor=1,
            mobile=False,
        )

    def evaluate(self, expression: str, timeout_s: float = 300.0):
        """The value of a script in the page (a promise is awaited)."""
        self.ws.sock.settimeout(timeout_s)
        result = self.call(
            "Runtime.evaluate", expression=expression, awaitPromise=True, returnByValue=True
        )
        if "exceptionDetails" in result:
            details = result["exceptionDetails"]
            text = details.get("exception", {}).get("description") or details.get("text")
            raise RuntimeError(f"page script failed: {text}")
        return result["result"].get("value")

    def screenshot(self) -> bytes:
        """The page as PNG bytes."""
        return base64.b64decode(self.call("Page.captureScreenshot", format="png")["data"])


def firefox() -> str | None:
    """Firefox (ESR) on PATH, if any."""
    return shutil.which("firefox-esr") or shutil.which("firefox")


class Firefox(_Page):
    """One Firefox with one page at ``url``, driven over WebDriver BiDi (a context manager).

    Headless Firefox has no WebGL on a machine without a GPU; it runs windowed on the X display
    in ``$DISPLAY`` (e.g. ``Xvfb``), where Mesa's llvmpipe gives it WebGL 2.
    """

    PREFS = (
        'user_pref("webgl.force-enabled", true);\n'
        'user_pref("webgl.disable-fail-if-major-performance-caveat", true);\n'
    )

    def __init__(self, url: str, width: int, height: int):
        self.profile = tempfile.mkdtemp(prefix="pavonine-firefox-")
        Path(self.profile, "user.js").write_text(self.PREFS)
        with socket.socket() as s:
            s.bind(("127.0.0.1", 0))
            port = s.getsockname()[1]
        self.process = subprocess.Popen(
            [
                firefox(),
                "--remote-debugging-port",
                str(port),
                "--profile",
                self.profile,
                "--no-remote",
                f"--window-size={width},{height}",
            ],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.PIPE,
            text=True,
        )
        deadline = time.monotonic() + 90
        while "WebDriver BiDi listening" not in self.process.stderr.readline():
            if time.monotonic() > deadline or self.process.poll() is not None:
                raise RuntimeError("firefox did not start WebDriver BiDi")
        self.ws = WebSocket(f"ws://127.0.0.1:{port}/session")
        self.next_id = 0
        self.call("session.new", capabilities={})
        self.context = self.call("browsingContext.getTree")["contexts"][0]["context"]
        self.call(
            "browsingContext.setViewport",
            context=self.context,
            viewport={"width": width, "height": height},
        )
        self.call("browsingContext.navigate", context=self.context, url=url, wait="complete")

    @staticmethod
    def _failure(message: dict):
        return message.get("message") if message.get("type") == "error" else None

    def evaluate(self, expression: str, timeout_s: float = 300.0):
        self.ws.sock.settimeout(timeout_s)
        result = self.call(
            "script.evaluate",
            expression=expression,
            target={"context": self.context},
            awaitPromise=True,
        )
        if result.get("type") == "exception":
            raise RuntimeError(f"page script failed: {result['exceptionDetails'].get('text')}")
        return result["result"].get("value")
