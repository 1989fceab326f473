"""Author and read feather materials: ``PavonineFeatherAPI`` on a ``UsdShade.Material``.

The schema attributes are the one source of truth. The MaterialX shader
(``outputs:mtlx:surface`` → ``ND_pavonine_feather_surfaceshader``) and the ``UsdPreviewSurface``
fallback (``outputs:surface``) are derived from them by :func:`create_feather_material` /
:func:`sync_derived_shaders`; ``pavonine validate`` reports them when they have drifted.
"""

from __future__ import annotations

import hashlib
import os
import re
from collections import Counter
from collections.abc import Mapping
from dataclasses import dataclass

from pxr import Gf, Sdf, Usd, UsdShade

from pavonine.base.errors import InputError
from pavonine.materials import materialx
from pavonine.materials.dispersion import Dispersion
from pavonine.materials.parameters import AXES, FeatherParameters, ParameterError
from pavonine.schemas.mtlx_types import SDF_TYPES, usd_value
from pavonine.schemas.plugin import SCHEMA_NAME, require_schema
from pavonine.schemas.primvars import FEATHER_UV_PRIMVAR

#: Map keys (as used by the converter and ``resolve_maps``) -> schema attribute.
MAP_ATTRS: dict[str, str] = {
    "alpha": "pavonine:alphaMap",
    "ocellar": "pavonine:ocellarMap",
    "gradation": "pavonine:gradationMap",
    "angle": "pavonine:angleMap",
    "displacement": "pavonine:displacementMap",
    "melanin": "pavonine:melaninMap",
}

#: (axis, LayerStack field) -> (schema attribute, value type).
CLASS_ATTRS: dict[tuple[str, str], tuple[str, Sdf.ValueTypeName]] = {
    (axis, field): (f"pavonine:{axis}:{name}", vtype)
    for axis in AXES
    for field, name, vtype in (
        ("interval", "layerInterval", Sdf.ValueTypeNames.Float2Array),
        ("radius", "rodRadius", Sdf.ValueTypeNames.Float2Array),
        ("count", "layerCount", Sdf.ValueTypeNames.Int2Array),
    )
}

#: Optional per-class arrays (physical mode; empty or unauthored = 0 for every class):
#: ``class_arrays()`` key -> schema attribute (all ``float2[]``).
STRUCTURE_ATTRS: dict[str, str] = {
    **{
        f"{axis}_{field}": f"pavonine:{axis}:{name}"
        for axis in AXES
        for field, name in (("spacing", "rodSpacing"), ("channel", "airChannelDiameter"))
    },
    "cortex": "pavonine:cortexThickness",
}

#: Dispersive materials (physical mode): FeatherParameters field -> ((attribute, Dispersion
#: fields it holds), ...), each attribute a ``float2``.
DISPERSION_ATTRS: dict[str, tuple[tuple[str, tuple[str, str]], ...]] = {
    "melanin": (
        ("pavonine:melaninDispersion", ("cauchy_a", "cauchy_b")),
        ("pavonine:melaninAbsorption", ("extinction", "extinction_scale")),
    ),
    "keratin": (("pavonine:keratinDispersion", ("cauchy_a", "cauchy_b")),),
}

