"""A feather authored undisplaced, displaced at render time, against the converter's baked mesh.

Both come from the same maps and recipe: ``convert`` bakes ``displacement_cm`` into the vane's
points; the other conversion has ``displacement_cm = 0`` and its material carries
``pavonine:displacementHeight`` with the same height, which the renderer applies
(render/displacement.py through base/map_filters.displacement_heights, the one formula).
The streak heights must agree vertex for vertex, and the hero view must agree within noise, while
the undisplaced feather does not.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest

from pavonine.render.diagnostics import StageWarning

pytestmark = [pytest.mark.render, pytest.mark.convert]

HEIGHT_CM = 0.5  # streaks ten times the shipped feathers', so that the control can fail
SIZE = (48, 72)
SPP = 32


@pytest.fixture(scope="module")
def feathers(tmp_path_factory):
    """(baked stage, displaced-at-render-time stage, undisplaced stage) of the eye feather."""
    from conftest import convert_eye

    work = tmp_path_factory.mktemp("feather_displacement")
    for name, cm in (("baked", HEIGHT_CM), ("flat", 0.0)):
        convert_eye(work, f"eye_{name}", f"displacement_cm = {cm}\n", "8000, 2000, 500", 32)
    scene = (Path(__file__).parents[2] / "assets/scenes/eye_feather_sun.usda").read_text()
    over = (
        '    )\n    {\n        over "Materials"\n        {\n            over "Feather"\n'
        f"            {{\n                float pavonine:displacementHeight = {HEIGHT_CM}\n"
        "            }\n        }\n    }\n"
    )
    stages = []
    for name, asset, displaced in (
        ("baked", "baked", False),
        ("displaced", "flat", True),
        ("flat", "flat", False),
    ):
        text = scene.replace(
            "@../feathers/eye_feather/eye_feather.usd@", f"@{work}/out/eye_{asset}/eye_{asset}.usd@"
        )
        if displaced:
            text = text.replace("    )\n    {\n    }\n", over, 1)
        path = work / f"{name}.usda"
        path.write_text(text)
        stages.append(path)
    return stages


def vane(stage_path):
    """The vane's built triangles (world space) and, when displaced later, its placeholder."""
    from pavonine.render.delegate import StageDelegate, open_stage, render_time
    from pavonine.render.diagnostics import Diagnostics

    diag = Diagnostics()
    stage = open_stage(stage_path, diag)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", StageWarning)
        shapes = StageDelegate(stage, render_time(stage, None), diag).sync().shapes
    return next(v for k, v in shapes.items() if "Vane" in k)


def test_render_time_displacement_gives_the_baked_streak_heights(feathers):
    import mitsuba as mi

    from pavonine.render import displacement

    baked, displaced, _ = feathers
    points = np.array(mi.traverse(vane(baked))["vertex_positions"]).reshape(-1, 3)
    item = vane(displaced)
    assert isinstance(item, displacement.DisplacedMesh)
    moved = displacement.displace(item.triangles, item.displacement, item.matrix_usd, item.tangents)
    before = np.linalg.norm(item.triangles.positions - points, axis=1)
    after = np.linalg.norm(moved.positions - points, axis=1)
    assert before.max() > 0.5 * HEIGHT_CM  # the streaks are there to be found
    assert after.max() < 0.01 * HEIGHT_CM  # float precision: measured 5e-4 cm at 0.5 cm


def blocks(rgb: np.ndarray, f: int = 4) -> np.ndarray:
    h, w = rgb.shape[0] // f * f, rgb.shape[1] // f * f
    return rgb[:h, :w].reshape(h // f, f, w // f, f, -1).mean(axis=(1, 3))


def test_hero_view_matches_the_baked_feather_within_noise(feathers):
    from pavonine.render.api import render_stage

    baked, displaced, flat = feathers

    def render(path, seed):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", StageWarning)
            return blocks(
                render_stage(path, spp=SPP, resolution=SIZE, seed=seed, progress=False).rgb
            )

    reference = render(baked, 0)
    scale = reference.mean()
    noise = np.abs(render(baked, 1) - reference).mean() / scale
    same = np.abs(render(displaced, 2) - reference).mean() / scale
    control = np.abs(render(flat, 3) - reference).mean() / scale
    assert same < 1.3 * noise, (same, noise)
    assert control > 1.5 * noise, (control, noise)  # the test can tell streaks from none
