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


def _rachis_centre_line(path: Path) -> np.ndarray:
    """The shaft's centre line: the mean of each ring of its points (a ring's points share
    their feather coordinate ``v``; the tip's cone, narrowing to its apex, left out)."""
    layer = Sdf.Layer.OpenAsAnonymous(str(path))
    rachis = layer.rootPrims[0].nameChildren["Geom"].nameChildren["Rachis"]
    points = np.array(rachis.attributes["points"].default, dtype=float)
    v = np.round(np.array(rachis.attributes["primvars:pavonine_featherUV"].default)[:, 1], 6)
    rings = [points[v == level] for level in np.unique(v)]
    centre = np.array([ring.mean(axis=0) for ring in rings if len(ring) >= 8])
    return centre[np.argsort(centre[:, 1])]


def test_the_shipped_eye_rachis_is_arched_and_its_barbs_follow_it():
    """The shaft bends back with the sheet (``bend_cm``: ``z = −bend·v²``, every level and the
    barbs alike): over the vane (``v`` from 0 to ``t = rachis_length``) a parabola's sagitta
    over its chord is ``bend·t/(4L)`` to first order, 2·0.74/120 = 1.23 % on the eye (measured
    1.23 % of a 22.43 cm chord). The rachis barbs' roots lie at the shaft's depth at their
    height (measured within 0.033 cm)."""
    geometry = tomllib.loads(RECIPE.read_text())["geometry"]
    centre = _rachis_centre_line(LAYER)
    vane = centre[centre[:, 1] >= 0.0]
    chord = vane[-1] - vane[0]
    length = np.linalg.norm(chord)
    rel = vane - vane[0]
    off = rel - np.outer(rel @ chord, chord) / length**2
    sagitta = float(np.linalg.norm(off, axis=1).max()) / length
    expected = geometry["bend_cm"] * geometry["rachis_length"] / (4.0 * geometry["length_cm"])
    barbs = Sdf.Layer.OpenAsAnonymous(str(LAYER.with_name("eye_feather_geo_barbs.usdc")))
    curves = None
    for prim in barbs.rootPrims[0].nameChildren["Geom"].nameChildren:
        if prim.typeName == "BasisCurves":
            curves = prim
    assert curves is not None
    points = np.array(curves.attributes["points"].default, dtype=float)
    counts = np.array(curves.attributes["curveVertexCounts"].default)
    roots = points[np.cumsum(counts) - counts]
    below = roots[:, 1] < vane[-1, 1] - 0.5  # the rachis barbs (the fan starts at the tip)
    depth = roots[below, 2] - np.interp(roots[below, 1], centre[:, 1], centre[:, 2])
    print(
        f"\nrachis sagitta {sagitta:.2%} of its chord ({length:.2f} cm; parabola {expected:.2%}); "
        f"{below.sum()} barb roots within {np.abs(depth).max():.3f} cm of its depth"
    )
    assert sagitta == pytest.approx(expected, rel=0.05)
    assert sagitta >= 0.01
    assert np.abs(depth).max() <= 0.05
