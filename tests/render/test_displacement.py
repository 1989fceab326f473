"""Displacement at render time (render/displacement.py): tessellation, heights, silhouettes.

The silhouette test is a small twin of hdmitsuba's ``shapes/displacement_preview_surface.usda``
(a quad displaced by a UsdUVTexture through UsdPreviewSurface's ``displacement``), seen edge-on
so the undisplaced quad covers no pixel and the displaced one shows its bump's profile.
"""

from __future__ import annotations

import numpy as np
import pytest
from pxr import Sdf, UsdGeom, UsdShade
from render_helpers import bind, image, new_stage, preview, render, sun, texture

from pavonine.render import displacement
from pavonine.render.mesh import TriangleMesh

SIZE = 48
HEIGHT = 0.5  # UsdUVTexture scale on the disc's texel value 1


def flat_quad(level_points: int = 2) -> TriangleMesh:
    """A unit square in z = 0 as two triangles, texcoords = xy."""
    p = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], np.float32)
    faces = np.array([[0, 1, 2], [0, 2, 3]], np.uint32)
    return TriangleMesh("q", p, faces, np.tile([0, 0, 1], (4, 1)).astype(np.float32), p[:, :2])


def test_tessellation_shares_edge_points_and_interpolates_linearly():
    for level in (2, 3, 7):
        fine = displacement.tessellate(flat_quad(), level)
        assert len(fine.faces) == 2 * level**2
        assert len(fine.positions) == (level + 1) ** 2  # the diagonal's points are shared
        assert np.allclose(fine.positions[:, :2], fine.texcoords)
        assert fine.area() == pytest.approx(1.0)
        normals = np.cross(
            *(fine.positions[fine.faces[:, k]] - fine.positions[fine.faces[:, 0]] for k in (1, 2))
        )
        assert np.all(normals[:, 2] > 0)  # winding kept


def test_heights_read_the_texture_with_its_wrap_and_uv_transform():
    texels = np.zeros((4, 4))
    texels[0, :] = 1.0  # the image's top row
    value = {
        "type": "bitmap",
        "bitmap": texels[..., None].astype(np.float32),
        "wrap_mode": "repeat",
    }
    d = displacement.from_texture("/M/T", value, scale=2.0, offset=-0.5)
    uv = np.array([[0.5, 0.125], [0.5, 1.125], [0.5, 0.625]])  # Mitsuba uv: v = 0 is the top
    faces = np.array([[0, 1, 2]])
    h = displacement.heights(d, uv, faces)
    assert h[0] == pytest.approx(1.5) and h[1] == pytest.approx(1.5)  # repeat: v 1.125 ≡ 0.125
    assert h[2] == pytest.approx(-0.5)
    assert displacement.heights(displacement.from_texture("/M", 0.25), uv, faces) == pytest.approx(
        [0.25] * 3
    )


def test_displaced_flat_quad_moves_along_its_normal_through_the_transform():
    d = displacement.Displacement("/M", offset=0.1)
    scale = np.diag([2.0, 2.0, 3.0, 1.0])  # object → world: z scaled by 3
    moved = displacement.displace(flat_quad(), d, scale)
    assert np.allclose(moved.positions[:, 2], 0.3)  # 0.1 object units along +z, times 3


def test_levels_fit_the_ceiling_by_one_factor():
    assert displacement.fit_levels([8, 4], [10, 10], 10**6) == [8, 4]
    levels = displacement.fit_levels([8, 4], [10, 10], 400)
    assert sum(10 * n * n for n in levels) <= 400 and levels[0] > levels[1] >= 1


def bump_stage(tmp_path, displaced: bool = True):
    """A 2×2 quad in y = 0 facing +y, seen edge-on from +z; a disc of texel 1 in its middle
    displaces it by ``HEIGHT`` (UsdUVTexture scale) when ``displaced``."""
    stage = new_stage(tmp_path / ("bump.usda" if displaced else "flat.usda"))
    mesh = UsdGeom.Mesh.Define(stage, "/Quad")
    mesh.CreatePointsAttr([(-1, 0, -1), (1, 0, -1), (1, 0, 1), (-1, 0, 1)])
    mesh.CreateFaceVertexCountsAttr([4])
    mesh.CreateFaceVertexIndicesAttr([0, 3, 2, 1])
    mesh.CreateSubdivisionSchemeAttr("catmullClark")  # displaced after subdivision
    mesh.CreateDoubleSidedAttr(True)
    UsdGeom.PrimvarsAPI(mesh).CreatePrimvar(
        "st", Sdf.ValueTypeNames.TexCoord2fArray, UsdGeom.Tokens.vertex
    ).Set([(0, 0), (1, 0), (1, 1), (0, 1)])
    sun(stage).AddRotateXOp().Set(-60.0)  # from above and in front
    rows, cols = np.mgrid[0:32, 0:32]
    disc = (((rows - 15.5) ** 2 + (cols - 15.5) ** 2) < 8**2).astype(np.uint8) * 255
    file = image(tmp_path / "disc.png", np.repeat(disc[..., None], 3, axis=2))
    material, surface = preview(stage, diffuseColor=(0.8, 0.8, 0.8))
    if displaced:
        tex = texture(stage, "/Looks/M", file, sourceColorSpace="raw", scale=(HEIGHT,) * 4)
        surface.CreateInput("displacement", Sdf.ValueTypeNames.Float).ConnectToSource(
            tex.ConnectableAPI(), "r"
        )
        material.CreateDisplacementOutput().ConnectToSource(
            surface.ConnectableAPI(), "displacement"
        )
    bind(mesh, material)
    return stage


