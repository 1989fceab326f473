"""Feather material parameters: Table 1 of the paper, presets, gradation interpolation, checks.

Lengths are in micrometres, as in the paper's Table 1. Every float is rounded to float32 on
construction so that a round trip through USD (``float``/``float2`` attributes) is exact.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field, fields, replace

import numpy as np

from pavonine.base.errors import ParameterError
from pavonine.materials.dispersion import KERATIN, MELANIN, Dispersion
from pavonine.materials.lattice import LATTICES, GeometryError, RodLattice

INTERFERENCE_MODES = ("paper", "intensity", "physical")
AXES = ("long", "short")
#: Per-class arrays beyond Table 1's interval/radius/count (physical mode; 0 = none/touching).
STRUCTURE_FIELDS = ("spacing", "channel")


#: Largest finite float32 (about 3.4e38): USD's ``float`` attributes hold nothing larger.
FLOAT32_MAX = float(np.finfo(np.float32).max)
#: Half an ulp above :data:`FLOAT32_MAX`: from here on, rounding to float32 gives ±inf.
_F32_OVERFLOW = 2.0**128 - 2.0**103


def f32(value: float) -> float:
    """``value`` rounded to the nearest float32, as USD stores ``float`` attributes; a finite
    value beyond float32's range becomes ±inf, as it would in USD (which the ``validate``
    methods refuse), without numpy's overflow warning."""
    if isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, bool):
        try:
            if abs(float(value)) >= _F32_OVERFLOW:
                return math.inf if value > 0 else -math.inf
        except OverflowError:  # an integer beyond even float64
            return math.inf if value > 0 else -math.inf
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


#: Most layers a stack may have: Table 1 has at most 16, and 1000 layers of a 0.2 µm interval make a
#: 0.2 mm stack, far thicker than any barbule (more would only cost time: the physical mode's
#: transfer matrices are per layer).
MAX_LAYER_COUNT = 1000


@dataclass(frozen=True)
class LayerStack:
    """The rod-layer structure seen in one barbule cross-section (one axis, one point).

    ``interval``: physical layer interval ``d`` (µm, Table 1's ``L_d``); ``radius``: melanin-rod
    radius ``a`` (µm); ``count``: number of layers ``N_d`` (real-valued after interpolation).
    Physical mode only: ``spacing`` of the rods within a layer (µm; 0 = touching, 2a) and the
    ``channel`` diameter of the air channels between them (µm; 0 = none).
    """

    interval: float
    radius: float
    count: float
    spacing: float = 0.0
    channel: float = 0.0

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
        if self.count > MAX_LAYER_COUNT:
            raise ParameterError(
                f"{name}.count",
                f"must be at most {MAX_LAYER_COUNT} layers, got {self.count:.6g}",
                "TooManyLayers",
            )
        if math.pi * self.radius > 2.0 * self.interval * (1.0 + 1e-6):
            raise ParameterError(
                f"{name}.radius",
                f"rods overlap: pi*a = {math.pi * self.radius:.4g} um exceeds 2*d = "
                f"{2 * self.interval:.4g} um (fill factor pi*a/(2d) > 1)",
                "RodsOverlap",
            )
        for quantity in STRUCTURE_FIELDS:
            value = getattr(self, quantity)
            if not math.isfinite(value) or value < 0:
                raise ParameterError(
                    f"{name}.{quantity}", f"must be finite and >= 0, got {value}", "NotPositive"
                )

    def lattice(self, arrangement: str, cortex: float = 0.0, count: int | None = None):
        """The :class:`RodLattice` of this stack in nm (``count`` defaults to ⌊N_d⌋)."""
        n = math.floor(self.count) if count is None else count
        return RodLattice(
            self.interval * 1000.0,
            self.radius * 1000.0,
            max(n, 1),
            self.spacing * 1000.0,
            arrangement,
            self.channel * 1000.0,
            cortex * 1000.0,
        )

    def check_geometry(self, name: str, arrangement: str, cortex: float = 0.0) -> None:
        """Raise :class:`ParameterError` if rods or channels of this lattice overlap."""
        try:
            self.lattice(arrangement, cortex, count=max(2, math.ceil(self.count))).check()
        except GeometryError as exc:
            raise ParameterError(f"{name}.{exc.field}", exc.reason, "RodsOverlap") from None


