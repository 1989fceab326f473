"""The static HTML comparison report, opened in headless Chromium."""

from __future__ import annotations

import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from pavonine.apps.compare.methods import compare_arrays
from pavonine.apps.compare.report import SceneEntry, write_report

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")


def entries() -> list[SceneEntry]:
    rng = np.random.default_rng(0)
    y, x = np.mgrid[0:48, 0:64] / 64
    base = np.stack([0.2 + 0.5 * x, 0.3 + 0.1 * y, 0.2 + 0.0 * x], axis=-1).astype(np.float32)
    noise = 0.01 * rng.normal(size=base.shape).astype(np.float32)
    changed = base.copy()
    changed[10:30, 20:40] *= 1.5
    out = []
    for name, test in (("eye <feather>", base + noise), ("blue_body", changed + noise)):
        results = [
            compare_arrays(test, base, m, ref_variance=np.full_like(base, 1e-4))
            for m in ("stat", "flip")
        ]
        out.append(SceneEntry(name, test, base, results, metadata={"spp": 64}))
    return out


def test_report_writes_page_images_and_escapes_names(tmp_path: Path):
    page = write_report(tmp_path / "report", entries())
    text = page.read_text()
    assert "eye &lt;feather&gt;" in text and "<feather>" not in text
    sources = re.findall(r'<img src="([^"]+)"', text)
    assert len(sources) == 2 * 4
    for src in sources:
        assert (page.parent / src).is_file()
    assert "FAIL" in text and "differences found" in text
    assert "mean_flip" in text and "fail_8x8" in text


def chromium(*args: str, user_data: Path) -> subprocess.CompletedProcess:
    return subprocess.run(
        [
            CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu",
            "--disable-background-networking", "--disable-component-update", "--disable-sync",
            "--no-first-run", f"--user-data-dir={user_data}", "--virtual-time-budget=5000", *args,
        ],
        capture_output=True, text=True, timeout=120, check=False,
    )  # fmt: skip


@pytest.mark.skipif(
    CHROMIUM is None, reason="Debian's chromium is not installed (.ci/setup installs it)"
)
def test_every_report_image_loads_in_headless_chromium(tmp_path: Path):
    page = write_report(tmp_path / "report", entries())
    dom = chromium("--dump-dom", page.as_uri(), user_data=tmp_path / "profile")
    assert dom.returncode == 0, dom.stderr[-2000:]
    status = re.search(r'<pre id="image-status">(.*?)</pre>', dom.stdout, re.S)
    assert status, dom.stdout[-2000:]
    lines = status.group(1).strip().splitlines()
    assert len(lines) == 8
    for line in lines:
        assert line.startswith("loaded 64x48 "), line
    shot = tmp_path / "shot.png"
    chromium(
        "--window-size=1200,900",
        f"--screenshot={shot}",
        page.as_uri(),
        user_data=tmp_path / "profile",
    )
    assert shot.is_file() and shot.stat().st_size > 10_000


@pytest.mark.skipif(
    CHROMIUM is None, reason="Debian's chromium is not installed (.ci/setup installs it)"
)
def test_a_missing_image_is_reported_broken(tmp_path: Path):
    page = write_report(tmp_path / "report", entries())
    next((page.parent / "images").glob("*-flip-diff.png")).unlink()
    dom = chromium("--dump-dom", page.as_uri(), user_data=tmp_path / "profile")
    status = re.search(r'<pre id="image-status">(.*?)</pre>', dom.stdout, re.S)
    assert status
    assert sum(line.startswith("broken ") for line in status.group(1).splitlines()) == 1
