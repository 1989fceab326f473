"""``RenderVar`` → Mitsuba's ``aov`` integrator, and the layers of a product's multi-layer EXR.

A product's ``orderedVars`` become, in order, layers of one EXR (channels ``<layer>.<c>``, the
layer named after the RenderVar prim); the first beauty var is the plain ``R``, ``G``, ``B``
(``A``) channels. Sources (``sourceName``, ``sourceType`` ``raw``/``intrinsic``, as Hydra,
RenderMan and Karma spell them):

==========================================  ==================  ===========================
sourceName                                  Mitsuba AOV         channels
==========================================  ==================  ===========================
color, Ci, C, rgb, rgba, LdrColor, beauty…  the path tracer     R G B (A for 4-channel types)
a, alpha, A                                 the beauty's alpha  A
depth, z, Z                                 ``depth``           Z (camera-space depth)
distance                                    ``depth``           Z (distance to the camera)
P, position                                 ``position``        X Y Z (world space)
N, Nn, normal, shadingNormal                ``sh_normal``       X Y Z (world space)
Ng, geometricNormal                         ``geo_normal``      X Y Z (world space)
albedo                                      ``albedo``          R G B (white-balanced)
uv, st                                      ``uv``              U V (Mitsuba's uv: v down)
primId                                      ``shape_index``     id (Mitsuba shape index)
elementId                                   ``prim_index``      id (triangle index)
dPdu, dPdv                                  ``dp_du``/``dp_dv`` X Y Z
==========================================  ==================  ===========================

Mitsuba's ``depth`` is measured along the ray from the near clipping plane; it is turned into
camera-space depth ``t·cos θ + near`` (or distance ``t + near / cos θ``) per pixel, θ the pixel's
angle to the view axis (pinhole; aperture offsets ignored), 0 where nothing is hit. Mitsuba's
spectral ``albedo`` is converted to RGB without a white point (white reads (1.21, 0.95, 0.91)); it
is divided by that white so a white surface reads 1.

``sourceType`` ``lpe`` is the beauty for ``C.*`` (and ``C.*[<L.>O]``); anything else, ``primvar``
sources, ``instanceId`` (Mitsuba's instances share their prototype's shapes) and unknown names are
warned about and left out of the file. Every layer is the box-filtered mean over the pixel's
samples, so ids are fractional where a pixel covers two shapes.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from pavonine.render.diagnostics import Diagnostics
from pavonine.render.settings import ProductSpec

BEAUTY = {"color", "ci", "c", "rgb", "rgba", "ldrcolor", "hdrcolor", "beauty", "raw", "cf"}
ALPHA = {"a", "alpha"}
BEAUTY_LPES = {"C.*", "C.*[<L.>O]", "C[DS]*[<L.>O]"}
FOUR_CHANNELS = {"color4f", "float4", "half4", "color4h", "color4d"}
SOURCES = {
    "depth": "depth",
    "z": "depth",
    "distance": "distance",
    "p": "position",
    "position": "position",
    "n": "sh_normal",
    "nn": "sh_normal",
    "normal": "sh_normal",
    "shadingnormal": "sh_normal",
    "sh_normal": "sh_normal",
    "ng": "geo_normal",
    "geometricnormal": "geo_normal",
    "geo_normal": "geo_normal",
    "albedo": "albedo",
    "uv": "uv",
    "st": "uv",
    "primid": "shape_index",
    "elementid": "prim_index",
    "dpdu": "dp_du",
    "dp_du": "dp_du",
    "dpdv": "dp_dv",
    "dp_dv": "dp_dv",
}
CHANNELS = {
    "depth": ("Z",),
    "distance": ("Z",),
    "position": ("X", "Y", "Z"),
    "sh_normal": ("X", "Y", "Z"),
    "geo_normal": ("X", "Y", "Z"),
    "albedo": ("R", "G", "B"),
    "uv": ("U", "V"),
    "shape_index": ("id",),
    "prim_index": ("id",),
    "dp_du": ("X", "Y", "Z"),
    "dp_dv": ("X", "Y", "Z"),
}
UNAVAILABLE = {
    "instanceid": "Mitsuba's instances share their prototype's shapes, so no instance id exists",
}


@dataclass
class Layer:
    """A layer of a product's EXR: its channel names and where its pixels come from."""

    name: str  # the RenderVar prim's name ('' for the plain R, G, B beauty)
    channels: tuple[str, ...]  # full EXR channel names
    source: str  # "beauty", "alpha", or a Mitsuba AOV type
    var: str | None = None  # the RenderVar's path


