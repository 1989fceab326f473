"""Every barb of the feather as a ribbon: streamlines of the maps' barb direction, from the
rachis to the silhouette, with the maps sampled along them.

**Layout.** Barbs leave the rachis on both sides every ``spacing_cm`` along it (the recipe's
``[geometry.barbs] spacing_cm``, *along the rachis, per side*), from the base of the vane up to
the rachis tip; ``tip_barbs`` barbs per full turn radiate from the tip (paper §3.3.4: until the
edges of the eyespot the barbs leave the shaft at a slight angle; at the centre of the eyespot,
the apex of the shaft, they are arranged radially; ``tip_barbs = 0``: a feather without an eye,
whose barbs all leave the rachis, has no fan and no radial zone). The maps say where: the
*radial zone* (:func:`radial_zone`) is where the direction field of :mod:`pavonine.pipeline.convert.barbs`
(measured from the displacement map's streaks) agrees with the ray from the tip. A rachis barb
follows the field by midpoint (RK2) steps of ``segment_cm``, its axis' sign kept continuous,
and ends where it enters the radial zone; a tip barb runs straight out (the field is radial
there to within its ±15° of measurement noise, and streamlines of that noise would bunch) and
ends where it leaves the zone; the two kinds meet along the zone's edge, each running one barb
spacing past it (their square ends would leave gaps).
Every barb ends where the alpha map's coverage falls to :data:`END_COVERAGE` (the silhouette:
its last vertex placed on that level between its last two samples), or on leaving the maps or
crossing the rachis. Rachis barbs seeded inside the zone, or whose measured direction leaves the
rachis at less than :data:`MIN_RACHIS_ANGLE_DEG`, are left to the tip's barbs. All barbs are
traced at once (NumPy arrays over barbs).

**Widths.** A ribbon spans the barb with its barbules: where the vane is closed (alpha 1) the
barbules of neighbouring barbs meet, so the width is the local distance between neighbouring
barbs (measured per vertex, perpendicular to the barb, to the nearest barb on either side,
:func:`neighbour_spacing`) times ``width_share``. Where the alpha map is partial (the loose lower
vane, the fringe) it is multiplied by the coverage ``c`` (the alpha map box-filtered over one
barb spacing): the ribbons cover the share ``c`` of the area, as the sheet's opacity does, and
the background shows between them (they are never cut at a threshold).

**Samples.** At every vertex: the feather coordinate (``pavonine_featherUV``, as on the sheet),
the barb tangent, the ocellar class (of the smooth class field, as on the sheet), gradation,
melanin and barbule angle (bilinear), and the barb's id (uniform).
"""

from __future__ import annotations

import math

import numpy as np
from scipy import ndimage
from scipy.spatial import cKDTree

from pavonine.base.map_files import sample_bilinear, sample_nearest
from pavonine.base.map_filters import gaussian_blur
from pavonine.materials.ocellus import smooth_class_field
from pavonine.pipeline.convert.barb_form import (
    CLOSED_COVERAGE,
    LOOSE_COVERAGE,
    FormOptions,
    apply_form,
)
from pavonine.pipeline.convert.barb_polylines import BarbCurves, polyline_tangents
from pavonine.pipeline.convert.barbs import sample_direction
from pavonine.pipeline.convert.rachis import RachisSpec, rachis_radius
from pavonine.pipeline.convert.recipe import BarbOptions
from pavonine.pipeline.convert.surface import FeatherFrame, normalise
from pavonine.pipeline.maps.paint import angle_degrees, ocellar_class

#: Alpha coverage at which a barb ends (the silhouette).
END_COVERAGE = 0.02
#: Smallest angle (degrees) at which a barb from the side of the rachis may leave it; steeper
#: directions belong to the barbs radiating from the rachis tip.
MIN_RACHIS_ANGLE_DEG = 8.0
#: Agreement ``|cos|`` of the measured barb direction with the ray from the rachis tip above
#: which the barbs radiate from the tip (within about 30°).
RADIAL_AGREEMENT = 0.85
#: Radius around the rachis tip, in barb spacings, where the measured direction is a blur of
#: every direction: the radial zone is the part connected to this disc, and a tip barb crosses
#: it before the zone's edge can end it.
TIP_SPACINGS = 4.0
#: Neighbours searched per vertex when measuring the spacing between barbs.
NEIGHBOURS = 12
#: Widest ribbon, as a multiple of ``spacing_cm`` (an isolated barb at the vane's edge).
MAX_WIDTH_SPACINGS = 2.0


