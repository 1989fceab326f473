"""The barbs' form: the vane's camber, each barb's bow, loose barbs drooping, ragged roots and
tips (``[geometry.form]``; issue 33, "the feather's form").

:func:`pavonine.pipeline.convert.barb_curves.build_barbs` traces every barb *on* the feather's
sheet: a perfect comb of streamlines (root gaps equal to 0.1 %, points within 0.8 % of the
feather's length of one plane). :func:`apply_form` then moves the placed points, in this order
(``s`` the arc length from a barb's root in cm, ``ℓ`` its length, ``x = s / ℓ``, ``n`` the vane
normal, ``w`` the feather's half width in cm):

1. **Root spacing** (``root_jitter``): every barb leaving the side of the rachis is shifted
   along the rachis by ``ε·spacing_cm``, ``ε ~ N(0, root_jitter)`` clipped to ±0.4 (barbs keep
   their order). Barb ridges form one by one in the follicle collar and new ridges are inserted
   where the collar has room, so their spacing is not a comb (Prum & Williamson 2001, J. Exp.
   Zool. 291: 30–57, "Theory of the growth and evolution of feather shape"). The gap CV is
   ``√2·root_jitter``. The default 0.1 is an estimate, not a measured figure.
2. **Barb length** (``length_jitter``): a barb's loose tail (coverage below
   :data:`LOOSE_COVERAGE`, no hooked barbules holding it to its neighbours) is cut short by a
   share ``U(0, length_jitter)`` of the barb's length ``ℓ`` (at most the whole tail): loose barb
   ends are ragged (Dakin et al. 2016, PLoS ONE 11(4): e0152759); interlocked barbs are left
   whole (their ends make the outline). The default 0.1 is an estimate.
3. **Camber** (``camber``, dimensionless): the vane curls away from the rachis across its width,
   ``δ = camber·s²/w`` cm toward ``−n`` (a circular arc of radius ``w/(2·camber)`` to second
   order; at the vane's edge ``s = w`` the offset is ``camber·w``), on top of the sheet's cup.
   The vane of a contour feather is cambered about its rachis (Lucas & Stettenheim 1972, *Avian
   Anatomy: Integument*, USDA Agriculture Handbook 362, ch. 6); the default is an estimate.
4. **Bow** (``bow`` in the vane, ``bow_out`` out of it, dimensionless). In the vane a barb
   curves toward the feather's tip (barbs curve distally, Lucas & Stettenheim 1972) with one
   curvature ``2·bow/w`` per cm: ``δ = bow·s²/w`` cm along the side of the barb facing the tip,
   weighted by how much it does (neighbouring barbs bend alike; a bow in each barb's own length
   would jag a ring's edge where neighbours end apart). Out of the vane toward ``−n`` only its
   loose part bows, ``δ = β·4x(1−x)·Λ(ℓ)`` with ``x = Λ(s)/Λ(ℓ)`` (``Λ`` the loose length
   below), ``β = bow_out·(1 + ½·N(0, 1))`` clipped to ``[0, 2·bow_out]``, one draw per barb:
   barbs whose barbules hook into their neighbours' cannot leave the vane one by one (Dakin et
   al. 2016). Defaults are estimates.
5. **Droop** (``droop_deg``): barbs without hooked barbules hang loose out of the vane (the
   eye's barbs interlock, the lower vane's and the fringe's do not: Dakin et al. 2016). With
   ``λ(s)`` the looseness (1 below :data:`LOOSE_COVERAGE`, 0 above :data:`CLOSED_COVERAGE`,
   linear between; 1 on the lower vane, ocellar class 0) and ``Λ(s) = ∫₀ˢ λ`` the loose length
   (cm), the barb's slope out of the vane grows with it, ``λ·tan(droop_deg)·min(1, Λ/Λ₀)``,
   ``Λ₀ =`` :data:`DROOP_SHARE` ``·w``: ``δ(s) = ∫₀ˢ slope ds`` cm toward ``−n`` (a cantilever
   bending more toward its free tip; where the barbules hook in again, ``λ = 0``, it runs
   parallel to the vane). The default 50° is an estimate.

6. **The fan's lift** (``fan_lift``): camber and bow grow with each barb's own arc length, so
   where the tip's fan (roots at the rachis tip, 5–6 cm long there) meets the rachis' barbs below
   the eye it lies deeper than they do (issue 33, "a seam below the eye"). The whole fan then
   moves toward ``+n`` by ``fan_lift`` times that step, :func:`seam_step_cm` (the median depth
   difference between fan and rachis-barb vertices within :data:`SEAM_NEAR_CM` of each other,
   fan vertices more than :data:`SEAM_FAN_FROM_CM` from their roots), faded in over the first
   :data:`LIFT_RAMP_CM` of each barb so that its root stays on the rachis tip. One lift for every
   fan barb: barbs beside each other stay at one depth (a lift varying across the fan casts
   shadows and moves the rings' colour at the hero view; docs/pipeline.md). 0 (the default)
   leaves the fan where camber puts it.
7. **Clumps** (``clump``, ``clump_size``): the fringe's loose tips gather into clumps
   (:mod:`pavonine.pipeline.convert.barb_clumps`), in the vane, before 3.–5. move the points
   out of it; its draws come after every other, so the rest of the form does not depend on it.

Tangents are then the moved polylines' (central differences), normals the old normals made
orthogonal to them. Every draw comes from ``numpy.random.default_rng(seed)``: the same recipe
always gives the same barbs.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from pavonine.pipeline.convert.barb_clumps import clump, clump_guides
from pavonine.pipeline.convert.barb_polylines import BarbCurves, polyline_tangents
from pavonine.pipeline.maps.canvas import smoothstep

#: Coverage below which a barb is loose (as :data:`pavonine.pipeline.convert.barb_layer.
#: LOOSE_COVERAGE`: free filaments) and above which it is interlocked.
LOOSE_COVERAGE = 0.75
CLOSED_COVERAGE = 0.95
#: Loose length, as a share of the feather's half width, over which a loose barb's slope out
#: of the vane grows to ``tan(droop_deg)``.
DROOP_SHARE = 0.5
#: Largest root shift, in barb spacings (neighbouring barbs keep their order).
MAX_ROOT_SHIFT = 0.4
#: Fan and rachis-barb vertices this close (cm, in the vane's xy plane) meet at the seam.
SEAM_NEAR_CM = 0.4
#: Fan vertices nearer their root than this (cm) are left out of the seam's step: at the rachis
#: tip the fan's roots neighbour the highest rachis barbs' roots, both on the shaft.
SEAM_FAN_FROM_CM = 2.0
#: Arc length (cm) over which a fan barb's lift fades in from its root (smoothstep).
LIFT_RAMP_CM = 0.5


@dataclass(frozen=True)
class FormOptions:
    """The barbs' form (``[geometry.form]``; module docstring for the formulas and sources)."""

    enabled: bool = True  # apply the form (false: the barbs lie on the sheet, a comb)
    camber: float = 0.08  # vane offset at the half width, as a share of the half width
    bow: float = 0.02  # in-vane offset toward the tip at the half width / the half width
    bow_out: float = 0.03  # mean out-of-vane sagitta of a barb / its length
    droop_deg: float = 50.0  # slope of a loose barb's tip out of the vane
    root_jitter: float = 0.1  # std of a root's shift along the rachis / spacing_cm
    length_jitter: float = 0.1  # largest share of a barb's length cut off its loose tail
    clump: float = 0.6  # share of the way a loose fringe tip moves toward its clump's guide
    clump_size: float = 4.0  # mean barbs per clump
    seed: int | None = None  # None: the asset's seed (CRC-32 of its name)
    fan_lift: float = 0.0  # share of the seam's depth step the whole tip fan moves forward


