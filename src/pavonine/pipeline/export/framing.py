"""Where a viewer frames a stage: the default eye of ``pavonine view``'s page (a stage without a
camera) and the viewer ``pavonine export`` fits a feather's glTF look for, one framing for both.
"""

from __future__ import annotations

import numpy as np

#: How far in front of its centre (bounding radii, along +Z) the page puts its eye when the stage
#: has no camera (with a 39.6° vertical field of view): also the viewer ``pavonine export`` fits
#: its look for by default.
FRAMING_RADII = 2.6


def stage_bound(stage) -> tuple[np.ndarray, np.ndarray]:
    """``(lo, hi)``: the world-space bound of the stage's default- and render-purpose geometry,
    the box the page frames."""
    from pxr import Usd, UsdGeom

    from pavonine.base.nesting import deep_call

    purposes = [UsdGeom.Tokens.default_, UsdGeom.Tokens.render]
    bbox = UsdGeom.BBoxCache(Usd.TimeCode.Default(), purposes)
    # recurses once per level of nesting: on a deep stack (pavonine.base.nesting)
    box = deep_call(bbox.ComputeWorldBound, stage.GetPseudoRoot()).ComputeAlignedRange()
    return np.array(box.GetMin(), dtype=np.float64), np.array(box.GetMax(), dtype=np.float64)


def framing(lo, hi) -> tuple[np.ndarray, np.ndarray, float]:
    """``(eye, centre, radius)`` for a bound ``[lo, hi]`` (world space): its centre, its radius
    (half its diagonal) and the default eye, :data:`FRAMING_RADII` radii in front (+Z) of the
    centre, looking at it."""
    lo, hi = np.asarray(lo, dtype=np.float64), np.asarray(hi, dtype=np.float64)
    centre, radius = (lo + hi) / 2.0, max(float(np.linalg.norm(hi - lo)) / 2.0, 1e-3)
    return centre + np.array([0.0, 0.0, FRAMING_RADII * radius]), centre, radius
