"""The display measured from an assembled train's USD: the eyes' lattice, their overlap, each
feather's bend.

Everything here is read back from the written assembly (the PointInstancer's instance
transforms and the prototypes' own meshes), not from the recipe, so it checks what a renderer
sees. Fan space (``pipeline/assemble/fan.py``): centimetres, Y up, the fan facing +Z, the rump at
the origin; a feather's *eye* is the top of its rachis (the shaft ends in the eye's heart,
``rachis_length`` of the eye feather recipe). What is measured, against what it should be
(``docs/pipeline.md``, *The display*):

* **rows and the lattice**: eyes grouped into concentric rows by their distance from the rump in
  the fan's plane (a new row where consecutive sorted distances jump by more than ``gap_cm``);
  per row the count, the angular step ``Δθ`` (median of consecutive angles) and the span
  (first to last eye plus a step). A hexagonal (quincunx) lattice has adjacent rows half a step
  apart along the row and ``√3/2`` of the step along the row apart across it (Singh et al. 2024,
  F1000Research 13: 520: eyes hexagonally packed in concentric rows).
* **eyes on the vanes below**: an eye lies on a feather when, in that feather's own frame, it is
  within the vane's outline (the component's vane mesh, per 1 cm of height) and in front of it.
* **sagitta**: the largest distance of a feather's rachis centreline from the chord between its
  base and tip (cm, world), which a flat feather has 0.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np


@dataclass
class Feathers:
    """An assembly's instances: prototype name, 4×4 transform (row vectors, cm) of each."""

    names: list[str]  # prototype of each instance
    matrices: np.ndarray  # (N, 4, 4)
    centrelines: dict[str, np.ndarray]  # prototype → (M, 3) rachis centreline, base to tip
    outlines: dict[str, np.ndarray]  # prototype → (K, 3) vane rows: y, half width, mean z

    def world(self, i: int, points: np.ndarray) -> np.ndarray:
        """``points`` (M, 3) of instance ``i``'s prototype in fan space."""
        return np.c_[points, np.ones(len(points))] @ self.matrices[i][:, :3]

    def local(self, i: int, points: np.ndarray) -> np.ndarray:
        """Fan-space ``points`` in instance ``i``'s own frame."""
        return (np.c_[points, np.ones(len(points))] @ np.linalg.inv(self.matrices[i]))[:, :3]


def _mesh_points(prim, name: str) -> np.ndarray:
    from pxr import Usd, UsdGeom

    for p in Usd.PrimRange(prim):
        if p.GetName() == name and p.IsA(UsdGeom.Mesh):
            return np.array(UsdGeom.Mesh(p).GetPointsAttr().Get(), dtype=np.float64)
    return np.zeros((0, 3))


def _centreline(rachis: np.ndarray, step_cm: float = 0.5) -> np.ndarray:
    """The rachis tube's centreline: its points' mean per ``step_cm`` of height."""
    bins = np.floor(rachis[:, 1] / step_cm).astype(int)
    return np.array([rachis[bins == b].mean(axis=0) for b in np.unique(bins)])


def _outline(vane: np.ndarray, step_cm: float = 1.0) -> np.ndarray:
    """Per ``step_cm`` of height: the vane's half width (largest |x|) and mean depth."""
    bins = np.floor(vane[:, 1] / step_cm).astype(int)
    rows = []
    for b in np.unique(bins):
        mine = vane[bins == b]
        rows.append(((b + 0.5) * step_cm, np.abs(mine[:, 0]).max(), mine[:, 2].mean()))
    return np.array(rows)


def read_feathers(path: str | Path) -> Feathers:
    """The one PointInstancer of the assembly at ``path``, its instances and prototypes."""
    from pxr import Usd, UsdGeom

    stage = Usd.Stage.Open(str(path))
    instancer = next(
        UsdGeom.PointInstancer(p) for p in stage.Traverse() if p.IsA(UsdGeom.PointInstancer)
    )
    targets = instancer.GetPrototypesRel().GetTargets()
    indices = np.array(instancer.GetProtoIndicesAttr().Get())
    matrices = np.array(
        [np.array(m) for m in instancer.ComputeInstanceTransformsAtTime(
            Usd.TimeCode.Default(), Usd.TimeCode.Default())]
    )  # fmt: skip
    centrelines, outlines = {}, {}
    for target in targets:
        prim = stage.GetPrimAtPath(target)
        centrelines[target.name] = _centreline(_mesh_points(prim, "Rachis"))
        outlines[target.name] = _outline(_mesh_points(prim, "Vane"))
    return Feathers([targets[i].name for i in indices], matrices, centrelines, outlines)


