"""Hypothesis generators of hostile USD layers: valid ``.usda`` grammar, hostile values.

Every generator is here, so a reviewer extends the fuzz in one place:

* :data:`HOSTILE_FLOATS` / :data:`HOSTILE_INTS`: the values mixed into every number (NaN, ±inf,
  ±1e38, zero, negatives, huge) next to ordinary ones;
* :data:`PRIMS`: one function per prim kind (mesh, implicit shapes, curves, point instancer,
  xform, lights, camera), each drawing a prim's ``.usda`` text from ``draw``; add a function and
  list it there to fuzz a new kind;
* :func:`layers`: a whole stage (render settings, a camera, 1-4 prims, and sometimes a reference
  or sublayer cycle through a second file) as ``{file name: text}``.

Attributes are sometimes authored with the wrong type (``string`` for a number, ``int[]`` for
points) and arrays are sometimes empty, huge (up to :data:`HUGE_ARRAY` elements) or of a length
that does not match the topology. Render sizes stay tiny (≤ 16×12) so each example is fast.
"""

from __future__ import annotations

import math

from hypothesis import strategies as st

#: Numbers that have broken renderers: non-finite, beyond float32, zero and negative sizes.
HOSTILE_FLOATS = [math.nan, math.inf, -math.inf, 1e38, -1e38, 3.5e38, 0.0, -1.0, 1e-38, -0.0]
#: Integers for counts, indices and sizes.
HOSTILE_INTS = [-1, 0, 1, 2, 3, 2**31 - 1, -(2**31), 100000]
#: Longest array a generator writes (a large PointInstancer or mesh, still quick to parse).
HUGE_ARRAY = 5000
#: Largest render the fuzz asks for (pixels are not what it is testing).
MAX_SIZE = (16, 12)

ordinary_floats = st.floats(-10.0, 10.0, allow_nan=False, allow_infinity=False)
floats = st.one_of(ordinary_floats, ordinary_floats, st.sampled_from(HOSTILE_FLOATS))
positive = st.one_of(st.floats(0.05, 5.0), st.sampled_from(HOSTILE_FLOATS))
ints = st.one_of(st.integers(0, 8), st.sampled_from(HOSTILE_INTS))


def number(value: float) -> str:
    """A float as ``.usda`` writes it (``nan``, ``inf``, ``-inf``, else ``repr``)."""
    if math.isnan(value):
        return "nan"
    if math.isinf(value):
        return "inf" if value > 0 else "-inf"
    return repr(float(value))


def vec(values) -> str:
    return "(" + ", ".join(number(v) for v in values) + ")"


def array(items: list[str]) -> str:
    return "[" + ", ".join(items) + "]"


