"""Without Debian's libatomic1 Dr.Jit (so Mitsuba) cannot load: ``pavonine demo`` still paints
and converts the feather and skips only the render, saying why; tests needing the renderer skip
with that reason instead of failing.

The library is made genuinely unloadable, not mocked: ``unshare -m`` gives the child a private
mount namespace in which ``/dev/null`` is bind-mounted over ``libatomic.so.1`` (the dynamic
loader then refuses it: "file too short"). That needs root and a kernel that allows mount
namespaces; elsewhere these tests skip, saying which is missing. ``test_without_libgl.py``
hides pymeshlab's libraries the same way.
"""

import glob
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.namespaces

ROOT = Path(__file__).resolve().parents[2]
#: Runs "$@" with /dev/null over every file in $LIBS, in a private mount namespace (nothing
#: leaks out of it).
HIDE = 'mount --make-rprivate / && for lib in $LIBS; do mount --bind /dev/null "$lib"; done && exec "$@"'


def hideable(*sonames: str) -> list[str]:
    """The real files behind ``sonames`` (as the loader finds them), or a skip saying why the
    test cannot hide them."""
    if os.geteuid() != 0:
        pytest.skip("hiding a system library needs root (a mount namespace with a bind mount)")
    if shutil.which("unshare") is None or shutil.which("mount") is None:
        pytest.skip("needs unshare(1) and mount(8) (util-linux)")
    libs = []
    for soname in sonames:
        found = sorted(glob.glob(f"/usr/lib/*/{soname}") + glob.glob(f"/lib/*/{soname}"))
        if not found:
            pytest.skip(f"{soname} is not installed: nothing to hide")
        libs.append(os.path.realpath(found[0]))
    libs = sorted(set(libs))
    check = subprocess.run(
        ["unshare", "-m", "sh", "-c", HIDE, "sh", "true"],
        env={**os.environ, "LIBS": " ".join(libs)},
        capture_output=True,
        text=True,
        check=False,
    )
    if check.returncode != 0:
        pytest.skip(f"this kernel or container refuses mount namespaces: {check.stderr.strip()}")
    return libs


def run_hiding(
    libs: list[str], *args: str, cwd: Path, timeout: float = 600
) -> subprocess.CompletedProcess:
    """``args`` in a mount namespace where ``libs`` cannot load (caches kept inside ``cwd``)."""
    env = {**os.environ, "LIBS": " ".join(libs), "PAVONINE_CACHE_DIR": str(cwd / "cache")}
    env.pop("DRJIT_LIBLLVM_PATH", None)  # as in a fresh shell
    return subprocess.run(
        ["unshare", "-m", "sh", "-c", HIDE, "sh", *args],
        env=env,
        cwd=cwd,
        capture_output=True,
        text=True,
        timeout=timeout,
        check=False,
    )


def run_hidden(*args: str, cwd: Path, timeout: float = 600) -> subprocess.CompletedProcess:
    """``args`` in a mount namespace where libatomic cannot load."""
    return run_hiding(hideable("libatomic.so.1"), *args, cwd=cwd, timeout=timeout)


@pytest.mark.convert
def test_demo_converts_and_skips_the_render_naming_the_package(tmp_path):
    out = tmp_path / "demo"
    cli = [sys.executable, "-m", "pavonine.apps.cli"]
    result = run_hidden(
        *cli, "demo", "-o", str(out), "--size", "64", "--spp", "1", "--resolution", "8x12",
        "--json", "-", cwd=tmp_path,
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    report = json.loads(result.stdout)
    assert "libatomic" in report["render_skipped"] and "libatomic1" in report["render_skipped"]
    assert report["png"] is None and report["exr"] is None
    warning = [line for line in result.stderr.splitlines() if "skipped the render" in line]
    assert len(warning) == 1, result.stderr
    assert "apt-get install libatomic1" in warning[0]
    assert "Traceback" not in result.stderr
    # Everything but the render is there: the maps, the converted asset, the scene.
    asset = Path(report["asset"])
    assert asset.is_file() and asset == out / "assets" / "eye_feather" / "eye_feather.usd"
    assert (out / "maps" / "eye" / "alpha.png").is_file()
    assert (out / "eye_feather_sun.usda").is_file()
    assert not (out / "eye_feather_sun.png").exists() and not (out / "eye_feather_sun.exr").exists()
    from pxr import Usd

    stage = Usd.Stage.Open(str(out / "eye_feather_sun.usda"))
    assert stage.GetPrimAtPath("/World/Feather").GetChildren(), "the scene must resolve the asset"


def test_render_tests_skip_with_the_reason_instead_of_failing(tmp_path):
    """The suite's conftest sees Dr.Jit fail to load: tests marked ``render`` and tests that
    import Mitsuba anyway are skipped, naming the package to install."""
    tests = ROOT / "tests"
    result = run_hidden(
        sys.executable, "-m", "pytest", "-q", "-rs", "-p", "no:cacheprovider",
        "--basetemp", str(tmp_path / "basetemp"), "--rootdir", str(ROOT),
        str(tests / "apps" / "test_demo.py::test_demo_paints_converts_and_renders"),
        str(tests / "render" / "test_feather_bsdf.py"),
        cwd=tmp_path,
    )  # fmt: skip
    assert result.returncode == 0, result.stdout + result.stderr
    summary = result.stdout.strip().splitlines()[-1]
    assert "skipped" in summary and "passed" not in summary and "error" not in summary, summary
    reasons = [line for line in result.stdout.splitlines() if line.startswith("SKIPPED")]
    assert reasons and all("apt-get install libatomic1" in line for line in reasons), reasons
