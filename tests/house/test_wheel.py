"""The wheel is self-contained: built from the tracked files, installed into a fresh virtual
environment, it runs ``pavonine demo`` and ``pavonine check-renders`` outside any checkout.

The temporary environment gets the wheel with ``--no-deps``; its dependencies come from the
environment running the tests, through a ``.pth`` file naming that environment's site-packages.
(``--system-site-packages`` alone is not enough: on a clean clone the dependencies live in the
project's ``.venv``, not in the base interpreter.) So the test does not download 1 GB, and what it
checks is the wheel itself: package data, entry point, imports that do not reach into a checkout.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]

pytestmark = [pytest.mark.render, pytest.mark.convert]


def run(*args, cwd: Path, env: dict | None = None, timeout: int = 600):
    return subprocess.run(
        [str(a) for a in args],
        cwd=cwd,
        env=env,
        capture_output=True,
        text=True,
        timeout=timeout,
        check=False,
    )


def tracked_copy(target: Path) -> Path:
    """The repository's tracked files (what a clean clone has), copied to ``target``."""
    listing = run("git", "ls-files", "-z", cwd=REPO) if shutil.which("git") else None
    if listing is None or listing.returncode != 0:
        pytest.skip("needs git to list the tracked files")
    for name in filter(None, listing.stdout.split("\0")):
        source = REPO / name
        if source.is_file():
            (target / name).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(source, target / name)
    return target


def site_dirs() -> list[str]:
    """Where this interpreter finds the dependencies: its site-packages folders (the project's
    ``.venv`` inside the checkout among them). Only their modules are visible through a ``.pth``
    line, not their ``.pth`` files, so the editable install of the checkout stays out."""
    dirs = [
        str(Path(entry).resolve())
        for entry in sys.path
        if Path(entry).name in ("site-packages", "dist-packages") and Path(entry).is_dir()
    ]
    return list(dict.fromkeys(dirs))


@pytest.fixture(scope="module")
def installed(tmp_path_factory) -> tuple[Path, dict]:
    work = tmp_path_factory.mktemp("wheel")
    source = tracked_copy(work / "src")
    built = run(
        sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation",
        "--disable-pip-version-check", "-v", "-w", work / "dist", source, cwd=work,
    )  # fmt: skip
    assert built.returncode == 0, built.stderr
    [wheel] = list((work / "dist").glob("pavonine-*.whl"))
    venv = work / "venv"
    made = run(sys.executable, "-m", "venv", "--without-pip", venv, cwd=work)
    assert made.returncode == 0, made.stderr
    python = venv / "bin" / "python"
    added = run(
        sys.executable, "-m", "pip", "--python", python, "install", "--no-deps",
        "--disable-pip-version-check", "-q", wheel, cwd=work,
    )  # fmt: skip
    assert added.returncode == 0, added.stderr
    purelib = run(
        python, "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])", cwd=work
    )
    (Path(purelib.stdout.strip()) / "_pavonine_test_deps.pth").write_text(
        "\n".join(site_dirs()) + "\n"
    )
    env = {k: v for k, v in os.environ.items() if not k.startswith(("PYTHON", "PXR_", "OCIO"))}
    env["PATH"] = f"{venv / 'bin'}{os.pathsep}{env.get('PATH', '')}"
    (work / "elsewhere").mkdir()
    return wheel, {
        "venv": venv,
        "env": env,
        "cwd": work / "elsewhere",
        "build_log": built.stdout + built.stderr,
    }


def test_the_build_lists_every_data_folder_as_a_package(installed):
    """setuptools warns, once per folder, about package-data folders missing from ``packages``
    (and says a later version may leave their files out); setup.py lists them."""
    _, where = installed
    assert "Building wheel for pavonine" in where["build_log"]  # -v shows the backend's output
    assert "is absent from the `packages` configuration" not in where["build_log"]