def covered_rows(rgb: np.ndarray) -> np.ndarray:
    """Rows (0 = top) with any lit pixel."""
    return np.flatnonzero((rgb.sum(axis=2) > 1e-3).any(axis=1))


@pytest.mark.render
def test_displacement_changes_the_silhouette(tmp_path):
    bumped = render(bump_stage(tmp_path), spp=4, resolution=(SIZE, SIZE))
    flat = render(bump_stage(tmp_path, displaced=False), spp=4, resolution=(SIZE, SIZE))
    assert not any("displace" in w for w in bumped.warnings), bumped.warnings
    assert len(covered_rows(flat.rgb)) <= 2  # edge-on: a line at most
    # camera: 50 mm lens, 20.955 mm aperture, 5 units away → 2 · 5 · 0.20955 units over SIZE rows
    rows_per_unit = SIZE / (2 * 5 * 20.955 / 100)
    top = covered_rows(bumped.rgb).min()
    assert SIZE / 2 - top == pytest.approx(HEIGHT * rows_per_unit, abs=2.5)


@pytest.mark.render
def test_beyond_the_ceiling_the_bump_map_is_the_fallback(tmp_path, monkeypatch):
    monkeypatch.setattr(displacement, "MAX_TRIANGLES", 10)
    result = render(bump_stage(tmp_path), spp=2, resolution=(SIZE, SIZE))
    assert any(
        w.startswith("/Quad: displacement tessellation ceiling (10 triangles) reached")
        and "bump map" in w
        for w in result.warnings
    ), result.warnings
    assert len(covered_rows(result.rgb)) <= 2  # undisplaced


def test_preview_displacement_without_a_terminal_is_warned(tmp_path):
    stage = new_stage(tmp_path / "no_terminal.usda")
    material, _ = preview(stage, displacement=0.2)
    from pavonine.render.diagnostics import Diagnostics, StageWarning
    from pavonine.render.shading import translate_material

    diag = Diagnostics()
    with pytest.warns(StageWarning, match="no displacement output of the material connects"):
        spec = translate_material(
            UsdShade.Material(material.GetPrim()), stage.GetStartTimeCode(), diag
        )
    assert spec.displacement is None
    assert any("no displacement output of the material connects" in w for w in diag.messages)


def terminal_material(tmp_path, context: str, node_id: str | None):
    """A material whose ``context`` displacement terminal reads a 2×2 texture (through
    ``node_id`` with scale 0.5, or straight from the texture when ``None``)."""
    stage = new_stage(tmp_path / f"terminal_{context or 'universal'}.usda")
    material, _ = preview(stage, diffuseColor=(0.5, 0.5, 0.5))
    file = image(tmp_path / "grey.png", np.full((2, 2, 3), 255, np.uint8))
    tex = texture(stage, "/Looks/M", file, sourceColorSpace="raw")
    source = tex
    if node_id is not None:
        source = UsdShade.Shader.Define(stage, "/Looks/M/Displace")
        source.CreateIdAttr(node_id)
        source.CreateInput("scale", Sdf.ValueTypeNames.Float).Set(0.5)
        source.CreateInput("displacement", Sdf.ValueTypeNames.Float).ConnectToSource(
            tex.ConnectableAPI(), "r"
        )
    output = "out" if node_id is not None else "r"
    material.CreateDisplacementOutput(context).ConnectToSource(source.ConnectableAPI(), output)
    return stage, material


def translated(stage, material):
    from pavonine.render.diagnostics import Diagnostics
    from pavonine.render.shading import translate_material

    diag = Diagnostics()
    return translate_material(material, stage.GetStartTimeCode(), diag), diag.messages


def test_materialx_displacementshader_and_hdmitsuba_terminal_displace(tmp_path):
    spec, messages = translated(*terminal_material(tmp_path, "mtlx", "ND_displacement_float"))
    assert spec.displacement is not None and spec.displacement.scale == 0.5, messages
    assert spec.bsdf["type"] == "bumpmap"  # the fallback
    spec, messages = translated(*terminal_material(tmp_path, "mitsuba", None))
    assert spec.displacement is not None and spec.displacement.offset == -0.5, messages
    uv = np.array([[0.5, 0.5]] * 3)
    assert displacement.heights(spec.displacement, uv, np.array([[0, 1, 2]])) == pytest.approx(
        [0.5] * 3  # white texel 1 − ½ (hdmitsuba's centring)
    )
    from pavonine.render.diagnostics import StageWarning

    with pytest.warns(StageWarning, match="ND_displacement_vector3"):
        spec, messages = translated(*terminal_material(tmp_path, "mtlx", "ND_displacement_vector3"))
    assert spec.displacement is None
    assert any("ND_displacement_vector3" in m and "not supported" in m for m in messages)
