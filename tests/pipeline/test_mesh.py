"""Feather geometry building blocks: silhouette cut, refinement, atlas checks, barb field."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import ndimage

pytest.importorskip("xatlas", reason="needs the [convert] extra", exc_type=ImportError)
pytestmark = pytest.mark.convert

from pavonine.pipeline.convert.atlas import (
    AtlasedMesh,
    build_atlas,
    st_flips,
    st_overlap_fraction,
)
from pavonine.pipeline.convert.barbs import (
    away_from_rachis,
    barb_direction_field,
    sample_direction,
)
from pavonine.pipeline.convert.refinement import refine
from pavonine.pipeline.convert.topology import edge_report
from pavonine.pipeline.convert.vane import clip_to_silhouette, grid_mesh, triangle_areas

CLEAN = {"non_manifold_edges": 0, "misoriented_edges": 0, "non_manifold_vertices": 0}


@settings(max_examples=25, deadline=None)
@given(
    cx=st.floats(0.2, 0.8),
    cy=st.floats(0.2, 0.8),
    radius=st.floats(0.1, 0.4),
    wobble=st.floats(0.0, 0.1),
    freq=st.integers(1, 7),
)
def test_silhouette_cut_is_manifold_without_slivers(cx, cy, radius, wobble, freq):
    uv, faces = grid_mesh(31, 23)
    angle = np.arctan2(uv[:, 1] - cy, uv[:, 0] - cx)
    level = radius * (1 + wobble * np.sin(freq * angle)) - np.hypot(uv[:, 0] - cx, uv[:, 1] - cy)
    cut_uv, cut_faces = clip_to_silhouette(uv, faces, level)
    assert edge_report(cut_faces, len(cut_uv)) == CLEAN
    area = triangle_areas(cut_uv, cut_faces)
    cell = 0.5 / (30 * 22)
    assert np.all(area > 0.15 * 0.15 * cell * 0.9)  # counter-clockwise and not thin
    # Every kept vertex is inside or on the contour (cut points sit on lattice edges).
    inside_level = radius * (1 + wobble) - np.hypot(cut_uv[:, 0] - cx, cut_uv[:, 1] - cy)
    assert np.all(inside_level > -0.05)


def _atlased_square(n: int = 6) -> AtlasedMesh:
    uv, faces = grid_mesh(n, n)
    points = np.column_stack([uv, 0.2 * uv[:, 0] ** 2])
    (mesh,), _ = build_atlas([(points, faces, uv)], resolution=256)
    return mesh


@pytest.mark.parametrize("n", [1, 2, 5])
def test_refinement_is_exact_for_linear_attributes_and_keeps_the_atlas(n):
    mesh = _atlased_square()
    refined = refine(mesh, n)
    assert len(refined.faces) == n * n * len(mesh.faces)
    assert edge_report(refined.faces, len(refined.attributes)) == CLEAN
    # Vertices shared by neighbouring coarse triangles are generated once (welded).
    unique = np.unique(np.round(refined.attributes, 12), axis=0)
    assert len(unique) == len(refined.attributes)
    # Face f of the welded mesh is face f of the atlas mesh.
    assert np.array_equal(refined.split_to_welded[refined.split_faces], refined.faces)
    fv = refined.st[refined.split_faces.ravel()]
    assert st_overlap_fraction(fv, 512) == 0.0
    assert st_flips(refined.st, refined.split_faces) == 0


def test_edge_report_finds_fins_bowties_and_flips():
    fin = np.array([[0, 1, 2], [1, 0, 3], [0, 1, 4]])
    assert edge_report(fin, 5)["non_manifold_edges"] == 1
    bowtie = np.array([[0, 1, 2], [0, 3, 4]])
    assert edge_report(bowtie, 5)["non_manifold_vertices"] == 1
    flipped = np.array([[0, 1, 2], [1, 2, 3]])  # edge 1→2 used twice in the same direction
    assert edge_report(flipped, 4)["misoriented_edges"] == 1
    good = np.array([[0, 1, 2], [2, 1, 3]])
    assert edge_report(good, 4) == CLEAN


def test_overlap_and_flip_checks():
    a = np.array([[0.1, 0.1], [0.5, 0.1], [0.1, 0.5]])
    mirrored = a * [-1, 1] + [1, 0]
    assert st_overlap_fraction(np.concatenate([a, mirrored]), 256) == 0.0
    shifted = a + 0.05
    assert st_overlap_fraction(np.concatenate([a, shifted]), 256) > 0.3
    quad = np.array([[0, 0], [1, 0], [0, 1], [1, 1], [2, 0]], float)
    strip = np.array([[0, 1, 2], [2, 1, 3], [1, 4, 3]])  # one chart, consistently wound
    assert st_flips(quad, strip) == 0
    assert st_flips(quad * [-1, 1], strip) == 0  # a mirrored chart is not a fold
    folded = quad.copy()
    folded[3] = (0.2, 0.2)  # vertex 3 pulled across edge 1-2: triangle (2, 1, 3) flips
    assert st_flips(folded, strip) == 1


@pytest.mark.parametrize("degrees", [20.0, 60.0, 90.0, 130.0])
def test_barb_direction_follows_the_streaks(degrees):
    rows, cols = np.mgrid[0:256, 0:256]
    x, y = cols + 0.5, 256 - rows - 0.5  # y up, as in feather space
    along = np.radians(degrees)
    across = np.array([-np.sin(along), np.cos(along)])
    streaks = 0.5 + 0.5 * np.cos(2 * np.pi * (x * across[0] + y * across[1]) / 8.0)
    field = barb_direction_field(streaks.astype(np.float32), max_size=256)
    centre = field[96:160, 96:160].reshape(-1, 2)
    expected = np.array([np.cos(along), np.sin(along)])
    assert np.all(np.abs(centre @ expected) > np.cos(np.radians(3)))  # an axis: sign free


def test_barb_direction_falls_back_to_the_shaft_without_streaks():
    field = barb_direction_field(np.full((64, 32), 0.4, np.float32))
    assert np.allclose(field[..., 0], 0) and np.allclose(field[..., 1], 1)


def test_barbs_too_fine_to_resolve_are_continued_radially_not_from_the_grain():
    """An eye: 120 barbs radiate from the centre; within about 0.1 of it they are finer than
    three texels and the painter draws their mean plus fine grain noise (as pipeline/maps/paint.py
    does). The field there continues the resolved barbs (radially), whatever the grain does."""
    size = 512
    rows, cols = np.mgrid[0:size, 0:size]
    x, y = (cols + 0.5) / size - 0.5, 0.5 - (rows + 0.5) / size
    theta, radius = np.arctan2(x, y), np.hypot(x, y)
    streaks = (0.5 + 0.5 * np.cos(120 * theta)) ** 3
    resolved = np.clip((2 * np.pi * radius / 120 * size - 2.5) / 2.0, 0.0, 1.0)
    grain = np.random.default_rng(3).standard_normal((size // 4, size // 4))
    grain = ndimage.gaussian_filter(np.kron(grain, np.ones((4, 4))), 2.0)  # 4-8 texel features
    height = 0.8 * (resolved * streaks + (1 - resolved) * 5 / 16) + 0.05 * grain
    field = barb_direction_field(height.astype(np.float32))
    radial = np.stack([x, y], axis=-1) / np.maximum(radius, 1e-9)[..., None]
    error = np.degrees(np.arccos(np.clip(np.abs(np.sum(field * radial, axis=-1)), 0.0, 1.0)))
    unresolved = (radius > 0.02) & (resolved == 0)
    assert unresolved.sum() > 1000
    assert np.percentile(error[unresolved], 95) < 15.0, np.percentile(error[unresolved], 95)
    ring = (radius > 0.2) & (radius < 0.45)
    assert np.percentile(error[ring], 95) < 10.0


def test_barb_vectors_point_away_from_the_rachis_so_neighbours_agree():
    """Horizontal barbs beside the eye (radial at heart level) must not alternate between
    (1, 0) and (-1, 0) from vertex to vertex: a triangle would interpolate them to nothing and
    draw a line. Oriented away from the rachis, all on one side point the same way."""
    field = np.zeros((8, 8, 2), np.float32)
    field[..., 0] = 1.0  # horizontal axes, slightly tilted up or down from texel to texel
    field[::2, :, 1], field[1::2, :, 1] = 0.05, -0.05
    field /= np.linalg.norm(field, axis=-1, keepdims=True)
    v = np.linspace(0.6, 0.8, 40)
    for u, sign in ((0.2, -1.0), (0.8, 1.0)):
        uv = np.column_stack([np.full_like(v, u), v])
        directions = sample_direction(field, uv, away_from_rachis(uv, 0.5, 0.74))
        assert np.all(np.sign(directions[:, 0]) == sign)
        assert np.min(directions[1:] @ directions[:-1].T) > 0.9  # neighbours agree
