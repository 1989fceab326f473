"""Geometry translators without rendering: implicit prims, subdivision, primvars, bad attributes."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from pxr import Gf, Sdf, Usd, UsdGeom, UsdShade

from pavonine.base.backend import select_variant
from pavonine.render import shapes, subdivision
from pavonine.render.delegate import StageDelegate, render_time
from pavonine.render.diagnostics import Diagnostics, StageWarning
from pavonine.render.mesh import mesh_attribute_name, read_mesh

CUBE_POINTS = [(x, y, z) for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]  # index 4x + 2y + z
CUBE_QUADS = [[0, 1, 3, 2], [4, 6, 7, 5], [0, 4, 5, 1], [2, 3, 7, 6], [0, 2, 6, 4], [1, 5, 7, 3]]


@pytest.fixture(scope="module", autouse=True)
def _variant():
    select_variant()


def quiet(function, *args):
    diag = Diagnostics()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", StageWarning)
        return function(*args, diag), diag


def implicit(stage, kind, path="/Shape", **attrs):
    prim = stage.DefinePrim(path, kind)
    for name, value in attrs.items():
        attr = prim.GetAttribute(name)
        if not attr:
            attr = prim.CreateAttribute(name, Sdf.ValueTypeNames.Double)
        attr.Set(value)
    return prim


def surface_of(prim):
    surface, diag = quiet(shapes.implicit_surface, prim, Usd.TimeCode.Default())
    return surface, diag


def triangle_geometry(surface):
    t = surface.topology
    p = t.points[t.face_vertex_indices[t.triangles]]
    normal = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    return p, normal


def cube_mesh(stage, path="/Cube", scheme="catmullClark"):
    mesh = UsdGeom.Mesh.Define(stage, path)
    mesh.CreatePointsAttr(CUBE_POINTS)
    mesh.CreateFaceVertexCountsAttr([4] * 6)
    mesh.CreateFaceVertexIndicesAttr([i for q in CUBE_QUADS for i in q])
    mesh.CreateSubdivisionSchemeAttr(scheme)
    return mesh


def refined(mesh):
    surface, diag = quiet(read_mesh, mesh, Usd.TimeCode.Default())
    out, diag2 = quiet(subdivision.refine_surface, surface, Usd.TimeCode.Default())
    return out, diag.messages + diag2.messages


# -- implicit prims -------------------------------------------------------------------------------

SHAPES = [
    # kind, attributes, expected bounds (lo, hi), analytic area
    ("Cube", {"size": 3.0}, ([-1.5] * 3, [1.5] * 3), 6 * 9.0),
    ("Sphere", {"radius": 2.0}, ([-2] * 3, [2] * 3), 4 * math.pi * 4),
    (
        "Cylinder",
        {"radius": 0.5, "height": 4.0, "axis": "X"},
        ([-2, -0.5, -0.5], [2, 0.5, 0.5]),
        2 * math.pi * 0.5 * 4 + 2 * math.pi * 0.25,
    ),
    (
        "Cone",
        {"radius": 1.0, "height": 2.0, "axis": "Y"},
        ([-1, -1, -1], [1, 1, 1]),
        math.pi * 1 * (1 + math.sqrt(5)),
    ),
    (
        "Capsule",
        {"radius": 0.5, "height": 1.0},
        ([-0.5, -0.5, -1], [0.5, 0.5, 1]),
        4 * math.pi * 0.25 + 2 * math.pi * 0.5,
    ),
    ("Plane", {"width": 4.0, "length": 2.0, "axis": "Y"}, ([-2, 0, -1], [2, 0, 1]), 8.0),
]


@pytest.mark.parametrize(("kind", "attrs", "bounds", "area"), SHAPES, ids=[s[0] for s in SHAPES])
def test_implicit_prims_follow_their_schema(kind, attrs, bounds, area):
    stage = Usd.Stage.CreateInMemory()
    prim = stage.DefinePrim("/Shape", kind)
    for name, value in attrs.items():
        prim.GetAttribute(name).Set(value)
    surface, diag = surface_of(prim)
    assert diag.messages == []
    points = surface.topology.points
    assert points.min(axis=0) == pytest.approx(bounds[0], abs=1e-9)
    assert points.max(axis=0) == pytest.approx(bounds[1], abs=1e-9)
    p, normal = triangle_geometry(surface)
    # the tessellation's area is within 0.2 % of the exact surface's
    assert 0.5 * np.linalg.norm(normal, axis=1).sum() == pytest.approx(area, rel=2e-3)
    if kind != "Plane":  # closed and star-shaped about the origin: every face winds outwards
        assert np.all(np.einsum("ij,ij->i", p.mean(axis=1), normal) > 0)
    # the authored normals point to the same side as the winding
    t = surface.topology
    corner_normals = surface.normals.values[t.triangles]
    assert np.all(np.einsum("ijk,ik->ij", corner_normals, normal) > 0)


def test_plane_faces_its_axis_and_cone_apex_is_up_the_axis():
    stage = Usd.Stage.CreateInMemory()
    plane, _ = surface_of(implicit(stage, "Plane", "/P", axis="X"))
    _, normal = triangle_geometry(plane)
    assert np.all(normal[:, 0] > 0) and plane.double_sided  # Plane's doubleSided fallback is true
    cone, _ = surface_of(implicit(stage, "Cone", "/C", axis="Y"))
    top = cone.topology.points[np.argmax(cone.topology.points[:, 1])]
    assert top == pytest.approx([0, 1, 0])


def test_capsule_1_caps_are_tangent_to_the_side():
    stage = Usd.Stage.CreateInMemory()
    prim = stage.DefinePrim("/Caps", "Capsule_1")
    prim.GetAttribute("radiusBottom").Set(1.0)
    prim.GetAttribute("radiusTop").Set(0.5)
    prim.GetAttribute("height").Set(2.0)
    surface, diag = surface_of(prim)
    assert diag.messages == []
    p = surface.topology.points
    assert p[:, 2].min() == pytest.approx(-2.0) and p[:, 2].max() == pytest.approx(1.5)
    # smooth everywhere: per-corner normals of a point agree wherever the point repeats
    t = surface.topology
    normals = surface.normals.values
    positions = p[t.face_vertex_indices]
    order = np.lexsort(np.round(positions, 9).T)
    same = np.all(np.isclose(positions[order][1:], positions[order][:-1], atol=1e-9), axis=1)
    both = normals[order][1:][same], normals[order][:-1][same]
    on_axis = np.hypot(*positions[order][1:][same][:, :2].T) < 1e-9
    assert np.allclose(both[0][~on_axis], both[1][~on_axis], atol=1e-9)


def test_bad_implicit_attributes_warn_and_render_goes_on():
    stage = Usd.Stage.CreateInMemory()
    negative = implicit(stage, "Sphere", "/Negative", radius=-1.0)
    assert surface_of(negative)[0] is None
    assert "/Negative: radius = -1 must be positive; skipped" in surface_of(negative)[1].messages
    stage.GetRootLayer().ImportFromString('#usda 1.0\ndef Cube "Wrong"\n{\n    int size = 4\n}\n')
    surface, diag = surface_of(stage.GetPrimAtPath("/Wrong"))
    assert surface.topology.points.max() == pytest.approx(1.0)  # the fallback size 2
    assert diag.messages == ["/Wrong: size has type int, expected double; using the fallback 2"]
    axis = implicit(stage, "Cylinder", "/Axis")
    axis.GetAttribute("axis").Set("W")
    surface, diag = surface_of(axis)
    assert surface is not None and "axis = 'W' is not one of Z, X, Y" in diag.messages[0]


def test_implicit_prims_go_through_the_delegate_with_transforms_and_display_color():
    stage = Usd.Stage.CreateInMemory()
    xf = UsdGeom.Xform.Define(stage, "/World")
    xf.AddTranslateOp().Set(Gf.Vec3d(10, 0, 0))
    sphere = UsdGeom.Sphere.Define(stage, "/World/Ball")
    sphere.CreateDisplayColorAttr([(1.0, 0.0, 0.0)])
    scene, diag = quiet(lambda d: StageDelegate(stage, render_time(stage, None), d).sync())
    assert diag.messages == [] and scene.mesh_count == 1
    assert scene.bounds[0] == pytest.approx([9, -1, -1]) and scene.bounds[1] == pytest.approx(
        [11, 1, 1]
    )


# -- subdivision ----------------------------------------------------------------------------------


def test_catmull_clark_level_one_follows_catmull_and_clark_1978(monkeypatch):
    """Cube [-1, 1]³: face points at the face centres (1), edge points (a + b + f₁ + f₂)/4 = 3/4,
    vertex points (F + 2R + (n − 3)P)/n = (1/3 + 4/3)/3 = 5/9 (n = 3).

    pymeshlab's Catmull-Clark filter gives 11/18 at the corners: its vertex rule is not the
    paper's, so it is no reference here (its Loop filter is: see the next test).
    """
    monkeypatch.setattr(subdivision, "MAX_LEVELS", 1)
    stage = Usd.Stage.CreateInMemory()
    surface, messages = refined(cube_mesh(stage))
    assert messages == []
    magnitudes = {tuple(sorted(np.round(np.abs(p), 9))) for p in surface.topology.points}
    assert magnitudes == {(0, 0, 1), (0, 0.75, 0.75), (round(5 / 9, 9),) * 3}
    assert len(surface.topology.points) == 8 + 12 + 6 and surface.topology.face_count == 24


@pytest.mark.pymeshlab
def test_loop_matches_pymeshlab_on_a_closed_octahedron():
    import pymeshlab

    points = [(1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0), (0, 0, 1), (0, 0, -1)]
    tris = [[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]]
    stage = Usd.Stage.CreateInMemory()
    mesh = UsdGeom.Mesh.Define(stage, "/Octa")
    mesh.CreatePointsAttr(points)
    mesh.CreateFaceVertexCountsAttr([3] * 8)
    mesh.CreateFaceVertexIndicesAttr([i for t in tris for i in t])
    mesh.CreateSubdivisionSchemeAttr("loop")
    surface, messages = refined(mesh)
    assert messages == []
    ms = pymeshlab.MeshSet()
    ms.add_mesh(pymeshlab.Mesh(np.array(points, float), np.array(tris, dtype=np.int32)))
    ms.meshing_surface_subdivision_loop(
        iterations=subdivision.MAX_LEVELS, threshold=pymeshlab.PercentageValue(0.0)
    )
    theirs = ms.current_mesh().vertex_matrix()
    ours = surface.topology.points
    assert len(ours) == len(theirs)
    key = lambda p: p[np.lexsort(np.round(p, 6).T)]  # noqa: E731
    assert np.allclose(key(ours), key(theirs), atol=1e-6)


def test_open_quad_keeps_its_corners_and_boundary_edgeandcorner():
    stage = Usd.Stage.CreateInMemory()
    mesh = UsdGeom.Mesh.Define(stage, "/Quad")
    mesh.CreatePointsAttr([(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)])
    mesh.CreateFaceVertexCountsAttr([4])
    mesh.CreateFaceVertexIndicesAttr([0, 1, 2, 3])
    st = UsdGeom.PrimvarsAPI(mesh).CreatePrimvar(
        "st", Sdf.ValueTypeNames.TexCoord2fArray, UsdGeom.Tokens.faceVarying
    )
    st.Set([(0, 0), (1, 0), (1, 1), (0, 1)])
    surface, _ = refined(mesh)
    p = surface.topology.points
    assert p.min(axis=0) == pytest.approx([0, 0, 0]) and p.max(axis=0) == pytest.approx([1, 1, 0])
    # face-varying st interpolated bilinearly: on a unit square st equals xy at every corner
    corners = p[surface.topology.face_vertex_indices]
    assert np.allclose(surface.primvars["st"].values, corners[:, :2], atol=1e-9)


def test_infinitely_sharp_creases_keep_the_cube():
    stage = Usd.Stage.CreateInMemory()
    mesh = cube_mesh(stage)
    edges = sorted({tuple(sorted((q[i], q[(i + 1) % 4]))) for q in CUBE_QUADS for i in range(4)})
    mesh.CreateCreaseIndicesAttr([v for e in edges for v in e])
    mesh.CreateCreaseLengthsAttr([2] * len(edges))
    mesh.CreateCreaseSharpnessesAttr([10.0] * len(edges))
    surface, messages = refined(mesh)
    assert messages == []
    assert np.allclose(np.abs(surface.topology.points).max(axis=1), 1.0)  # all on the cube faces
    smooth, _ = refined(cube_mesh(stage, "/Smooth"))
    assert np.abs(smooth.topology.points).max() < 0.9  # without creases the corners round off


def test_vertex_primvars_refine_with_the_points_and_uniform_per_face():
    stage = Usd.Stage.CreateInMemory()
    mesh = cube_mesh(stage)
    pv = UsdGeom.PrimvarsAPI(mesh)
    pv.CreatePrimvar("rest", Sdf.ValueTypeNames.Point3fArray, "vertex").Set(CUBE_POINTS)
    pv.CreatePrimvar("faceId", Sdf.ValueTypeNames.FloatArray, "uniform").Set(list(range(6)))
    mesh.CreateHoleIndicesAttr([5])
    surface, _ = refined(mesh)
    assert np.allclose(surface.primvars["rest"].values, surface.topology.points)
    face_id = surface.primvars["faceId"].values[:, 0]
    assert np.array_equal(face_id, surface.authored_face)
    # the hole's refined faces are not rendered
    assert 5 not in set(surface.authored_face[surface.topology.triangle_face])


def test_subsets_on_a_subdivided_mesh_keep_their_materials():
    stage = Usd.Stage.CreateInMemory()
    mesh = cube_mesh(stage)
    red = UsdShade.Material.Define(stage, "/Looks/Red")
    subset = UsdGeom.Subset.CreateGeomSubset(mesh, "top", "face", [3], "materialBind")
    UsdShade.MaterialBindingAPI.Apply(subset.GetPrim()).Bind(red)
    scene, _ = quiet(lambda d: StageDelegate(stage, Usd.TimeCode.Default(), d).sync())
    assert scene.mesh_count == 2


def test_loop_on_quads_is_triangulated_with_a_warning_and_budget_is_respected(monkeypatch):
    stage = Usd.Stage.CreateInMemory()
    surface, messages = refined(cube_mesh(stage, scheme="loop"))
    assert any("loop subdivision needs triangles" in m for m in messages)
    assert np.all(surface.topology.face_vertex_counts == 3)
    monkeypatch.setattr(subdivision, "FACE_BUDGET", 10)
    cage, messages = refined(cube_mesh(stage, "/Big"))
    assert len(cage.topology.points) == 8
    assert any("above the subdivision budget" in m for m in messages)


def test_hdmitsuba_subdivision_level_sets_the_levels(monkeypatch):
    """``mitsuba:subdivision_level`` (hdmitsuba's per-mesh setting): 0 is the control mesh, N is
    N levels (6 · 4^N quads) even past the usual 3, within the face budget (warned when capped);
    an unusable value is warned and the mesh refined as usual."""
    stage = Usd.Stage.CreateInMemory()
    faces, notes = {}, {}
    for index, level in enumerate((0, 1, 5, -1, "two")):
        mesh = cube_mesh(stage, f"/Level{index}")
        kind = Sdf.ValueTypeNames.String if isinstance(level, str) else Sdf.ValueTypeNames.Int
        mesh.GetPrim().CreateAttribute("mitsuba:subdivision_level", kind).Set(level)
        surface, messages = refined(mesh)
        faces[level], notes[level] = len(surface.topology.face_vertex_counts), messages
    assert faces[0] == 6 and faces[1] == 6 * 4 and faces[5] == 6 * 4**5
    assert faces[-1] == faces["two"] == 6 * 4**3 and "not an integer from 0 to 16" in notes[-1][0]
    assert notes[0] == notes[1] == notes[5] == []
    monkeypatch.setattr(subdivision, "FACE_BUDGET", 100)
    mesh = cube_mesh(stage, "/Capped")
    mesh.GetPrim().CreateAttribute("mitsuba:subdivision_level", Sdf.ValueTypeNames.Int).Set(4)
    surface, messages = refined(mesh)
    assert len(surface.topology.face_vertex_counts) == 6 * 4**2
    assert messages == ["/Capped: mitsuba:subdivision_level = 4 refined to 2 levels: the budget "
                        "is 100 refined faces"]  # fmt: skip


# -- primvars as mesh attributes ---------------------------------------------------------------


def test_mesh_attribute_names_follow_the_contract():
    assert mesh_attribute_name("displayColor", "vertex") == "vertex_displayColor"
    assert mesh_attribute_name("primvars:a:b", "faceVarying") == "vertex_a_b"
    assert mesh_attribute_name("displayOpacity", "uniform") == "face_displayOpacity"
    assert mesh_attribute_name("displayColor", "constant") is None
    with pytest.raises(ValueError):
        mesh_attribute_name("x", "perPoint")


def test_primvars_a_material_reads_reach_the_mitsuba_mesh():
    """No material: the fallback reads displayColor/displayOpacity, so both become attributes
    (colour with its ``_color`` twin); st is the texture coordinates; primvars nobody reads are
    not built."""
    import mitsuba as mi

    stage = Usd.Stage.CreateInMemory()
    mesh = cube_mesh(stage, scheme="none")
    pv = UsdGeom.PrimvarsAPI(mesh)
    pv.CreatePrimvar("displayColor", Sdf.ValueTypeNames.Color3fArray, "vertex").Set(
        [(i / 8, 0, 1) for i in range(8)]
    )
    opacity = pv.CreatePrimvar("displayOpacity", Sdf.ValueTypeNames.FloatArray, "uniform")
    opacity.Set([0.5, 1.0])
    opacity.SetIndices([0, 1, 0, 1, 0, 1])
    pv.CreatePrimvar("st", Sdf.ValueTypeNames.TexCoord2fArray, "faceVarying").Set(
        [(u, v) for _ in range(6) for u, v in ((0, 0), (1, 0), (1, 1), (0, 1))]
    )
    pv.CreatePrimvar("my:weight", Sdf.ValueTypeNames.Float, "constant").Set(2.0)
    pv.CreatePrimvar("unread", Sdf.ValueTypeNames.FloatArray, "faceVarying").Set([0.5] * 24)
    scene, diag = quiet(lambda d: StageDelegate(stage, Usd.TimeCode.Default(), d).sync())
    assert diag.messages == []
    (shape,) = scene.shapes.values()
    for name in ("vertex_displayColor", "vertex_displayColor_color", "face_displayOpacity"):
        assert shape.has_attribute(name), name
    for name in ("vertex_my_weight", "vertex_unread", "vertex_st"):
        assert not shape.has_attribute(name), name
    params = mi.traverse(shape)
    faces = np.array(params["faces"]).reshape(-1, 3)
    positions = np.array(params["vertex_positions"]).reshape(-1, 3)
    assert len(positions) == 24  # unwelded for the face-varying st (the texture coordinates)
    assert len(np.array(params["vertex_texcoords"])) == 2 * len(positions)
    colours = np.array(params["vertex_displayColor"]).reshape(-1, 3)
    index = (4 * (positions[:, 0] > 0) + 2 * (positions[:, 1] > 0) + (positions[:, 2] > 0)) / 8
    assert np.allclose(colours[:, 0], index)  # per vertex, after unwelding for st
    face_opacity = np.array(params["face_displayOpacity"])
    assert len(face_opacity) == len(faces)
    assert sorted(set(face_opacity.round(3))) == [0.5, 1.0]


def test_a_primvar_reader_gets_its_attribute_and_the_mesh_stays_welded():
    """A material reading one vertex primvar: that attribute is built (values per vertex), the
    unread face-varying ones are not, so the cube keeps its 8 shared vertices."""
    import mitsuba as mi

    stage = Usd.Stage.CreateInMemory()
    mesh = cube_mesh(stage, scheme="none")
    pv = UsdGeom.PrimvarsAPI(mesh)
    pv.CreatePrimvar("wear", Sdf.ValueTypeNames.FloatArray, "vertex").Set([i / 8 for i in range(8)])
    pv.CreatePrimvar("unread", Sdf.ValueTypeNames.Float3Array, "faceVarying").Set([(1, 0, 0)] * 24)
    material = UsdShade.Material.Define(stage, "/Looks/Worn")
    shader = UsdShade.Shader.Define(stage, "/Looks/Worn/Surface")
    shader.CreateIdAttr("UsdPreviewSurface")
    material.CreateSurfaceOutput().ConnectToSource(shader.ConnectableAPI(), "surface")
    reader = UsdShade.Shader.Define(stage, "/Looks/Worn/Wear")
    reader.CreateIdAttr("UsdPrimvarReader_float")
    reader.CreateInput("varname", Sdf.ValueTypeNames.String).Set("wear")
    shader.CreateInput("roughness", Sdf.ValueTypeNames.Float).ConnectToSource(
        reader.ConnectableAPI(), "result"
    )
    UsdShade.MaterialBindingAPI.Apply(mesh.GetPrim()).Bind(material)
    scene, diag = quiet(lambda d: StageDelegate(stage, Usd.TimeCode.Default(), d).sync())
    assert diag.messages == []
    (shape,) = scene.shapes.values()
    assert shape.has_attribute("vertex_wear") and not shape.has_attribute("vertex_wear_color")
    assert not shape.has_attribute("vertex_unread")
    params = mi.traverse(shape)
    positions = np.array(params["vertex_positions"]).reshape(-1, 3)
    assert len(positions) == 8
    index = (4 * (positions[:, 0] > 0) + 2 * (positions[:, 1] > 0) + (positions[:, 2] > 0)) / 8
    assert np.allclose(np.array(params["vertex_wear"]), index)


def test_tubes_whose_material_reads_a_varying_primvar_are_tessellated():
    """Mitsuba curves carry no attributes: tubes with a per-vertex displayColor (read by the
    no-material fallback) become a tube mesh carrying it; with a constant one (or none) they
    stay Mitsuba curves, the constant being the curves' colour."""
    import mitsuba as mi

    stage = Usd.Stage.CreateInMemory()
    curve = UsdGeom.BasisCurves.Define(stage, "/Hair")
    curve.CreateTypeAttr("linear")
    curve.CreateCurveVertexCountsAttr([2])
    curve.CreatePointsAttr([(0, 0, 0), (1, 0, 0)])
    curve.CreateWidthsAttr([0.1])
    curve.SetWidthsInterpolation("constant")
    colour = curve.CreateDisplayColorPrimvar("vertex")
    colour.Set([(1, 0, 0), (0, 0, 1)])

    def synced_curve():
        scene, diag = quiet(lambda d: StageDelegate(stage, Usd.TimeCode.Default(), d).sync())
        (shape,) = scene.shapes.values()
        return shape, diag.messages

    tube, messages = synced_curve()
    assert messages == [] and isinstance(tube, mi.Mesh)
    params = mi.traverse(tube)
    positions = np.array(params["vertex_positions"]).reshape(-1, 3)
    red = np.array(params["vertex_displayColor"]).reshape(-1, 3)[:, 0]
    assert np.allclose(red, 1.0 - positions[:, 0], atol=1e-6)  # red at x = 0, blue at x = 1
    assert np.hypot(positions[:, 1], positions[:, 2]) == pytest.approx(0.05)
    colour.SetInterpolation("constant")
    colour.Set([(1, 0, 0)])
    red, messages = synced_curve()
    assert messages == [] and not isinstance(red, mi.Mesh)
    colour.GetAttr().Clear()
    plain, messages = synced_curve()
    assert messages == [] and not isinstance(plain, mi.Mesh) and str(plain) != str(red)


def test_sidedness_wrappers_follow_double_sided_and_leave_transmission_alone():
    """singleSided → front only, doubleSided → twosided; a transmissive surface (glass from the
    ``mitsuba`` context) and a BSDF that shades both sides itself (the feather) are never wrapped."""
    from pavonine.render.shading.primvars import Binding
    from pavonine.render.shading.spec import MaterialSpec, load_bsdf

    def loaded(bsdf, double_sided, **fields):
        spec = MaterialSpec("/M", bsdf, **fields)
        result, diag = quiet(load_bsdf, spec, double_sided, Binding(), "/M")
        assert diag.messages == []
        return str(result)

    assert loaded({"type": "diffuse"}, False).startswith("FrontOnly[")
    assert loaded({"type": "diffuse"}, True).startswith("TwoSided[")
    assert loaded({"type": "diffuse"}, False, opacity=0.5).startswith("FrontOnly[Mask[")
    for double_sided in (False, True):
        assert loaded({"type": "dielectric"}, double_sided).startswith("SmoothDielectric[")
        assert loaded({"type": "principled", "spec_trans": 0.5}, double_sided).startswith(
            "Principled BSDF"
        )
        assert loaded({"type": "diffuse"}, double_sided, two_sided=True).startswith(
            "SmoothDiffuse["
        )


# -- wrongly typed geometry attributes --------------------------------------------------------


def test_wrongly_typed_geometry_attributes_warn_by_prim_and_attribute():
    stage = Usd.Stage.CreateInMemory()
    topology = (
        "int[] faceVertexCounts = [4, 4, 4, 4, 4, 4]\n"
        f"int[] faceVertexIndices = {[i for q in CUBE_QUADS for i in q]}\n"
        'uniform token subdivisionScheme = "none"\n'
    )
    cube = f"point3f[] points = {[tuple(p) for p in CUBE_POINTS]}\n"
    stage.GetRootLayer().ImportFromString(
        "#usda 1.0\n"
        f'def Mesh "ColourPoints"\n{{\n{topology}color3f[] {cube[9:]}}}\n'
        f'def Mesh "IntPoints"\n{{\n{topology}int[] points = [1, 2, 3]\n}}\n'
        f'def Mesh "IntNormals"\n{{\n{topology}{cube}int normals = 7\n}}\n'
        f'def Mesh "DoublePoints"\n{{\n{topology}double3[] {cube[9:]}}}\n'
        f'def Mesh "EmptyPrimvar"\n{{\n{topology}{cube}float2[] primvars:st = []\n}}\n'
    )
    bad_counts = cube_mesh(stage, "/BadCounts", scheme="none")
    bad_counts.GetFaceVertexCountsAttr().Set([4, 4, 4])
    bad_extent = cube_mesh(stage, "/BadExtent", scheme="none")
    bad_extent.CreateExtentAttr([(1, 1, 1), (0, 0, 0)])
    bad_st = cube_mesh(stage, "/BadIndices", scheme="none")
    st = UsdGeom.PrimvarsAPI(bad_st).CreatePrimvar(
        "st", Sdf.ValueTypeNames.TexCoord2fArray, "faceVarying"
    )
    st.Set([(0, 0)])
    st.SetIndices([0, 5] * 12)
    scene, diag = quiet(lambda d: StageDelegate(stage, Usd.TimeCode.Default(), d).sync())
    # ColourPoints, IntNormals, EmptyPrimvar, BadExtent, BadIndices
    assert scene.mesh_count == 5
    expected = [
        "/ColourPoints: points is authored as color3f[], not point3f[]; read as point3f[]",
        "/IntPoints: points has type int[], expected point3f[]; ignored",
        "/IntNormals: normals has type int, expected normal3f[]; ignored",
        "/DoublePoints: points has type double3[], expected point3f[]; ignored",
        "/BadCounts: faceVertexCounts sum to 12 but there are 24 faceVertexIndices",
        "/BadExtent: extent [1.0, 1.0, 1.0]..[0.0, 0.0, 0.0] is inverted",
        "/BadIndices: primvars:st: 12 indices out of range (0..0); ignored",
    ]
    for line in expected:
        assert any(m.startswith(line) for m in diag.messages), (line, diag.messages)


# -- UsdSkel --------------------------------------------------------------------------------------


def skinned_bar(stage):
    """The bending bar of :func:`skel_rig.bending_bar` at ``/Rig`` (0.2 wide, no normals)."""
    from skel_rig import bending_bar

    return bending_bar(stage)


def test_skinned_points_follow_the_animation_at_the_render_time():
    stage = Usd.Stage.CreateInMemory()
    skinned_bar(stage)
    bounds = {}
    for t in (0.0, 10.0):
        scene, diag = quiet(lambda d, t=t: StageDelegate(stage, Usd.TimeCode(t), d).sync())
        assert diag.messages == [] and scene.mesh_count == 1
        bounds[t] = scene.bounds
    assert bounds[0.0][1] == pytest.approx([2, 0.1, 0], abs=1e-5)  # rest pose: the bar along x
    # joint b at x = 1 turned 90° about z: the tip (x = 2) swings to y = 1 (± the bar's half width)
    assert bounds[10.0][1][1] == pytest.approx(1.0, abs=1e-5)
    assert bounds[10.0][1][0] == pytest.approx(1.1, abs=1e-5)


# -- BasisCurves -----------------------------------------------------------------------------------


def test_curve_bases_convert_exactly_to_bsplines():
    from pavonine.render.curves import bases

    rng = np.random.default_rng(1)
    bezier = rng.normal(size=(4, 4))
    (bspline,) = bases.to_bspline(bezier, "cubic", "bezier", "nonperiodic")

    # B-spline segment evaluated at t = 0, 1/2, 1 equals the Bézier curve there
    def basis(t):
        return (
            np.array(
                [(1 - t) ** 3, 3 * t**3 - 6 * t**2 + 4, -3 * t**3 + 3 * t**2 + 3 * t + 1, t**3]
            )
            / 6
        )

    bern = lambda t: np.array([(1 - t) ** 3, 3 * t * (1 - t) ** 2, 3 * t**2 * (1 - t), t**3])  # noqa: E731
    for t in (0.0, 0.5, 1.0):
        assert basis(t) @ bspline == pytest.approx(bern(t) @ bezier)
    pinned = bases.to_bspline(bezier, "cubic", "bspline", "pinned")[0]
    assert basis(0.0) @ pinned[:4] == pytest.approx(bezier[0])  # starts on its first point
    assert basis(1.0) @ pinned[-4:] == pytest.approx(bezier[-1])
    periodic = bases.to_bspline(bezier, "cubic", "bspline", "periodic")[0]
    assert len(periodic) == 7 and np.array_equal(periodic[4:], bezier[:3])