#: FeatherParameters scalar field -> (schema attribute, value type).
SCALAR_ATTRS: dict[str, tuple[str, Sdf.ValueTypeName]] = {
    "melanin_index": ("pavonine:melaninIndex", Sdf.ValueTypeNames.Float),
    "medium_index": ("pavonine:mediumIndex", Sdf.ValueTypeNames.Float),
    "crescent_sigma_deg": ("pavonine:crescentSigma", Sdf.ValueTypeNames.Float),
    "block_sigma_deg": ("pavonine:blockSigma", Sdf.ValueTypeNames.Float),
    "rod_length_um": ("pavonine:rodLength", Sdf.ValueTypeNames.Float),
    "interference": ("pavonine:interference", Sdf.ValueTypeNames.Token),
    "melanin_color": ("pavonine:melaninColor", Sdf.ValueTypeNames.Color3f),
}
#: Discrete barbule blocks (``pavonine.materials.glitter``): FeatherParameters field ->
#: (schema attribute, value type). Optional on reading: layers written before them mean glitter 0.
GLITTER_ATTRS: dict[str, tuple[str, Sdf.ValueTypeName]] = {
    "glitter": ("pavonine:glitter", Sdf.ValueTypeNames.Float),
    "glitter_seed": ("pavonine:glitterSeed", Sdf.ValueTypeNames.Int),
    "block_length_um": ("pavonine:blockLength", Sdf.ValueTypeNames.Float),
    "barbule_width_um": ("pavonine:barbuleWidth", Sdf.ValueTypeNames.Float),
}
#: Scalars only the physical mode reads (not mirrored on the MaterialX nodedef).
PHYSICAL_SCALAR_ATTRS: dict[str, tuple[str, Sdf.ValueTypeName]] = {
    "lattice": ("pavonine:rodLattice", Sdf.ValueTypeNames.Token),
}
UNIFORM_ATTRS = ("pavonine:interference", "pavonine:rodLattice")

MTLX_SHADER = "FeatherMtlx"
PREVIEW_SHADER = "PreviewSurface"
ALPHA_TEXTURE = "AlphaTexture"
TEXCOORD_READER = "TexCoordReader"
MTLX_RENDER_CONTEXT = "mtlx"
#: customData key on a feather material recording what its baked textures were made from.
BAKE_KEY = "pavonine:bake"
#: Class and gradation the preview colour is evaluated at (missing maps mean class 0, and the
#: middle of the gradation range is the class's typical colour).
PREVIEW_CLASS = 0
PREVIEW_GRADATION = 0.5


@dataclass(frozen=True)
class DerivedValues:
    """Everything the bound shaders carry, derived from the schema attributes."""

    mtlx_inputs: dict[str, object]
    diffuse_color: tuple[float, float, float]
    roughness: float


def _as_prim(material: Usd.Prim | UsdShade.Material) -> Usd.Prim:
    prim = material.GetPrim() if isinstance(material, UsdShade.Material) else material
    if not prim or not prim.IsValid():
        raise ValueError(f"not a valid prim: {material!r}")
    return prim


def _check_counts(params: FeatherParameters) -> None:
    for i, cls in enumerate(params.classes):
        for axis in AXES:
            for end, stack in zip(("black", "white"), getattr(cls, axis), strict=True):
                if float(stack.count) != int(stack.count):
                    raise ParameterError(
                        f"class[{i}].{axis}.{end}.count",
                        f"USD stores whole layer counts (int2), got {stack.count}",
                    )


def author_parameters(prim: Usd.Prim, params: FeatherParameters) -> None:
    """Write every schema attribute of ``params`` on ``prim`` (explicitly, so that the values
    survive in tools that do not know the schema)."""
    arrays = params.class_arrays()
    for (axis, field), (name, vtype) in CLASS_ATTRS.items():
        rows = arrays[f"{axis}_{field}"]
        if vtype == Sdf.ValueTypeNames.Int2Array:
            value = [Gf.Vec2i(int(b), int(w)) for b, w in rows]
        else:
            value = [Gf.Vec2f(float(b), float(w)) for b, w in rows]
        prim.CreateAttribute(name, vtype, custom=False).Set(value)
    for key, name in STRUCTURE_ATTRS.items():
        rows = arrays[key]
        value = [Gf.Vec2f(float(b), float(w)) for b, w in rows] if rows.any() else []
        prim.CreateAttribute(name, Sdf.ValueTypeNames.Float2Array, custom=False).Set(value)
    for field, (name, vtype) in {**SCALAR_ATTRS, **PHYSICAL_SCALAR_ATTRS, **GLITTER_ATTRS}.items():
        value = getattr(params, field)
        if vtype == Sdf.ValueTypeNames.Color3f:
            value = Gf.Vec3f(*value)
        attr = prim.CreateAttribute(name, vtype, custom=False, variability=_variability(name))
        attr.Set(value)
    for field, attrs in DISPERSION_ATTRS.items():
        material = getattr(params, field)
        for name, parts in attrs:
            value = Gf.Vec2f(*(float(getattr(material, part)) for part in parts))
            prim.CreateAttribute(name, Sdf.ValueTypeNames.Float2, custom=False).Set(value)


