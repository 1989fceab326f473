"""BasisCurves as USD images them, seen in renders: ribbons (authored normals) are flat, face their
normals and carry their primvars; tubes are round. The feather BSDF on a ribbon fed by barb
primvars renders the colour of a sheet fed by maps of the same values."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

from pavonine.materials.colour import delta_e2000, linear_srgb_to_lab
from pavonine.render.api import render_stage
from pavonine.render.diagnostics import StageWarning

pytestmark = pytest.mark.render
SIZE = 64
FRAME = 3.0  # the orthographic camera sees [-1.5, 1.5]² of the z = 0 plane
PIXEL = FRAME / SIZE

#: A foreign stage written by hand (no Pavonine schema): a catmullRom ribbon with varying
#: normals and vertex displayColor (red to blue), a linear tube, and a bspline tube with vertex
#: displayColor (tessellated: Mitsuba's curves carry no primvars), each turned about its own
#: axis (X) by {turn} degrees.
FOREIGN = """#usda 1.0
(
    upAxis = "Y"
)

def Camera "Cam"
{{
    token projection = "orthographic"
    float horizontalAperture = 30
    float verticalAperture = 30
    float2 clippingRange = (0.1, 100)
    double3 xformOp:translate = (0, 0, 10)
    uniform token[] xformOpOrder = ["xformOp:translate"]
}}

def DistantLight "Sun"
{{
    float inputs:angle = 0
    float inputs:intensity = 3.14159265
    bool inputs:normalize = 1
}}

def Xform "RibbonTurn"
{{
    double3 xformOp:translate = (0, 0.6, 0)
    float xformOp:rotateX = {turn}
    uniform token[] xformOpOrder = ["xformOp:translate", "xformOp:rotateX"]

    def BasisCurves "Ribbon"
    {{
        uniform token type = "cubic"
        uniform token basis = "catmullRom"
        uniform token wrap = "pinned"
        int[] curveVertexCounts = [4]
        point3f[] points = [(-1.2, 0, 0), (-0.4, 0, 0), (0.4, 0, 0), (1.2, 0, 0)]
        normal3f[] normals = [(0, 0, 1), (0, 0, 1), (0, 0, 1), (0, 0, 1)] (
            interpolation = "varying"
        )
        float[] widths = [0.6] (
            interpolation = "constant"
        )
        color3f[] primvars:displayColor = [(1, 0, 0), (1, 0, 0), (0, 0, 1), (0, 0, 1)] (
            interpolation = "vertex"
        )
    }}
}}

def Xform "TubeTurn"
{{
    double3 xformOp:translate = (0, -0.6, 0)
    float xformOp:rotateX = {turn}
    uniform token[] xformOpOrder = ["xformOp:translate", "xformOp:rotateX"]

    def BasisCurves "Tube"
    {{
        uniform token type = "linear"
        int[] curveVertexCounts = [2]
        point3f[] points = [(-1.2, 0, 0), (1.2, 0, 0)]
        float[] widths = [0.4] (
            interpolation = "constant"
        )
    }}
}}

