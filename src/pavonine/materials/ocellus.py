"""The ocellar class below the map's texel: a smooth class field, thresholded.

The ocellar map holds one class per texel (grey ``g`` → class ``round((1 − g)(n − 1))``); read
per texel, a ring boundary is a staircase of texels (293 µm on the shipped eye feather, whose map
is 512 × 1024 over 15 × 30 cm), plain in any close-up. A boundary at a shallow angle to the
texel grid is a staircase of long runs (one texel step every ``P`` texels), a periodic error of
half a texel that a filter shorter than ``P`` keeps. So the grey is smoothed with a Gaussian of
:data:`SMOOTHING_TEXELS` texels, read bilinearly and only *then* rounded to a class: the
boundary becomes the smooth field's iso-line at the two classes' mid-grey. A staircase of period
``P`` keeps ``exp(−2π² σ² / P²)`` of its amplitude (the Gaussian's transfer function at ``1/P``):
0.11 for ``P = 12`` texels. Every point still gets exactly one of the map's classes (never a
blend of two stacks). The price: features narrower than about 2σ (a ring under 6 texels wide, a
sharp corner) are rounded off, and a boundary of radius ``R`` moves inward by about ``σ²/(2R)``
(0.09 texel for the eye's 50-texel dark centre).
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage

#: Gaussian σ (texels of the ocellar map) of the smooth class field.
SMOOTHING_TEXELS = 3.0


def smooth_class_field(grey: np.ndarray, sigma_texels: float = SMOOTHING_TEXELS) -> np.ndarray:
    """The ocellar grey ``[row, column]`` smoothed for sub-texel class boundaries (float32)."""
    values = np.asarray(grey, dtype=np.float32)
    return ndimage.gaussian_filter(values, sigma_texels, mode="nearest").astype(np.float32)