def _variability(name: str) -> Sdf.Variability:
    return Sdf.VariabilityUniform if name in UNIFORM_ATTRS else Sdf.VariabilityVarying


def author_maps(prim: Usd.Prim, maps: Mapping[str, str]) -> None:
    """Set the map asset paths (as given, typically ``./maps/x.png``), read as raw data."""
    unknown = sorted(set(maps) - set(MAP_ATTRS))
    if unknown:
        raise ParameterError("maps", f"unknown map kind(s) {unknown}; known: {sorted(MAP_ATTRS)}")
    for key, path in maps.items():
        if path is None:
            continue
        attr = prim.CreateAttribute(MAP_ATTRS[key], Sdf.ValueTypeNames.Asset, custom=False)
        attr.Set(Sdf.AssetPath(str(path)))
        attr.SetColorSpace("raw")


def create_feather_material(
    stage: Usd.Stage,
    path: str | Sdf.Path,
    params: FeatherParameters,
    maps: Mapping[str, str] | None = None,
) -> UsdShade.Material:
    """Define a Material at ``path`` with ``PavonineFeatherAPI``, ``params`` and ``maps``, plus the
    derived MaterialX (``outputs:mtlx:surface``) and UsdPreviewSurface (``outputs:surface``) shaders.

    Raises :class:`ParameterError` for unphysical parameters or unknown map kinds.
    """
    require_schema()
    params.validate()
    _check_counts(params)
    material = UsdShade.Material.Define(stage, Sdf.Path(str(path)))
    prim = material.GetPrim()
    if not prim.ApplyAPI(SCHEMA_NAME):
        raise ParameterError("path", f"cannot apply {SCHEMA_NAME} to {prim.GetPath()}")
    author_parameters(prim, params)
    author_maps(prim, dict(maps or {}))
    sync_derived_shaders(material)
    return material


def read_feather_parameters(material: Usd.Prim | UsdShade.Material) -> FeatherParameters:
    """The ``FeatherParameters`` a material carries (authored values, else schema fallbacks).

    Raises :class:`ParameterError` naming the attribute when arrays are missing or disagree.
    Values are not checked for physical sense (``.validate()`` does that).
    """
    prim = _as_prim(material)
    arrays: dict[str, list] = {}
    lengths: dict[str, int] = {}
    for (axis, field), (name, vtype) in CLASS_ATTRS.items():
        value = _typed_value(prim, name, vtype)
        if value is None:
            raise ParameterError(name, f"no value (is {SCHEMA_NAME} applied and known to USD?)")
        rows = [(float(v[0]), float(v[1])) for v in value]
        arrays[f"{axis}_{field}"] = rows
        lengths[name] = len(rows)
    common, _ = Counter(lengths.values()).most_common(1)[0]
    odd = next((n for n, k in lengths.items() if k != common or not k), None)
    if odd is not None:
        others = ", ".join(f"{n}={k}" for n, k in lengths.items() if n != odd)
        raise ParameterError(
            odd,
            f"has {lengths[odd]} class{'es' * (lengths[odd] != 1)}; the six per-class arrays "
            f"must be equally long (>= 1): {others}",
        )
    scalars: dict[str, object] = {}
    for field, (name, vtype) in {**SCALAR_ATTRS, **PHYSICAL_SCALAR_ATTRS}.items():
        value = _typed_value(prim, name, vtype)
        if value is None:
            raise ParameterError(name, f"no value (is {SCHEMA_NAME} applied and known to USD?)")
        if field == "melanin_color":
            value = tuple(float(c) for c in value)
        elif field in ("interference", "lattice"):
            value = str(value)
        else:
            value = float(value)
        scalars[field] = value
    for field, (name, vtype) in GLITTER_ATTRS.items():
        value = _typed_value(prim, name, vtype)
        if value is not None:
            scalars[field] = int(value) if field == "glitter_seed" else float(value)
    n_classes = next(iter(lengths.values()))
    for key, name in STRUCTURE_ATTRS.items():
        value = _typed_value(prim, name, Sdf.ValueTypeNames.Float2Array)
        rows = [(float(v[0]), float(v[1])) for v in value] if value else []
        if rows and len(rows) != n_classes:
            raise ParameterError(
                name,
                f"has {len(rows)} class{'es' * (len(rows) != 1)} but the material has {n_classes} "
                "(or leave it empty)",
            )
        arrays[key] = rows
    for field, attrs in DISPERSION_ATTRS.items():
        parts: dict[str, float] = {}
        for name, names in attrs:
            value = _typed_value(prim, name, Sdf.ValueTypeNames.Float2)
            if value is None:
                raise ParameterError(name, f"no value (is {SCHEMA_NAME} applied and known to USD?)")
            parts.update(zip(names, (float(v) for v in value), strict=True))
        scalars[field] = Dispersion(**parts)
    return FeatherParameters.from_class_arrays(arrays, **scalars)


