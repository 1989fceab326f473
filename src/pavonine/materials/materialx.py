"""The feather surface shader as a MaterialX node definition with a standard-node implementation.

``pavonine_feather.mtlx`` (beside this module) is *generated* by :func:`build_document` and checked
by the test suite; edit this module, then run ``python -m pavonine.materials.materialx``.

Node definition ``ND_pavonine_feather_surfaceshader`` mirrors the USD schema ``PavonineFeatherAPI``:
per ocellar class ``k`` (0…5) and axis the (black, white) ends of layer interval (µm), rod radius
(µm) and layer count, plus the scalar optics. Its implementation ``NG_pavonine_feather_surfaceshader``
uses only MaterialX standard nodes, so any MaterialX renderer shows the feather's dominant hue:

1. The class index is ``round((1 − g)(n − 1))`` of the ocellar map's grey ``g`` (``ocellar``) and the
   material's class count ``n`` (``class_count``), as the renderer reads the map; ``switch`` picks
   the class and ``mix`` interpolates black→white by ``gradation``.
2. Eq. 1 (paper; MODEL-NOTES): ``f = π a / (2 d)``, ``D = d·[n_ml·f + n_0·(1 − f)]`` (µm).
3. A thin film of index ``n_ml`` on a keratin substrate (n = 1.53, MODEL-NOTES' keratin index at
   long wavelengths) reflects constructively where ``2·n_ml·t = (m + ½)·λ`` (one π phase shift, at
   the air/film interface). Thickness ``t = 1.5·D/n_ml`` (converted µm → nm) puts its m = 1 peak
   at ``λ = 2·D``, the first-order peak of the rod multilayer at normal incidence (Eq. 4), with the
   neighbouring peaks (6·D and 1.2·D) outside the visible range for the Table 1 values: a saturated
   single hue, like the feather's.
4. ``dielectric_bsdf`` (``thinfilm_thickness``/``thinfilm_ior``, MaterialX 1.39) per axis, mixed
   50/50 (Eq. 7 averaged over the barbule direction ψ), weighted by the structural share (melanin
   map) and layered over an ``oren_nayar_diffuse_bsdf`` in the melanin colour. Roughness is the
   Beckmann α for a slope standard deviation tan σ, ``α = √2·tan σ``, used as GGX α (the two lobes
   match near their peak): along the barbule (the BSDF's ``tangent``) from ``block_sigma``, across
   it from ``crescent_sigma``, as in :mod:`pavonine.materials.brdf`. The barbule's long axis is the
   ``tangent`` input (the barb direction) turned by ``barbule_angle · 180°`` (the angle map's grey)
   counter-clockwise about ``normal``; a host bumps ``normal`` with the displacement map.

Layer counts, rod length, the interference mode and the glitter inputs are carried for renderers that implement the
full model (``pavonine render``); a single thin film cannot express them, so the graph ignores them.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path
from typing import Any

from pavonine.materials.parameters import FeatherParameters

MTLX_PATH = Path(__file__).resolve().parent / "pavonine_feather.mtlx"
NODE = "pavonine_feather"
NODEDEF = "ND_pavonine_feather_surfaceshader"
NODEGRAPH = "NG_pavonine_feather_surfaceshader"
MAX_CLASSES = 6  # the six ocellar classes of the paper's eye feather (§3.3)
KERATIN_INDEX = 1.53  # substrate of the thin film; MODEL-NOTES: keratin n = 1.532 + 5890/λ²
FILM_ORDER_FACTOR = 1.5  # n·t = 1.5·D → the film's m = 1 peak sits at λ = 2·D (see module doc)
AXES = ("long", "short")
QUANTITIES = ("layer_interval", "rod_radius", "layer_count")
_PARAM_FIELD = {"layer_interval": "interval", "rod_radius": "radius", "layer_count": "count"}


def class_input(k: int, axis: str, quantity: str) -> str:
    """Nodedef input name for class ``k``, axis and quantity, e.g. ``class2_long_rod_radius``."""
    return f"class{k}_{axis}_{quantity}"


#: The material's defaults, read from :class:`~pavonine.materials.parameters.FeatherParameters`
#: (the one place they are written; the USD schema's fallbacks are generated from it too).
_DEFAULTS = {f.name: f.default for f in dataclasses.fields(FeatherParameters)}

#: Scalar nodedef inputs: name -> (MaterialX type, default, doc).
SCALAR_INPUTS: dict[str, tuple[str, Any, str]] = {
    "ocellar": (
        "float",
        1.0,
        "Ocellar map grey g: class round((1 - g)(class_count - 1)), white = class 0.",
    ),
    "class_count": ("integer", MAX_CLASSES, "Number of ocellar classes of the material (1-6)."),
    "gradation": ("float", 0.0, "0 = black end, 1 = white end of the class parameters."),
    "barbule_angle": (
        "float",
        0.0,
        "Angle map grey g: barbule long axis at g*180 degrees counter-clockwise from tangent.",
    ),
    "melanin_index": (
        "float",
        _DEFAULTS["melanin_index"],
        "Refractive index of the melanin rods (n_ml).",
    ),
    "medium_index": (
        "float",
        _DEFAULTS["medium_index"],
        "Refractive index between the rods (n_0).",
    ),
    "crescent_sigma": (
        "float",
        _DEFAULTS["crescent_sigma_deg"],
        "Normal spread across the barbule, degrees (Eq 6).",
    ),
    "block_sigma": (
        "float",
        _DEFAULTS["block_sigma_deg"],
        "Normal spread along the barbule, degrees.",
    ),
    "rod_length": (
        "float",
        _DEFAULTS["rod_length_um"],
        "Rod length, um (full model only; unused by this graph).",
    ),
    "interference": (
        "string",
        _DEFAULTS["interference"],
        "Rod-layer optics: paper | intensity | physical (full model only).",
    ),
    "melanin_color": ("color3", _DEFAULTS["melanin_color"], "Linear sRGB melanin-brown albedo."),
    "glitter": (
        "float",
        _DEFAULTS["glitter"],
        "0 = smooth average over barbule blocks, 1 = discrete blocks that glint (full model only).",
    ),
    "glitter_seed": (
        "integer",
        _DEFAULTS["glitter_seed"],
        "Seed of the blocks' tilts (full model only).",
    ),
    "block_length": (
        "float",
        _DEFAULTS["block_length_um"],
        "Block length along the barbule, um (full model only).",
    ),
    "barbule_width": (
        "float",
        _DEFAULTS["barbule_width_um"],
        "Barbule spacing across its axis, um (full model only).",
    ),
    "structural": ("float", 1.0, "Share of structural colour, from the melanin map."),
    "opacity": ("float", 1.0, "Opacity, from the alpha map."),
}

#: Geometric nodedef inputs: name -> (default geometric property, doc). Hosts connect ``normal``
#: to the displacement map's bump and ``tangent`` to the mesh's barb direction.
GEOMETRIC_INPUTS: dict[str, tuple[str, str]] = {
    "normal": ("Nworld", "Shading normal (world space)."),
    "tangent": ("Tworld", "Barb direction (world space), the angle map's zero."),
}
#: Inputs a host drives per texel from the maps and the mesh (not derived from the schema).
PER_TEXEL_INPUTS = ("ocellar", "gradation", "barbule_angle", "structural", "opacity")


def input_values(params, ocellar: float = 1.0, gradation: float = 0.0) -> dict[str, Any]:
    """Nodedef input values derived from a ``FeatherParameters`` (classes beyond 6 are dropped;
    fewer than 6 repeat the last class so that every class index stays defined), with the
    per-texel inputs at the given ocellar grey and gradation (the rest at their defaults)."""
    values: dict[str, Any] = {}
    classes = list(params.classes[:MAX_CLASSES])
    classes += [classes[-1]] * (MAX_CLASSES - len(classes))
    for k, cls in enumerate(classes):
        for axis in AXES:
            black, white = getattr(cls, axis)
            for quantity in QUANTITIES:
                field = _PARAM_FIELD[quantity]
                values[class_input(k, axis, quantity)] = (
                    float(getattr(black, field)),
                    float(getattr(white, field)),
                )
    values.update(
        ocellar=float(ocellar),
        class_count=min(len(params.classes), MAX_CLASSES),
        gradation=float(gradation),
        barbule_angle=0.0,
        melanin_index=float(params.melanin_index),
        medium_index=float(params.medium_index),
        crescent_sigma=float(params.crescent_sigma_deg),
        block_sigma=float(params.block_sigma_deg),
        rod_length=float(params.rod_length_um),
        interference=str(params.interference),
        melanin_color=tuple(float(c) for c in params.melanin_color),
        glitter=float(params.glitter),
        glitter_seed=int(params.glitter_seed),
        block_length=float(params.block_length_um),
        barbule_width=float(params.barbule_width_um),
        structural=1.0,
        opacity=1.0,
    )
    return values


def input_names() -> list[str]:
    """Every input of the node definition."""
    classes = [
        class_input(k, axis, quantity)
        for k in range(MAX_CLASSES)
        for axis in AXES
        for quantity in QUANTITIES
    ]
    return [*classes, *SCALAR_INPUTS, *GEOMETRIC_INPUTS]


def input_type(name: str) -> str:
    """MaterialX type of a nodedef input."""
    if name in SCALAR_INPUTS:
        return SCALAR_INPUTS[name][0]
    if name in GEOMETRIC_INPUTS:
        return "vector3"
    return "vector2"


def _default_params():
    from pavonine.materials.parameters import preset

    return preset("paper-table1")


def build_document():
    """The MaterialX document holding the nodedef and its node-graph implementation."""
    import MaterialX as mx

    doc = mx.createDocument()
    doc.setColorSpace("lin_rec709")
    defaults = input_values(_default_params())

    nodedef = doc.addNodeDef(NODEDEF, "surfaceshader", NODE)
    nodedef.setNodeGroup("pbr")
    nodedef.setDocString(
        "Peacock-feather barbule (Imamura et al., BRDF Rendering of Peacock Feathers): "
        "structural colour of melanin-rod layers over melanin brown. Mirrors the USD schema "
        "PavonineFeatherAPI; lengths in micrometres."
    )
    for k in range(MAX_CLASSES):
        for axis in AXES:
            for quantity in QUANTITIES:
                name = class_input(k, axis, quantity)
                inp = nodedef.addInput(name, "vector2")
                inp.setValueString(", ".join(_f32_text(v) for v in defaults[name]))
                unit = "um" if quantity != "layer_count" else "layers"
                inp.setDocString(f"Class {k}, {axis} axis, {quantity} ({unit}): (black, white).")
    for name, (mtype, _default, text) in SCALAR_INPUTS.items():
        inp = nodedef.addInput(name, mtype)
        value = defaults[name]
        if mtype == "color3":
            inp.setValue(mx.Color3(*value))
        elif mtype == "integer":
            inp.setValue(int(value))
        else:
            inp.setValue(value)
        if name in ("rod_length", "interference", "class_count"):
            inp.setIsUniform(True)
        inp.setDocString(text)
    for name, (geomprop, text) in GEOMETRIC_INPUTS.items():
        inp = nodedef.addInput(name, "vector3")
        inp.setDefaultGeomPropString(geomprop)
        inp.setDocString(text)

    graph = doc.addNodeGraph(NODEGRAPH)
    graph.setNodeDefString(NODEDEF)
    _Builder(mx, graph).build()
    graph.addOutput("out", "surfaceshader").setConnectedNode(graph.getNode("surface"))
    return doc


class _Builder:
    """Adds the implementation nodes to the node graph (see the module docstring)."""

    def __init__(self, mx, graph):
        self.mx = mx
        self.graph = graph

    def node(self, category: str, name: str, out_type: str, **inputs) -> Any:
        node = self.graph.addNode(category, name, out_type)
        for key, value in inputs.items():
            self.connect(node, key, value)
        return node

    def connect(self, node, key: str, value) -> None:
        mx = self.mx
        if isinstance(value, tuple) and value[0] == "interface":
            name = value[1]
            inp = node.addInput(key, input_type(name))
            inp.setInterfaceName(name)
        elif isinstance(value, mx.Node):
            inp = node.addInput(key, value.getType())
            inp.setConnectedNode(value)
        elif isinstance(value, bool):
            node.addInput(key, "boolean").setValue(value)
        elif isinstance(value, int):
            node.addInput(key, "integer").setValue(value)
        elif isinstance(value, float):
            # A string keeps every digit (MaterialX's writer rounds floats to 6 digits).
            node.addInput(key, "float").setValueString(repr(value))
        elif isinstance(value, str):
            node.addInput(key, "string").setValue(value)
        else:
            raise TypeError(f"cannot connect {value!r}")

    def build(self) -> None:
        iface = lambda name: ("interface", name)  # noqa: E731
        lobes = {}
        deg = math.pi / 180.0
        # Beckmann α = √2·tan σ for slope deviation tan σ (Walter et al. 2007, Eq. 25), used as GGX α.
        alphas = []
        for sigma in ("crescent_sigma", "block_sigma"):
            rad = self.node("multiply", f"{sigma}_rad", "float", in1=iface(sigma), in2=deg)
            tan = self.node("tan", f"{sigma}_tan", "float", **{"in": rad})
            alphas.append(
                self.node("multiply", f"{sigma}_alpha", "float", in1=tan, in2=math.sqrt(2.0))
            )
        # Along the barbule (the BSDF's tangent): block spread; across it: crescent spread.
        roughness = self.node("combine2", "roughness", "vector2", in1=alphas[1], in2=alphas[0])
        n_diff = self.node(
            "subtract",
            "index_contrast",
            "float",
            in1=iface("melanin_index"),
            in2=iface("medium_index"),
        )
        # Class index round((1 − g)(n − 1)) of the ocellar grey g and class count n.
        darkness = self.node("subtract", "ocellar_darkness", "float", in1=1.0, in2=iface("ocellar"))
        count = self.node("convert", "class_count_float", "float", **{"in": iface("class_count")})
        last = self.node("subtract", "last_class", "float", in1=count, in2=1.0)
        scaled = self.node("multiply", "class_position", "float", in1=darkness, in2=last)
        class_index = self.node("round", "class_index", "float", **{"in": scaled})
        # Barbule long axis: the tangent turned by barbule_angle·180° about the normal.
        degrees = self.node(
            "multiply", "barbule_degrees", "float", in1=iface("barbule_angle"), in2=180.0
        )
        turned = self.node(
            "rotate3d",
            "barbule_turned",
            "vector3",
            amount=degrees,
            axis=iface("normal"),
            **{"in": iface("tangent")},
        )
        barbule = self.node("normalize", "barbule_axis", "vector3", **{"in": turned})
        for axis in AXES:
            ends = {}
            for quantity in ("layer_interval", "rod_radius"):
                pair = self.node(
                    "switch",
                    f"{axis}_{quantity}_class",
                    "vector2",
                    which=class_index,
                    **{
                        f"in{k + 1}": iface(class_input(k, axis, quantity))
                        for k in range(MAX_CLASSES)
                    },
                )
                black = self.node(
                    "extract", f"{axis}_{quantity}_black", "float", index=0, **{"in": pair}
                )
                white = self.node(
                    "extract", f"{axis}_{quantity}_white", "float", index=1, **{"in": pair}
                )
                ends[quantity] = self.node(
                    "mix", f"{axis}_{quantity}", "float", bg=black, fg=white, mix=iface("gradation")
                )
            d, a = ends["layer_interval"], ends["rod_radius"]
            # Eq. 1: f = π a / (2 d); D = d·[n_0 + f·(n_ml − n_0)]  (µm)
            pa = self.node("multiply", f"{axis}_half_pi_a", "float", in1=a, in2=math.pi / 2.0)
            fill = self.node("divide", f"{axis}_fill_factor", "float", in1=pa, in2=d)
            mixed = self.node("multiply", f"{axis}_fill_contrast", "float", in1=fill, in2=n_diff)
            n_eff = self.node(
                "add", f"{axis}_effective_index", "float", in1=mixed, in2=iface("medium_index")
            )
            dist = self.node("multiply", f"{axis}_optical_distance", "float", in1=d, in2=n_eff)
            # t = 1.5·D/n_ml, µm → nm (×1000)
            scaled = self.node(
                "multiply",
                f"{axis}_film_optical_nm",
                "float",
                in1=dist,
                in2=FILM_ORDER_FACTOR * 1000.0,
            )
            thickness = self.node(
                "divide", f"{axis}_film_thickness", "float", in1=scaled, in2=iface("melanin_index")
            )
            lobes[axis] = self.node(
                "dielectric_bsdf",
                f"{axis}_structural",
                "BSDF",
                ior=KERATIN_INDEX,
                roughness=roughness,
                thinfilm_thickness=thickness,
                thinfilm_ior=iface("melanin_index"),
                normal=iface("normal"),
                tangent=barbule,
                scatter_mode="R",
            )
        # Eq. 7 averaged over ψ: ⟨cos²ψ⟩ = ⟨sin²ψ⟩ = ½
        structural = self.node(
            "mix", "structural_lobes", "BSDF", fg=lobes["long"], bg=lobes["short"], mix=0.5
        )
        weighted = self.node(
            "multiply", "structural_share", "BSDF", in1=structural, in2=iface("structural")
        )
        melanin = self.node(
            "oren_nayar_diffuse_bsdf",
            "melanin",
            "BSDF",
            color=iface("melanin_color"),
            normal=iface("normal"),
        )
        layered = self.node("layer", "feather", "BSDF", top=weighted, base=melanin)
        self.node("surface", "surface", "surfaceshader", bsdf=layered, opacity=iface("opacity"))


def _f32_text(value: float) -> str:
    """Shortest text that reads back as the same float32 (USD and MaterialX floats are 32-bit)."""
    import numpy as np

    return np.format_float_positional(np.float32(value), unique=True, trim="-")


# ---------------------------------------------------------------------------------------------
# Evaluating the graph (headless): the arithmetic part node by node, the thin film by formula
# ---------------------------------------------------------------------------------------------

_ARITHMETIC = {
    "add": lambda i: i["in1"] + i["in2"],
    "subtract": lambda i: i["in1"] - i["in2"],
    "multiply": lambda i: i["in1"] * i["in2"],
    "divide": lambda i: i["in1"] / i["in2"],
    "mix": lambda i: i["fg"] * i["mix"] + i["bg"] * (1.0 - i["mix"]),
    "extract": lambda i: i["in"][int(i["index"])],
    "switch": lambda i: i[f"in{int(i['which']) + 1}"],
    "round": lambda i: float(math.floor(i["in"] + 0.5)),
    "convert": lambda i: float(i["in"]),
    "tan": lambda i: math.tan(i["in"]),
    "combine2": lambda i: (i["in1"], i["in2"]),
}


def evaluate_node(doc, node_name: str, values: dict[str, Any]) -> Any:
    """Value of a float/vector2 node of ``NG_pavonine_feather_surfaceshader`` in ``doc`` for the
    nodedef input ``values``, computed by walking the graph as written in the document (only
    the arithmetic node categories this graph uses are supported)."""
    graph = doc.getNodeGraph(NODEGRAPH)
    nodedef = doc.getNodeDef(NODEDEF)
    cache: dict[str, Any] = {}

    def value_of(inp) -> Any:
        if inp.getNodeName():
            return node_value(inp.getNodeName())
        if inp.getInterfaceName():
            name = inp.getInterfaceName()
            if name in values:
                return values[name]
            return _parse(nodedef.getInput(name))
        return _parse(inp)

    def node_value(name: str) -> Any:
        if name not in cache:
            node = graph.getNode(name)
            if node.getCategory() not in _ARITHMETIC:
                raise ValueError(f"cannot evaluate {node.getCategory()} node {name}")
            inputs = {inp.getName(): value_of(inp) for inp in node.getInputs()}
            cache[name] = _ARITHMETIC[node.getCategory()](inputs)
        return cache[name]

    return node_value(node_name)


def _parse(inp) -> Any:
    text = inp.getValueString()
    if inp.getType() in ("float", "integer"):
        return float(text)
    return tuple(float(v) for v in text.split(","))


def thin_film_reflectance(
    wavelength_nm, thickness_nm: float, n_film: float, n_substrate: float, n_outside: float = 1.0
):
    """Normal-incidence reflectance of one film on a substrate (Airy summation; Born & Wolf,
    Principles of Optics, §1.6.4): ``r = (r01 + r12·e^{2iδ}) / (1 + r01·r12·e^{2iδ})``,
    ``δ = 2π·n_film·t/λ``, ``R = |r|²``. Wavelength and thickness in nm."""
    import numpy as np

    lam = np.asarray(wavelength_nm, dtype=float)
    r01 = (n_outside - n_film) / (n_outside + n_film)
    r12 = (n_film - n_substrate) / (n_film + n_substrate)
    phase = np.exp(2j * (2.0 * np.pi * n_film * thickness_nm / lam))
    r = (r01 + r12 * phase) / (1.0 + r01 * r12 * phase)
    return np.abs(r) ** 2


def film_thickness_nm(
    params, axis: str, ocellar: float = 1.0, gradation: float = 0.0, doc=None
) -> float:
    """``thinfilm_thickness`` the shipped graph computes for one axis at an ocellar grey (nm)."""
    import MaterialX as mx

    if doc is None:
        doc = mx.createDocument()
        mx.readFromXmlFile(doc, str(MTLX_PATH))
    values = input_values(params, ocellar=ocellar, gradation=gradation)
    return float(evaluate_node(doc, f"{axis}_film_thickness", values))


def graph_reflectance(
    params, wavelength_nm, ocellar: float = 1.0, gradation: float = 0.0, doc=None
):
    """Normal-incidence reflectance of the graph's structural lobes (long and short film, ½ each),
    as a generic MaterialX renderer would show it before roughness and the melanin base."""
    n_film = float(params.melanin_index)
    return sum(
        0.5
        * thin_film_reflectance(
            wavelength_nm,
            film_thickness_nm(params, axis, ocellar, gradation, doc),
            n_film,
            KERATIN_INDEX,
        )
        for axis in AXES
    )


def load_libraries():
    """A document holding MaterialX's standard data libraries."""
    import MaterialX as mx

    lib = mx.createDocument()
    mx.loadLibraries(mx.getDefaultDataLibraryFolders(), mx.getDefaultDataSearchPath(), lib)
    return lib


def validate_file(path: str | Path = MTLX_PATH) -> tuple[bool, str]:
    """``Document.validate()`` of ``path`` with the standard libraries imported."""
    import MaterialX as mx

    doc = mx.createDocument()
    mx.readFromXmlFile(doc, str(path))
    doc.setDataLibrary(load_libraries())
    return doc.validate()


def document_text() -> str:
    """The ``.mtlx`` text of :func:`build_document`."""
    import MaterialX as mx

    return mx.writeToXmlString(build_document())


def main() -> int:
    MTLX_PATH.write_text(document_text())
    ok, message = validate_file(MTLX_PATH)
    print(f"wrote {MTLX_PATH}: {'valid' if ok else message}")
    return 0 if ok else 1


if __name__ == "__main__":
    raise SystemExit(main())