STACK_QUANTITIES = ("interval", "radius", "count", *STRUCTURE_FIELDS)


def _lerp(a: float, b: float, t: float) -> float:
    return a + (b - a) * t


@dataclass(frozen=True)
class OcellarClass:
    """One ocellar-map class: per axis, the (black, white) ends of the gradation map, and the
    keratin cortex thickness above the rods (µm, (black, white); physical mode)."""

    long: tuple[LayerStack, LayerStack]
    short: tuple[LayerStack, LayerStack]
    cortex: tuple[float, float] = (0.0, 0.0)

    def __post_init__(self) -> None:
        object.__setattr__(self, "cortex", tuple(f32(c) for c in self.cortex))

    def at(self, gradation: float) -> tuple[LayerStack, LayerStack]:
        """``(long, short)`` stacks at gradation ``t`` ∈ [0, 1]: 0 = black end, 1 = white end."""
        t = min(max(float(gradation), 0.0), 1.0)
        return tuple(
            LayerStack(
                *(_lerp(getattr(black, f.name), getattr(white, f.name), t) for f in fields(black))
            )
            for black, white in (self.long, self.short)
        )  # type: ignore[return-value]

    def cortex_at(self, gradation: float) -> float:
        """Cortex thickness (µm) at gradation ``t``."""
        t = min(max(float(gradation), 0.0), 1.0)
        return _lerp(self.cortex[0], self.cortex[1], t)

    def validate(self, name: str) -> None:
        for axis in AXES:
            for end, stack in zip(("black", "white"), getattr(self, axis), strict=True):
                stack.validate(f"{name}.{axis}.{end}")
        for end, value in zip(("black", "white"), self.cortex, strict=True):
            if not math.isfinite(value) or value < 0:
                raise ParameterError(
                    f"{name}.cortex.{end}", f"must be finite and >= 0, got {value}", "NotPositive"
                )


