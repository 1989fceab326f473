"""The stage's integrator and samples per pixel: hdmitsuba's ``mitsuba:`` render settings.

google/hdmitsuba (``usd_mitsuba/translator.py``) reads the ``RenderSettings`` prim's attributes
``mitsuba:integrator:<key>`` as the Mitsuba integrator's dictionary (``type`` required once any
is authored; ``path`` without them) and ``mitsuba:sample_count`` as the samples per pixel, so a
stage made for it says how it wants to be rendered. Pavonine honours what keeps its images
spectral and unbiased:

* ``type`` ``path``, ``volpath`` or ``pavonine_path``: Pavonine's path tracer
  (:mod:`.integrator`, ``volpath``'s estimator; Mitsuba's ``path`` also stops shadow rays at
  null surfaces and counts a pass through one as a bounce) with ``max_depth`` (-1: no limit,
  Mitsuba's convention), ``rr_depth`` and ``hide_emitters``; a stage that authors ``rr_depth``
  gets ``volpath``'s Russian roulette exactly, one that does not also the early roulette of
  low-throughput paths (``rr_threshold``, :mod:`.integrator`);
* ``type`` ``direct``: Mitsuba's ``direct`` integrator with ``shading_samples`` or
  ``emitter_samples`` / ``bsdf_samples``, and ``hide_emitters``;
* ``mitsuba:sample_count``: the samples per pixel when the caller gives none.

Another ``type`` is rendered by the path tracer (with the ``max_depth``, ``rr_depth`` and
``hide_emitters`` Mitsuba's Monte Carlo integrators share) and another key ignored, each with a
warning naming it; a value of the wrong kind or out of Mitsuba's range is an
:class:`InputError` naming the layer and the attribute. ``mitsuba:variant`` is warned about
unless it is the variant in use (Pavonine picks a spectral variant, ``--variant``), as is any
``mitsuba:`` attribute of a product or var, or of any other prim (:func:`warn_unread`:
hdmitsuba's ``mitsuba:sensor:*`` on cameras, for one).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any

from pavonine.base.errors import InputError
from pavonine.render.integrator import (
    DEFAULT_MAX_DEPTH,
    DEFAULT_RR_DEPTH,
    RR_THRESHOLD,
    runs_pavonine_path,
)
from pavonine.render.sensors import READ as SENSOR_SETTINGS

if TYPE_CHECKING:
    from pxr import Usd

    from pavonine.render.diagnostics import Diagnostics

INTEGRATOR = "mitsuba:integrator:"
SAMPLE_COUNT = "mitsuba:sample_count"
VARIANT = "mitsuba:variant"
PATH_TYPES = ("path", "volpath", "pavonine_path")
DEFAULT_SPP = 64  # samples per pixel when neither the caller nor the stage says
MAX_DEPTH_LIMIT = 2**31 - 1  # the largest depth Mitsuba's integer properties hold
MAX_SHADING_SAMPLES = 65_536  # per camera sample, like the default --max-spp ceiling
#: hdmitsuba's per-mesh refinement level (usd_mitsuba/mesh.py), read by render/subdivision.py
SUBDIVISION_LEVEL = "mitsuba:subdivision_level"
USD_RENDER = ("RenderSettings", "RenderProduct", "RenderVar")  # audited by render/settings.py
DIRECT_SAMPLES = ("shading_samples", "emitter_samples", "bsdf_samples")


@dataclass(frozen=True)
class IntegratorSpec:
    """How the stage asks to be rendered (fields: Mitsuba's integrator parameters)."""

    type: str = "path"  # "path" (Pavonine's path tracer) or "direct"
    max_depth: int = DEFAULT_MAX_DEPTH  # scattering vertices; -1: no limit
    rr_depth: int = DEFAULT_RR_DEPTH  # first depth of Russian roulette
    rr_threshold: float = RR_THRESHOLD  # early roulette below this throughput; 0: volpath's
    hide_emitters: bool = False
    samples: tuple[tuple[str, int], ...] = ()  # ``direct``'s sample counts, as authored

    def with_max_depth(self, max_depth: int | None) -> IntegratorSpec:
        """This spec with ``max_depth`` overridden (``None``: unchanged; ``direct`` has none)."""
        if max_depth is None or self.type == "direct":
            return self
        return replace(self, max_depth=int(max_depth))

    def for_variant(self, variant: str) -> IntegratorSpec:
        """This spec as rendered in ``variant``: scalar variants render the path tracer with
        Mitsuba's ``volpath`` (:func:`.integrator.path_tracer`), which has no early roulette."""
        if self.type == "direct" or runs_pavonine_path(variant):
            return self
        return replace(self, rr_threshold=0.0)

    def mitsuba_dict(self) -> dict[str, Any]:
        """The integrator's Mitsuba dictionary for the active variant."""
        if self.type == "direct":
            return self.describe()  # Mitsuba's own parameters, as recorded
        from pavonine.render import integrator

        return integrator.path_tracer(
            self.max_depth,
            rr_depth=self.rr_depth,
            hide_emitters=self.hide_emitters,
            rr_threshold=self.rr_threshold,
        )

    def describe(self) -> dict[str, Any]:
        """The settings as recorded in an image's metadata."""
        if self.type == "direct":
            return {"type": "direct", "hide_emitters": self.hide_emitters, **dict(self.samples)}
        return {
            "type": "path",
            "max_depth": self.max_depth,
            "rr_depth": self.rr_depth,
            "rr_threshold": self.rr_threshold,
            "hide_emitters": self.hide_emitters,
        }


def read_integrator(prim: Usd.Prim, diag: Diagnostics) -> IntegratorSpec:
    """The integrator a ``RenderSettings`` prim authors (:class:`IntegratorSpec` defaults when
    it authors none)."""
    authored = {
        attr.GetName()[len(INTEGRATOR) :]: attr
        for attr in prim.GetAttributes()
        if attr.GetName().startswith(INTEGRATOR) and attr.HasAuthoredValue()
    }
    if not authored:
        return IntegratorSpec()
    where = str(prim.GetPath())
    if "type" not in authored:
        raise InputError(field_of(authored[next(iter(authored))]), f"needs {INTEGRATOR}type too")
    kind = _text(authored.pop("type"))
    if kind not in (*PATH_TYPES, "direct"):
        diag.warn(
            where,
            f"{INTEGRATOR}type {kind!r} is not supported; rendered with the path tracer "
            f"(supported: {', '.join(PATH_TYPES)}, direct)",
        )
    if kind == "direct":
        keys: tuple[str, ...] = (*DIRECT_SAMPLES, "hide_emitters")
    else:  # Mitsuba's Monte Carlo integrators share these three
        kind = "path"
        keys = ("max_depth", "rr_depth", "hide_emitters")
    spec = IntegratorSpec(type=kind)
    samples = []
    for key, attr in authored.items():
        if key not in keys:
            diag.warn(where, f"{INTEGRATOR}{key} is not supported here; ignored")
        elif key == "hide_emitters":
            spec = replace(spec, hide_emitters=_flag(attr))
        elif key == "max_depth":
            spec = replace(spec, max_depth=_integer(attr, minimum=-1, maximum=MAX_DEPTH_LIMIT))
        elif key == "rr_depth":
            depth = _integer(attr, minimum=1, maximum=MAX_DEPTH_LIMIT)
            spec = replace(spec, rr_depth=depth, rr_threshold=0.0)  # as authored, volpath's
        else:
            samples.append((key, _integer(attr, minimum=0, maximum=MAX_SHADING_SAMPLES)))
    counts = dict(samples)
    if "shading_samples" in counts and counts.keys() & {"emitter_samples", "bsdf_samples"}:
        raise InputError(
            field_of(authored["shading_samples"]),
            "cannot be given with emitter_samples or bsdf_samples (Mitsuba's direct)",
        )
    shading = counts.get("shading_samples", 1)
    if counts.get("emitter_samples", shading) + counts.get("bsdf_samples", shading) == 0:
        first = authored[next(k for k in DIRECT_SAMPLES if k in counts)]
        raise InputError(field_of(first), "direct needs at least one emitter or BSDF sample")
    return replace(spec, samples=tuple(sorted(samples)))


def read_sample_count(prim: Usd.Prim) -> tuple[int | None, str]:
    """``mitsuba:sample_count`` of a ``RenderSettings`` prim (``None``: not authored) and where
    it is authored (``layer: /Prim.attribute``; empty when not)."""
    attr = prim.GetAttribute(SAMPLE_COUNT)
    if not attr or not attr.HasAuthoredValue():
        return None, ""
    return _integer(attr, minimum=1, maximum=None), field_of(attr)


def warn_unread(prim: Usd.Prim, diag: Diagnostics) -> None:
    """Name every authored ``mitsuba:`` attribute of a prim that is not a UsdRender prim
    (hdmitsuba's ``mitsuba:sensor:type`` on a camera, ``mitsuba:sensor`` on a mesh …): none is
    read there. UsdRender prims are audited with their settings (:mod:`.settings`)."""
    kind = prim.GetTypeName()
    if kind in USD_RENDER:
        return
    for name in prim.GetAuthoredPropertyNames():
        if name == SUBDIVISION_LEVEL and kind == "Mesh":
            continue  # read with the subdivision scheme (render/subdivision.py)
        if name in SENSOR_SETTINGS.get(kind, ()):
            continue  # hdmitsuba's sensors (render/sensors.py)
        if name.startswith("mitsuba:"):
            warn_ignored(prim, name, "not supported", diag)


def warn_ignored(prim: Usd.Prim, name: str, reason: str, diag: Diagnostics) -> None:
    """The one warning for a ``mitsuba:`` attribute that is not read, and why."""
    diag.warn(str(prim.GetPath()), f"{name} (hdmitsuba's setting) is ignored: {reason}")


def check_variant(prim: Usd.Prim, used: str, diag: Diagnostics) -> None:
    """Warn when the ``RenderSettings`` prim's ``mitsuba:variant`` is not the variant ``used``
    (Pavonine picks a spectral one: ``--variant``); the same one passes silently."""
    attr = prim.GetAttribute(VARIANT)
    if attr and attr.HasAuthoredValue() and attr.Get() != used:
        diag.warn(
            str(prim.GetPath()),
            f"{VARIANT} {attr.Get()!r} (hdmitsuba's setting) is not used: Pavonine renders "
            f"spectrally, here with {used} (choose with --variant)",
        )


def is_honoured(name: str) -> bool:
    """Whether a ``mitsuba:`` attribute of a ``RenderSettings`` prim is read here."""
    return name.startswith(INTEGRATOR) or name in (SAMPLE_COUNT, VARIANT)


def field_of(attr: Usd.Attribute) -> str:
    """``layer: /Prim.attribute``, the layer being the strongest one authoring the value."""
    from pxr import Usd

    stack = attr.GetPropertyStack(Usd.TimeCode.Default())
    layer = stack[0].layer if stack else attr.GetStage().GetRootLayer()
    return f"{layer.realPath or layer.identifier}: {attr.GetPath()}"


def _value(attr: Usd.Attribute) -> Any:
    """The attribute's default value (time samples are not read: a render setting is one value)."""
    value = attr.Get()
    if value is None:
        raise InputError(field_of(attr), "has no default value (time samples are not read)")
    return value


def _integer(attr: Usd.Attribute, minimum: int, maximum: int | None) -> int:
    value = _value(attr)
    number = isinstance(value, (int, float)) and not isinstance(value, bool)
    if not number or not math.isfinite(value) or value != int(value):
        raise InputError(field_of(attr), f"must be an integer, got {value!r}")
    if int(value) < minimum:
        raise InputError(field_of(attr), f"must be at least {minimum}, got {int(value)}")
    if maximum is not None and int(value) > maximum:
        raise InputError(field_of(attr), f"must be at most {maximum:,}, got {int(value):,}")
    return int(value)


def _flag(attr: Usd.Attribute) -> bool:
    value = _value(attr)
    if isinstance(value, bool) or (isinstance(value, int) and value in (0, 1)):
        return bool(value)
    raise InputError(field_of(attr), f"must be a bool, got {value!r}")


def _text(attr: Usd.Attribute) -> str:
    value = _value(attr)
    if not isinstance(value, str) or not value:
        raise InputError(field_of(attr), f"must be a non-empty string, got {value!r}")
    return value
