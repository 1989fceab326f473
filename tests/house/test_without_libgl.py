"""Without Debian's libgl1, libopengl0 and libgomp1 (a bare ``debian:bookworm``) pymeshlab cannot
load: ``pavonine convert`` still converts, meshing with NumPy, and says so in one warning.

The libraries are made genuinely unloadable, as in ``test_without_libatomic.py``: ``/dev/null``
is bind-mounted over the real files behind ``libGL.so.1``, ``libOpenGL.so.0`` and
``libgomp.so.1`` in a private mount namespace (root and ``unshare -m``; elsewhere this skips).
"""

import json
import sys
from pathlib import Path

import pytest
from test_without_libatomic import hideable, run_hiding

pytestmark = [pytest.mark.namespaces, pytest.mark.convert]

PYMESHLAB_LIBRARIES = ("libGL.so.1", "libOpenGL.so.0", "libgomp.so.1")


def test_convert_meshes_with_numpy_and_warns_once_naming_the_library(tmp_path):
    from test_convert import LOD, recipe_text

    from pavonine.pipeline.maps.paint import generate_maps, write_maps

    libs = hideable(*PYMESHLAB_LIBRARIES)
    write_maps(generate_maps("eye", 64, seed=4), tmp_path / "m")
    (tmp_path / "eye.toml").write_text(recipe_text("eye_feather"))
    cli = [sys.executable, "-m", "pavonine.apps.cli"]
    probe = run_hiding(libs, sys.executable, "-c", "import pymeshlab", cwd=tmp_path)
    assert probe.returncode != 0 and "libGL.so.1" in probe.stderr  # really hidden
    result = run_hiding(libs, *cli, "convert", "eye.toml", "-o", "out", "--json", "-", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    assert "Traceback" not in result.stderr
    warnings = [line for line in result.stderr.splitlines() if line.startswith("warning:")]
    assert len(warnings) == 1, result.stderr
    assert "NumPy" in warnings[0] and "libGL.so.1" in warnings[0] and "libgl1" in warnings[0]
    report = json.loads(result.stdout)
    assert report["failed"] == [] and len(report["converted"]) == 1
    triangles = report["converted"][0]["triangles"]
    for lod, target in LOD.items():
        assert 0.8 * target <= triangles[lod] <= 1.25 * target, (lod, triangles)
    asset = tmp_path / Path(report["converted"][0]["asset"])
    validate = run_hiding(libs, *cli, "validate", str(asset), cwd=tmp_path)
    assert validate.returncode == 0, validate.stdout + validate.stderr


def test_without_libopengl_only_the_filters_fail_and_stdout_stays_clean(tmp_path):
    """With libGL but not libOpenGL (Debian's libgl1 without libopengl0) pymeshlab imports but
    its filter plugins do not, and its loader prints a page about them to stdout: the probe
    keeps that page out of stdout (``--json -``) and still picks NumPy."""
    libs = hideable("libOpenGL.so.0")
    code = "from pavonine.pipeline.convert.meshing import meshing_backend as b; print(b().name)"
    result = run_hiding(libs, sys.executable, "-c", code, cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    assert result.stdout == "numpy\n"
    assert result.stderr.count("\n") == 1 and "libOpenGL.so.0" in result.stderr, result.stderr
    assert "libopengl0" in result.stderr
