"""``benchmarks/usd_suites.py``: its checks can fail, its camera is usdrecord's, a small suite runs."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import numpy as np
import pytest

SCRIPT = Path(__file__).parents[2] / "benchmarks" / "usd_suites.py"


@pytest.fixture(scope="module")
def suites():
    spec = importlib.util.spec_from_file_location("usd_suites", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_stages_without_camera_use_the_renderer_s_default_view(suites):
    """The script has no framing camera of its own: the renderer's is usdrecord's."""
    source = SCRIPT.read_text()
    assert "camera_translator.default_view(" in source and "usd_view_resolution(" in source
    assert not hasattr(suites, "usdrecord_camera_matrix")


def test_silhouette_agreement_and_checks_can_fail(suites, tmp_path):
    import OpenImageIO as oiio

    reference = np.zeros((40, 40, 4), np.float32)
    reference[10:30, 10:30, 3] = 1.0
    path = tmp_path / "screenshots" / "x_usdrecord_22.08.png"
    path.parent.mkdir()
    out = oiio.ImageBuf(oiio.ImageSpec(40, 40, 4, oiio.UINT8))
    out.set_pixels(oiio.ROI(0, 40, 0, 40), reference)
    out.write(str(path))
    same = np.zeros((20, 20))
    same[5:15, 5:15] = 1.0
    iou, inside, ref_cover = suites.silhouette_agreement(same, path)
    assert iou == pytest.approx(1.0) and inside == pytest.approx(1.0) and ref_cover == 0.25
    shifted = np.roll(same, 4, axis=1)
    assert suites.silhouette_agreement(shifted, path)[0] < suites.SILHOUETTE_IOU
    metrics = {
        "status": "ok",
        "gprims": 1,
        "coverage": 0.0,
        "lit_luminance": 0.0,
        "warnings": ["/Box: NurbsPatch prims are not supported by the Mitsuba delegate; skipped"],
        "silhouette_iou": 0.5,
        "inside_reference": 0.5,
        "reference_coverage": 0.25,
        "subdivided": 0,
    }
    outcome = suites.checks(metrics)
    assert outcome == {
        "runs": True,
        "coverage": False,
        "lit": None,
        "silhouette": False,
        "supported": False,
    }
    assert suites.checks({"status": "traceback"}) == {"runs": False}


@pytest.mark.render
def test_a_small_suite_runs_and_reports(suites, tmp_path, monkeypatch):
    suite = tmp_path / "test_assets"
    suite.mkdir()
    (suite / "ball.usda").write_text('#usda 1.0\ndef Sphere "Ball"\n{\n    double radius = 2\n}\n')
    (suite / "broken.usda").write_text(
        '#usda 1.0\ndef Mesh "M" {\n  point3f[] points = [(0, 0\n}\n'
    )
    out = tmp_path / "out"
    assert suites.main([str(suite), "-o", str(out), "--size", "24", "--spp", "2"]) == 0
    rows = {row["name"]: row for row in json.loads((out / "report.json").read_text())}
    assert rows["ball.usda"]["passed"], rows["ball.usda"]
    assert rows["ball.usda"]["metrics"]["coverage"] > 0.2
    broken = rows["broken.usda"]
    assert (
        broken["checks"] == {"runs": False}
        and "cannot open USD stage" in broken["metrics"]["detail"]
    )
    assert (out / "contact_sheet.png").stat().st_size > 0

    # --resume reuses each stage the worker finished (its metrics.json, the unreadable one's too)
    # and runs again only the one without (here: deleted, as a timed-out or crashed worker leaves)
    (Path(rows["ball.usda"]["out"]) / "metrics.json").unlink()
    launched = []
    real_run = suites.subprocess.run

    def counting_run(cmd, **kwargs):
        launched.append(Path(cmd[3]).name)
        return real_run(cmd, **kwargs)

    monkeypatch.setattr(suites.subprocess, "run", counting_run)
    assert suites.main([str(suite), "-o", str(out), "--size", "24", "--spp", "2", "--resume"]) == 0
    monkeypatch.undo()
    assert launched == ["ball.usda"]
    again = {row["name"]: row for row in json.loads((out / "report.json").read_text())}
    assert (
        again["ball.usda"]["passed"]
        and again["ball.usda"]["metrics"]["coverage"] == (rows["ball.usda"]["metrics"]["coverage"])
    )
