"""Ribbon tessellation (render/curves/ribbons.py): width, orientation, bases, primvars, bad input."""

from __future__ import annotations

import numpy as np
import pytest
from pxr import Sdf, Usd, UsdGeom

from pavonine.render.curves import ribbon_surface
from pavonine.render.curves.bases import basis_weights, segment_windows
from pavonine.render.diagnostics import Diagnostics

pytestmark = pytest.mark.filterwarnings("ignore::pavonine.render.diagnostics.StageWarning")
STRAIGHT = [(-1.5, 0, 0), (-0.5, 0, 0), (0.5, 0, 0), (1.5, 0, 0)]
_STAGES: list[Usd.Stage] = []  # in-memory stages live as long as the test module


def ribbon(
    points,
    normals,
    *,
    kind="cubic",
    basis="bspline",
    wrap="pinned",
    counts=None,
    width=0.2,
    normal_interpolation="vertex",
):
    stage = Usd.Stage.CreateInMemory()
    _STAGES.append(stage)
    curves = UsdGeom.BasisCurves.Define(stage, "/Barb")
    curves.CreateTypeAttr(kind)
    curves.CreateBasisAttr(basis)
    curves.CreateWrapAttr(wrap)
    curves.CreateCurveVertexCountsAttr(counts or [len(points)])
    curves.CreatePointsAttr(points)
    curves.CreateWidthsAttr([width])
    curves.SetWidthsInterpolation("constant")
    curves.CreateNormalsAttr(normals)
    curves.SetNormalsInterpolation(normal_interpolation)
    return curves


def tessellate(curves, **kwargs):
    diag = Diagnostics()
    surface = ribbon_surface(curves.GetPrim(), Usd.TimeCode.Default(), diag, **kwargs)
    return surface, diag.messages


def edges(surface):
    """(N, 2, 3): each sample's two ribbon edge points (the −S edge, then the +S edge)."""
    return surface.topology.points.reshape(-1, 2, 3)


def face_normals(surface):
    t = surface.topology
    corners = t.points[t.face_vertex_indices[t.triangles]]
    n = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    length = np.linalg.norm(n, axis=1, keepdims=True)
    return np.divide(n, length, out=np.zeros_like(n), where=length > 0)  # no area: no normal


@pytest.mark.parametrize("normal", [(0, 0, 1), (0, 1, 0), (0, 0.6, -0.8)])
def test_ribbon_has_its_width_across_and_faces_its_normals(normal):
    surface, messages = tessellate(ribbon(STRAIGHT, [normal] * 4, width=0.3))
    assert messages == []
    pairs = edges(surface)
    across = pairs[:, 1] - pairs[:, 0]
    assert np.linalg.norm(across, axis=1) == pytest.approx(0.3)
    assert np.abs(across[:, 0]).max() < 1e-12  # across the curve (which runs along X)
    assert np.abs(across @ np.asarray(normal, float)).max() < 1e-6  # in the plane (float3 normals)
    assert face_normals(surface) @ np.asarray(normal, float) == pytest.approx(1.0)
    assert surface.normals.values == pytest.approx(np.tile(normal, (len(pairs) * 2, 1)))
    assert surface.double_sided
    # the barb tangent is dP/du: along the curve
    assert surface.primvars["pavonine_barbTangent"].values == pytest.approx(
        np.tile([1.0, 0, 0], (len(pairs) * 2, 1))
    )


def test_normals_off_the_plane_are_made_perpendicular_to_the_curve():
    tilted = (0.5, 0.0, 1.0)  # leans along the curve: only its part across the curve counts
    surface, _ = tessellate(ribbon(STRAIGHT, [tilted] * 4))
    assert face_normals(surface) @ np.array([0, 0, 1.0]) == pytest.approx(1.0)


def test_varying_normals_twist_the_ribbon_linearly_per_segment():
    # pinned bspline of 4 points: 3 segments, 4 varying values (UsdGeomBasisCurves' varying table)
    up, side = (0, 0, 1), (0, 1, 0)
    surface, messages = tessellate(
        ribbon(STRAIGHT, [up, up, side, side], normal_interpolation="varying")
    )
    assert messages == []
    n = surface.normals.values[::2]
    assert n[0] == pytest.approx(up) and n[-1] == pytest.approx(side)
    across = edges(surface)[:, 1] - edges(surface)[:, 0]
    assert abs(across[0][1]) == pytest.approx(0.2) and abs(across[-1][2]) == pytest.approx(0.2)