#: Range of every number key of ``[geometry.form]``: key → (low, high), both included.
FORM_RANGES: dict[str, tuple[float, float]] = {
    "camber": (0.0, 0.2),
    "bow": (0.0, 0.2),
    "bow_out": (0.0, 0.2),
    "droop_deg": (0.0, 80.0),
    "root_jitter": (0.0, 0.3),
    "length_jitter": (0.0, 0.9),
    "clump": (0.0, 1.0),
    "clump_size": (1.0, 20.0),
    "fan_lift": (0.0, 1.0),
}


def _normalise(v: np.ndarray) -> np.ndarray:
    return v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), 1e-12)


def arc_lengths(points: np.ndarray, counts: np.ndarray) -> np.ndarray:
    """Arc length (cm) from each barb's root to each of its vertices."""
    seg = np.linalg.norm(np.diff(points, axis=0), axis=1)
    starts = np.cumsum(counts) - counts
    first = np.zeros(len(points), dtype=bool)
    first[starts] = True
    step = np.concatenate([[0.0], np.where(first[1:], 0.0, seg)])
    total = np.cumsum(step)
    barb = np.repeat(np.arange(len(counts)), counts)
    return total - total[starts][barb]


def _per_barb_cumsum(values: np.ndarray, counts: np.ndarray) -> np.ndarray:
    total = np.cumsum(values)
    starts = np.cumsum(counts) - counts
    barb = np.repeat(np.arange(len(counts)), counts)
    return total - total[starts][barb] + values[starts][barb]


