"""The barbs of a converted asset's barbs layer (``*_geo_barbs.usdc``), read for the tests."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from pxr import Sdf


def curve_attributes(path: Path) -> dict[str, np.ndarray]:
    """The barbs' ``BasisCurves`` attributes of the layer at ``path`` as arrays, by attribute name
    (``points``, ``curveVertexCounts``, ``primvars:…``); the layer is opened as a private copy, so
    the shipped file stays untouched."""
    layer = Sdf.Layer.OpenAsAnonymous(str(path))
    curves = None
    for prim in layer.rootPrims[0].nameChildren["Geom"].nameChildren:
        if prim.typeName == "BasisCurves":
            curves = prim
    assert curves is not None, f"{path}: no barbs"
    return {
        spec.name: np.array(spec.default)
        for spec in curves.attributes
        if spec.default is not None and not isinstance(spec.default, (str, Sdf.AssetPath))
    }
