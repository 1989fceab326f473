"""Feather material parameters: Table 1 of the paper, presets, gradation interpolation, checks.

Lengths are in micrometres, as in the paper's Table 1. Every float is rounded to float32 on
construction so that a round trip through USD (``float``/``float2`` attributes) is exact.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field, fields, replace

import numpy as np

INTERFERENCE_MODES = ("paper", "intensity")
AXES = ("long", "short")


class ParameterError(ValueError):
    """A physically meaningless parameter; ``field`` names it (e.g. ``class[2].long.radius``).

    ``kind`` classifies the problem (``NotFinite``, ``NotPositive``, ``TooFewLayers``,
    ``RodsOverlap``, ``Invalid``) for tools that report findings by name, such as the USD validators.
    """

    def __init__(self, field_name: str, message: str, kind: str = "Invalid"):
        super().__init__(f"{field_name}: {message}")
        self.field = field_name
        self.reason = message
        self.kind = kind


def f32(value: float) -> float:
    """``value`` rounded to the nearest float32, as USD stores ``float`` attributes."""
    return float(np.float32(value))


def check_finite_positive(name: str, value: float) -> None:
    """Raise :class:`ParameterError` unless ``value`` is a finite number > 0."""
    if not isinstance(value, (int, float, np.floating, np.integer)) or isinstance(value, bool):
        raise ParameterError(name, f"expected a number, got {value!r}")
    if math.isnan(value):
        raise ParameterError(name, "is NaN", "NotFinite")
    if not math.isfinite(value):
        raise ParameterError(name, f"must be finite, got {value}", "NotFinite")
    if value <= 0:
        raise ParameterError(name, f"must be positive, got {value:.6g}", "NotPositive")


@dataclass(frozen=True)
class LayerStack:
    """The rod-layer structure seen in one barbule cross-section (one axis, one point).

    ``interval``: physical layer interval ``d`` (µm, Table 1's ``L_d``); ``radius``: melanin-rod
    radius ``a`` (µm); ``count``: number of layers ``N_d`` (real-valued after interpolation).
    """

    interval: float
    radius: float
    count: float

    def __post_init__(self) -> None:
        for f in fields(self):
            object.__setattr__(self, f.name, f32(getattr(self, f.name)))

    def validate(self, name: str = "stack") -> None:
        """Raise :class:`ParameterError` for non-positive values or overlapping rods (π·a > 2·d)."""
        check_finite_positive(f"{name}.interval", self.interval)
        check_finite_positive(f"{name}.radius", self.radius)
        check_finite_positive(f"{name}.count", self.count)
        if self.count < 1:
            raise ParameterError(
                f"{name}.count", f"must be >= 1 layer, got {self.count:.6g}", "TooFewLayers"
            )
        if math.pi * self.radius > 2.0 * self.interval * (1.0 + 1e-6):
            raise ParameterError(
                f"{name}.radius",
                f"rods overlap: pi*a = {math.pi * self.radius:.4g} um exceeds 2*d = "
                f"{2 * self.interval:.4g} um (fill factor pi*a/(2d) > 1)",
                "RodsOverlap",
            )


def _lerp(a: float, b: float, t: float) -> float:
    return a + (b - a) * t


@dataclass(frozen=True)
class OcellarClass:
    """One ocellar-map class: per axis, the (black, white) ends of the gradation map."""

    long: tuple[LayerStack, LayerStack]
    short: tuple[LayerStack, LayerStack]

    def at(self, gradation: float) -> tuple[LayerStack, LayerStack]:
        """``(long, short)`` stacks at gradation ``t`` ∈ [0, 1]: 0 = black end, 1 = white end."""
        t = min(max(float(gradation), 0.0), 1.0)
        return tuple(
            LayerStack(
                _lerp(black.interval, white.interval, t),
                _lerp(black.radius, white.radius, t),
                _lerp(black.count, white.count, t),
            )
            for black, white in (self.long, self.short)
        )  # type: ignore[return-value]

    def validate(self, name: str) -> None:
        for axis in AXES:
            for end, stack in zip(("black", "white"), getattr(self, axis), strict=True):
                stack.validate(f"{name}.{axis}.{end}")


@dataclass(frozen=True)
class FeatherParameters:
    """Everything the feather BRDF needs besides the maps (paper §2–3, Table 1)."""

    classes: tuple[OcellarClass, ...]
    melanin_index: float = 2.0  # n_ml, paper §2.2
    medium_index: float = 1.0  # n_0 (air)
    crescent_sigma_deg: float = 15.0  # θ0 of Eq. 6, across the barbule
    block_sigma_deg: float = 8.0  # spread along the barbule (saddle blocks), not given by the paper
    rod_length_um: float = 5.0  # "several µm": diffraction at rod ends, along the barbule
    interference: str = "paper"  # Eq. 3/4 as printed (|Σ|/N) or "intensity" (|Σ|²/N²)
    melanin_color: tuple[float, float, float] = field(default=(0.22, 0.12, 0.06))  # linear sRGB

    def __post_init__(self) -> None:
        for name in (
            "melanin_index",
            "medium_index",
            "crescent_sigma_deg",
            "block_sigma_deg",
            "rod_length_um",
        ):
            object.__setattr__(self, name, f32(getattr(self, name)))
        object.__setattr__(self, "melanin_color", tuple(f32(c) for c in self.melanin_color))
        object.__setattr__(self, "classes", tuple(self.classes))

    def validate(self) -> FeatherParameters:
        """Raise :class:`ParameterError` naming the first unphysical field; return ``self``."""
        if not self.classes:
            raise ParameterError("classes", "at least one ocellar class is required")
        for i, cls in enumerate(self.classes):
            cls.validate(f"class[{i}]")
        check_finite_positive("melanin_index", self.melanin_index)
        check_finite_positive("medium_index", self.medium_index)
        for name, upper in (("crescent_sigma_deg", 60.0), ("block_sigma_deg", 60.0)):
            value = getattr(self, name)
            check_finite_positive(name, value)
            if value > upper:
                raise ParameterError(name, f"must be at most {upper} degrees, got {value}")
        check_finite_positive("rod_length_um", self.rod_length_um)
        if self.interference not in INTERFERENCE_MODES:
            raise ParameterError(
                "interference", f"must be one of {INTERFERENCE_MODES}, got {self.interference!r}"
            )
        for c in self.melanin_color:
            if not (math.isfinite(c) and 0.0 <= c <= 1.0):
                raise ParameterError("melanin_color", f"components must lie in [0, 1], got {c}")
        return self

    def stacks(self, ocellar_class: int, gradation: float) -> tuple[LayerStack, LayerStack]:
        """``(long, short)`` stacks for a class index and gradation value."""
        if not 0 <= ocellar_class < len(self.classes):
            raise ParameterError(
                "ocellar_class",
                f"unknown class {ocellar_class}; this material has {len(self.classes)} classes",
            )
        return self.classes[ocellar_class].at(gradation)

    def with_(self, **changes) -> FeatherParameters:
        """A copy with some fields replaced (``dataclasses.replace``)."""
        return replace(self, **changes)

    def class_arrays(self) -> dict[str, np.ndarray]:
        """Table-shaped arrays ``{axis}_{interval|radius|count}`` of shape (classes, 2 ends)."""
        out: dict[str, np.ndarray] = {}
        for axis in AXES:
            for quantity in ("interval", "radius", "count"):
                out[f"{axis}_{quantity}"] = np.array(
                    [[getattr(s, quantity) for s in getattr(c, axis)] for c in self.classes],
                    dtype=np.float64,
                )
        return out

    @classmethod
    def from_class_arrays(cls, arrays: dict[str, Sequence], **scalars) -> FeatherParameters:
        """Inverse of :meth:`class_arrays`."""
        n = len(arrays["long_interval"])
        classes = []
        for i in range(n):
            per_axis = {}
            for axis in AXES:
                per_axis[axis] = tuple(
                    LayerStack(
                        arrays[f"{axis}_interval"][i][end],
                        arrays[f"{axis}_radius"][i][end],
                        arrays[f"{axis}_count"][i][end],
                    )
                    for end in (0, 1)
                )
            classes.append(OcellarClass(**per_axis))
        return cls(classes=tuple(classes), **scalars)


def _cls(long_d, long_a, long_n, short_d, short_a, short_n) -> OcellarClass:
    """A Table 1 row; each cell is a value or a (black, white) pair."""

    def ends(v):
        return v if isinstance(v, tuple) else (v, v)

    def axis(d, a, n):
        return tuple(
            LayerStack(di, ai, ni) for di, ai, ni in zip(ends(d), ends(a), ends(n), strict=True)
        )

    return OcellarClass(long=axis(long_d, long_a, long_n), short=axis(short_d, short_a, short_n))


# Table 1 of the paper ("black/white for the grad. map"), lengths in µm. One departure: class 5's
# white-end radius along both axes is printed .075 with L_d = .11, i.e. π·a = 0.236 > 2·d = 0.22
# (rods would overlap, fill factor 1.07). It is clamped to the largest radius that fits,
# 2·d/π = 0.0700 µm (docs/model.md, "Table 1").
_CLASS5_WHITE_RADIUS = 2 * 0.11 / math.pi

TABLE1 = (
    _cls(0.19, (0.075, 0.070), 4, 0.15, 0.065, (16, 18)),
    _cls(0.19, 0.075, 4, 0.15, 0.065, 16),
    _cls((0.19, 0.17), 0.075, (4, 8), 0.15, (0.065, 0.060), (16, 8)),
    _cls((0.23, 0.17), 0.075, (2, 16), (0.15, 0.17), (0.070, 0.060), 16),
    _cls(0.15, 0.075, (4, 2), 0.11, 0.065, (16, 4)),
    _cls(0.11, (0.060, _CLASS5_WHITE_RADIUS), 16, 0.11, (0.060, _CLASS5_WHITE_RADIUS), 16),
)

CLASS_NAMES = ("white", "1", "2", "3", "4", "black")


def _uniform(interval: float, radius: float, count: float) -> OcellarClass:
    return _cls(interval, radius, count, interval, radius, count)


PRESETS: dict[str, FeatherParameters] = {
    "paper-table1": FeatherParameters(classes=TABLE1),
    # Paper §2.1: yellow covert barbules, 3–6 layers at 190 nm; rods 130–140 nm in diameter.
    "yellow": FeatherParameters(classes=(_uniform(0.190, 0.070, 4),)),
    # Paper §2.1: blue body barbules, 8–12 layers at 150 nm.
    "blue": FeatherParameters(classes=(_uniform(0.150, 0.065, 10),)),
}


def preset(name: str) -> FeatherParameters:
    """A named preset (``paper-table1``, ``yellow``, ``blue``)."""
    try:
        return PRESETS[name]
    except KeyError:
        raise ParameterError(
            "preset", f"unknown preset {name!r}; known: {sorted(PRESETS)}"
        ) from None


def uniform_parameters(
    interval_um: float, radius_um: float, count: float, **scalars
) -> FeatherParameters:
    """A one-class material with the same stack along both axes (``--interval/--radius/--layers``)."""
    return FeatherParameters(classes=(_uniform(interval_um, radius_um, count),), **scalars)