@dataclass
class AovPlan:
    """The layers a product writes and the Mitsuba AOVs they need."""

    layers: list[Layer] = field(default_factory=list)
    aovs: list[str] = field(default_factory=list)  # Mitsuba AOV types, in integrator order
    distances: bool = False  # depth or distance layers: converted from Mitsuba's ray distance
    alpha: bool = False  # the beauty is rendered with alpha (film pixel format rgba)

    @property
    def beauty_channels(self) -> int:
        return 4 if self.alpha else 3

    def integrator(self, inner: dict) -> dict:
        """The integrator: ``inner`` (the path tracer) alone, or an ``aov`` integrator around it."""
        if not self.aovs:
            return inner
        aovs = ",".join(f"aov{i}:{kind}" for i, kind in enumerate(self.aovs))
        return {"type": "aov", "aovs": aovs, "beauty": inner}

    def split(self, image: np.ndarray) -> dict[str, np.ndarray]:
        """Rendered H×W×C (beauty channels, then the AOVs in order) → pixels by layer name."""
        beauty = image[..., : self.beauty_channels]
        starts, offset = {}, self.beauty_channels
        for kind in self.aovs:
            starts.setdefault(kind, offset)
            offset += len(CHANNELS[kind])
        starts["distance"] = starts.get("depth")
        out: dict[str, np.ndarray] = {}
        for layer in self.layers:
            if layer.source == "beauty":
                out[layer.name] = beauty[..., : len(layer.channels)]
            elif layer.source == "alpha":
                out[layer.name] = beauty[..., 3:4]
            else:
                start = starts[layer.source]
                out[layer.name] = image[..., start : start + len(CHANNELS[layer.source])]
        return out


def plan(product: ProductSpec, diag: Diagnostics) -> AovPlan:
    """The layers of a product (a product without vars: the beauty alone)."""
    result = AovPlan()
    if not product.vars:
        result.layers.append(Layer("", ("R", "G", "B"), "beauty"))
        return result
    names: set[str] = set()
    plain_beauty = False
    for var in product.vars:
        source = _source(var.source_name, var.source_type, var.path, diag)
        if source is None:
            continue
        name = _unique(var.name, names)
        if source == "beauty":
            wide = var.data_type in FOUR_CHANNELS or var.source_name.lower() == "rgba"
            result.alpha |= wide
            base = ("R", "G", "B", "A") if wide else ("R", "G", "B")
            prefix = "" if not plain_beauty else f"{name}."
            plain_beauty = True
            result.layers.append(Layer(name, tuple(prefix + c for c in base), "beauty", var.path))
        elif source == "alpha":
            result.alpha = True
            result.layers.append(Layer(name, (f"{name}.A",), "alpha", var.path))
        else:
            mitsuba = "depth" if source == "distance" else source
            if mitsuba not in result.aovs:
                result.aovs.append(mitsuba)
            result.distances |= mitsuba == "depth"
            channels = tuple(f"{name}.{c}" for c in CHANNELS[source])
            result.layers.append(Layer(name, channels, source, var.path))
    return result