@pytest.mark.parametrize("basis", ["bezier", "bspline", "catmullRom"])
def test_centre_line_is_the_curve_in_its_basis(basis):
    rng = np.random.default_rng(3)
    points = np.cumsum(rng.uniform(0.2, 1.0, size=(7, 3)) * [1, 0.3, 0], axis=0)
    wrap = "nonperiodic"
    surface, messages = tessellate(
        ribbon([tuple(p) for p in points], [(0, 0, 1)] * 7, basis=basis, wrap=wrap), steps=4
    )
    assert messages == []
    centre = edges(surface).mean(axis=1)
    u = np.linspace(0, 1, 5)
    if basis == "bezier":  # two segments, Bernstein polynomials on points 0..3 and 3..6
        bern = np.stack([(1 - u) ** 3, 3 * u * (1 - u) ** 2, 3 * u**2 * (1 - u), u**3], 1)
        expected = np.concatenate([bern @ points[0:4], bern @ points[3:7]])
    elif basis == "catmullRom":  # interpolates its interior points at the segment ends
        expected = None
        ends = centre.reshape(-1, 5, 3)
        assert ends[:, 0] == pytest.approx(points[1:5]) and ends[-1, -1] == pytest.approx(points[5])
    else:
        weights, _ = basis_weights(u, "cubic")
        expected = np.concatenate([weights @ points[i : i + 4] for i in range(4)])
    if expected is not None:
        assert centre == pytest.approx(expected)


def test_segment_windows_of_a_linear_curve_are_its_edges():
    p = np.arange(12.0).reshape(4, 3)
    windows = segment_windows(p, "linear", "bezier", "periodic")
    assert windows.shape == (4, 2, 3) and np.array_equal(windows[-1], p[[3, 0]])


def test_primvars_reach_the_samples_with_their_interpolation():
    curves = ribbon(STRAIGHT + [(p[0], 2.0, 0) for p in STRAIGHT], [(0, 0, 1)] * 8, counts=[4, 4])
    api = UsdGeom.PrimvarsAPI(curves)
    x = api.CreatePrimvar("pavonine_gradation", Sdf.ValueTypeNames.FloatArray, "vertex")
    x.Set([p[0] for p in STRAIGHT] * 2)  # the x coordinate: a B-spline reproduces it exactly
    api.CreatePrimvar("pavonine_barbId", Sdf.ValueTypeNames.IntArray, "uniform").Set([7, 9])
    api.CreatePrimvar("pavonine_melanin", Sdf.ValueTypeNames.FloatArray, "varying").Set(
        [0.0, 1.0, 2.0, 3.0, 10.0, 11.0, 12.0, 13.0]
    )
    api.CreatePrimvar("pavonine_barbuleAngle", Sdf.ValueTypeNames.Float, "constant").Set(30.0)
    surface, messages = tessellate(curves, steps=2)
    assert messages == []
    points = surface.topology.points
    assert surface.primvars["pavonine_gradation"].values[:, 0] == pytest.approx(points[:, 0])
    ids = surface.primvars["pavonine_barbId"]
    assert ids.interpolation == "uniform" and len(ids.values) == surface.topology.face_count
    upper = points[surface.topology.face_vertex_indices[::3], 1] > 1.0  # each triangle's curve
    assert np.all(ids.values[:, 0] == np.where(upper, 9, 7))
    melanin = surface.primvars["pavonine_melanin"].values[::2, 0].reshape(2, 3, 3)
    assert melanin[0] == pytest.approx(np.array([[0, 0.5, 1], [1, 1.5, 2], [2, 2.5, 3]]))
    assert melanin[1, -1] == pytest.approx(np.array([12, 12.5, 13]))
    assert surface.primvars["pavonine_barbuleAngle"].interpolation == "constant"


