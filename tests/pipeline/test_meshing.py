"""Meshing without pymeshlab: the NumPy clean-up and quadric collapse the converter falls back
to when pymeshlab's system libraries are missing (``pavonine.pipeline.convert.meshing``)."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("xatlas", reason="needs the [convert] extra", exc_type=ImportError)
pytestmark = pytest.mark.convert

from test_convert import LOD, mesh_arrays, open_lod, recipe_text, run

from pavonine.pipeline.convert import meshing
from pavonine.pipeline.convert.atlas import st_flips, st_overlap_fraction
from pavonine.pipeline.convert.cleaning import clean
from pavonine.pipeline.convert.collapse import boundary_vertices, collapse_to
from pavonine.pipeline.convert.topology import edge_report
from pavonine.pipeline.convert.vane import grid_mesh, triangle_areas
from pavonine.pipeline.maps.paint import generate_maps, write_maps

MISSING = "/lib/x86_64-linux-gnu/libGL.so.1: cannot open shared object file"
MANIFOLD = {"non_manifold_edges": 0, "misoriented_edges": 0, "non_manifold_vertices": 0}


@pytest.fixture
def without_pymeshlab(monkeypatch):
    """The probe sees pymeshlab fail to load (as without Debian's libgl1)."""
    monkeypatch.delenv(meshing.MESHING_ENV, raising=False)
    monkeypatch.setattr(meshing, "pymeshlab_error", lambda: MISSING)
    meshing.meshing_backend.cache_clear()
    yield
    meshing.meshing_backend.cache_clear()


def bumpy_sheet(rows: int = 61, cols: int = 41) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A displaced lattice (streaks along v), split along the seam v = 0.5 as the converter
    hands meshes to decimation; ``st`` is the lattice coordinate, mirrored in the upper chart."""
    uv, faces = grid_mesh(rows, cols)
    height = 0.02 * np.sin(40 * uv[:, 0]) + 0.05 * np.sin(5 * uv[:, 1])
    points = np.column_stack([uv[:, 0] * 2.0, uv[:, 1] * 3.0, height])
    st = uv.copy()
    upper = faces[uv[faces].mean(axis=1)[:, 1] > 0.5]
    lower = faces[uv[faces].mean(axis=1)[:, 1] <= 0.5]
    seam = np.flatnonzero(np.isclose(uv[:, 1], 0.5, atol=1e-9))
    copy = np.arange(len(uv))
    copy[seam] = len(uv) + np.arange(len(seam))
    points = np.concatenate([points, points[seam]])
    st = np.concatenate([st, st[seam]])
    st[copy[np.unique(upper)], 0] = 1.0 - st[copy[np.unique(upper)], 0]  # a mirrored chart
    return points, np.concatenate([lower, copy[upper]]), st


def test_collapse_keeps_boundary_and_seams_and_reaches_the_target():
    points, faces, st = bumpy_sheet()
    target = len(faces) // 3
    out = collapse_to(points, faces, st, target)
    assert target - 2 <= len(out) <= target
    assert edge_report(out, len(points)) == MANIFOLD
    assert st_flips(st, out) == 0
    # Every boundary vertex (outline and both sides of the seam) survives, in place.
    assert set(np.flatnonzero(boundary_vertices(faces, len(points)))) <= set(out.ravel())
    assert np.array_equal(
        boundary_vertices(out, len(points)), boundary_vertices(faces, len(points))
    )
    # Same surface: same area within 1 %, and the flat lattice is decimated where it is flat.
    area = triangle_areas(points, faces).sum()
    assert triangle_areas(points, out).sum() == pytest.approx(area, rel=0.01)
    assert triangle_areas(points, out).min() > 0


def test_collapse_stops_when_no_valid_collapse_is_left():
    points, faces, st = bumpy_sheet(5, 5)  # 6 interior vertices: at most 12 triangles go
    out = collapse_to(points, faces, st, 1)
    assert len(faces) - 12 <= len(out) < len(faces)
    assert edge_report(out, len(points)) == MANIFOLD and st_flips(st, out) == 0
    assert np.array_equal(
        boundary_vertices(out, len(points)), boundary_vertices(faces, len(points))
    )


def height_error(points: np.ndarray, faces: np.ndarray) -> float:
    """RMS height difference between the sheet's vertices and the decimated height field (the
    seam's two copies of a vertex welded)."""
    from matplotlib.tri import LinearTriInterpolator, Triangulation

    welded, index = np.unique(points, axis=0, return_inverse=True)
    used = np.unique(index.reshape(-1)[faces])
    remap = np.full(len(welded), -1)
    remap[used] = np.arange(len(used))
    tri = Triangulation(welded[used, 0], welded[used, 1], remap[index.reshape(-1)[faces]])
    height = LinearTriInterpolator(tri, welded[used, 2])(points[:, 0], points[:, 1])
    return float(np.sqrt(np.mean((np.asarray(height) - points[:, 2]) ** 2)))


@pytest.mark.pymeshlab
def test_collapse_is_as_faithful_as_pymeshlabs(monkeypatch):
    from pavonine.pipeline.convert.mesh import quadric_collapse

    points, faces, st = bumpy_sheet()
    target = len(faces) // 3
    monkeypatch.setenv(meshing.MESHING_ENV, "pymeshlab")
    meshing.meshing_backend.cache_clear()
    try:
        theirs = quadric_collapse(points, faces, st, target)
    finally:
        meshing.meshing_backend.cache_clear()
    ours = collapse_to(points, faces, st, target)
    assert abs(len(ours) - len(theirs)) <= 0.02 * target
    # The same surface to within 25 % of pymeshlab's height error (the relief kept as well).
    assert height_error(points, ours) <= 1.25 * height_error(points, theirs)


def broken_lattice() -> tuple[np.ndarray, np.ndarray]:
    """A 4×4 lattice (16 vertices, 18 triangles) with what meshlab's clean-up repairs."""
    uv, lattice = grid_mesh(4, 4)  # vertex 5 is inside
    points = np.concatenate(
        [
            uv,
            uv[[5]],  # 16: a duplicate of vertex 5, used by half its triangles
            [[0.5, 0.34]],  # 17: a sliver on the inner edge 5-6 (three faces on it)
            [[2.0, 2.0], [1.5, 1.0]],  # 18, 19: a triangle touching corner 15 only
        ]
    )
    faces = lattice.copy()
    at5 = np.argwhere(faces == 5)
    faces[tuple(at5[::2].T)] = 16
    return points, np.concatenate([faces, [[0, 1, 1]], [[5, 6, 17]], [[15, 18, 19]]])


def test_clean_repairs_what_meshlab_repairs():
    points, bad = broken_lattice()
    assert all(edge_report(bad, len(points)).values())
    clean_points, clean_faces = clean(points, bad)
    assert edge_report(clean_faces, len(clean_points)) == MANIFOLD
    assert len(clean_faces) == 18 + 1  # the lattice and the corner triangle: null and sliver go
    assert len(clean_points) == 16 + 2 + 1  # 16 merged into 5, 17 dropped, corner 15 split
    assert len(np.unique(clean_points, axis=0)) == len(clean_points) - 1
    assert np.all(triangle_areas(clean_points, clean_faces) != 0)


def triangles_by_position(points: np.ndarray, faces: np.ndarray) -> set:
    return {frozenset(map(tuple, np.round(points[f], 9))) for f in faces}


@pytest.mark.pymeshlab
def test_clean_gives_what_pymeshlab_gives(monkeypatch):
    from pavonine.pipeline.convert.vane import clean_flat

    points, bad = broken_lattice()
    monkeypatch.setenv(meshing.MESHING_ENV, "pymeshlab")
    meshing.meshing_backend.cache_clear()
    try:
        theirs = clean_flat(points, bad)
    finally:
        meshing.meshing_backend.cache_clear()
    ours = clean(points, bad)
    assert len(ours[0]) == len(theirs[0]) and len(ours[1]) == len(theirs[1])
    assert np.array_equal(np.unique(ours[0], axis=0), np.unique(theirs[0], axis=0))
    assert triangles_by_position(*ours) == triangles_by_position(*theirs)


def test_convert_falls_back_with_one_warning_and_a_valid_asset(tmp_path, without_pymeshlab, caplog):
    write_maps(generate_maps("eye", 128, seed=4), tmp_path / "m")
    (tmp_path / "eye.toml").write_text(recipe_text("eye_feather"))
    result = run("convert", str(tmp_path / "eye.toml"), "-o", str(tmp_path / "out"))
    assert result.exit_code == 0, result.output
    warnings = [line for line in result.stderr.splitlines() if line.startswith("warning:")]
    assert len(warnings) == 1, result.stderr
    assert "NumPy" in warnings[0] and "libGL.so.1" in warnings[0] and "libgl1" in warnings[0]
    asset = tmp_path / "out" / "eye_feather" / "eye_feather.usd"
    assert run("validate", str(asset)).exit_code == 0
    counts = {}
    for lod, target in LOD.items():
        stage = open_lod(asset, lod)
        faces = 0
        for name in ("Vane", "Rachis"):
            m = mesh_arrays(stage, name)
            assert edge_report(m["faces"], len(m["points"])) == MANIFOLD
            size = np.ptp(m["points"], axis=0).max()
            assert triangle_areas(m["points"], m["faces"]).min() > 1e-9 * size**2
            assert np.all((m["st"] >= 0) & (m["st"] <= 1))
            faces += len(m["faces"])
        both = np.concatenate([mesh_arrays(stage, n)["st"] for n in ("Vane", "Rachis")])
        assert st_overlap_fraction(both, 1024) == 0.0
        assert 0.8 * target <= faces <= 1.25 * target, (lod, faces)
        counts[lod] = faces
    assert counts["high"] > counts["medium"] > counts["low"]


def test_insisting_on_pymeshlab_without_it_is_one_line_exit_2(
    tmp_path, without_pymeshlab, monkeypatch
):
    monkeypatch.setenv(meshing.MESHING_ENV, "pymeshlab")
    (tmp_path / "eye.toml").write_text(recipe_text("eye_feather"))
    result = run("convert", str(tmp_path / "eye.toml"), "-o", str(tmp_path / "out"))
    assert result.exit_code == 2
    line = result.output.strip()
    assert "\n" not in line and "libGL.so.1" in line and "PAVONINE_MESHING=pymeshlab" in line
    assert not (tmp_path / "out").exists()
    monkeypatch.setenv(meshing.MESHING_ENV, "opengl")
    meshing.meshing_backend.cache_clear()
    result = run("convert", str(tmp_path / "eye.toml"), "-o", str(tmp_path / "out"))
    assert result.exit_code == 2 and "PAVONINE_MESHING: 'opengl'" in result.output