def sagittas(feathers: Feathers) -> np.ndarray:
    """Each instance's sagitta (cm): its rachis centreline's largest distance from its chord."""
    out = np.zeros(len(feathers.names))
    for i, name in enumerate(feathers.names):
        line = feathers.world(i, feathers.centrelines[name])
        chord = line[-1] - line[0]
        chord /= np.linalg.norm(chord)
        offsets = line - line[0]
        out[i] = np.linalg.norm(offsets - np.outer(offsets @ chord, chord), axis=1).max()
    return out


def eye_centres(feathers: Feathers, component: str = "eye") -> tuple[np.ndarray, np.ndarray]:
    """(indices, (E, 3) fan-space heart) of the ``component`` instances: their rachis tips."""
    index = np.array([i for i, n in enumerate(feathers.names) if n == component])
    tips = np.array([feathers.world(i, feathers.centrelines[component][-1:])[0] for i in index])
    return index, tips


@dataclass
class EyeRow:
    """One concentric row of eyes, as measured."""

    members: np.ndarray  # instance indices, by angle
    radius_cm: float  # mean distance of its eyes from the rump, in the fan's plane
    step_deg: float  # median angle between neighbouring eyes
    span_deg: float  # first to last eye, plus one step
    angles_deg: np.ndarray  # each eye's angle from straight up (positive to the right)


def eye_rows(feathers: Feathers, gap_cm: float = 2.5) -> list[EyeRow]:
    """The eyes in concentric rows, outermost first (module docstring)."""
    index, tips = eye_centres(feathers)
    radius = np.hypot(tips[:, 0], tips[:, 1])
    angle = np.degrees(np.arctan2(tips[:, 0], tips[:, 1]))
    order = np.argsort(-radius)
    breaks = np.flatnonzero(-np.diff(radius[order]) > gap_cm) + 1
    rows = []
    for group in np.split(order, breaks):
        group = group[np.argsort(angle[group])]
        step = float(np.median(np.diff(angle[group]))) if len(group) > 1 else 0.0
        span = float(angle[group][-1] - angle[group][0]) + step
        rows.append(EyeRow(index[group], float(radius[group].mean()), step, span, angle[group]))
    return rows


def lattice(rows: list[EyeRow]) -> list[tuple[float, float]]:
    """Per pair of adjacent rows: (radial step / step along the row, stagger in steps [0, ½]).

    A hexagonal lattice gives ``(√3/2, ½)``: the radial step over the mean radius times ``Δθ``,
    and each inner eye's angular offset from its nearest outer eye over ``Δθ``.
    """
    out = []
    for outer, inner in itertools.pairwise(rows):
        step = math.radians((outer.step_deg + inner.step_deg) / 2)
        along = step * (outer.radius_cm + inner.radius_cm) / 2
        offsets = np.abs(inner.angles_deg[:, None] - outer.angles_deg[None, :]).min(axis=1)
        stagger = float(np.median(offsets)) / math.degrees(step)
        out.append(((outer.radius_cm - inner.radius_cm) / along, stagger))
    return out


def lies_on(feathers: Feathers, point: np.ndarray, i: int) -> bool:
    """Whether fan-space ``point`` lies over instance ``i``'s vane, in front of it."""
    x, y, z = feathers.local(i, point[None, :])[0]
    outline = feathers.outlines[feathers.names[i]]
    if not outline[0, 0] - 0.5 <= y <= outline[-1, 0] + 0.5:
        return False
    row = outline[np.abs(outline[:, 0] - y).argmin()]
    return bool(abs(x) <= row[1] and z > row[2])


def eyes_on_vanes(feathers: Feathers, rows: list[EyeRow]) -> list[float]:
    """Per row after the first: the share of its eyes lying on (in front of) the vane of at
    least one feather of the row behind it (the next outer row)."""
    index, tips = eye_centres(feathers)
    where = {i: k for k, i in enumerate(index)}
    shares = []
    for outer, inner in itertools.pairwise(rows):
        on = [
            any(lies_on(feathers, tips[where[e]], o) for o in outer.members) for e in inner.members
        ]
        shares.append(float(np.mean(on)))
    return shares


def side_overlap(feathers: Feathers, row: EyeRow) -> float:
    """Mean overlap of neighbouring vanes across a row at the eyes' height: ``1 − d / w`` with
    ``d`` the distance between neighbouring eyes and ``w`` the (scaled) vane width there."""
    index, tips = eye_centres(feathers)
    where = {i: k for k, i in enumerate(index)}
    points = tips[[where[i] for i in row.members]]
    gaps = np.linalg.norm(np.diff(points, axis=0), axis=1)
    widths = []
    for i in row.members[:-1]:
        outline = feathers.outlines[feathers.names[i]]
        heart = feathers.centrelines[feathers.names[i]][-1]
        half = outline[np.abs(outline[:, 0] - heart[1]).argmin(), 1]
        scale = np.linalg.norm(feathers.matrices[i][0, :3])
        widths.append(2 * half * scale)
    return float(np.mean(1 - gaps / np.array(widths)))
