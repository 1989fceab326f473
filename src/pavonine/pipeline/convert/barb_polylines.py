"""A feather's barbs as data: concatenated polylines with their per-vertex attributes
(:class:`BarbCurves`), and the polylines' tangents. Traced by :mod:`.barb_curves`, moved into
their form by :mod:`.barb_form`, written by :mod:`.barb_layer`."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pavonine.pipeline.convert.surface import normalise


@dataclass
class BarbCurves:
    """All barbs of a feather, concatenated: ``counts[i]`` vertices for barb ``i``."""

    counts: np.ndarray  # (b,) vertices per barb
    points: np.ndarray  # (n, 3) cm, object space
    normals: np.ndarray  # (n, 3) the vane normal
    widths: np.ndarray  # (n,) cm
    feather_uv: np.ndarray  # (n, 2)
    tangent: np.ndarray  # (n, 3) unit barb direction (away from the rachis)
    ocellar_class: np.ndarray  # (n,) int
    gradation: np.ndarray  # (n,)
    melanin: np.ndarray  # (n,) structural share
    barbule_angle_deg: np.ndarray  # (n,) barbule axis to its barb, counter-clockwise
    coverage: np.ndarray  # (n,) alpha coverage at the vertex
    barb_id: np.ndarray  # (b,)
    display_color: np.ndarray | None = None  # (n, 3) linear Rec. 709, baked

    @property
    def barb_count(self) -> int:
        return len(self.counts)

    @property
    def vertex_count(self) -> int:
        return len(self.points)

    def barb_of_vertex(self) -> np.ndarray:
        """The barb index of every vertex."""
        return np.repeat(np.arange(len(self.counts)), self.counts)

    def extent(self) -> np.ndarray:
        half = 0.5 * float(self.widths.max(initial=0.0))
        return np.stack([self.points.min(axis=0) - half, self.points.max(axis=0) + half])


def polyline_tangents(xy: np.ndarray, counts: np.ndarray) -> np.ndarray:
    """Unit tangents of concatenated polylines (central differences, one-sided at the ends)."""
    ends = np.cumsum(counts)
    starts = ends - counts
    index = np.arange(len(xy))
    barb = np.repeat(np.arange(len(counts)), counts)
    ahead = np.minimum(index + 1, ends[barb] - 1)
    behind = np.maximum(index - 1, starts[barb])
    return normalise(xy[ahead] - xy[behind])