def finish(
    plan: AovPlan,
    images: dict[str, np.ndarray],
    cosines: np.ndarray | None,
    near: float,
    white: np.ndarray | None,
) -> None:
    """Mitsuba's depth → camera depth or distance, and white-balanced albedo (module doc)."""
    for layer in plan.layers:
        pixels = images[layer.name]
        hit = pixels[..., :1] > 0
        if layer.source == "depth" and cosines is not None:
            images[layer.name] = np.where(hit, pixels * cosines[..., None] + near, 0.0)
        elif layer.source == "distance" and cosines is not None:
            images[layer.name] = np.where(hit, pixels + near / cosines[..., None], 0.0)
        elif layer.source == "albedo" and white is not None:
            images[layer.name] = pixels / white


def pinhole_cosines(sensor: dict, film_size: tuple[int, int]) -> np.ndarray:
    """cos θ of each pixel centre's ray to a sensor's view axis (1 for orthographic sensors)."""
    width, height = film_size
    if sensor.get("type") == "orthographic":
        return np.ones((height, width))
    half = np.tan(np.radians(float(sensor.get("fov", 30.0))) / 2.0)
    axis = sensor.get("fov_axis", "x")
    tan_x = (
        half if axis == "x" or (axis == "smaller" and width <= height) else half * width / height
    )
    tan_y = tan_x * height / width
    x = ((np.arange(width) + 0.5) / width * 2.0 - 1.0) * tan_x
    y = ((np.arange(height) + 0.5) / height * 2.0 - 1.0) * tan_y
    return 1.0 / np.sqrt(1.0 + x[None, :] ** 2 + y[:, None] ** 2)


_WHITE: dict[str, np.ndarray] = {}


def albedo_white() -> np.ndarray:
    """Mitsuba's ``albedo`` AOV of a white Lambertian surface in the current variant (cached)."""
    import mitsuba as mi

    variant = mi.variant()
    if variant not in _WHITE:
        if "spectral" not in variant:
            _WHITE[variant] = np.ones(3)
        else:
            scene = mi.load_dict(
                {
                    "type": "scene",
                    "card": {"type": "rectangle", "bsdf": {"type": "diffuse", "reflectance": 1.0}},
                    "sensor": {
                        "type": "orthographic",
                        "to_world": mi.ScalarTransform4f()
                        .translate([0, 0, 1])
                        .rotate([0, 1, 0], 180),
                        "film": {
                            "type": "hdrfilm",
                            "width": 2,
                            "height": 2,
                            "rfilter": {"type": "box"},
                        },
                    },
                }
            )
            integrator = mi.load_dict({"type": "aov", "aovs": "white:albedo"})
            pixels = np.asarray(mi.render(scene, integrator=integrator, spp=4096, seed=7))
            _WHITE[variant] = pixels.reshape(-1, 3).mean(axis=0)
    return _WHITE[variant]


def _source(name: str, source_type: str, where: str, diag: Diagnostics) -> str | None:
    key = name.strip().lower()
    if source_type == "lpe":
        if name.strip() in BEAUTY_LPES:
            return "beauty"
        diag.warn(
            where, f"light path expression {name!r} is not supported; this RenderVar is skipped"
        )
        return None
    if source_type == "primvar":
        diag.warn(where, f"primvar RenderVar {name!r} is not supported; skipped")
        return None
    if source_type not in ("raw", "intrinsic"):
        diag.warn(where, f"sourceType {source_type!r} is not supported; skipped")
        return None
    if key in BEAUTY:
        return "beauty"
    if key in ALPHA:
        return "alpha"
    if key in SOURCES:
        return SOURCES[key]
    reason = UNAVAILABLE.get(key, "Mitsuba has no such output")
    diag.warn(where, f"RenderVar sourceName {name!r} is not supported ({reason}); skipped")
    return None


def _unique(name: str, taken: set[str]) -> str:
    candidate, n = name, 1
    while candidate in taken:
        candidate, n = f"{name}_{n}", n + 1
    taken.add(candidate)
    return candidate
