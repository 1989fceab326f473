"""What a mesh needs from its material, and how sidedness, opacity and emission are put together.

A :class:`MaterialSpec` is translated once per USD material. For each mesh it is bound to, the
delegate asks for :meth:`MaterialSpec.bsdf_dict` / :meth:`MaterialSpec.emitter_dict` with that
mesh's ``doubleSided`` and primvar :class:`~.primvars.Binding`:

* ``doubleSided`` wraps the surface in ``twosided`` *inside* any opacity wrapper
  (``mask(twosided(...))``: Mitsuba refuses ``twosided`` around anything transmissive);
* opacity < 1: ``opacityMode`` ``presence`` (and any ``opacityThreshold`` cut-out) → ``mask``;
  ``transparent`` (the default) → ``blendbsdf`` of the surface with a ``thindielectric`` of the
  material's ``ior``, so opacity removes the diffuse response but keeps the specular reflection,
  as the UsdPreviewSurface spec describes;
* emission → an ``area`` emitter's radiance (emits on the side its normal faces).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from pxr import Usd, UsdGeom

from pavonine.render.diagnostics import Diagnostics, first_line
from pavonine.render.shading.network import COLOR, FLOAT
from pavonine.render.shading.primvars import Binding, bind, placeholder, resolve

DEFAULT_GREY = 0.5
PRESENCE, TRANSPARENT = "presence", "transparent"


@dataclass
class MaterialSpec:
    """A translated material (see the module docstring)."""

    key: str  # cache key: the material's path, or a synthetic name
    bsdf: dict[str, Any]  # the surface BSDF (may hold primvar placeholders)
    uv_primvar: str = "st"  # primvar passed to Mitsuba as the mesh's texcoords
    attributes: dict[str, str] = field(default_factory=dict)  # primvar → vertex attribute (feather)
    two_sided: bool = False  # the BSDF already shades both sides (no ``twosided`` wrapper)
    is_feather: bool = False
    opacity: Any = 1.0  # float, texture dict or placeholder
    opacity_mode: str = PRESENCE
    ior: float = 1.5
    emission: Any = None  # area-emitter radiance (rgb dict, texture dict, placeholder) or None
    primvars: tuple[str, ...] = ()  # primvars read per mesh (placeholders in bsdf/opacity/emission)

    def binding(self, prim: Usd.Prim, time: Usd.TimeCode) -> Binding:
        """How this material's primvars are found on ``prim``."""
        return bind(self.primvars, prim, time) if self.primvars else Binding()

    def surface(self, double_sided: bool, binding: Binding, where: str, diag: Diagnostics) -> dict:
        """The surface BSDF for one mesh: placeholders resolved, ``twosided`` if asked for."""
        core = resolve(self.bsdf, binding, where, diag)
        if double_sided and not self.two_sided:
            core = {"type": "twosided", "bsdf": core}
        return core

    def bsdf_dict(
        self, double_sided: bool, binding: Binding, where: str, diag: Diagnostics
    ) -> dict:
        """The whole BSDF for one mesh (surface, then the opacity wrapper)."""
        return self.wrap_opacity(
            self.surface(double_sided, binding, where, diag), binding, where, diag
        )

    def wrap_opacity(self, core: dict, binding: Binding, where: str, diag: Diagnostics) -> dict:
        opacity = resolve(self.opacity, binding, where, diag)
        if isinstance(opacity, float) and opacity >= 1.0:
            return core
        if self.opacity_mode == TRANSPARENT:
            glass = {"type": "thindielectric", "int_ior": max(float(self.ior), 1.0), "ext_ior": 1.0}
            return {"type": "blendbsdf", "weight": opacity, "bsdf_0": glass, "bsdf_1": core}
        return {"type": "mask", "opacity": opacity, "bsdf": core}

    def emitter_dict(self, binding: Binding, where: str, diag: Diagnostics) -> dict | None:
        """The ``area`` emitter of an emissive material for one mesh, or ``None``."""
        if self.emission is None:
            return None
        radiance = resolve(self.emission, binding, where, diag)
        if isinstance(radiance, dict) and radiance.get("type") == "rgb":
            if max(radiance["value"]) <= 0.0:
                return None
        return {"type": "area", "radiance": radiance}


def load_bsdf(
    spec: MaterialSpec, double_sided: bool, binding: Binding, where: str, diag: Diagnostics
):
    """The loaded Mitsuba BSDF for one mesh; grey diffuse (warned) if Mitsuba rejects it.

    A surface that already transmits (a Mitsuba ``dielectric`` from the ``mitsuba`` render
    context) cannot be nested in ``twosided``; it shades both sides anyway, so it is kept as is.
    """
    import mitsuba as mi

    try:
        return mi.load_dict(spec.bsdf_dict(double_sided, binding, where, diag))
    except Exception as exc:
        if double_sided and "transmission" in str(exc):
            try:
                return mi.load_dict(spec.bsdf_dict(False, binding, where, diag))
            except Exception as inner:
                exc = inner
        diag.warn(
            spec.key, f"Mitsuba rejected the material ({first_line(exc)}); rendering grey diffuse"
        )
        return mi.load_dict(default_material().bsdf)


def default_material(display_color: tuple[float, float, float] | None = None) -> MaterialSpec:
    """Grey diffuse, or diffuse in one constant ``displayColor``."""
    if display_color is None:
        return MaterialSpec(
            "__default_grey", {"type": "diffuse", "reflectance": rgb([DEFAULT_GREY] * 3)}
        )
    key = "__display_color_" + "_".join(f"{c:.4f}" for c in display_color)
    return MaterialSpec(key, {"type": "diffuse", "reflectance": rgb(display_color)})


def fallback_material() -> MaterialSpec:
    """A mesh without a material: diffuse in its ``displayColor`` and ``displayOpacity`` primvars.

    Either may be constant, per vertex, per face-vertex or per face (mesh attributes), and is
    grey 0.5 / opaque when absent.
    """
    from pavonine.render.shading.network import Affine, Network

    net = Network("__display", Usd.TimeCode.Default(), Diagnostics())
    colour = placeholder("displayColor", COLOR, [DEFAULT_GREY] * 3, Affine(), net)
    opacity = placeholder("displayOpacity", FLOAT, [1.0], Affine(), net)
    return MaterialSpec(
        "__display_primvars",
        {"type": "diffuse", "reflectance": colour},
        opacity=opacity,
        opacity_mode=PRESENCE,
        primvars=tuple(net.primvars),
    )


def display_color(prim: Usd.Prim, time: Usd.TimeCode) -> tuple[float, float, float] | None:
    """A gprim's ``primvars:displayColor`` when it is one colour (constant or a single value)."""
    primvar = UsdGeom.PrimvarsAPI(prim).GetPrimvar("displayColor")
    if not primvar or not primvar.HasValue():
        return None
    values = primvar.ComputeFlattened(time)
    if values is None or len(values) != 1:
        return None
    return tuple(float(c) for c in values[0])  # type: ignore[return-value]


def rgb(color) -> dict:
    """An ``rgb`` dict."""
    return {"type": "rgb", "value": [float(c) for c in color]}


__all__ = [
    "MaterialSpec",
    "default_material",
    "display_color",
    "fallback_material",
    "load_bsdf",
    "rgb",
]