def looseness(coverage: np.ndarray, ocellar_class: np.ndarray) -> np.ndarray:
    """Per vertex, 1 where a barb hangs loose, 0 where its barbules hook into its neighbours'."""
    span = CLOSED_COVERAGE - LOOSE_COVERAGE
    loose = np.clip((CLOSED_COVERAGE - coverage) / span, 0.0, 1.0)
    return np.where(ocellar_class == 0, 1.0, loose)


def _trim(curves: BarbCurves, cut: np.ndarray) -> tuple[BarbCurves, np.ndarray]:
    """Each barb cut at arc length ``cut[i]`` (at least its first two vertices kept), and the
    mask of the vertices kept."""
    counts = curves.counts.astype(np.int64)
    s = arc_lengths(curves.points, counts)
    barb = curves.barb_of_vertex()
    starts = np.cumsum(counts) - counts
    index = np.arange(len(s)) - starts[barb]
    inside = (s < cut[barb]) | (index < 2)
    # The first vertex past the cut is kept, moved onto the cut.
    prev_inside = np.concatenate([[True], inside[:-1]]) | (index == 0)
    edge = ~inside & prev_inside
    keep = inside | edge
    points = curves.points.copy()
    at = np.nonzero(edge)[0]
    a, b = points[at - 1], points[at]
    t = (cut[barb[at]] - s[at - 1]) / np.maximum(s[at] - s[at - 1], 1e-12)
    points[at] = a + np.clip(t, 0.0, 1.0)[:, None] * (b - a)
    new_counts = np.bincount(barb[keep], minlength=len(counts)).astype(np.int32)
    per_vertex = {
        name: getattr(curves, name)[keep]
        for name in (
            "normals",
            "widths",
            "feather_uv",
            "tangent",
            "ocellar_class",
            "gradation",
            "melanin",
            "barbule_angle_deg",
            "coverage",
        )
    }
    colour = None if curves.display_color is None else curves.display_color[keep]
    trimmed = replace(
        curves, counts=new_counts, points=points[keep], display_color=colour, **per_vertex
    )
    return trimmed, keep