def test_wheel_carries_the_shipped_data_and_the_licence(installed):
    from pavonine.apps.view.server import STATIC as VIEW_STATIC

    wheel, _ = installed
    names = set(zipfile.ZipFile(wheel).namelist())
    for name in (
        "pavonine/assets/scenes/eye_feather_sun.usda",
        "pavonine/assets/recipes/eye_feather.toml",
        "pavonine/assets/feathers/eye_feather/eye_feather.usd",
        *(
            f"pavonine/assets/{p.relative_to(REPO / 'assets').as_posix()}"
            for p in (REPO / "assets" / "feathers").rglob("*")
            if p.is_file()
        ),
        "pavonine/assets/baselines/eye_feather_sun/mean.exr",
        "pavonine/materials/data/cie1931_d65_1nm.csv",
        "pavonine/schemas/plugInfo.json",
        "pavonine/schemas/shaderDefs/ND_pavonine_feather_surfaceshader.usda",
        "pavonine/schemas/shaderDefs/ND_image_float.usda",
        "pavonine-0.1.0.dist-info/licenses/LICENSE",
        # pavonine view's page and the vendored three.js with its licence (nothing fetched)
        *(f"pavonine/apps/view/static/{n}" for n in VIEW_STATIC),
        "pavonine/apps/view/static/vendor/LICENSE.three",
    ):
        assert name in names, name
    assert not [n for n in names if n.startswith(("tests/", "docs/", "benchmarks/"))]
    # every shipped scene with what it references (feathers, assemblies, textures), every
    # baseline, recipe and map: all tracked assets but the maps' contact sheets
    tracked = run("git", "ls-files", "assets", cwd=REPO).stdout.split()
    shipped = [f"pavonine/{n}" for n in tracked if not n.endswith("/contact_sheet.png")]
    assert len(shipped) > 150
    assert not [n for n in shipped if n not in names]
    metadata = zipfile.ZipFile(wheel).read("pavonine-0.1.0.dist-info/METADATA").decode()
    assert "License-Expression: Apache-2.0" in metadata
    assert "Provides-Extra: render" in metadata and "Provides-Extra: convert" in metadata


def test_installed_package_is_the_wheel_not_the_checkout(installed):
    _, where = installed
    probe = run(
        where["venv"] / "bin" / "python", "-c",
        "import pavonine, pavonine.base.shipped as s; print(pavonine.__file__); print(s.assets_dir())",
        cwd=where["cwd"], env=where["env"],
    )  # fmt: skip
    assert probe.returncode == 0, probe.stderr
    module, assets = probe.stdout.split()
    assert Path(module).is_relative_to(where["venv"]) and Path(assets).is_relative_to(where["venv"])


def test_demo_runs_from_the_wheel_outside_the_checkout(installed):
    _, where = installed
    demo = run(
        "pavonine", "-q", "demo", "-o", "demo", "--size", "64", "--spp", "2",
        "--resolution", "24x36", "--json", "-", cwd=where["cwd"], env=where["env"],
    )  # fmt: skip
    assert demo.returncode == 0, demo.stderr
    report = json.loads(demo.stdout)
    png = where["cwd"] / report["png"]
    assert png.is_file() and png.read_bytes()[:4] == b"\x89PNG"


def test_check_renders_and_baselines_from_the_wheel(installed):
    """Every shipped scene has its baseline in the wheel, and checks against it from there."""
    _, where = installed
    listing = run("pavonine", "baseline", "list", "--json", "-", cwd=where["cwd"], env=where["env"])
    assert listing.returncode == 0, listing.stderr
    rows = {row["scene"]: row for row in json.loads(listing.stdout)["baselines"]}
    here = subprocess.run(
        [sys.executable, "-m", "pavonine.apps.cli", "baseline", "list", "--json", "-"],
        capture_output=True, text=True, cwd=REPO, check=False,
    )  # fmt: skip
    checkout_rows = {row["scene"]: row for row in json.loads(here.stdout)["baselines"]}
    scenes = sorted(p.stem for p in (REPO / "assets" / "scenes").glob("*.usda"))
    assert sorted(rows) == sorted(checkout_rows) == scenes
    assert {"eye_feather_sun", "peacock_train", "light_dome"} <= set(scenes)
    for scene, row in rows.items():
        # the wheel carries the very scene, feathers and maps each baseline records (or not, alike)
        assert row["inputs_changed"] == checkout_rows[scene]["inputs_changed"], scene
    # Rendering every scene again is test_check_renders' job (the inputs are the same, above):
    # from the wheel, a feather scene (maps and feathers as package data) and the dome (its
    # texture) render and pass against the wheel's baselines.
    from_wheel = ["eye_feather_sun", "light_dome"]
    checked = run(
        "pavonine", "-q", "check-renders", *from_wheel, "--json", "-", cwd=where["cwd"],
        env=where["env"], timeout=1800,
    )  # fmt: skip
    assert checked.returncode == 0, checked.stdout + checked.stderr
    report = json.loads(checked.stdout)
    assert report["passed"] is True
    assert sorted(report["scenes"]) == from_wheel
    refused = run(
        "pavonine", "baseline", "update", "eye_feather_sun", cwd=where["cwd"], env=where["env"]
    )
    assert refused.returncode == 2 and "belong to the installed package" in refused.stderr
