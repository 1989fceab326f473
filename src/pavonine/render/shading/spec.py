"""What a mesh needs from its material, and how sidedness, opacity and emission are put together.

A :class:`MaterialSpec` is translated once per USD material. For each mesh it is bound to, the
delegate asks for :func:`load_bsdf` / :meth:`MaterialSpec.emitter_dict` with that mesh's
``doubleSided`` and primvar :class:`~.primvars.Binding` (built after the mesh's attributes):

* sidedness, innermost: ``doubleSided`` wraps the surface in ``twosided``; a single-sided surface
  has its back faces culled for every ray (:mod:`pavonine.render.facing`), as viewers cull them.
  A surface that transmits (a ``dielectric`` from the ``mitsuba`` render context, a principled
  BSDF with ``spec_trans``) is left as it is either way: it shades both sides already, Mitsuba
  refuses ``twosided`` around it, and rays inside a closed glass must see its back faces;
* opacity < 1: ``opacityMode`` ``presence`` (and any ``opacityThreshold`` cut-out) → ``mask``;
  ``transparent`` (the default) → ``blendbsdf`` of the surface with a ``thindielectric`` of the
  material's ``ior``, so opacity removes the diffuse response but keeps the specular reflection,
  as the UsdPreviewSurface spec describes. The back-face cull wraps the whole (a culled face is
  invisible from behind, its glass included): ``mask(front, opacity(surface))`` and
  ``opacity(twosided(surface))``;
* emission → an ``area`` emitter's radiance (emits on the side its normal faces).
"""

from __future__ import annotations

import hashlib
from collections.abc import Mapping
from dataclasses import dataclass, field, fields, is_dataclass
from typing import Any

import numpy as np
from pxr import Usd, UsdGeom

from pavonine.render import facing
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
    #: how the material displaces its meshes (:mod:`pavonine.render.displacement`), or ``None``
    displacement: Any = None

    def content_key(self) -> tuple:
        """What the material is, whatever its path: every field but :attr:`key`, arrays by their
        bytes, other objects by identity. Two materials with the same content (the copies of one
        material that phase-shifted prototypes carry) share their loaded BSDFs: a Python BSDF is
        traced at every render call, once per distinct object."""
        cached = self.__dict__.get("_content_key")
        if cached is None:
            cached = tuple(
                (f.name, _fingerprint(getattr(self, f.name)))
                for f in fields(self)
                if f.name != "key"
            )
            self.__dict__["_content_key"] = cached
        return cached

    def primvars_for(self, prim: Usd.Prim) -> tuple[str, dict[str, str]]:
        """``(uv primvar, attributes)`` for one mesh: a feather primvar the mesh lacks under its
        current name but carries under its legacy one (``feather.LEGACY_PRIMVARS``) is read by
        that."""
        if not self.is_feather:
            return self.uv_primvar, dict(self.attributes)
        from pavonine.render.shading.feather import LEGACY_PRIMVARS

        api = UsdGeom.PrimvarsAPI(prim)

        def name(primvar: str) -> str:
            legacy = LEGACY_PRIMVARS.get(primvar)
            if legacy and not api.HasPrimvar(primvar) and api.HasPrimvar(legacy):
                return legacy
            return primvar

        return name(self.uv_primvar), {name(k): v for k, v in self.attributes.items()}

    def on_ribbon(self, prim: Usd.Prim, diag: Diagnostics) -> MaterialSpec:
        """The material as it shades ``prim``'s ribbons (tessellated ``BasisCurves``): itself, but
        a feather's without its sheet-only wrappers (:func:`.feather.on_ribbon`)."""
        if not self.is_feather:
            return self
        from pavonine.render.shading.feather import on_ribbon

        return on_ribbon(self, prim, diag)

    def binding(
        self, prim: Usd.Prim, time: Usd.TimeCode, attributes: Mapping[str, np.ndarray]
    ) -> Binding:
        """How this material's primvars are found on ``prim``, whose mesh carries ``attributes``."""
        return bind(self.primvars, prim, time, attributes) if self.primvars else Binding()

    def surface(self, binding: Binding, where: str, diag: Diagnostics) -> dict:
        """The surface BSDF dict for one mesh (placeholders resolved), before any wrapper."""
        return resolve(self.bsdf, binding, where, diag)

    def wrap_opacity(self, core: Any, binding: Binding, where: str, diag: Diagnostics) -> Any:
        """``core`` (a dict or a loaded BSDF) inside the opacity wrapper, if opacity < 1."""
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


def _fingerprint(value: Any) -> Any:
    """A hashable, content-exact stand-in for a material field (:meth:`MaterialSpec.content_key`)."""
    if value is None or isinstance(value, (bool, int, float, str)):
        return value
    if isinstance(value, dict):
        return ("dict", tuple(sorted((str(k), _fingerprint(v)) for k, v in value.items())))
    if isinstance(value, (list, tuple)):
        return (type(value).__name__, tuple(_fingerprint(v) for v in value))
    if isinstance(value, np.ndarray) or type(value).__module__.startswith("drjit"):
        array = np.ascontiguousarray(np.asarray(value))  # a map's Dr.Jit tensor: its values
        digest = hashlib.sha1(array.tobytes()).hexdigest()
        return (type(value).__name__, array.shape, str(array.dtype), digest)
    if is_dataclass(value) and not isinstance(value, type):
        inner = tuple((f.name, _fingerprint(getattr(value, f.name))) for f in fields(value))
        return (type(value).__qualname__, inner)
    return ("object", id(value))  # shared only when it is the very same object


def load_bsdf(
    spec: MaterialSpec,
    double_sided: bool,
    binding: Binding,
    where: str,
    diag: Diagnostics,
    *,
    feathers: list | None = None,
):
    """The loaded Mitsuba BSDF for one mesh (see the module docstring); grey diffuse (warned) if
    Mitsuba rejects it. A feather's loaded ``pavonine_feather`` objects are appended to
    ``feathers`` (per-instance primvar tables are bound to it once the scene is built:
    :mod:`pavonine.render.instance_primvars`)."""
    import mitsuba as mi

    try:
        surface = spec.surface(binding, where, diag)
        if spec.is_feather:  # mask(bumpmap(pavonine_feather)): keep a handle on the feather
            from pavonine.render.feather_encoding import load_with_feathers

            core, found = load_with_feathers(surface)
            if feathers is not None:
                feathers.extend(found)
        else:
            core = mi.load_dict(surface)
        sided = not spec.two_sided and not mi.has_flag(core.flags(), mi.BSDFFlags.Transmission)
        tree = {"type": "twosided", "bsdf": core} if sided and double_sided else core
        tree = spec.wrap_opacity(tree, binding, where, diag)
        if sided and not double_sided:
            tree = facing.cull_back_faces(tree)
        return mi.load_dict(tree) if isinstance(tree, dict) else tree
    except Exception as exc:
        diag.warn(
            spec.key, f"Mitsuba rejected the material ({first_line(exc)}); rendering grey diffuse"
        )
        return mi.load_dict(default_material().bsdf)


def default_material() -> MaterialSpec:
    """Grey diffuse: what an unsupported or rejected material renders as (always warned)."""
    return MaterialSpec(
        "__default_grey", {"type": "diffuse", "reflectance": rgb([DEFAULT_GREY] * 3)}
    )


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


def rgb(color) -> dict:
    """An ``rgb`` dict."""
    return {"type": "rgb", "value": [float(c) for c in color]}


__all__ = [
    "MaterialSpec",
    "default_material",
    "fallback_material",
    "load_bsdf",
    "rgb",
]