def apply_form(
    curves: BarbCurves,
    along: np.ndarray,
    rachis_barb: np.ndarray,
    spacing_cm: float,
    half_width_cm: float,
    options: FormOptions,
    seed: int,
    family: np.ndarray | None = None,
    position: np.ndarray | None = None,
) -> BarbCurves:
    """The barbs moved into their form (module docstring). ``along``: per vertex, the unit
    direction up the rachis (toward the feather's tip) in object space; ``rachis_barb``: per
    barb, whether it leaves the side of the rachis (else the tip's fan); lengths in cm.
    ``family`` and ``position`` (per barb) order the barbs for the clumps
    (:func:`pavonine.pipeline.convert.barb_clumps.clump_guides`); without them all barbs are
    one family in their order."""
    if not options.enabled or curves.barb_count == 0:
        return curves
    rng = np.random.default_rng(seed)
    b = curves.barb_count
    shift = np.clip(rng.normal(0.0, 1.0, b) * options.root_jitter, -MAX_ROOT_SHIFT, MAX_ROOT_SHIFT)
    trim_share = rng.uniform(0.0, 1.0, b) * options.length_jitter
    arch = np.clip(1.0 + 0.5 * rng.normal(0.0, 1.0, b), 0.0, 2.0) * options.bow_out
    counts = curves.counts.astype(np.int64)
    barb = curves.barb_of_vertex()
    # 1. Roots along the rachis: the whole barb moves with its root.
    moved = np.where(rachis_barb[barb], shift[barb] * spacing_cm, 0.0)
    curves = replace(curves, points=curves.points + moved[:, None] * along)
    # 2. Ragged loose tails.
    s = arc_lengths(curves.points, counts)
    ends = np.cumsum(counts) - 1
    length = s[ends]
    closed = np.where(curves.coverage >= LOOSE_COVERAGE, s, 0.0)
    last_closed = np.maximum.reduceat(closed, np.cumsum(counts) - counts)
    cut = length - np.minimum(trim_share * length, length - last_closed)
    if options.length_jitter > 0.0:
        curves, keep = _trim(curves, cut)
        along = along[keep]
    counts = curves.counts.astype(np.int64)
    barb = curves.barb_of_vertex()
    points, normal = curves.points.copy(), curves.normals
    s = arc_lengths(points, counts)
    # 3. Camber, 4. out-of-vane bow, 5. droop: all toward -n.
    out = options.camber * s**2 / half_width_cm
    loose = looseness(curves.coverage, curves.ocellar_class)
    step = _segment_share(s, counts)
    loose_len = _per_barb_cumsum(step * loose, counts)
    total_loose = np.maximum(loose_len[np.cumsum(counts) - 1], 1e-9)
    xl = loose_len / total_loose[barb]
    out += arch[barb] * 4.0 * xl * (1.0 - xl) * total_loose[barb]
    slope = math.tan(math.radians(options.droop_deg))
    ramp = loose * np.minimum(1.0, loose_len / (DROOP_SHARE * half_width_cm))
    out += slope * _per_barb_cumsum(step * ramp, counts)
    # Clumps of loose barbs (barb_clumps): drawn after every other draw, so that the rest of
    # the form does not depend on them.
    if family is None or position is None:
        family, position = np.zeros(b, dtype=np.int64), np.arange(b, dtype=np.float64)
    guide = clump_guides(family, position, options.clump_size, rng)
    # The fringe: barbs of the tip's fan whose tips hang loose (not those meeting the rachis'
    # barbs below the eye).
    fringe = ~rachis_barb & (curves.coverage[np.cumsum(counts) - 1] < LOOSE_COVERAGE)
    points = clump(points, s, counts, xl, guide, options.clump, fringe)
    # 4. In-vane bow toward the feather's tip.
    side = _normalise(np.cross(normal, curves.tangent))
    toward_tip = np.sum(side * along, axis=1, keepdims=True) * side
    points += (options.bow * s**2 / half_width_cm)[:, None] * toward_tip
    if options.fan_lift > 0.0:
        out = lift_fan(points, s, out, rachis_barb[barb], options.fan_lift)
    points -= out[:, None] * normal
    return _reframe(replace(curves, points=points), counts)


def seam_step_cm(
    points: np.ndarray, s: np.ndarray, depth: np.ndarray, rachis_vertex: np.ndarray
) -> float:
    """How much deeper (cm, along ``depth``) the fan lies than the rachis' barbs where they
    meet: the median of ``depth[fan] − depth[rachis]`` over the pairs within
    :data:`SEAM_NEAR_CM` in the xy plane, fan vertices at arc length ``s`` above
    :data:`SEAM_FAN_FROM_CM`; 0 where they do not meet."""
    from scipy.spatial import cKDTree

    rachis = np.flatnonzero(rachis_vertex)
    fan = np.flatnonzero(~rachis_vertex & (s > SEAM_FAN_FROM_CM))
    if len(rachis) == 0 or len(fan) == 0:
        return 0.0
    near = cKDTree(points[rachis, :2]).query_ball_point(points[fan, :2], SEAM_NEAR_CM)
    steps = [depth[i] - depth[rachis[js]] for i, js in zip(fan, near, strict=True) if js]
    return float(np.median(np.concatenate(steps))) if steps else 0.0


def lift_fan(
    points: np.ndarray, s: np.ndarray, out: np.ndarray, rachis_vertex: np.ndarray, share: float
) -> np.ndarray:
    """The offsets toward ``−n`` (cm) with every fan vertex moved forward by ``share`` times
    :func:`seam_step_cm`, faded in over the first :data:`LIFT_RAMP_CM` of its barb
    (smoothstep of ``s``): step 6. of the module docstring."""
    lift = share * seam_step_cm(points, s, out, rachis_vertex)
    return out - np.where(rachis_vertex, 0.0, lift * smoothstep(0.0, LIFT_RAMP_CM, s))


def _segment_share(s: np.ndarray, counts: np.ndarray) -> np.ndarray:
    """Per vertex, the arc length of the segment ending there (0 at a root)."""
    step = np.diff(s, prepend=0.0)
    step[np.cumsum(counts) - counts] = 0.0
    return step


def _reframe(curves: BarbCurves, counts: np.ndarray) -> BarbCurves:
    """Tangents of the moved polylines, normals made orthogonal to them."""
    tangent = polyline_tangents(curves.points, counts)
    normal = curves.normals - np.sum(curves.normals * tangent, axis=1, keepdims=True) * tangent
    return replace(curves, tangent=tangent, normals=_normalise(normal))