def test_normals_that_do_not_fit_leave_tubes_and_a_warning():
    surface, messages = tessellate(ribbon(STRAIGHT, [(0, 0, 1)] * 3))
    assert surface is None
    assert messages == ["/Barb: vertex normals has 3 values for 4 points; rendered as round tubes"]


def test_primvar_with_too_few_values_is_ignored_by_name():
    curves = ribbon(STRAIGHT, [(0, 0, 1)] * 4)
    UsdGeom.PrimvarsAPI(curves).CreatePrimvar(
        "displayColor", Sdf.ValueTypeNames.Color3fArray, "vertex"
    ).Set([(1, 0, 0)] * 2)
    surface, messages = tessellate(curves)
    assert "displayColor" not in surface.primvars
    assert messages == ["/Barb: vertex primvars:displayColor has 2 values for 4 points; ignored"]


def test_normal_along_the_curve_narrows_the_ribbon_to_nothing_there():
    surface, messages = tessellate(ribbon(STRAIGHT, [(1, 0, 0)] * 4))
    assert np.ptp(surface.topology.points[:, 1]) == 0.0
    assert len(messages) == 1 and "narrows to nothing" in messages[0]


def test_tube_mesh_is_round_faces_out_and_does_not_twist():
    """A helix as a tessellated tube: every ring at its radius, every face outward, and the
    rings' frames turn about the curve by < 1° per sample (rotation-minimising)."""
    from pavonine.render.curves import tube_surface

    turns = np.linspace(0, 3 * np.pi, 9)
    stage = Usd.Stage.CreateInMemory()
    _STAGES.append(stage)
    curves = UsdGeom.BasisCurves.Define(stage, "/Hair")
    curves.CreateTypeAttr("cubic")
    curves.CreateBasisAttr("bspline")
    curves.CreateWrapAttr("pinned")
    curves.CreateCurveVertexCountsAttr([9])
    curves.CreatePointsAttr([(np.cos(t), np.sin(t), 0.2 * t) for t in turns])
    curves.CreateWidthsAttr([0.2])
    curves.SetWidthsInterpolation("constant")
    diag = Diagnostics()
    surface = tube_surface(curves.GetPrim(), Usd.TimeCode.Default(), diag, sides=16)
    assert diag.messages == []
    rings = surface.topology.points.reshape(-1, 16, 3)
    centre = rings.mean(axis=1)
    assert np.linalg.norm(rings - centre[:, None], axis=2) == pytest.approx(0.1)
    t = surface.topology
    corners = t.points[t.face_vertex_indices[t.triangles]]
    normal = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    ring_of_corner = t.face_vertex_indices[t.triangles[:, 0]] // 16
    assert np.all(np.sum(normal * (corners[:, 0] - centre[ring_of_corner]), axis=1) > 0)
    tangent = surface.primvars["pavonine_barbTangent"].values[::16]
    r = rings[:, 0] - centre
    r /= np.linalg.norm(r, axis=1, keepdims=True)
    back = turned(tangent[1:], tangent[:-1], r[1:])  # each frame turned back onto the previous
    twist = np.degrees(np.arccos(np.clip(np.sum(back * r[:-1], axis=1), -1, 1)))
    assert twist.max() < 1.0