@dataclass(frozen=True)
class FeatherParameters:
    """Everything the feather BRDF needs besides the maps (paper §2–3, Table 1)."""

    classes: tuple[OcellarClass, ...]
    melanin_index: float = 2.0  # n_ml, paper §2.2
    medium_index: float = 1.0  # n_0 (air)
    crescent_sigma_deg: float = 15.0  # θ0 of Eq. 6, across the barbule
    block_sigma_deg: float = 8.0  # spread along the barbule (saddle blocks), not given by the paper
    rod_length_um: float = 5.0  # "several µm": diffraction at rod ends, along the barbule
    # Discrete barbule blocks (materials/glitter.py). Not in the repr: the repr is the digest
    # that tells baked textures stale, and a bake (the smooth average) is the same for any glitter.
    glitter: float = field(default=0.0, repr=False)  # 0 smooth average over blocks, 1 discrete
    glitter_seed: int = field(default=0, repr=False)  # the asset's seed of the block tilts
    block_length_um: float = field(default=25.0, repr=False)  # "typically 20-30 µm" (§2.1)
    barbule_width_um: float = field(default=20.0, repr=False)  # not given by the paper
    interference: str = "paper"  # Eq. 3/4 as printed (|Σ|/N), "intensity" (|Σ|²/N²), "physical"
    melanin_color: tuple[float, float, float] = field(default=(0.22, 0.12, 0.06))  # linear sRGB
    lattice: str = "staggered"  # physical mode: rod layers "staggered" or "rectangular"
    melanin: Dispersion = MELANIN  # physical mode: rod index n(λ) + i k(λ)
    keratin: Dispersion = KERATIN  # physical mode: matrix and cortex index n(λ)

    def __post_init__(self) -> None:
        for name in (
            "melanin_index",
            "medium_index",
            "crescent_sigma_deg",
            "block_sigma_deg",
            "rod_length_um",
            "glitter",
            "block_length_um",
            "barbule_width_um",
        ):
            object.__setattr__(self, name, f32(getattr(self, name)))
        object.__setattr__(self, "melanin_color", tuple(f32(c) for c in self.melanin_color))
        object.__setattr__(self, "classes", tuple(self.classes))
        for name in ("melanin", "keratin"):
            value = getattr(self, name)
            object.__setattr__(
                self, name, Dispersion(*(f32(getattr(value, f.name)) for f in fields(value)))
            )

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
        if not (isinstance(self.glitter, float) and 0.0 <= self.glitter <= 1.0):
            raise ParameterError("glitter", f"must lie in [0, 1], got {self.glitter}")
        if isinstance(self.glitter_seed, bool) or not isinstance(self.glitter_seed, int):
            raise ParameterError("glitter_seed", f"expected an integer, got {self.glitter_seed!r}")
        if not 0 <= self.glitter_seed <= 0x7FFFFFFF:
            raise ParameterError(
                "glitter_seed", f"must lie in [0, 2147483647], got {self.glitter_seed}"
            )
        check_finite_positive("block_length_um", self.block_length_um)
        check_finite_positive("barbule_width_um", self.barbule_width_um)
        if self.interference not in INTERFERENCE_MODES:
            raise ParameterError(
                "interference", f"must be one of {INTERFERENCE_MODES}, got {self.interference!r}"
            )
        for c in self.melanin_color:
            if not (math.isfinite(c) and 0.0 <= c <= 1.0):
                raise ParameterError("melanin_color", f"components must lie in [0, 1], got {c}")
        if self.lattice not in LATTICES:
            raise ParameterError("lattice", f"must be one of {LATTICES}, got {self.lattice!r}")
        for name in ("melanin", "keratin"):
            try:
                getattr(self, name).check(name)
            except ValueError as exc:
                raise ParameterError(name, str(exc).split(": ", 1)[-1]) from None
        self._check_geometry()
        return self

    def _check_geometry(self) -> None:
        """Physical mode: rods or channels that overlap are an error (:meth:`RodLattice.check`)."""
        if self.interference != "physical":
            return
        for i, cls in enumerate(self.classes):
            for axis in AXES:
                ends = zip(("black", "white"), getattr(cls, axis), cls.cortex, strict=True)
                for end, stack, cortex in ends:
                    stack.check_geometry(f"class[{i}].{axis}.{end}", self.lattice, cortex)

    def geometry_warnings(self) -> list[tuple[int, str, str]]:
        """Paper modes: ``(class, axis, message)`` for each class and axis whose rods would overlap
        if staggered (``d < √3·a``). The paper mode keeps Table 1 as printed (class 4's short axis
        fails); the physical mode refuses such a stack (:meth:`validate`)."""
        if self.interference == "physical":
            return []
        out = []
        for i, cls in enumerate(self.classes):
            for axis in AXES:
                tight = [
                    (end, stack)
                    for end, stack in zip(("black", "white"), getattr(cls, axis), strict=True)
                    if stack.interval * (1 + 1e-6) < math.sqrt(3.0) * stack.radius
                ]
                if tight:
                    stack = tight[0][1]
                    which = " and ".join(e for e, _ in tight)
                    out.append(
                        (
                            i,
                            axis,
                            f"class {i} {axis} axis ({which} end{'s' if len(tight) > 1 else ''}): "
                            f"staggered rods overlap, d = {stack.interval:.4g} um < sqrt(3)*a = "
                            f"{math.sqrt(3.0) * stack.radius:.4g} um; kept as printed in the "
                            "paper mode, an error in the physical mode",
                        )
                    )
        return out

    def stacks(self, ocellar_class: int, gradation: float) -> tuple[LayerStack, LayerStack]:
        """``(long, short)`` stacks for a class index and gradation value."""
        if not 0 <= ocellar_class < len(self.classes):
            raise ParameterError(
                "ocellar_class",
                f"unknown class {ocellar_class}; this material has {len(self.classes)} class{'es' * (len(self.classes) != 1)}",
            )
        return self.classes[ocellar_class].at(gradation)

    def with_(self, **changes) -> FeatherParameters:
        """A copy with some fields replaced (``dataclasses.replace``)."""
        return replace(self, **changes)

    def class_arrays(self) -> dict[str, np.ndarray]:
        """Table-shaped arrays of shape (classes, 2 ends): ``{axis}_{quantity}`` for every
        :class:`LayerStack` field, and ``cortex``."""
        out: dict[str, np.ndarray] = {}
        for axis in AXES:
            for quantity in STACK_QUANTITIES:
                out[f"{axis}_{quantity}"] = np.array(
                    [[getattr(s, quantity) for s in getattr(c, axis)] for c in self.classes],
                    dtype=np.float64,
                ).reshape(-1, 2)
        out["cortex"] = np.array([c.cortex for c in self.classes], dtype=np.float64).reshape(-1, 2)
        return out

    @classmethod
    def from_class_arrays(cls, arrays: dict[str, Sequence], **scalars) -> FeatherParameters:
        """Inverse of :meth:`class_arrays`; the physical-mode arrays (``spacing``, ``channel``,
        ``cortex``) may be missing or empty (= 0 for every class)."""
        n = len(arrays["long_interval"])

        def cell(key: str, i: int, end: int) -> float:
            values = arrays.get(key)
            return 0.0 if values is None or len(values) == 0 else values[i][end]

        classes = []
        for i in range(n):
            per_axis = {}
            for axis in AXES:
                per_axis[axis] = tuple(
                    LayerStack(*(cell(f"{axis}_{q}", i, end) for q in STACK_QUANTITIES))
                    for end in (0, 1)
                )
            cortex = (cell("cortex", i, 0), cell("cortex", i, 1))
            classes.append(OcellarClass(**per_axis, cortex=cortex))
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
# white-end radius along both axes is printed .075 with L_d = .11: staggered rods of that size
# overlap (they need d >= sqrt(3)*a) and even their cell is over-full (pi*a > 2*d). It is set to
# the largest radius whose staggered rods still fit, d/sqrt(3) = 0.0635 µm (fill factor 0.91, so
# the stack keeps its index contrast; docs/model.md, "Table 1").
_CLASS5_WHITE_RADIUS = 0.11 / math.sqrt(3.0)

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