_FIELD = re.compile(r"class\[(\d+)\]\.(long|short|cortex)\.?(black|white)?\.?(\w+)?")
_NAMED_FIELDS = {
    "lattice": "pavonine:rodLattice",
    "melanin": "pavonine:melaninDispersion",
    "keratin": "pavonine:keratinDispersion",
}


def attribute_of_field(field: str) -> str:
    """The schema attribute behind a :class:`ParameterError` field (``class[4].short.black.radius``
    → ``pavonine:short:rodRadius``, ``crescent_sigma_deg`` → ``pavonine:crescentSigma``)."""
    if field.startswith("pavonine:"):  # the reader names the attribute itself
        return field
    match = _FIELD.fullmatch(field)
    if not match:
        scalar = {**SCALAR_ATTRS, **PHYSICAL_SCALAR_ATTRS, **GLITTER_ATTRS}.get(field)
        if scalar is not None:
            return scalar[0]
        return _NAMED_FIELDS.get(field.split(".")[0], f"pavonine:{field}")
    _, axis, _, quantity = match.groups()
    if axis == "cortex":
        return STRUCTURE_ATTRS["cortex"]
    if quantity in ("spacing", "channel"):
        return STRUCTURE_ATTRS[f"{axis}_{quantity}"]
    return CLASS_ATTRS[(axis, quantity if quantity in ("interval", "count") else "radius")][0]


def parameter_input_error(prim: Usd.Prim, exc: ParameterError) -> InputError:
    """``exc`` as an :class:`InputError` naming the layer that authors the attribute at fault
    and ``<prim>.<attribute>`` (``crescent_sigma_deg: is NaN`` alone names neither)."""
    name = attribute_of_field(exc.field)
    attr = prim.GetAttribute(name)
    stack = attr.GetPropertyStack() if attr else []
    layer = stack[0].layer if stack else prim.GetStage().GetRootLayer()
    where = layer.realPath or layer.identifier
    return InputError(f"{where}: {prim.GetPath()}.{name}", exc.reason)


def resolve_maps(material: Usd.Prim | UsdShade.Material) -> dict[str, str | None]:
    """Absolute resolved file paths of the six maps; ``None`` where not authored (= uniform).

    An authored path that does not resolve gives the path anchored to the authoring layer (so
    that callers can report the missing file by name).
    """
    prim = _as_prim(material)
    out: dict[str, str | None] = {}
    for key, name in MAP_ATTRS.items():
        has_map = _typed_value(prim, name, Sdf.ValueTypeNames.Asset) is not None
        out[key] = _resolved_path(prim.GetAttribute(name)) if has_map else None
    return out


#: Height (stage units) of the displacement map at 1 for meshes authored undisplaced (schema.usda).
DISPLACEMENT_HEIGHT_ATTR = "pavonine:displacementHeight"