def Xform "ColouredTubeTurn"
{{
    double3 xformOp:translate = (0, -1.2, 0)
    float xformOp:rotateX = {turn}
    uniform token[] xformOpOrder = ["xformOp:translate", "xformOp:rotateX"]

    def BasisCurves "ColouredTube"
    {{
        uniform token type = "cubic"
        uniform token basis = "bspline"
        uniform token wrap = "pinned"
        int[] curveVertexCounts = [4]
        point3f[] points = [(-1.2, 0, 0), (-0.4, 0, 0), (0.4, 0, 0), (1.2, 0, 0)]
        float[] widths = [0.2, 0.2, 0.2, 0.2] (
            interpolation = "vertex"
        )
        color3f[] primvars:displayColor = [(1, 0, 0), (1, 0, 0), (0, 0, 1), (0, 0, 1)] (
            interpolation = "vertex"
        )
    }}
}}
"""


def render(path, spp=4):
    result = render_stage(str(path), spp=spp, resolution=(SIZE, SIZE), progress=False)
    return result.rgb, result.warnings


def band_widths(lit: np.ndarray, y_centre: float, columns: slice, band=0.45) -> np.ndarray:
    """Lit pixels per column within ±``band`` scene units of ``y_centre`` (image rows), in units."""
    row = round(SIZE / 2 - y_centre / PIXEL)
    half = round(band / PIXEL)
    return lit[row - half : row + half, columns].sum(axis=0) * PIXEL


def test_foreign_ribbon_is_flat_faces_its_normals_and_carries_its_colours(tmp_path):
    images = {}
    for turn in (0, 90):
        path = tmp_path / f"curves_{turn}.usda"
        path.write_text(FOREIGN.format(turn=turn))
        images[turn], warnings_ = render(path)
        assert warnings_ == []
    along = slice(round(SIZE / 2 - 1.0 / PIXEL), round(SIZE / 2 + 1.0 / PIXEL))  # x in ±1
    face_on, edge_on = (images[t].mean(axis=2) > 0.02 for t in (0, 90))
    ribbon_face_on = band_widths(face_on, 0.6, along)
    # flat and as wide as authored all along, seen facing its normals ...
    assert ribbon_face_on == pytest.approx(0.6, abs=1.5 * PIXEL)
    # ... and nothing seen edge-on (turned 90° about its length)
    assert band_widths(edge_on, 0.6, along).max() <= PIXEL
    # the tube is round: the same width from both sides
    tube = [band_widths(image, -0.6, along) for image in (face_on, edge_on)]
    assert tube[0] == pytest.approx(0.4, abs=1.5 * PIXEL)
    assert tube[1] == pytest.approx(0.4, abs=1.5 * PIXEL)
    coloured = [band_widths(image, -1.2, along, band=0.25) for image in (face_on, edge_on)]
    assert coloured[0] == pytest.approx(0.2, abs=1.5 * PIXEL)
    assert coloured[1] == pytest.approx(0.2, abs=1.5 * PIXEL)
    # vertex displayColor reaches the ribbon and the tessellated tube: red at the start, blue at
    # the end
    for y, rows in ((0.6, 3), (-1.2, 1)):
        row = round(SIZE / 2 - y / PIXEL)
        start = images[0][row - rows : row + rows, round(SIZE / 2 - 1.1 / PIXEL)].mean(axis=0)
        end = images[0][row - rows : row + rows, round(SIZE / 2 + 1.1 / PIXEL)].mean(axis=0)
        assert start[0] > 0.4 and start[0] > 10 * max(start[1], start[2])
        assert end[2] > 0.4 and end[2] > 10 * max(end[0], end[1])


# -- the feather BSDF on a ribbon -----------------------------------------------------------------

CLASS, GRADATION, SHARE, ANGLE_DEG = 2, 0.4, 0.8, 36.0  # 8-bit-exact grey levels in the maps
THETA_I = 20.0  # sun 20° from the normal, in the plane of the barb (x)
FEATHER_SIZE = 48
HALF_UNIT = FEATHER_SIZE // 6  # pixels per half scene unit


def feather_scene(path, tmp_path):
    """A stage seen from +Z under a sun THETA_I off the normal, with a feather material whose
    maps hold CLASS, GRADATION, SHARE and ANGLE_DEG."""
    from pxr import Gf, Usd, UsdGeom, UsdLux
    from render_helpers import image

    from pavonine.materials.parameters import preset
    from pavonine.schemas.authoring import create_feather_material

    params = preset("paper-table1")
    greys = {
        "ocellar": 1.0 - CLASS / (len(params.classes) - 1),
        "gradation": GRADATION,
        "melanin": SHARE,
        "angle": ANGLE_DEG / 180.0,
    }
    maps = {
        name: image(tmp_path / f"{name}.png", np.full((8, 8, 1), round(g * 255), np.uint8))
        for name, g in greys.items()
    }
    stage = Usd.Stage.CreateNew(str(path))
    cam = UsdGeom.Camera.Define(stage, "/Cam")
    cam.CreateProjectionAttr(UsdGeom.Tokens.orthographic)
    cam.CreateHorizontalApertureAttr(FRAME * 10)
    cam.CreateVerticalApertureAttr(FRAME * 10)
    cam.CreateClippingRangeAttr(Gf.Vec2f(0.1, 100))
    cam.AddTranslateOp().Set(Gf.Vec3d(0, 0, 10))
    sun = UsdLux.DistantLight.Define(stage, "/Sun")
    sun.CreateAngleAttr(0.0)
    sun.CreateNormalizeAttr(True)
    sun.CreateIntensityAttr(math.pi)
    sun.AddRotateYOp().Set(THETA_I)
    return stage, create_feather_material(stage, "/Looks/Feather", params, maps)


def barb(stage, material, prim_path, x0, y, length=1.0, gradation=None, primvars=True, width=1.0):
    """A straight barb ribbon along +X from (x0, y), facing +Z, carrying the feather inputs as
    vertex primvars (``gradation``: its 4 control points' values)."""
    from pxr import Sdf, UsdGeom, UsdShade

    curves = UsdGeom.BasisCurves.Define(stage, prim_path)
    curves.CreateTypeAttr("cubic")
    curves.CreateBasisAttr("bspline")
    curves.CreateWrapAttr("pinned")
    curves.CreateCurveVertexCountsAttr([4])
    curves.CreatePointsAttr([(x0 + i * length / 3, y, 0) for i in range(4)])
    curves.CreateNormalsAttr([(0, 0, 1)] * 4)
    curves.SetNormalsInterpolation("varying")
    curves.CreateWidthsAttr([width] * 4)
    curves.SetWidthsInterpolation("vertex")
    api = UsdGeom.PrimvarsAPI(curves)
    if primvars:
        for name, values, kind in (
            ("pavonine_ocellarClass", [CLASS] * 4, Sdf.ValueTypeNames.IntArray),
            ("pavonine_gradation", gradation or [GRADATION] * 4, Sdf.ValueTypeNames.FloatArray),
            ("pavonine_melanin", [SHARE] * 4, Sdf.ValueTypeNames.FloatArray),
            ("pavonine_barbuleAngle", [ANGLE_DEG] * 4, Sdf.ValueTypeNames.FloatArray),
        ):
            api.CreatePrimvar(name, kind, "vertex").Set(values)
        api.CreatePrimvar("pavonine_barbId", Sdf.ValueTypeNames.IntArray, "uniform").Set([1])
    UsdShade.MaterialBindingAPI.Apply(curves.GetPrim()).Bind(material)
    return curves


def render_feather(path):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", StageWarning)
        result = render_stage(path, spp=16, resolution=(FEATHER_SIZE, FEATHER_SIZE), progress=False)
    return result.rgb, result.warnings


def patch_mean(rgb, cx, cy, half=5):
    """Mean colour of the 2·half × 2·half pixels around scene point (cx, cy) (spectral renders
    carry wavelength-sampling noise per pixel: about 100 pixels average it below ΔE00 0.5)."""
    col = round(FEATHER_SIZE / 2 + cx * 2 * HALF_UNIT)
    row = round(FEATHER_SIZE / 2 - cy * 2 * HALF_UNIT)
    return rgb[row - half : row + half, col - half : col + half].reshape(-1, 3).mean(axis=0)


def de(a, b) -> float:
    return float(delta_e2000(linear_srgb_to_lab(a), linear_srgb_to_lab(b)))


def test_feather_on_a_ribbon_matches_the_sheet_with_the_same_inputs(tmp_path):
    """Top left a sheet quad reading the maps, top right a ribbon carrying the same values as
    vertex primvars, bottom right a ribbon without them (neutral inputs, warned)."""
    from pxr import UsdShade
    from render_helpers import feather_sheet

    stage, material = feather_scene(tmp_path / "feather.usda", tmp_path)
    corners = [(-1.25, 0.25, 0), (-0.25, 0.25, 0), (-0.25, 1.25, 0), (-1.25, 1.25, 0)]
    sheet = feather_sheet(stage, "/Sheet", corners)  # u along +X: the barb direction
    UsdShade.MaterialBindingAPI.Apply(sheet.GetPrim()).Bind(material)
    barb(stage, material, "/Ribbon", 0.25, 0.75)
    barb(stage, material, "/Bare", 0.25, -0.75, primvars=False)
    stage.Save()
    rgb, warnings_ = render_feather(stage.GetRootLayer().realPath)
    on_sheet, on_ribbon, bare = (
        patch_mean(rgb, x, y) for x, y in ((-0.75, 0.75), (0.75, 0.75), (0.75, -0.75))
    )
    assert on_sheet.max() > 0.05  # lit: a colour to compare
    assert de(on_ribbon, on_sheet) < 1.0
    assert de(bare, on_sheet) > 5.0  # without the primvars: the neutral inputs, another colour
    assert warnings_ == [
        "/Bare: feather material /Looks/Feather: the ribbons have no primvars:pavonine_featherUV "
        "to place its maps and no primvars:pavonine_ocellarClass, primvars:pavonine_gradation, "
        "primvars:pavonine_barbuleAngle, primvars:pavonine_melanin; those inputs take their "
        "neutral values"
    ]


def test_feather_primvars_are_read_on_an_instance_own_mesh(tmp_path):
    """A ribbon whose gradation runs 0 → 0.9 along it, in place (top), through a PointInstancer
    (middle) and through a native instance (bottom), both moved 1.5 units along the barb: the
    same colours at the same places along it (Mitsuba locates a mesh attribute from the hit point
    against the prototype's vertices)."""
    from pxr import Gf, Sdf, UsdGeom

    stage, material = feather_scene(tmp_path / "instanced.usda", tmp_path)
    ramp = [0.0, 0.3, 0.6, 0.9]
    barb(stage, material, "/InPlace", -1.0, 0.9, length=2.0, gradation=ramp, width=0.6)
    instancer = UsdGeom.PointInstancer.Define(stage, "/Instancer")
    UsdGeom.Xform.Define(stage, "/Instancer/Prototypes/Barb")
    barb(stage, material, "/Instancer/Prototypes/Barb/Ribbon", -2.5, 0, 2.0, ramp, width=0.6)
    instancer.CreatePrototypesRel().SetTargets([Sdf.Path("/Instancer/Prototypes/Barb")])
    instancer.CreateProtoIndicesAttr([0])
    instancer.CreatePositionsAttr([(1.5, 0, 0)])
    stage.CreateClassPrim("/Prototypes")
    UsdGeom.Xform.Define(stage, "/Prototypes/Barb")
    barb(stage, material, "/Prototypes/Barb/Ribbon", -2.5, 0.0, 2.0, ramp, width=0.6)
    instance = stage.DefinePrim("/Instance")
    instance.GetReferences().AddInternalReference("/Prototypes/Barb")
    instance.SetInstanceable(True)
    UsdGeom.Xformable(instance).AddTranslateOp().Set(Gf.Vec3d(1.5, -0.9, 0))
    stage.Save()
    rgb, warnings_ = render_feather(stage.GetRootLayer().realPath)
    assert warnings_ == []
    along, instanced, native = (
        [patch_mean(rgb, x, y, half=4) for x in (-0.6, 0.0, 0.6)] for y in (0.9, 0.0, -0.9)
    )
    assert de(along[0], along[-1]) > 3.0  # the gradation shows along the barb
    for a, b, c in zip(along, instanced, native, strict=True):
        # broken (world hit point on the prototype): ΔE00 9 to 15
        assert de(a, b) < 1.5 and de(a, c) < 1.5


#: A barb ribbon that tapers to nothing at its root: width 0 at (0, 0), NEEDLE at (2, 0). Its
#: one triangle with area, (root, +edge, −edge), is a needle: its two long edges differ by
#: 1e-4, so in float32 |e1|²|e2|² − (e1·e2)² is exactly 0, and Mitsuba's barycentric solve for
#: mesh attributes (Mesh::barycentric_coordinates, from the hit point) divides by it.
NEEDLE = 1e-4
NEEDLE_STAGE = """
import sys
import numpy as np
from pavonine.render.api import render_stage
result = render_stage(sys.argv[1], spp=4, resolution=(16, 16), progress=False)
lit = result.rgb.max(axis=2) > 0.01
print(f"{lit.mean():.3f}")
"""


def test_a_ribbon_tapering_to_a_needle_renders_its_primvars_without_crashing(tmp_path):
    """Regression (issue 23): the eye's barbs at the hero view, 512×768 @ 64 spp, died of SIGSEGV.
    Lanes hitting a needle triangle of a tapering barb read NaN primvars, the feather BSDF's
    stack-table index became NaN → 0x80000000 and its gather read 8 GiB past the table. Here the
    camera sees only the needle's wide end (frame 2.5·NEEDLE), so most lanes hit it; run in a
    child process, so a crash fails the test instead of ending pytest."""
    import subprocess
    import sys

    from pxr import Gf

    stage, material = feather_scene(tmp_path / "needle.usda", tmp_path)
    curves = barb(stage, material, "/Needle", 0.0, 0.0, length=2.0)
    curves.CreateTypeAttr("linear")
    curves.CreateCurveVertexCountsAttr([2])
    curves.CreatePointsAttr([(0, 0, 0), (2, 0, 0)])
    curves.CreateNormalsAttr([(0, 0, 1)] * 2)
    curves.CreateWidthsAttr([0.0, NEEDLE])
    for name in ("ocellarClass", "gradation", "melanin", "barbuleAngle"):
        primvar = curves.GetPrim().GetAttribute(f"primvars:pavonine_{name}")
        primvar.Set(primvar.Get()[:2])
    from pxr import UsdGeom

    cam = UsdGeom.Camera(stage.GetPrimAtPath("/Cam"))
    cam.GetHorizontalApertureAttr().Set(25 * NEEDLE)
    cam.GetVerticalApertureAttr().Set(25 * NEEDLE)
    UsdGeom.Xformable(cam).GetOrderedXformOps()[0].Set(Gf.Vec3d(2 - NEEDLE, 0, 10))
    stage.Save()
    done = subprocess.run(
        [sys.executable, "-c", NEEDLE_STAGE, stage.GetRootLayer().realPath],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 0, done.stderr[-2000:]
    assert float(done.stdout.split()[-1]) > 0.2  # the needle fills its share of the frame: lit
