"""The flex of one feather in the rattle: its geometry read from the component asset, and the
two blend shapes (in-phase and quadrature offsets, cm) of its vibration at the drive frequency.

Dakin et al. 2016, *PLoS ONE* 11(4): e0152759 (:mod:`.rattle` for the whole model): the rachis
below the eyespot bends side to side as a standing half sine with its node at the eyespot's
lower edge; each loose barb swings as a cantilever from the rachis in the first mode of a
clamped-free beam (:func:`cantilever_mode`), lagging the rachis by up to a quarter period at its
tip; barbs hooked into the eyespot (ocellar class ≥ :data:`EYESPOT_CLASS`) do not swing.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

#: Ocellar classes at and above this are the eyespot, whose barbs are hooked together
#: (``pipeline/maps/paint.py``: 2…5 the rings, 1 the vane around them, 0 the loose lower vane).
EYESPOT_CLASS = 2
#: First cantilever mode (clamped-free beam): ``beta L`` and its shape's ``sigma``.
_BETA1 = 1.8751040687
_SIGMA1 = (math.cosh(_BETA1) + math.cos(_BETA1)) / (math.sinh(_BETA1) + math.sin(_BETA1))
#: Per-barb phase offset of barb curves (``geometry = "barbs"``): uniform in ± this (radians);
#: the loose barbs move "independently", a modelling choice, not a measured spread.
BARB_PHASE_SPREAD = math.pi / 4


def cantilever_mode(xi: np.ndarray) -> np.ndarray:
    """First bending mode of a clamped-free beam at ``xi`` in [0, 1], 0 at the root, 1 at the tip."""
    b = _BETA1 * np.clip(xi, 0.0, 1.0)
    shape = np.cosh(b) - np.cos(b) - _SIGMA1 * (np.sinh(b) - np.sin(b))
    tip = math.cosh(_BETA1) - math.cos(_BETA1) - _SIGMA1 * (math.sinh(_BETA1) - math.sin(_BETA1))
    return shape / tip


@dataclass
class Deformed:
    """One prim of a prototype that flexes: the points that move and their two offsets (cm)."""

    path: str  # relative to the prototype root, e.g. "Geom/Vane"
    indices: np.ndarray  # (n,) point indices
    sin: np.ndarray  # (n, 3) offset at weight sin(wt + phase)
    cos: np.ndarray  # (n, 3) offset at weight cos(wt + phase)
    eyespot: np.ndarray  # (n,) bool: the point lies on the eyespot (for checks)


@dataclass
class Shape:
    """A prototype's vibration, before the amplitude is set (unit rachis and barb amplitude)."""

    name: str
    deformed: list[Deformed] = field(default_factory=list)
    sway_radius_cm: float = 1.0  # base → the farthest eyespot point (the tip without one)
    peak: float = 0.0  # largest displacement of the unit shape over its loose points
    loose_reach_cm: float = 0.0  # the farthest loose point from the rachis


@dataclass
class _Prim:
    path: str
    points: np.ndarray
    uv: np.ndarray | None
    tangent: np.ndarray | None
    curves: np.ndarray | None  # curveVertexCounts of a BasisCurves


def _read_prims(asset: Path, lod: str, geometry: str) -> list[_Prim]:
    """Point-based prims of a component with its ``lod`` and ``geometry`` selected."""
    from pxr import Usd, UsdGeom

    stage = Usd.Stage.Open(str(asset))
    stage.SetEditTarget(stage.GetSessionLayer())
    root = stage.GetDefaultPrim()
    for name, selection in (("lod", lod), ("geometry", geometry)):
        variants = root.GetVariantSets().GetVariantSet(name)
        if selection in variants.GetVariantNames():
            variants.SetVariantSelection(selection)
    found = []
    for prim in Usd.PrimRange(root):
        if not prim.IsA(UsdGeom.PointBased):
            continue
        points = UsdGeom.PointBased(prim).GetPointsAttr().Get()
        if not points:
            continue
        points = np.array(points, dtype=np.float64)
        counts = None
        if prim.IsA(UsdGeom.BasisCurves):
            counts = np.array(UsdGeom.BasisCurves(prim).GetCurveVertexCountsAttr().Get(), int)
        found.append(
            _Prim(
                str(prim.GetPath().MakeRelativePath(root.GetPath())),
                points,
                _vertex_primvar(prim, "pavonine_featherUV", 2, len(points)),
                _vertex_primvar(prim, "pavonine_barbTangent", 3, len(points)),
                counts,
            )
        )
    return found


def _vertex_primvar(prim, name: str, width: int, count: int) -> np.ndarray | None:
    """A vertex primvar's first ``width`` components per point, ``None`` when it is missing or
    not one value per point."""
    from pxr import UsdGeom

    primvar = UsdGeom.PrimvarsAPI(prim).GetPrimvar(name)
    if not primvar or primvar.GetInterpolation() not in ("vertex", "varying"):
        return None
    values = primvar.ComputeFlattened()
    if values is None or len(values) != count:
        return None
    array = np.array(values, dtype=np.float64).reshape(count, -1)
    return array[:, :width] if array.shape[1] >= width else None


