"""The rachis ends in a taper, not a blunt cap (issue 33, "a tapered rachis tip").

From the shipped eye feather's high LOD (``assets/feathers/eye_feather/eye_feather_geo_high.usdc``,
read as a layer): the shaft's points near its end lie within the cone from its last ring
(radius ``rachis_tip_radius_cm``) to its apex :data:`TIP_TAPER_CM` further on.

    pytest tests/pipeline/test_rachis.py -s   # prints the figures
"""

from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np
import pytest
from pxr import Sdf

from pavonine.pipeline.convert.rachis import TIP_TAPER_CM, RachisSpec, base_rachis, rachis_positions
from pavonine.pipeline.convert.surface import FeatherFrame

REPO = Path(__file__).resolve().parents[2]
LAYER = REPO / "assets" / "feathers" / "eye_feather" / "eye_feather_geo_high.usdc"
RECIPE = REPO / "assets" / "recipes" / "eye_feather.toml"


def test_the_cap_is_a_cone_tip_taper_long():
    """A flat frame: the apex lies TIP_TAPER_CM past the top ring, the cone's radius falls
    linearly to it (half way: half the tip radius)."""
    frame = FeatherFrame(30.0, 0.5, 0.0, 0.0)
    spec = RachisSpec(5.0, 0.74, 0.14, 0.03)
    coords, _ = base_rachis(spec, frame)
    points, _ = rachis_positions(spec, frame, coords)
    top_ring = coords[:, 0] == spec.top
    apex = points[-1]
    assert apex[1] - points[top_ring, 1].mean() == pytest.approx(TIP_TAPER_CM, abs=1e-6)
    half = coords[top_ring] * 0.5 + coords[-1] * 0.5  # half way along the cone
    mid, _ = rachis_positions(spec, frame, half)
    centre = rachis_positions(spec, frame, np.array([[spec.top, 1.0, 0.0, 0.0]]))[0][0]
    radius = np.linalg.norm(mid[:, [0, 2]] - centre[[0, 2]], axis=1)
    assert np.allclose(radius, 0.5 * spec.tip_radius_cm, rtol=1e-6)


def test_the_shipped_eye_rachis_tapers_to_a_point():
    geometry = tomllib.loads(RECIPE.read_text())["geometry"]
    tip_radius = geometry["rachis_tip_radius_cm"]
    layer = Sdf.Layer.OpenAsAnonymous(str(LAYER))
    rachis = layer.rootPrims[0].nameChildren["Geom"].nameChildren["Rachis"]
    points = np.array(rachis.attributes["points"].default, dtype=float)
    apex = points[np.argmax(points[:, 1])]
    along = apex[1] - points[:, 1]
    axis_x = apex[0]
    near = along < TIP_TAPER_CM
    width = np.abs(points[near, 0] - axis_x)
    allowed = tip_radius * along[near] / TIP_TAPER_CM
    print(
        f"\nrachis tip: {near.sum()} points within {TIP_TAPER_CM} cm of the apex, widest "
        f"{width.max():.4f} cm (tip radius {tip_radius} cm)"
    )
    assert near.sum() >= 8
    assert np.all(width <= allowed + 0.002)  # inside the cone (bend and float32 aside)
