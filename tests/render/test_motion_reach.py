"""How far the moving scene travels in the image within the shutter, and the slices that follow
from it (``pavonine.render.motion.reach``). The stage: ``tests/motion_scene.py`` (a quad crossing
the image at 32 pixels a frame)."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest
from motion_scene import SIZE, SPEED, UNITS_PER_PIXEL, motion_stage

from pavonine.render.api import render_stage
from pavonine.render.diagnostics import StageWarning
from pavonine.render.motion import blur
from pavonine.render.motion import reach as motion_reach
from pavonine.render.options import RenderOptions

pytestmark = pytest.mark.render
PIXELS_PER_FRAME = SPEED / UNITS_PER_PIXEL  # 32


def render(path: Path, **options):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", StageWarning)
        return render_stage(path, RenderOptions(progress=False, **{"time": 1.0, **options}))


@pytest.mark.parametrize("how", ["xform", "points", "velocities", "instancer", "prototype"])
def test_reach_is_the_image_motion_within_the_shutter(tmp_path, how):
    """The quad moves 32 px a frame; half a frame of shutter is 16 px of reach, and 16 slices of
    one pixel each (however the quad moves: transform, points, velocities, an instance, a
    prototype's points)."""
    path = tmp_path / "moving.usda"
    motion_stage(path, (-0.25, 0.25), how)
    result = render(path, spp=64, resolution=SIZE)
    assert result.metadata["motion_reach_px"] == pytest.approx(0.5 * PIXELS_PER_FRAME, abs=0.3)
    assert result.metadata["time_slices"] == min(blur.DEFAULT_SLICES, 64 // 8)


def test_slow_motion_takes_fewer_slices_and_still_averages_its_sub_frames(tmp_path):
    """A shutter of 0.1 frame: 3.2 px of reach, 4 slices instead of the samples' 8; the image is
    the mean of the 4 instantaneous renders at the slices' times with the slices' seeds."""
    path = tmp_path / "slow.usda"
    shutter = (-0.05, 0.05)
    motion_stage(path, shutter)
    result = render(path, spp=64, seed=3)
    assert result.metadata["motion_reach_px"] == pytest.approx(0.1 * PIXELS_PER_FRAME, abs=0.2)
    assert result.metadata["time_slices"] == 4
    times = blur.Shutter(*shutter).times(1.0, 4, 3)
    sharp = tmp_path / "sharp.usda"
    motion_stage(sharp, None)
    frames = [
        render(sharp, spp=16, time=t, seed=blur.slice_seed(3, i, 4)).rgb
        for i, t in enumerate(times)
    ]
    np.testing.assert_allclose(result.rgb, np.mean(frames, axis=0), atol=1e-5)


def test_a_swing_out_and_back_counts_its_whole_path(tmp_path):
    """The quad goes 8 px right and comes back within the shutter: its ends are where they were,
    but its path is 16 px, and so are the slices."""
    path = tmp_path / "swing.usda"
    motion_stage(path, (-0.25, 0.25), samples={0.75: 0.0, 1.0: 8 * UNITS_PER_PIXEL, 1.25: 0.0})
    result = render(path, spp=128)
    assert result.metadata["motion_reach_px"] == pytest.approx(16.0, abs=0.3)
    assert result.metadata["time_slices"] == 16


def test_a_moving_camera_leaves_the_slices_to_the_samples(tmp_path):
    """A moving camera moves every point: the reach is not estimated, the samples decide."""
    path = tmp_path / "camera.usda"
    motion_stage(path, (-0.25, 0.25), "camera")
    result = render(path, spp=32)
    assert "motion_reach_px" not in result.metadata
    assert result.metadata["time_slices"] == 4


def test_asked_slices_are_kept_whatever_the_motion(tmp_path):
    path = tmp_path / "slow.usda"
    motion_stage(path, (-0.05, 0.05))
    result = render(path, spp=64, motion_slices=8)
    assert result.metadata["time_slices"] == 8 and "motion_reach_px" not in result.metadata


@pytest.mark.parametrize("reach, slices", [(0.0, 1), (0.4, 1), (1.0, 1), (1.01, 2), (4.2, 5)])
def test_slices_keep_each_step_within_a_pixel(reach, slices):
    assert motion_reach.slices_for(reach) == slices
    assert motion_reach.slices_for(None) is None
    assert motion_reach.slices_for(float("nan")) is None


def test_a_nan_time_sample_leaves_the_slices_to_the_samples(tmp_path):
    """A NaN transform within the shutter is no path to follow: the samples decide (8 slices at
    64 spp), not a reach of zero."""
    path = tmp_path / "nan.usda"
    motion_stage(path, (-0.25, 0.25), samples={0.0: -1.0, 1.0: 0.0, 1.125: float("nan")})
    result = render(path, spp=64)
    assert "motion_reach_px" not in result.metadata
    assert result.metadata["time_slices"] == 8