def _eyespot_lock(asset: Path) -> tuple[np.ndarray, np.ndarray] | None:
    """The component's eyespot from its ocellar map (``maps/ocellar.png``): a mask (class ≥ 2)
    and a lock weight (1 on the mask and just beyond, falling to 0 over ~1 % of the map), or
    ``None`` when the component has no such map or no eyespot."""
    from scipy import ndimage

    from pavonine.base.map_files import read_data_map
    from pavonine.pipeline.maps.paint import ocellar_class

    path = asset.parent / "maps" / "ocellar.png"
    if not path.is_file():
        return None
    grey = read_data_map(path, "maps.ocellar").values
    mask = ocellar_class(grey) >= EYESPOT_CLASS
    if not mask.any():
        return None
    sigma = 0.01 * max(mask.shape)
    lock = np.clip(2.0 * ndimage.gaussian_filter(mask.astype(np.float32), sigma), 0.0, 1.0)
    return mask, lock


def _sample(image: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """Nearest texel of a map at feather UVs (v up: row 0 is the top, v = 1)."""
    height, width = image.shape
    cols = np.clip(np.rint(uv[:, 0] * (width - 1)), 0, width - 1).astype(int)
    rows = np.clip(np.rint((1.0 - uv[:, 1]) * (height - 1)), 0, height - 1).astype(int)
    return image[rows, cols]


def _curve_tangents(points: np.ndarray, counts: np.ndarray) -> np.ndarray:
    tangents = np.zeros_like(points)
    start = 0
    for n in counts:
        segment = points[start : start + n]
        if n > 1:
            tangents[start : start + n] = np.gradient(segment, axis=0)
        start += n
    return tangents


@dataclass
class Geometry:
    """A prototype's point-based prims with the eyespot's lock weight and mask at each point."""

    name: str
    prims: list[_Prim]
    locks: list[np.ndarray]
    masks: list[np.ndarray]

    @property
    def loose_reach_cm(self) -> float:
        """The farthest point from the rachis that is not locked into the eyespot (cm)."""
        reach = [np.abs(p.points[lock < 1.0, 0]) for p, lock in zip(self.prims, self.locks,
                                                                     strict=True)]  # fmt: skip
        reach = [r for r in reach if len(r)]
        return float(max(r.max() for r in reach)) if reach else 0.0


def read_geometry(name: str, asset: Path, lod: str, geometry: str) -> Geometry:
    """The prototype ``name`` (``asset`` at ``lod``/``geometry``) as :class:`Geometry`."""
    prims = _read_prims(asset, lod, geometry)
    eyespot = _eyespot_lock(asset)
    locks, masks = [], []
    for prim in prims:
        if eyespot is not None and prim.uv is not None:
            mask = _sample(eyespot[0], prim.uv).astype(bool)
            masks.append(mask)
            locks.append(np.maximum(_sample(eyespot[1], prim.uv).astype(np.float64), mask))
        else:
            masks.append(np.zeros(len(prim.points), bool))
            locks.append(np.zeros(len(prim.points)))
    return Geometry(name, prims, locks, masks)


def node_height(geometry: Geometry) -> float:
    """Where the rachis' standing wave has its node (cm above the base): the eyespot's lower
    edge (the lowest point its lock touches), else the feather's tip."""
    touched = [p.points[lock > 0, 1] for p, lock in zip(geometry.prims, geometry.locks,
                                                          strict=True)]  # fmt: skip
    touched = [t for t in touched if len(t)]
    if touched:
        return max(float(min(t.min() for t in touched)), 1e-6)
    tips = [p.points[:, 1].max() for p in geometry.prims]
    return max(float(max(tips)), 1e-6) if tips else 1e-6


def tip_height(geometry: Geometry) -> float:
    """The feather's length: its highest point above the base (cm)."""
    return max((float(p.points[:, 1].max()) for p in geometry.prims), default=1e-6)


def prototype_shape(geometry: Geometry, reach_cm: float, tip_cm: float, seed: int) -> Shape:
    """The unit vibration of one prototype before :func:`scale_shapes`. ``reach_cm`` is the
    train's longest loose barb and ``tip_cm`` its longest feather: a barb's mode shape is of its
    distance from the rachis over ``reach_cm`` and a rachis' amplitude is its feather's length
    over ``tip_cm`` (geometrically similar standing waves), so shorter barbs and feathers, which
    are stiffer, swing less."""
    shape = Shape(geometry.name)
    prims, locks = geometry.prims, geometry.locks
    if not prims:
        return shape
    every = np.concatenate([p.points for p in prims])
    touched = [p.points[lock > 0] for p, lock in zip(prims, locks, strict=True)]
    touched = np.concatenate(touched)
    if len(touched):  # the sway: to the eyespot's farthest point
        held = np.concatenate([p.points[lock >= 0.999] for p, lock in zip(prims, locks,
                                                                            strict=True)])  # fmt: skip
        held = held if len(held) else touched
        shape.sway_radius_cm = float(np.hypot(held[:, 0], held[:, 1]).max())
    else:  # no eyespot: the sway is measured at the tip
        shape.sway_radius_cm = float(np.hypot(every[:, 0], every[:, 1]).max())
    y_node = node_height(geometry)
    rachis_amplitude = min(tip_height(geometry) / max(tip_cm, 1e-6), 1.0)
    shape.sway_radius_cm = max(shape.sway_radius_cm, 1e-6)
    shape.loose_reach_cm = geometry.loose_reach_cm
    reach = max(reach_cm, 1e-6)
    rng = np.random.default_rng([seed & 0xFFFFFFFF, 0xBA4B5])
    for prim, lock, mask in zip(prims, locks, geometry.masks, strict=True):
        p = prim.points
        # The rachis: a half sine between the base and the node, nothing above it.
        xi = p[:, 1] / y_node
        rachis = np.where((xi > 0) & (xi < 1), np.sin(np.pi * np.clip(xi, 0, 1)), 0.0)
        rachis *= rachis_amplitude
        # The barbs: in the vane's plane, perpendicular to the barb, the +x way round.
        tangent = prim.tangent
        if tangent is None and prim.curves is not None:
            tangent = _curve_tangents(p, prim.curves)
        normal = np.zeros_like(p)
        normal[:, 0] = 1.0
        if tangent is not None:
            t = tangent[:, :2]
            length = np.linalg.norm(t, axis=1)
            ok = length > 1e-9
            n = np.stack([-t[:, 1], t[:, 0]], axis=1)
            n[ok] /= length[ok, None]
            n[n[:, 0] < 0] *= -1.0
            normal[ok, :2] = n[ok]
        s = np.clip(np.abs(p[:, 0]) / reach, 0.0, 1.0)
        barb = cantilever_mode(s) * (1.0 - lock)
        lag = 0.5 * np.pi * s  # up to a quarter period behind the rachis at the longest tip
        if prim.curves is not None:  # each barb its own phase offset
            offsets = rng.uniform(-BARB_PHASE_SPREAD, BARB_PHASE_SPREAD, len(prim.curves))
            lag = lag + np.repeat(offsets, prim.curves)
        # displacement = rachis·x̂·sin(θ) + barb·n̂·sin(θ − lag) = sin(θ)·S + cos(θ)·C
        sin = (barb * np.cos(lag))[:, None] * normal
        sin[:, 0] += rachis
        cos = -(barb * np.sin(lag))[:, None] * normal
        moving = np.flatnonzero(np.abs(sin).sum(axis=1) + np.abs(cos).sum(axis=1) > 1e-7)
        if len(moving) == 0:
            continue
        shape.deformed.append(Deformed(prim.path, moving, sin[moving], cos[moving], mask[moving]))
        peak = _peak(sin, cos)[lock < 1.0]
        if len(peak):
            shape.peak = max(shape.peak, float(peak.max()))
    return shape


def _peak(sin: np.ndarray, cos: np.ndarray) -> np.ndarray:
    """Largest ``|sin·a + cos·b|`` over a cycle, per point (the ellipse's semi-major axis)."""
    ss = np.einsum("ij,ij->i", sin, sin)
    cc = np.einsum("ij,ij->i", cos, cos)
    sc = np.einsum("ij,ij->i", sin, cos)
    return np.sqrt(0.5 * (ss + cc) + np.sqrt(0.25 * (ss - cc) ** 2 + sc**2))


def peak_displacement(deformed: Deformed) -> np.ndarray:
    """Largest displacement of each moving point over a cycle (cm, prototype space)."""
    return _peak(deformed.sin, deformed.cos)


def scale_shapes(
    shapes: list[Shape], lengths: dict[str, float], barb_mm: float, eyespot_mm: float
) -> float:
    """Scale every prototype's flex so that the largest flex of a loose point in the train (a
    prototype's peak × its longest instance) is ``barb_mm − eyespot_mm``: with the rigid sway,
    which moves no loose point more than the eyespot (``eyespot_mm``; the tip of a feather
    without one), no loose barb moves more than ``barb_mm``. Returns the factor (cm per unit)."""
    worst = max((s.peak * lengths.get(s.name, 1.0) for s in shapes), default=0.0)
    target = max(barb_mm - eyespot_mm, 0.0) / 10.0
    factor = target / worst if worst > 0 else 0.0
    for shape in shapes:
        for d in shape.deformed:
            d.sin *= factor
            d.cos *= factor
        shape.peak *= factor
    return factor


# ------------------------------------------------------------------------------ authoring
