"""Acceptance (issue 33, "the feather's form", barbs level): the shipped eye feather's barbs
are no comb lying on the sheet.

Measured from ``assets/feathers/eye_feather/eye_feather_geo_barbs.usdc`` (read as a layer, never
edited): the 95th percentile of the barb points' distances from their best-fit plane (one
plane for all points) as a share of the feather's length (the points' extent along it), the
median barb bow (largest distance of a barb's points from its chord / chord length), and the
root-gap CV (std / mean of the gaps between consecutive roots along the rachis, each side).

    pytest tests/pipeline/test_barb_form.py -s   # prints the figures
"""

from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np
import pytest
from barb_layer import curve_attributes

from pavonine.pipeline.convert.barb_form import FormOptions, apply_form

REPO = Path(__file__).resolve().parents[2]
LAYER = REPO / "assets" / "feathers" / "eye_feather" / "eye_feather_geo_barbs.usdc"
RECIPE = REPO / "assets" / "recipes" / "eye_feather.toml"


def _barbs() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Points (cm), vertex counts and feather coordinates of the shipped eye feather's barbs."""
    attrs = curve_attributes(LAYER)
    points = attrs["points"].astype(float)
    counts = attrs["curveVertexCounts"].astype(int)
    return points, counts, attrs["primvars:pavonine_featherUV"].astype(float)


def form_figures(
    points: np.ndarray, counts: np.ndarray, uv: np.ndarray, rachis_top: float, width_cm: float
) -> tuple[float, float, list[float]]:
    """(plane p95 / length, median bow, [root-gap CV left, right]) of concatenated barbs; the
    rachis barbs are those whose root lies below the rachis tip (``rachis_top``, a share of the
    mapped length), split by the side of the centre line (``width_cm`` the mapped width)."""
    starts = np.cumsum(counts) - counts
    length = np.ptp(points[:, 1])
    centred = points - points.mean(axis=0)
    normal = np.linalg.svd(centred, full_matrices=False)[2][2]
    plane = float(np.percentile(np.abs(centred @ normal), 95)) / length
    bows = []
    for start, n in zip(starts, counts, strict=True):
        barb = points[start : start + n]
        chord = barb[-1] - barb[0]
        chord_length = np.linalg.norm(chord)
        if n < 3 or chord_length < 1e-9:
            continue
        rel = barb - barb[0]
        off = rel - np.outer(rel @ chord, chord) / chord_length**2
        bows.append(np.linalg.norm(off, axis=1).max() / chord_length)
    roots_uv = uv[starts]
    side = np.sign(roots_uv[:, 0] - 0.5) * width_cm
    cvs = []
    for sign in (-1.0, 1.0):
        chosen = (np.sign(side) == sign) & (roots_uv[:, 1] < rachis_top - 0.01)
        roots = points[starts][chosen][np.argsort(roots_uv[chosen, 1])]
        gaps = np.linalg.norm(np.diff(roots, axis=0), axis=1)
        cvs.append(float(gaps.std() / gaps.mean()))
    return plane, float(np.median(bows)), cvs


def test_the_shipped_eye_feathers_barbs_have_a_form():
    recipe = tomllib.loads(RECIPE.read_text())
    geometry = recipe["geometry"]
    points, counts, uv = _barbs()
    width = geometry["length_cm"] * 0.5  # the eye maps' 1:2 aspect
    plane, bow, cvs = form_figures(points, counts, uv, geometry["rachis_length"], width)
    print(
        f"\nplane p95 {plane:.2%} of the length, median bow {bow:.2%}, "
        f"root-gap CV {cvs[0]:.3f} / {cvs[1]:.3f} ({len(counts)} barbs)"
    )
    assert plane >= 0.025
    assert bow >= 0.03
    assert min(cvs) >= 0.08


def _comb(barbs: int = 6, n: int = 12):
    """Straight barbs in the plane z = 0 leaving x = 0 every 0.2 cm up y, 3 cm long."""
    from pavonine.pipeline.convert.barb_polylines import BarbCurves

    s = np.linspace(0.0, 3.0, n)
    points = np.concatenate(
        [np.column_stack([s, np.full(n, 0.2 * i), 0 * s]) for i in range(barbs)]
    )
    v = len(points)
    curves = BarbCurves(
        counts=np.full(barbs, n, np.int32),
        points=points,
        normals=np.tile([0.0, 0.0, 1.0], (v, 1)),
        widths=np.full(v, 0.2),
        feather_uv=np.zeros((v, 2)),
        tangent=np.tile([1.0, 0.0, 0.0], (v, 1)),
        ocellar_class=np.ones(v, int),
        gradation=np.zeros(v),
        melanin=np.zeros(v),
        barbule_angle_deg=np.zeros(v),
        coverage=np.where(np.tile(s, barbs) > 1.5, 0.2, 1.0),  # loose beyond 1.5 cm
        barb_id=np.arange(barbs, dtype=np.int32),
    )
    along = np.tile([0.0, 1.0, 0.0], (v, 1))
    return curves, along, np.ones(barbs, bool)


def test_the_form_is_deterministic_and_keeps_frames_orthonormal():
    curves, along, rachis = _comb()
    a = apply_form(curves, along, rachis, 0.2, 7.5, FormOptions(), seed=3)
    b = apply_form(curves, along, rachis, 0.2, 7.5, FormOptions(), seed=3)
    c = apply_form(curves, along, rachis, 0.2, 7.5, FormOptions(), seed=4)
    assert np.array_equal(a.points, b.points) and not np.array_equal(a.points, c.points)
    assert np.allclose(np.linalg.norm(a.tangent, axis=1), 1.0)
    assert np.allclose(np.linalg.norm(a.normals, axis=1), 1.0)
    assert np.abs(np.sum(a.tangent * a.normals, axis=1)).max() < 1e-9
    assert len(a.points) == len(a.widths) == int(a.counts.sum())


def test_loose_tails_droop_out_of_the_vane_and_interlocked_parts_stay_in_it():
    curves, along, rachis = _comb()
    flat = FormOptions(camber=0.0, bow=0.0, bow_out=0.0, root_jitter=0.0, length_jitter=0.0)
    moved = apply_form(curves, along, rachis, 0.2, 7.5, flat, seed=1)
    s = moved.points[:, 0]
    assert np.allclose(moved.points[s <= 1.5, 2], 0.0)  # hooked barbules hold the vane
    tips = np.cumsum(moved.counts) - 1
    assert np.all(moved.points[tips, 2] < -0.2)  # loose tails hang behind the vane
    off = apply_form(curves, along, rachis, 0.2, 7.5, FormOptions(enabled=False), seed=1)
    assert off is curves


@pytest.mark.parametrize("jitter", [0.0, 0.05, 0.1])  # below the ±0.4 clip
def test_root_jitter_sets_the_gap_spread(jitter):
    curves, along, rachis = _comb(barbs=400, n=3)
    options = FormOptions(camber=0.0, bow=0.0, bow_out=0.0, droop_deg=0.0, root_jitter=jitter)
    moved = apply_form(curves, along, rachis, 0.2, 7.5, options, seed=2)
    roots = moved.points[np.cumsum(moved.counts) - moved.counts, 1]
    gaps = np.diff(roots)
    assert np.all(gaps > 0.0)  # barbs keep their order
    assert gaps.std() / gaps.mean() == pytest.approx(np.sqrt(2.0) * jitter, abs=0.02)
