"""How the six maps of paper §3.3 store their values in [0, 1] (docs/pipeline.md, "Maps"): the
ocellar class as a grey level, the barbule angle as a grey level."""

from __future__ import annotations

import numpy as np

MAP_NAMES = ("alpha", "ocellar", "gradation", "angle", "displacement", "melanin")
CLASS_COUNT = 6


def ocellar_grey(ocellar_class: np.ndarray | int, classes: int = CLASS_COUNT) -> np.ndarray:
    """Grey level of ocellar class ``k`` of ``n`` classes: ``1 - k/(n-1)`` (0 = white, n-1 = black).

    With the paper's six classes: ``1 - k/5``. A one-class material reads every grey as class 0
    and is painted white.
    """
    if classes <= 1:
        return np.ones_like(np.asarray(ocellar_class, dtype=np.float32))
    return 1.0 - np.asarray(ocellar_class, dtype=np.float32) / (classes - 1)


def ocellar_class(grey: np.ndarray, classes: int = CLASS_COUNT) -> np.ndarray:
    """Class of an ocellar grey level: the nearest level, ``k = round((1 - g)(n - 1))``."""
    k = np.rint((1.0 - np.asarray(grey, dtype=np.float64)) * max(classes - 1, 0))
    return np.clip(k, 0, max(classes - 1, 0)).astype(np.int32)


def angle_grey(angle_deg: np.ndarray) -> np.ndarray:
    """Angle-map grey of a barbule axis at ``angle_deg`` counter-clockwise from its barb
    (seen from the front): ``(angle mod 180°) / 180°`` (an axis: 180° is the same line as 0°)."""
    return (np.mod(np.asarray(angle_deg, dtype=np.float64), 180.0) / 180.0).astype(np.float32)


def angle_degrees(grey: np.ndarray) -> np.ndarray:
    """Inverse of :func:`angle_grey`: the barbule axis angle in degrees in [0, 180]."""
    return np.asarray(grey, dtype=np.float32) * 180.0