def displacement_height(material: Usd.Prim | UsdShade.Material) -> float:
    """``pavonine:displacementHeight`` (0 when unauthored: the mesh carries its displacement).

    Raises :class:`ParameterError` naming the attribute when it is not a finite number ≥ 0.
    """
    value = _typed_value(_as_prim(material), DISPLACEMENT_HEIGHT_ATTR, Sdf.ValueTypeNames.Float)
    if value is None:
        return 0.0
    if not (float(value) >= 0.0 and float(value) < float("inf")):
        raise ParameterError(DISPLACEMENT_HEIGHT_ATTR, f"must be a finite number >= 0, got {value}")
    return float(value)


def _typed_value(prim: Usd.Prim, name: str, vtype: Sdf.ValueTypeName):
    """The value of attribute ``name``; :class:`ParameterError` if authored with another type."""
    attr = prim.GetAttribute(name)
    if not attr:
        return None
    authored = authored_type(attr)
    if authored is not None and authored != vtype:
        raise ParameterError(name, f"is authored as {authored}, but the schema declares {vtype}")
    return attr.Get()


def authored_type(attr: Usd.Attribute) -> Sdf.ValueTypeName | None:
    """The type the strongest layer wrote for ``attr`` (``attr.GetTypeName()`` reports the schema's)."""
    for spec in attr.GetPropertyStack(Usd.TimeCode.Default()):
        if spec.typeName:
            return spec.typeName
    return None


def _resolved_path(attr: Usd.Attribute) -> str | None:
    value = attr.Get()
    if value is None or not value.path:
        return None
    if value.resolvedPath:
        return os.path.abspath(value.resolvedPath)
    return os.path.abspath(anchored_path(attr, value.path))


def anchored_path(attr: Usd.Attribute, asset: str) -> str:
    """``asset`` anchored to the layer that authors ``attr``'s strongest value."""
    for spec in attr.GetPropertyStack(Usd.TimeCode.Default()):
        if spec.HasDefaultValue() and spec.layer and not spec.layer.anonymous:
            return spec.layer.ComputeAbsolutePath(asset)
    return asset


def parameters_digest(params: FeatherParameters) -> str:
    """A short digest of a material's parameters, recorded with baked textures to tell when
    they are stale."""
    return hashlib.sha256(repr(params).encode()).hexdigest()[:16]


def derived_values(params: FeatherParameters) -> DerivedValues:
    """The shader values derived from ``params`` (the schema attributes)."""
    return DerivedValues(
        mtlx_inputs=materialx.input_values(params),
        diffuse_color=preview_color(params),
        roughness=preview_roughness(params),
    )


def preview_color(params: FeatherParameters) -> tuple[float, float, float]:
    """UsdPreviewSurface diffuse colour: the optics model's D65 colour of class 0 (linear sRGB)."""
    from pavonine.materials.optics import preview_color as optics_preview_color

    rgb = optics_preview_color(params, ocellar_class=PREVIEW_CLASS, gradation=PREVIEW_GRADATION)
    return tuple(float(Gf.Vec3f(*rgb)[i]) for i in range(3))  # float32, as stored


def preview_roughness(params: FeatherParameters) -> float:
    """UsdPreviewSurface roughness for the crescent spread σ (Eq. 6).

    The Beckmann roughness for a slope standard deviation tan σ is α = √2·tan σ (Walter et al.
    2007, Eq. 25); UsdPreviewSurface is GGX, whose lobe matches Beckmann's near its peak for the
    same α, so α is used as the GGX α; its perceptual roughness r has α = r², so r = √α.
    """
    import math

    alpha = math.sqrt(2.0) * math.tan(math.radians(params.crescent_sigma_deg))
    return float(Gf.Vec2f(min(1.0, math.sqrt(alpha)), 0)[0])