@st.composite
def points(draw, min_size: int = 0, max_size: int = 12) -> list[str]:
    """Point3f values: mostly a small cloud, sometimes hostile, sometimes a huge array."""
    if draw(st.integers(0, 19)) == 0:
        count = draw(st.integers(1000, HUGE_ARRAY))
        return [vec((i % 7, i // 7 % 5, 0.0)) for i in range(count)]
    return draw(st.lists(st.tuples(floats, floats, floats).map(vec), min_size=min_size,
                         max_size=max_size))  # fmt: skip


@st.composite
def attribute(draw, kind: str, name: str, value: str, wrong: str = 'string {name} = "oops"') -> str:
    """``kind name = value``, or (sometimes) the attribute with a wrong type."""
    if draw(st.integers(0, 9)) == 0:
        return wrong.format(name=name)
    return f"{kind} {name} = {value}"


@st.composite
def xform_ops(draw) -> str:
    """A translate, sometimes a scale, with hostile values possible."""
    ops = [f"double3 xformOp:translate = {vec(draw(st.tuples(floats, floats, floats)))}"]
    order = ['"xformOp:translate"']
    if draw(st.booleans()):
        ops.append(f"float3 xformOp:scale = {vec(draw(st.tuples(positive, positive, positive)))}")
        order.append('"xformOp:scale"')
    ops.append(f"uniform token[] xformOpOrder = [{', '.join(order)}]")
    return "\n    ".join(ops)


@st.composite
def prim_text(draw, kind: str, name: str, body: list[str]) -> str:
    """``def KIND "NAME" { body }``, sometimes with (possibly hostile) xformOps."""
    if draw(st.booleans()):
        body = [*body, draw(xform_ops())]
    return f'def {kind} "{name}" {{\n    ' + "\n    ".join(body) + "\n}"


@st.composite
def mesh(draw, name: str) -> str:
    pts = draw(points())
    counts = draw(st.one_of(st.just([4]), st.lists(ints, max_size=4)))
    indices = draw(st.one_of(st.just([0, 1, 2, 3]), st.lists(ints, max_size=12)))
    body = [
        draw(attribute("point3f[]", "points", array(pts), "int[] {name} = [1, 2, 3]")),
        draw(attribute("int[]", "faceVertexCounts", array([str(c) for c in counts]))),
        draw(attribute("int[]", "faceVertexIndices", array([str(i) for i in indices]))),
        f'uniform token subdivisionScheme = "{draw(st.sampled_from(["none", "catmullClark"]))}"',
    ]
    if draw(st.booleans()):  # a primvar whose count may not match its interpolation
        st_count = draw(st.integers(0, 6))
        interp = draw(st.sampled_from(["vertex", "faceVarying", "uniform", "constant"]))
        values = array([vec((i / 4, i / 4)) for i in range(st_count)])
        body.append(f'texCoord2f[] primvars:st = {values} (interpolation = "{interp}")')
    if draw(st.booleans()):
        normals = array([vec(draw(st.tuples(floats, floats, floats))) for _ in range(2)])
        body.append(f"normal3f[] normals = {normals}")
    return draw(prim_text("Mesh", name, body))


@st.composite
def implicit(draw, name: str) -> str:
    kind, attr, type_ = draw(
        st.sampled_from(
            [("Sphere", "radius", "double"), ("Cube", "size", "double"),
             ("Cylinder", "height", "double"), ("Cone", "radius", "double"),
             ("Capsule", "radius", "double")]
        )
    )  # fmt: skip
    body = [draw(attribute(type_, attr, number(draw(positive))))]
    return draw(prim_text(kind, name, body))


@st.composite
def curves(draw, name: str) -> str:
    pts = draw(points(max_size=8))
    counts = draw(st.one_of(st.just([len(pts)]), st.lists(ints, max_size=3)))
    widths = draw(st.lists(positive, max_size=3))
    body = [
        f'uniform token type = "{draw(st.sampled_from(["linear", "cubic"]))}"',
        f'uniform token basis = "{draw(st.sampled_from(["bspline", "bezier", "catmullRom"]))}"',
        draw(attribute("point3f[]", "points", array(pts))),
        draw(attribute("int[]", "curveVertexCounts", array([str(c) for c in counts]))),
        f"float[] widths = {array([number(w) for w in widths])}",
    ]
    if draw(st.booleans()):  # ribbons: normals of any count, interpolation and value
        interpolation = draw(st.sampled_from(["vertex", "varying", "uniform", "constant", "bad"]))
        normals = draw(attribute("normal3f[]", "normals", array(draw(points(max_size=8)))))
        body.append(f'{normals} (\n        interpolation = "{interpolation}"\n    )')
        colours = array(draw(points(max_size=8)))
        body.append(f'color3f[] primvars:displayColor = {colours} (interpolation = "vertex")')
    return f'def BasisCurves "{name}" {{\n    ' + "\n    ".join(body) + "\n}"


@st.composite
def point_instancer(draw, name: str) -> str:
    """Instances with hostile positions, scales and orientations, and bad protoIndices."""
    count = draw(st.one_of(st.integers(0, 6), st.sampled_from([40, 2000])))
    indices = draw(
        st.one_of(st.just([0] * count), st.lists(st.sampled_from([0, 1, -1, 7, 2**31 - 1]),
                                                 min_size=count, max_size=count))
    )  # fmt: skip
    positions = [vec((i % 10, i // 10 % 10, 0)) for i in range(count)]
    if draw(st.booleans()) and count:
        positions[0] = vec(draw(st.tuples(floats, floats, floats)))
    length = draw(st.sampled_from([count, max(count - 1, 0), count + 1]))
    positions = [*positions, vec((0, 0, 0))][:length]
    body = [
        f"rel prototypes = </{name}/Protos/Ball>",
        f"point3f[] positions = {array(positions)}",
        f"int[] protoIndices = {array([str(i) for i in indices])}",
    ]
    if draw(st.booleans()) and count:
        body.append(f"float3[] scales = {array([vec((draw(positive),) * 3)] * count)}")
    if draw(st.booleans()) and count:
        quat = vec(draw(st.tuples(floats, floats, floats, floats)))
        body.append(f"quath[] orientations = {array([quat] * count)}")
    proto = (
        f'def Sphere "Ball" {{\n            double radius = {number(draw(positive))}\n        }}'
    )
    body.append(f'def Scope "Protos" {{\n        {proto}\n    }}')
    return f'def PointInstancer "{name}" {{\n    ' + "\n    ".join(body) + "\n}"


@st.composite
def light(draw, name: str) -> str:
    kind = draw(st.sampled_from(["DistantLight", "SphereLight", "RectLight", "DomeLight"]))
    body = [
        draw(attribute("float", "inputs:intensity", number(draw(floats)))),
        f"color3f inputs:color = {vec(draw(st.tuples(floats, floats, floats)))}",
    ]
    if kind == "SphereLight":
        body.append(f"float inputs:radius = {number(draw(positive))}")
    return draw(prim_text(kind, name, body))


@st.composite
def xform_group(draw, name: str) -> str:
    """An Xform with (possibly hostile) ops around a small quad."""
    quad = (
        'def Mesh "Quad" {\n        point3f[] points = [(-1, -1, 0), (1, -1, 0), (1, 1, 0), '
        "(-1, 1, 0)]\n        int[] faceVertexCounts = [4]\n        int[] faceVertexIndices = "
        '[0, 1, 2, 3]\n        uniform token subdivisionScheme = "none"\n    }'
    )
    return f'def Xform "{name}" {{\n    {draw(xform_ops())}\n    {quad}\n}}'


#: Every prim generator the fuzz draws from: ``f(draw, name) -> .usda text``. Extend here.
PRIMS = [mesh, implicit, curves, point_instancer, light, xform_group]


SANE_CAMERA = (
    'def Camera "Cam" {\n    double3 xformOp:translate = (0, 0, 12)\n'
    '    uniform token[] xformOpOrder = ["xformOp:translate"]\n}'
)


@st.composite
def camera(draw) -> str:
    """Mostly a camera that sees the prims (so the fuzz reaches them), sometimes a hostile one."""
    if draw(st.integers(0, 3)):
        return SANE_CAMERA
    body = [
        draw(attribute("float", "focalLength", number(draw(st.one_of(st.just(50.0), positive))))),
        f"float horizontalAperture = {number(draw(st.one_of(st.just(36.0), positive)))}",
        f"float2 clippingRange = {vec(draw(st.tuples(positive, positive)))}",
        draw(xform_ops()),
    ]
    if draw(st.booleans()):
        body.append(f"float fStop = {number(draw(positive))}")
        body.append(f"float focusDistance = {number(draw(positive))}")
    return 'def Camera "Cam" {\n    ' + "\n    ".join(body) + "\n}"


@st.composite
def render_settings(draw) -> str:
    width = draw(st.one_of(st.integers(1, MAX_SIZE[0]), st.sampled_from([0, -4, 100000])))
    height = draw(st.one_of(st.integers(1, MAX_SIZE[1]), st.sampled_from([0, -4, 100000])))
    body = [f"int2 resolution = ({width}, {height})", "rel camera = </Cam>"]
    if draw(st.integers(0, 3)) == 0:
        aspect = draw(st.one_of(st.floats(0.5, 2.0), st.sampled_from(HOSTILE_FLOATS)))
        body.append(f"float pixelAspectRatio = {number(aspect)}")
    return 'def Scope "Render" {\n    def RenderSettings "Settings" {\n        ' + (
        "\n        ".join(body) + "\n    }\n}"
    )


@st.composite
def layers(draw) -> dict[str, str]:
    """A stage as ``{file name: .usda text}``; ``scene.usda`` is the root layer."""
    header = ['upAxis = "Y"', 'renderSettingsPrimPath = "/Render/Settings"']
    files: dict[str, str] = {}
    cycle = draw(st.sampled_from(["none", "none", "sublayer", "reference"]))
    if cycle == "sublayer":  # scene → other → scene
        header.append("subLayers = [@./other.usda@]")
        files["other.usda"] = (
            '#usda 1.0\n(\n    subLayers = [@./scene.usda@]\n)\ndef Xform "X" {}\n'
        )
    body = [draw(render_settings()), draw(camera())]
    kinds = draw(st.lists(st.sampled_from(PRIMS), min_size=1, max_size=4))
    body += [draw(kind(f"P{i}")) for i, kind in enumerate(kinds)]
    if cycle == "reference":  # /Ref references other.usda, which references /Ref back
        body.append('def Xform "Ref" (\n    references = @./other.usda@</Back>\n) {}')
        files["other.usda"] = (
            '#usda 1.0\ndef Xform "Back" (\n    references = @./scene.usda@</Ref>\n) {}\n'
        )
    files["scene.usda"] = "#usda 1.0\n(\n    " + "\n    ".join(header) + "\n)\n" + "\n".join(body)
    return files


#: Nesting of :func:`deep_layers`' stage: 3000 ``Xform`` levels overflowed the main thread's stack
#: in ``UsdGeomBBoxCache`` (issue 35; ``pavonine.base.nesting``).
DEEP = 3000


def deep_layers(depth: int = DEEP) -> dict[str, str]:
    """A valid stage of ``depth`` nested ``Xform`` prims with a quad at the bottom, and neither
    camera nor light (so the render frames it by the stage's bounds, where the crash was)."""
    opening = "".join(f'def Xform "X{i}"\n{{\n' for i in range(depth))
    quad = (
        'def Mesh "Quad"\n{\n'
        "point3f[] points = [(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)]\n"
        "int[] faceVertexCounts = [4]\nint[] faceVertexIndices = [0, 1, 2, 3]\n}\n"
    )
    return {"scene.usda": '#usda 1.0\n(\n    upAxis = "Y"\n)\n' + opening + quad + "}\n" * depth}