def coverage_map(alpha: np.ndarray, spacing_texels: float) -> np.ndarray:
    """The alpha map box-filtered over one barb spacing: the share of a barb's strip the vane
    covers."""
    size = max(1, round(spacing_texels))
    return ndimage.uniform_filter(np.asarray(alpha, dtype=np.float32), size, mode="constant")


def seeds(
    frame: FeatherFrame, rachis: RachisSpec, layout: BarbOptions
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Start points (feather square units ``x = (u − ½)·aspect, y = v``), the outward direction
    there and whether each is a rachis barb (True) or one of the tip's fan (False)."""
    step = layout.spacing_cm / frame.length
    along = np.arange(0.5 * step, rachis.top, step)
    along = along[along >= 0.0]
    offset = rachis_radius(rachis, frame, along) / frame.length
    sides = np.concatenate([-np.ones_like(along), np.ones_like(along)])
    start = np.column_stack([sides * np.tile(offset, 2), np.tile(along, 2)])
    outward = np.column_stack([sides, np.zeros_like(sides)])
    if layout.tip_barbs == 0:  # no fan: every barb leaves the rachis
        theta = np.zeros(0)
    else:
        turn = 2.0 * math.pi / layout.tip_barbs
        count = int((math.pi - 0.5 * turn) // turn)
        theta = turn * np.arange(-count, count + 1)
    tip_gap = rachis.tip_radius_cm / frame.length
    fan_dir = np.column_stack([np.sin(theta), np.cos(theta)])
    fan = np.array([0.0, rachis.top]) + tip_gap * fan_dir
    points = np.concatenate([start, fan])
    directions = np.concatenate([outward, fan_dir])
    kinds = np.concatenate([np.ones(len(start), bool), np.zeros(len(fan), bool)])
    return points, directions, kinds


def _to_uv(xy: np.ndarray, aspect: float) -> np.ndarray:
    return np.column_stack([xy[:, 0] / aspect + 0.5, xy[:, 1]])


def radial_zone(
    field: np.ndarray, tip: np.ndarray, aspect: float, sigma_texels: float
) -> np.ndarray:
    """Where the barbs radiate from the rachis tip (the eye): the texels whose measured barb
    direction lies within :data:`RADIAL_AGREEMENT` of the ray from the tip (``|cos|`` smoothed
    over ``sigma_texels``), connected to the tip."""
    h, w = field.shape[:2]
    rows, cols = np.mgrid[0:h, 0:w]
    ray = np.stack(
        [((cols + 0.5) / w - 0.5) * aspect - tip[0], 1.0 - (rows + 0.5) / h - tip[1]], -1
    )
    ray_length = ray.copy()
    ray /= np.maximum(np.linalg.norm(ray, axis=-1, keepdims=True), 1e-12)
    agreement = ndimage.gaussian_filter(np.abs(np.sum(field * ray, axis=-1)), sigma_texels)
    zone = agreement > RADIAL_AGREEMENT
    labels, _ = ndimage.label(zone)
    # The measured direction is a blur at the tip itself: the zone is the piece around it.
    near = np.hypot(ray_length[..., 0], ray_length[..., 1]) < TIP_SPACINGS * sigma_texels / h
    pieces = np.unique(labels[near & zone])
    return np.isin(labels, pieces[pieces > 0])


def trace(
    field: np.ndarray,
    coverage: np.ndarray,
    zone: np.ndarray,
    start: np.ndarray,
    outward: np.ndarray,
    rachis_barb: np.ndarray,
    tip: np.ndarray,
    aspect: float,
    step: float,
    max_steps: int,
    tip_radius: float = 0.0,
    overlap_steps: int = 1,
) -> tuple[np.ndarray, np.ndarray]:
    """Barbs from every start point at once (feather square units): returns ``(points,
    counts)``, points ``(b, max_steps + 1, 2)`` valid up to ``counts``.

    A rachis barb follows the streamlines of ``field`` by midpoint steps of length ``step``, the
    axis' sign kept along it (the previous step is the ``outward`` of the next lookup); a barb
    of the tip's fan runs straight out from ``tip``. A barb stops on the level
    :data:`END_COVERAGE` of ``coverage`` (its last point interpolated onto it), on leaving the
    maps, where a rachis barb enters the radial ``zone`` or reaches the centre line, and where a
    fan barb beyond ``tip_radius`` of the tip is outside it: the two kinds meet along its edge,
    each running ``overlap_steps`` steps past it so that their square ends leave no gap.
    """
    b = len(start)
    path = np.full((b, max_steps + 1, 2), np.nan)
    path[:, 0] = start
    level = sample_bilinear(coverage, _to_uv(start, aspect)) - END_COVERAGE
    counts = np.where(level > 0.0, 1, 0)
    alive = level > 0.0
    heading = np.where(
        rachis_barb[:, None], sample_direction(field, _to_uv(start, aspect), outward), outward
    )
    side = np.sign(start[:, 0])
    x, last_level = start.copy(), level.copy()
    half_x = 0.5 * aspect
    zone_f = zone.astype(np.float32)
    past = np.zeros(b, dtype=np.int64)
    for i in range(1, max_steps + 1):
        if not alive.any():
            break
        idx = np.nonzero(alive)[0]
        p, on_rachis = x[idx], rachis_barb[idx, None]
        d1 = np.where(
            on_rachis, sample_direction(field, _to_uv(p, aspect), heading[idx]), heading[idx]
        )
        mid = p + 0.5 * step * d1
        d2 = np.where(on_rachis, sample_direction(field, _to_uv(mid, aspect), d1), d1)
        q = p + step * d2
        inside = (np.abs(q[:, 0]) <= half_x) & (q[:, 1] >= 0.0) & (q[:, 1] <= 1.0)
        in_zone = sample_nearest(zone_f, _to_uv(q, aspect)) > 0.5
        centre = on_rachis[:, 0] & (q[:, 0] * side[idx] <= 0.0)
        # Where the two kinds meet, each ends one step into the other's side: no gap between.
        beyond = np.hypot(q[:, 0] - tip[0], q[:, 1] - tip[1]) > tip_radius
        met = np.where(on_rachis[:, 0], in_zone, beyond & ~in_zone)
        past[idx] = np.where(met, past[idx] + 1, 0)
        met = past[idx] >= overlap_steps
        crossed = centre | met
        new_level = np.where(inside, sample_bilinear(coverage, _to_uv(q, aspect)), 0.0)
        new_level = new_level - END_COVERAGE
        ends = (new_level <= 0.0) | crossed
        # A barb leaving the vane ends on the coverage level between its last two points.
        t = np.clip(last_level[idx] / np.maximum(last_level[idx] - new_level, 1e-12), 0.0, 1.0)
        t = np.where(new_level <= 0.0, t, 1.0)
        t = np.where(centre | ~inside, 0.0, t)
        end_point = p + (t * step)[:, None] * d2
        ok = ~ends | (t > 1e-3)
        path[idx[ok], i] = np.where(ends[ok, None], end_point[ok], q[ok])
        counts[idx[ok]] = i + 1
        x[idx] = q
        heading[idx] = d2
        last_level[idx] = new_level
        alive[idx[ends]] = False
    return path, counts


def neighbour_spacing(
    xy: np.ndarray,
    tangent: np.ndarray,
    barb: np.ndarray,
    limit: float,
    family: np.ndarray | None = None,
) -> np.ndarray:
    """Per vertex, the distance to the neighbouring barbs perpendicular to its own: the mean
    of the nearest on its left and on its right (either alone at the vane's edge), at most
    ``limit``. ``xy``: vertices (square feather units), ``tangent``: unit 2-D barb directions,
    ``barb``: each vertex's barb index; ``family`` (optional, per vertex): only neighbours of the
    same family count (rachis and tip barbs overlap by a step where they meet, and must not
    narrow each other there)."""
    tree = cKDTree(xy)
    k = min(NEIGHBOURS, len(xy))
    dist, near = tree.query(xy, k=k, distance_upper_bound=limit)
    valid = np.isfinite(dist) & (near < len(xy))
    near = np.where(valid, near, 0)
    other = valid & (barb[near] != barb[:, None])
    if family is not None:
        other &= family[near] == family[:, None]
    side = np.column_stack([-tangent[:, 1], tangent[:, 0]])
    offset = np.einsum("nkc,nc->nk", xy[near] - xy[:, None, :], side)
    left = np.where(other & (offset > 1e-9), offset, np.inf).min(axis=1)
    right = np.where(other & (offset < -1e-9), -offset, np.inf).min(axis=1)
    both = np.isfinite(left) & np.isfinite(right)
    one = np.where(np.isfinite(left), left, right)
    spacing = np.where(both, 0.5 * (left + right), one)
    return np.minimum(np.where(np.isfinite(spacing), spacing, limit), limit)


def build_barbs(
    maps: dict[str, np.ndarray],
    field: np.ndarray,
    frame: FeatherFrame,
    rachis: RachisSpec,
    layout: BarbOptions,
    displacement_cm: float = 0.0,
    form: FormOptions | None = None,
    seed: int = 0,
) -> BarbCurves:
    """Every barb of the feather (module docstring) from its maps and barb direction ``field``
    (:func:`pavonine.pipeline.convert.barbs.barb_direction_field`); with ``form``, moved into
    the feather's form by :func:`pavonine.pipeline.convert.barb_form.apply_form` (draws from
    ``seed``), else lying on the sheet."""
    alpha = maps["alpha"]
    height = alpha.shape[0]
    spacing = layout.spacing_cm / frame.length  # square feather units
    coverage = coverage_map(alpha, spacing * height)
    start, outward, rachis_barb = seeds(frame, rachis, layout)
    tip = np.array([0.0, rachis.top])
    if layout.tip_barbs == 0:
        zone = np.zeros(field.shape[:2], dtype=bool)
    else:
        zone = radial_zone(field, tip, frame.aspect, spacing * field.shape[0])
    uv0 = _to_uv(start, frame.aspect)
    initial = sample_direction(field, uv0, outward)
    steep = np.abs(initial[:, 0]) >= math.sin(math.radians(MIN_RACHIS_ANGLE_DEG))
    outside = sample_nearest(zone.astype(np.float32), uv0) < 0.5
    keep = ~rachis_barb | (steep & outside)
    start, outward, rachis_barb = start[keep], outward[keep], rachis_barb[keep]
    step = layout.segment_cm / frame.length
    max_steps = math.ceil(math.hypot(frame.aspect, 1.0) / step) + 1
    path, counts = trace(
        field,
        coverage,
        zone,
        start,
        outward,
        rachis_barb,
        tip,
        frame.aspect,
        step,
        max_steps,
        TIP_SPACINGS * spacing,
        math.ceil(spacing / step) + 1,
    )
    kept = counts >= 2
    path, counts, rachis_barb = path[kept], counts[kept], rachis_barb[kept]
    family, position = barb_families(path[:, 0], rachis_barb, tip)
    order = np.arange(path.shape[1])[None, :] < counts[:, None]
    xy = path[order]
    xy, counts, klass = split_at_classes(
        xy, counts, smooth_class_field(maps["ocellar"]), frame.aspect
    )
    barb = np.repeat(np.arange(len(counts)), counts)
    tangent2 = polyline_tangents(xy, counts)
    uv = np.clip(_to_uv(xy, frame.aspect), 0.0, 1.0)
    cover = np.clip(sample_bilinear(coverage, uv), 0.0, 1.0)
    local = neighbour_spacing(xy, tangent2, barb, MAX_WIDTH_SPACINGS * spacing, rachis_barb[barb])
    widths = local * frame.length * layout.width_share * cover * filament_share(cover)
    normal = frame.normal(uv)
    smooth = gaussian_blur(maps["displacement"], 0.5 * spacing * height)
    lift = displacement_cm * sample_bilinear(smooth, uv)
    points = frame.position(uv) + lift[:, None] * normal
    dpdu, dpdv = frame.derivatives(uv)
    tangent = dpdu * (tangent2[:, :1] / frame.aspect) + dpdv * tangent2[:, 1:2]
    tangent = normalise(tangent - np.sum(tangent * normal, axis=1, keepdims=True) * normal)
    curves = BarbCurves(
        counts=counts.astype(np.int32),
        points=points,
        normals=normal,
        widths=widths.astype(np.float64),
        feather_uv=uv,
        tangent=tangent,
        ocellar_class=klass,
        gradation=sample_bilinear(maps["gradation"], uv).astype(np.float64),
        melanin=sample_bilinear(maps["melanin"], uv).astype(np.float64),
        barbule_angle_deg=angle_degrees(sample_bilinear(maps["angle"], uv)).astype(np.float64),
        coverage=cover.astype(np.float64),
        barb_id=np.arange(len(counts), dtype=np.int32),
    )
    if form is None:
        return curves
    along = normalise(dpdv)
    half_width = 0.5 * frame.width
    return apply_form(
        curves, along, rachis_barb, layout.spacing_cm, half_width, form, seed, family, position
    )


def barb_families(
    roots: np.ndarray, rachis_barb: np.ndarray, tip: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Per barb, its family (0 left of the rachis, 1 right of it, 2 the tip's fan) and its
    place in it (a rachis barb's root height, a fan barb's angle around the tip), from the
    roots in feather square units: neighbours for the clumps."""
    side = np.where(roots[:, 0] < 0.0, 0, 1)
    family = np.where(rachis_barb, side, 2)
    angle = np.arctan2(roots[:, 0] - tip[0], roots[:, 1] - tip[1])
    return family, np.where(rachis_barb, roots[:, 1], angle)


#: A loose barb's ribbon (coverage below :data:`~pavonine.pipeline.convert.barb_form.
#: LOOSE_COVERAGE`: no hooked barbules hold it to its neighbours, Dakin et al. 2016) as a share of
#: the width its coverage gives: a free filament, so that the background shows between loose barbs
#: in whole pixels where the sheet shows a partial alpha (issue 33: a real eye feather's lower barbs
#: are thin filaments). A parameter, set from the hero view's measure (docs/pipeline.md, *Barbs*).
FILAMENT_SHARE = 0.5


def filament_share(coverage: np.ndarray) -> np.ndarray:
    """Per vertex, the share of its width a barb keeps: 1 where its barbules interlock (coverage
    at least ``CLOSED_COVERAGE``), :data:`FILAMENT_SHARE` where it hangs loose (at most
    ``LOOSE_COVERAGE``), linear between (no step along a barb)."""
    span = CLOSED_COVERAGE - LOOSE_COVERAGE
    closed = np.clip((np.asarray(coverage, dtype=np.float64) - LOOSE_COVERAGE) / span, 0.0, 1.0)
    return FILAMENT_SHARE + (1.0 - FILAMENT_SHARE) * closed


#: Bisection steps placing a ring boundary along a barb segment (to 1/256 of a segment).
BOUNDARY_STEPS = 8
#: Half the gap between the two vertices that straddle a ring boundary, in segments.
BOUNDARY_GAP = 0.01


def split_at_classes(
    xy: np.ndarray, counts: np.ndarray, ocellar: np.ndarray, aspect: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Barb vertices with a pair straddling every ring boundary, and each vertex's class.

    ``ocellar`` is the renderer's smooth class field (:func:`pavonine.materials.ocellus.
    smooth_class_field`: the map's grey under a Gaussian of 3 texels; the bilinear grey of the
    map itself rounds to a contour that still steps with the texels, 2.1 px from a smooth curve
    in a 4 cm close-up at 512 px). A vertex's class is that field's bilinear grey rounded to the
    nearest class level, so ring boundaries are the field's mid-level contours, the sheet's own
    (where the map jumps two classes, the class between shows in a thin band).
    Where two neighbouring vertices of a barb differ, the boundary is found on the segment by
    bisection (the grey crossing the mean of their two levels) and two vertices of their two
    classes are inserted :data:`BOUNDARY_GAP` of a segment either side of it: a renderer
    interpolating the class between vertices switches at the boundary, not half a segment off
    (not on a barb's last segment, which fades out at the silhouette). Returns ``(xy, counts, class)``.
    """
    grey = sample_bilinear(ocellar, _to_uv(xy, aspect))
    klass = ocellar_class(grey)
    ends = np.cumsum(counts) - 1
    last = np.zeros(len(xy), dtype=bool)
    last[ends] = True
    # Not on a barb's last segment: it fades to nothing at the silhouette.
    inner = ~last[:-1] & ~last[1:]
    seg = np.nonzero(inner & (klass[:-1] != klass[1:]))[0]
    if len(seg) == 0:
        return xy, counts, klass
    a, b = xy[seg], xy[seg + 1]
    level = 1.0 - 0.5 * (klass[seg] + klass[seg + 1]) / 5.0
    below = np.sign(grey[seg] - level)
    lo, hi = np.zeros(len(seg)), np.ones(len(seg))
    for _ in range(BOUNDARY_STEPS):
        mid = 0.5 * (lo + hi)
        g = sample_bilinear(ocellar, _to_uv(a + mid[:, None] * (b - a), aspect))
        same = np.sign(g - level) == below
        lo, hi = np.where(same, mid, lo), np.where(same, hi, mid)
    # Kept a gap away from the segment's own ends: no two vertices of a barb coincide.
    t = np.clip(0.5 * (lo + hi), 2.0 * BOUNDARY_GAP, 1.0 - 2.0 * BOUNDARY_GAP)
    before = a + (t - BOUNDARY_GAP)[:, None] * (b - a)
    after = a + (t + BOUNDARY_GAP)[:, None] * (b - a)
    at = np.repeat(seg + 1, 2)
    points = np.stack([before, after], axis=1).reshape(-1, 2)
    classes = np.stack([klass[seg], klass[seg + 1]], axis=1).ravel()
    barb = np.repeat(np.arange(len(counts)), counts)
    added = np.bincount(barb[seg], minlength=len(counts)) * 2
    return np.insert(xy, at, points, axis=0), counts + added, np.insert(klass, at, classes)