def sync_derived_shaders(material: UsdShade.Material) -> None:
    """(Re)author the MaterialX and UsdPreviewSurface shaders from the schema attributes."""
    params = read_feather_parameters(material)
    values = derived_values(params)
    stage = material.GetPrim().GetStage()
    base = material.GetPath()

    mtlx = UsdShade.Shader.Define(stage, base.AppendChild(MTLX_SHADER))
    mtlx.SetShaderId(materialx.NODEDEF)
    for name, value in values.mtlx_inputs.items():
        _set_mtlx_input(mtlx, name, value)
    mtlx_out = mtlx.CreateOutput("out", Sdf.ValueTypeNames.Token)
    material.CreateSurfaceOutput(MTLX_RENDER_CONTEXT).ConnectToSource(mtlx_out)

    preview = UsdShade.Shader.Get(stage, base.AppendChild(PREVIEW_SHADER))
    diffuse = preview.GetInput("diffuseColor") if preview else None
    if diffuse and diffuse.HasConnectedSource():
        return  # a baked preview (pavonine bake) reads textures; re-bake to update it
    _author_preview(material, values)


def _author_preview(material: UsdShade.Material, values: DerivedValues) -> None:
    """The unbaked UsdPreviewSurface: the derived constants, opacity from the alpha map."""
    stage = material.GetPrim().GetStage()
    base = material.GetPath()
    preview = UsdShade.Shader.Define(stage, base.AppendChild(PREVIEW_SHADER))
    preview.SetShaderId("UsdPreviewSurface")
    preview.CreateInput("diffuseColor", Sdf.ValueTypeNames.Color3f).Set(
        Gf.Vec3f(*values.diffuse_color)
    )
    preview.CreateInput("roughness", Sdf.ValueTypeNames.Float).Set(values.roughness)
    preview.CreateInput("metallic", Sdf.ValueTypeNames.Float).Set(0.0)
    preview.CreateInput("ior", Sdf.ValueTypeNames.Float).Set(materialx.KERATIN_INDEX)
    alpha_path = material.GetPrim().GetAttribute(MAP_ATTRS["alpha"])
    alpha = alpha_path.Get() if alpha_path else None
    opacity = preview.CreateInput("opacity", Sdf.ValueTypeNames.Float)
    if alpha is not None and alpha.path:
        reader = UsdShade.Shader.Define(stage, base.AppendChild(TEXCOORD_READER))
        reader.SetShaderId("UsdPrimvarReader_float2")
        reader.CreateInput("varname", Sdf.ValueTypeNames.String).Set(FEATHER_UV_PRIMVAR)
        reader_out = reader.CreateOutput("result", Sdf.ValueTypeNames.Float2)
        texture = UsdShade.Shader.Define(stage, base.AppendChild(ALPHA_TEXTURE))
        texture.SetShaderId("UsdUVTexture")
        texture.CreateInput("file", Sdf.ValueTypeNames.Asset).Set(Sdf.AssetPath(alpha.path))
        texture.CreateInput("sourceColorSpace", Sdf.ValueTypeNames.Token).Set("raw")
        texture.CreateInput("st", Sdf.ValueTypeNames.Float2).ConnectToSource(reader_out)
        opacity.ConnectToSource(texture.CreateOutput("r", Sdf.ValueTypeNames.Float))
    else:
        # No alpha map (any more): drop the reader chain a previous sync may have authored.
        opacity.DisconnectSource()
        for name in (TEXCOORD_READER, ALPHA_TEXTURE):
            stage.RemovePrim(base.AppendChild(name))
        opacity.Set(1.0)
    preview_out = preview.CreateOutput("surface", Sdf.ValueTypeNames.Token)
    material.CreateSurfaceOutput().ConnectToSource(preview_out)


def mtlx_usd_value(name: str, value: object) -> object:
    """The USD value a MaterialX nodedef input is authored with."""
    return usd_value(materialx.input_type(name), value)


def _set_mtlx_input(shader: UsdShade.Shader, name: str, value: object) -> None:
    vtype = SDF_TYPES[materialx.input_type(name)]
    shader.CreateInput(name, vtype).Set(mtlx_usd_value(name, value))