#: Freyer & Stavenga 2020 (Faraday Discuss. 223:49), the six eye-feather regions as
#: (lattice a, lattice b, cortex c, melanosome diameter D_m, air channel D_a in nm; layers N_m).
#: Pavonine reads ``a`` as the lattice spacing across the layers (the layer interval, Zi et al.'s
#: lattice constant) and ``b`` as the rod spacing within a layer; the reverse reading puts the
#: brown and green-yellow regions' bands in the blue (docs/model.md, "Literature preset").
FREYER_2020_REGIONS = {
    "purple": (185, 190, 140, 100, 70, 3),
    "brass-green": (185, 160, 130, 120, 70, 4),
    "green-yellow": (195, 150, 130, 120, 55, 5),
    "brown": (190, 150, 70, 110, 50, 5),
    "blue-green": (160, 170, 100, 110, 33, 9),
    "black-violet": (140, 150, 100, 100, 33, 10),
}
#: Ocellar class (0 = white … 5 = black) of each region, from the eye's heart outwards 5 … 1;
#: class 0, the lower vane of loose barbs, takes the remaining region.
FREYER_2020_CLASSES = (
    "purple",
    "brass-green",
    "green-yellow",
    "brown",
    "blue-green",
    "black-violet",
)


#: Gradation of the literature preset (docs/model.md, "Gradation in freyer2020"). Each region's
#: measured structure sits at the middle of the gradation map (t = ½); its black (t = 0) and
#: white (t = 1) ends are the same structure uniformly scaled by ``1 ∓ FREYER_2020_SIZE_SPREAD``:
#: lattice constants (layer interval ``a``, rod spacing ``b``), melanosome and air-channel
#: diameters and cortex together, the layer count unchanged. Zi et al. 2003 (PNAS 100:12576):
#: peacock barbules tune their colour by the lattice constant and their purity (mixed colours) by
#: the number of periods; Freyer & Stavenga 2020: the layer count sets the number of reflectance
#: peaks, so it stays a property of the region, and slight size variations shift the bands.
#: ±3 % is about 5 nm on the lattice constants (140–195 nm), below half the step between the
#: nearest measured regions (185 → 195 nm, 5 %), so both ends keep the region's named colour.
FREYER_2020_SIZE_SPREAD = 0.03


