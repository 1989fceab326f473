"""The rod lattice of one barbule cross-section, as geometry: rods, air channels, cortex, slices.

Both exact-optics methods read the structure from here: the physical mode's transfer matrix
(:mod:`pavonine.materials.stack`, effective-medium slices) and the rigorous reference
(:mod:`pavonine.materials.rcwa`, the actual rod lattice). Lengths in nm; depth ``z`` grows into
the barbule from its surface (``z = 0``).

Geometry (Zi et al. 2003, PNAS 100:12576; Freyer & Stavenga 2020, Faraday Discuss. 223:49):

* a keratin **cortex** of thickness ``c`` on top; the first rod layer's tops touch ``z = c``;
* ``N`` **layers** of melanin rods (radius ``r``) at depths ``z_j = c + r + j d`` (interval ``d``),
  horizontal rod spacing ``L`` within a layer (``L = 2r``: touching rods, the cell of the paper's
  Eq. 1, ``f = π r / (2 d)``);
* **staggered** layers (each shifted by ``L/2``, the centred-rectangular packing the paper's
  Table 1 needs: class 5 has ``d < 2r``) or **rectangular** (rods straight above each other,
  Freyer & Stavenga's lattice);
* optional **air channels** of diameter ``D_a``: in a rectangular lattice at the centre of each
  cell between two layers, in a staggered lattice midway between neighbouring rods of a layer.

Rods (and channels) may not overlap: a staggered lattice needs ``√((L/2)² + d²) ≥ 2r``, which for
touching rods is ``d ≥ √3 r``; a rectangular one ``d ≥ 2r``; always ``L ≥ 2r``.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

LATTICES = ("staggered", "rectangular")
ROD, AIR = "rod", "air"


class GeometryError(ValueError):
    """Rods or channels that overlap; ``field`` names the offending quantity (``radius``, …)."""

    def __init__(self, field: str, message: str):
        super().__init__(f"{field}: {message}")
        self.field = field
        self.reason = message


@dataclass(frozen=True)
class Segment:
    """One chord of a slice: material ``kind`` from ``centre − half_width`` to ``centre + half_width``."""

    kind: str
    centre: float
    half_width: float


@dataclass(frozen=True)
class Slice:
    """A horizontal slab of the structure: thickness (nm) and the chords across one period ``L``."""

    thickness: float
    segments: tuple[Segment, ...]

    def fractions(self, period: float) -> tuple[float, float]:
        """Shares of the period filled with melanin and with air (the rest is matrix)."""
        rod = sum(2.0 * s.half_width for s in self.segments if s.kind == ROD) / period
        air = sum(2.0 * s.half_width for s in self.segments if s.kind == AIR) / period
        return rod, air


@dataclass(frozen=True)
class RodLattice:
    """A stack of ``count`` rod layers (lengths in nm); ``spacing = 0`` means touching rods (2r)."""

    interval: float
    radius: float
    count: int
    spacing: float = 0.0
    lattice: str = "staggered"
    channel: float = 0.0  # air-channel diameter
    cortex: float = 0.0

    @property
    def period(self) -> float:
        """Horizontal period ``L`` of one layer (nm)."""
        return self.spacing if self.spacing > 0.0 else 2.0 * self.radius

    @property
    def shift(self) -> float:
        """Horizontal shift of each layer against the one above (nm)."""
        return 0.5 * self.period if self.lattice == "staggered" else 0.0

    def check(self) -> RodLattice:
        """Raise :class:`GeometryError` where rods or channels would overlap; return ``self``."""
        r, d, big_l = self.radius, self.interval, self.period
        if self.lattice not in LATTICES:
            raise GeometryError("lattice", f"must be one of {LATTICES}, got {self.lattice!r}")
        tol = 1.0 + 1e-6
        if 2.0 * r > big_l * tol:
            raise GeometryError(
                "spacing", f"rods overlap in a layer: 2r = {2 * r:.4g} nm > L = {big_l:.4g} nm"
            )
        if self.count > 1:
            gap = math.hypot(self.shift, d)
            if 2.0 * r > gap * tol:
                need = (
                    f"d >= sqrt(3)*r = {math.sqrt(3.0) * r:.4g} nm"
                    if self.lattice == "staggered" and self.spacing <= 0.0
                    else f"neighbour distance {gap:.4g} nm >= 2r"
                )
                raise GeometryError(
                    "radius",
                    f"rods of neighbouring {self.lattice} layers overlap: d = {d:.4g} nm, "
                    f"r = {r:.4g} nm (needs {need})",
                )
        if self.channel > 0.0:
            reach = r + 0.5 * self.channel
            for dx, dz in self._channel_neighbours():
                if math.hypot(dx, dz) * tol < reach:
                    raise GeometryError(
                        "channel", f"air channels of {self.channel:.4g} nm overlap the rods"
                    )
        if self.cortex < 0.0:
            raise GeometryError("cortex", f"must not be negative, got {self.cortex:.4g} nm")
        return self

    def _channel_neighbours(self) -> list[tuple[float, float]]:
        """Offsets (dx, dz) from a channel centre to the nearest rod centres."""
        big_l, d = self.period, self.interval
        if self.lattice == "rectangular":
            return [(0.5 * big_l, 0.5 * d)]
        return [(0.5 * big_l, 0.0), (0.0, d)]

    def rods(self) -> list[tuple[float, float]]:
        """``(x, z)`` of one rod per layer (x within [0, L))."""
        r, d = self.radius, self.interval
        return [
            ((j * self.shift) % self.period, self.cortex + r + j * d) for j in range(self.count)
        ]

    def channels(self) -> list[tuple[float, float]]:
        """``(x, z)`` of one air channel per channel row (none when ``channel = 0``)."""
        if self.channel <= 0.0:
            return []
        half = 0.5 * self.period
        if self.lattice == "rectangular":
            return [(half, z + 0.5 * self.interval) for _, z in self.rods()[:-1]]
        return [((x + half) % self.period, z) for x, z in self.rods()]

    @property
    def depth(self) -> float:
        """Depth of the bottom of the last rod layer (nm)."""
        return self.cortex + 2.0 * self.radius + (self.count - 1) * self.interval

    def slices_between(self, top: float, bottom: float, per_diameter: int = 16) -> list[Slice]:
        """Depths ``top``…``bottom`` cut into horizontal slabs, about ``per_diameter`` per rod.

        Each chord's half-width is chosen so that the slab holds exactly the disc area between its
        faces (area-preserving staircase).
        """
        n = max(1, math.ceil((bottom - top) / (2.0 * self.radius) * per_diameter))
        edges = [top + (bottom - top) * k / n for k in range(n + 1)]
        shapes = [(ROD, x, z, self.radius) for x, z in self.rods()]
        shapes += [(AIR, x, z, 0.5 * self.channel) for x, z in self.channels()]
        out = []
        for z0, z1 in itertools.pairwise(edges):
            segments = []
            for kind, x, zc, radius in shapes:
                area = _disc_band_area(radius, z0 - zc, z1 - zc)
                if area > 0.0:
                    segments.append(Segment(kind, x, 0.5 * area / (z1 - z0)))
            out.append(Slice(z1 - z0, tuple(segments)))
        return out

    def cells(self, per_diameter: int = 16) -> Cells:
        """The layers below the cortex as a top cell, repeated bulk cells and a bottom cell.

        Cell ``j`` spans ``z_j ± d/2`` (clipped to the stack): every bulk cell (``0 < j < N−1``)
        holds the same slices up to the layer shift, so exact solvers can raise one cell pair to
        a power instead of walking all ``N`` layers.
        """
        z = [zc for _, zc in self.rods()]
        half = 0.5 * self.interval
        if self.count == 1:
            return Cells(self.slices_between(self.cortex, self.depth, per_diameter), (), 0, [])
        top = self.slices_between(self.cortex, z[0] + half, per_diameter)
        bottom = self.slices_between(z[-1] - half, self.depth, per_diameter)
        bulk: tuple[list[Slice], ...] = ()
        if self.count > 2:
            first = self.slices_between(z[1] - half, z[1] + half, per_diameter)
            bulk = (first, [_shifted(s, self.shift, self.period) for s in first])
        return Cells(top, bulk, self.count - 2, bottom)


@dataclass(frozen=True)
class Cells:
    """``top`` slices, the bulk cell (and its shifted twin), how many bulk cells, ``bottom`` slices."""

    top: list[Slice]
    bulk: tuple[list[Slice], ...]
    n_bulk: int
    bottom: list[Slice]


def _shifted(piece: Slice, shift: float, period: float) -> Slice:
    segments = tuple(
        Segment(s.kind, (s.centre + shift) % period, s.half_width) for s in piece.segments
    )
    return Slice(piece.thickness, segments)


def _disc_band_area(radius: float, lo: float, hi: float) -> float:
    """Area of a disc (centre 0) between the horizontal lines ``z = lo`` and ``z = hi``."""

    def primitive(t: float) -> float:  # ∫ 2√(r² − z²) dz from 0 to t
        t = min(max(t, -radius), radius)
        return t * math.sqrt(max(radius * radius - t * t, 0.0)) + radius * radius * math.asin(
            t / radius
        )

    return max(primitive(hi) - primitive(lo), 0.0)
