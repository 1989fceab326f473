"""Every warning is the command's own ``warning: …`` line (issue 27): ``baseline update`` printed
Python's ``…/lights/common.py:70: StageWarning: …``, ``compare`` NumPy's ``overflow encountered in
cast``, and a light of intensity 3e38 rendered black without a word. The session-wide check
(``tests/conftest.py``, ``_no_raw_warnings``) holds every CLI run of the suite to it."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest
from conftest import raw_warnings

QUAD = """#usda 1.0
(
    upAxis = "Y"
)
def Mesh "Quad"
{{
    int[] faceVertexCounts = [4]
    int[] faceVertexIndices = [0, 1, 2, 3]
    point3f[] points = [(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)]
    uniform token subdivisionScheme = "none"
    color3f[] primvars:displayColor = [(0.8, 0.8, 0.8)] (interpolation = "constant")
}}
def DistantLight "Lamp"
{{
    float inputs:intensity = {intensity}
    float inputs:exposure = {exposure}
}}
def Camera "Cam"
{{
    double3 xformOp:translate = (0, 0, 6)
    uniform token[] xformOpOrder = ["xformOp:translate"]
}}
"""


def lit_quad(folder: Path, name: str, intensity: str = "10", exposure: str = "0") -> Path:
    path = folder / f"{name}.usda"
    path.write_text(QUAD.format(intensity=intensity, exposure=exposure))
    return path


def run(*args):
    from click.testing import CliRunner

    from pavonine.apps.cli import cli

    return CliRunner().invoke(cli, [str(a) for a in args])


def test_the_check_knows_python_and_numpy_warnings_from_the_commands_own_lines():
    assert raw_warnings("/x/render/lights/common.py:70: StageWarning: /L: bad\n  warn(...)\n")
    assert raw_warnings("methods.py:228: RuntimeWarning: overflow encountered in cast")
    assert raw_warnings("warning: overflow encountered in cast")  # NumPy's words, rerouted
    assert not raw_warnings("warning: /L: inputs:exposure = nan is not a finite number\n")
    assert not raw_warnings("error: out/x.exr: cannot write: No space left on device\n")


def test_a_library_warning_inside_a_command_is_a_warning_line(capsys):
    from pavonine.apps.cli.options import configure_logging, warnings_as_lines

    configure_logging()
    with warnings_as_lines():
        warnings.warn("a library's deprecation", FutureWarning, stacklevel=1)
    err = capsys.readouterr().err
    assert err.strip() == "warning: a library's deprecation", err


def test_compare_of_images_beyond_float32_variance_has_no_numpy_warning(tmp_path):
    """The noise variance of values near 1e20 overflowed float32 ('overflow encountered in
    cast'), and near 3e38 made the Z-test pass two images differing by half their value."""
    from pavonine.render.imageio import write_exr

    rng = np.random.default_rng(0)
    for value in (1e20, 3e38):
        a = (rng.random((16, 16, 3)) * value).astype(np.float32)
        write_exr(tmp_path / "a.exr", a, {})
        write_exr(tmp_path / "b.exr", a * np.float32(0.5), {})
        with warnings.catch_warnings():
            warnings.simplefilter("error")  # a NumPy warning fails here, whatever routes it
            result = run("compare", tmp_path / "a.exr", tmp_path / "b.exr", "-o", tmp_path, "-q")
        assert result.exception is None or isinstance(result.exception, SystemExit)
        assert not raw_warnings(result.stderr), result.stderr
        assert result.exit_code == 1, (value, result.output)  # they differ by half


@pytest.mark.render
def test_baseline_update_warns_through_its_own_line(tmp_path):
    stage = lit_quad(tmp_path, "lamp", exposure="nan")
    result = run("baseline", "update", stage, "--resolution", "8x8", "--spp", "64",
                 "--check-spp", "32", "--scenes-dir", tmp_path,
                 "--baselines-dir", tmp_path / "b")  # fmt: skip
    assert result.exit_code == 0, result.stderr
    assert "warning: /Lamp: inputs:exposure = nan is not a finite number" in result.stderr
    assert not raw_warnings(result.stderr), result.stderr
    assert "StageWarning" not in result.stderr


@pytest.mark.render
def test_a_light_beyond_float32_is_warned_by_name_where_a_bright_one_renders(tmp_path):
    from pavonine.render.imageio import read_exr

    means = {}
    for intensity in ("1e38", "3e38"):
        stage = lit_quad(tmp_path, f"l{intensity}", intensity=intensity)
        out = tmp_path / f"l{intensity}.exr"
        result = run("render", stage, "-o", out, "--resolution", "8x8", "--spp", "2",
                     "--camera", "/Cam", "-q")  # fmt: skip
        assert result.exit_code == 0, result.stderr
        assert not raw_warnings(result.stderr), result.stderr
        overflow = [line for line in result.stderr.splitlines() if "beyond the" in line]
        if intensity == "3e38":
            assert len(overflow) == 1 and overflow[0].startswith("warning: /Lamp: inputs:intensity")
            assert "emits 3e+38" in overflow[0], overflow
        else:
            assert not overflow, result.stderr
        means[intensity] = float(np.nanmean(np.asarray(read_exr(out)[0])))
    assert means["1e38"] > 1e30, means  # bright
    assert means["3e38"] == 0.0, means  # skipped, and still the stage's lighting: no default sun
    exposure = lit_quad(tmp_path, "exposed", intensity="1e38", exposure="2")  # 4e38 after 2^2
    result = run("render", exposure, "-o", tmp_path / "e.exr", "--resolution", "8x8", "--spp",
                 "2", "--camera", "/Cam", "-q")  # fmt: skip
    assert "emits 4e+38" in result.stderr, result.stderr