def freyer_class(region: str, spread: float = FREYER_2020_SIZE_SPREAD) -> OcellarClass:
    """The ocellar class of one Freyer & Stavenga 2020 region (:data:`FREYER_2020_REGIONS`):
    the measured structure at gradation ½, scaled by ``1 − spread`` at the black end and
    ``1 + spread`` at the white end (both axes alike). Every overlap rule of
    :class:`~pavonine.materials.lattice.RodLattice` compares lengths, so a uniform scale keeps
    each end as valid as the measured structure."""
    if region not in FREYER_2020_REGIONS:
        raise ParameterError(
            "region", f"unknown region {region!r}; known: {sorted(FREYER_2020_REGIONS)}"
        )
    if not 0.0 <= spread < 1.0:
        raise ParameterError("spread", f"must lie in [0, 1), got {spread}")
    a, b, c, dm, da, nm = FREYER_2020_REGIONS[region]
    ends = []
    for scale in (1.0 - spread, 1.0 + spread):
        nm_to_um = scale / 1000.0
        ends.append(
            (
                LayerStack(a * nm_to_um, dm * nm_to_um / 2, nm, b * nm_to_um, da * nm_to_um),
                c * nm_to_um,
            )
        )
    (black, black_cortex), (white, white_cortex) = ends
    return OcellarClass(
        long=(black, white), short=(black, white), cortex=(black_cortex, white_cortex)
    )


PRESETS: dict[str, FeatherParameters] = {
    "paper-table1": FeatherParameters(classes=TABLE1),
    # Freyer & Stavenga 2020: measured eye-feather structure, literature melanin and keratin.
    "freyer2020": FeatherParameters(
        classes=tuple(freyer_class(region) for region in FREYER_2020_CLASSES),
        interference="physical",
        lattice="rectangular",
    ),
    # Paper §2.1: yellow covert barbules, 3–6 layers at 190 nm; rods 130–140 nm in diameter.
    "yellow": FeatherParameters(classes=(_uniform(0.190, 0.070, 4),)),
    # Paper §2.1: blue body barbules, 8–12 layers at 150 nm.
    "blue": FeatherParameters(classes=(_uniform(0.150, 0.065, 10),)),
}


#: Gradation at which a preset's classes hold the structure they were measured or tabulated at:
#: the middle for ``freyer2020`` (:func:`freyer_class`), the black end (t = 0) otherwise.
PRESET_GRADATION: dict[str, float] = {"freyer2020": 0.5}


def preset_gradation(name: str) -> float:
    """The gradation (0-1) at which preset ``name`` shows its measured or tabulated structure."""
    return PRESET_GRADATION.get(name, 0.0)


def preset(name: str) -> FeatherParameters:
    """A named preset (``paper-table1``, ``freyer2020``, ``yellow``, ``blue``)."""
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