def turned(a: np.ndarray, b: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``v`` turned by the smallest rotations taking unit vectors ``a`` onto ``b`` (Rodrigues)."""
    axis = np.cross(a, b)
    sin = np.linalg.norm(axis, axis=1, keepdims=True)
    cos = np.sum(a * b, axis=1, keepdims=True)
    k = axis / np.maximum(sin, 1e-30)
    return v * cos + np.cross(k, v) * sin + k * np.sum(k * v, axis=1, keepdims=True) * (1 - cos)


def test_non_finite_normals_read_as_zero_and_narrow_the_ribbon():
    nan = float("nan")
    surface, messages = tessellate(ribbon(STRAIGHT, [(nan, nan, nan)] * 2 + [(0, 0, 1)] * 2))
    assert messages[0] == "/Barb: normals are NaN or infinite; those read as 0"
    assert "narrows to nothing" in messages[1] and len(messages) == 2
    assert np.all(np.isfinite(surface.topology.points))


def test_widths_overshooting_below_zero_in_the_basis_are_clamped():
    curves = ribbon(STRAIGHT, [(0, 0, 1)] * 4, basis="catmullRom")
    curves.CreateWidthsAttr([1.0, 1.0, 0.0, 0.0])  # Catmull-Rom dips below 0 before the last 0
    curves.SetWidthsInterpolation("vertex")
    surface, messages = tessellate(curves, steps=8)
    across = edges(surface)[:, 1] - edges(surface)[:, 0]
    assert messages == [] and np.all(across[:, 1] <= 0)  # S = T × N = −Y: no edge crosses over
    assert across[:, 1].max() == 0.0


def mitsuba_determinants(surface) -> tuple[np.ndarray, np.ndarray]:
    """Per triangle: the determinant Mitsuba's barycentric solve divides by (edges from the
    FIRST vertex, float32, Mesh::barycentric_coordinates) and the triangle's area (float64)."""
    t = surface.topology
    corners = t.points[t.face_vertex_indices[t.triangles]]
    p = corners.astype(np.float32)
    du, dv = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]
    a, b, c = (du * du).sum(1), (du * dv).sum(1), (dv * dv).sum(1)
    area = np.linalg.norm(
        np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]), axis=1
    )
    return a * c - b * b, area / 2


@pytest.mark.parametrize("tip", [1e-4, 1e-6])
def test_a_tapering_ribbon_has_no_triangle_mitsuba_cannot_interpolate_on(tip):
    """Regression (issue 23, the SIGSEGV at the hero view): a ribbon tapering from 0.4 to ``tip``
    has needle triangles; each starts at its widest corner, so Mitsuba's float32 determinant of
    every triangle with area is positive (from the needle's sharp corner it is exactly 0 and the
    primvars read NaN), and the winding still faces the normal."""
    curves = ribbon([(0, 0, 0), (2, 0, 0), (4, 0, 0)], [(0, 0, 1)] * 3, kind="linear")
    curves.CreateWidthsAttr([0.4, 0.0, tip])
    curves.SetWidthsInterpolation("vertex")
    surface, messages = tessellate(curves)
    det, area = mitsuba_determinants(surface)
    assert messages == []
    assert np.all(det[area > 0] > 0)
    assert area.max() > 0 and (area == 0).any()  # the root's zero-width end: no area to hit
    assert np.all(face_normals(surface)[area > 0][:, 2] > 0.999)


def test_ribbons_carry_the_barb_coordinate_the_glitter_blocks_follow():
    """Per vertex: arc length along the barb, place across it (counter-clockwise from the barb
    seen from the front: the −S edge at +w/2) and the barb's id (``pavonine_barbId``, else the
    curve's index)."""
    from pavonine.render.mesh import BARB_COORDINATE

    points = [(0, 0, 0), (3, 0, 0), (3, 4, 0), (0, 1, 0), (0, 2, 0)]
    curves = ribbon(points, [(0, 0, 1)] * 5, kind="linear", counts=[3, 2], width=0.5)
    surface, _ = tessellate(curves)
    coordinate = surface.primvars[BARB_COORDINATE].values.reshape(-1, 2, 3)
    np.testing.assert_allclose(coordinate[:, 0, 0], coordinate[:, 1, 0])
    np.testing.assert_allclose(np.unique(coordinate[:, 0, 0]), [0.0, 1.0, 3.0, 7.0])
    np.testing.assert_allclose(coordinate[:, :, 1], np.tile([0.25, -0.25], (len(coordinate), 1)))
    # +w/2 lies counter-clockwise of the barb direction seen from the normal (+z): +y for +x
    sides = edges(surface)
    first = coordinate[:, 0, 2] == 0
    assert np.all(sides[first & (coordinate[:, 0, 0] < 3), 0, 1] > 0)
    assert set(np.unique(coordinate[:, :, 2])) == {0.0, 1.0}
    UsdGeom.PrimvarsAPI(curves).CreatePrimvar(
        "pavonine_barbId", Sdf.ValueTypeNames.IntArray, UsdGeom.Tokens.uniform
    ).Set([17, 4])
    surface, _ = tessellate(curves)
    ids = surface.primvars[BARB_COORDINATE].values[:, 2]
    assert set(np.unique(ids)) == {17.0, 4.0}
