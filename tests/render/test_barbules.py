"""Issue 33: barbules you can see — the ramus and barbules under every barb, found at render time
from the barb's own coordinate (``materials/barbule_pattern.py``, ``render/barbules.py``).

* The pattern: deterministic (a hash of barb, side and barbule), a fishbone (barbules leave the
  ramus towards the barb's tip on both sides), closed where barbs lie side by side (the
  neighbours' overlapping barbules leave under a tenth of the vane open) but with gaps, and a thin
  ramus; its sizes checked, a bad one named.
* The twist's share of the crescent: the spreads add as Gaussians, so the barbules' average is
  the smooth BSDF's.
* Tessellation: curves authoring ``primvars:pavonine_barbules`` are three vertices across, wider
  than authored, their edges drooping; other ribbons as before.
* Rendered (``render``): 4 mm close-ups of the vane and of the heart's edge, two seeds, same
  camera: the fine detail both seeds share (``barbule_views.shared_detail``) at least 8× what the
  plain ribbons showed (measured with the same code at commit c6f73bc: 1.35e-4 on the vane,
  0.015 at the heart's edge; 200 px, 16 spp).

    pytest tests/test_barbules.py -s   # prints the figures
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from pavonine.materials import barbule_pattern as bp
from pavonine.materials.arraymath import NUMPY

#: Shared fine detail of the plain ribbons (commit c6f73bc), 200 px, 16 spp (module docstring).
BEFORE = {"vane": 1.35e-4, "heart_edge": 0.015}
CLOSE_RES, CLOSE_SPP = 200, 16


def _pattern(s, a, h=1000.0, barb=3.0, angle=35.0, layout=None):
    s, a = np.broadcast_arrays(np.asarray(s, float), np.asarray(a, float))
    return bp.barbule_pattern(
        s,
        a,
        np.full(s.shape, h),
        np.full(s.shape, barb),
        np.full(s.shape, angle),
        layout or bp.BarbuleLayout(),
        NUMPY,
    )


def test_the_pattern_is_the_same_every_time_and_differs_between_barbs():
    rng = np.random.default_rng(0)
    s, a = rng.uniform(0, 30_000, 5000), rng.uniform(-1000, 1000, 5000)
    first, again = _pattern(s, a), _pattern(s, a)
    assert all(np.array_equal(x, y) for x, y in zip(first, again, strict=True))
    other = _pattern(s, a, barb=4.0)
    assert 0.05 < np.mean(first.present != other.present) < 0.5


@pytest.mark.parametrize("side", [1.0, -1.0])
def test_barbules_leave_the_ramus_towards_the_barb_tip_on_both_sides(side):
    """With barbules narrower than their pitch (so that presence tells them apart), a point on a
    barbule near the ramus and the point 60 µm further along the fishbone's axis (towards the
    tip, away from the ramus) lie on barbules far more often than the point 60 µm along the
    mirror axis (towards the root)."""
    layout = bp.BarbuleLayout(
        barbule_width_um=8.0, barbule_pitch_um=20.0, barbule_taper=0.0, neck_depth=0.0
    )
    rng = np.random.default_rng(1)
    n = 20000
    s = rng.uniform(5000, 30000, n)
    a = side * rng.uniform(100, 300, n)
    start = _pattern(s, a, layout=layout)
    on = start.present & ~start.ramus
    phi = math.radians(35.0)
    step = 60.0
    ahead = _pattern(s + step * math.cos(phi), a + side * step * math.sin(phi), layout=layout)
    mirror = _pattern(s - step * math.cos(phi), a + side * step * math.sin(phi), layout=layout)
    same = np.mean(ahead.present[on])
    crossed = np.mean(mirror.present[on])
    print(f"side {side:+.0f}: along the barbule {same:.2f}, along its mirror {crossed:.2f}")
    assert same > 0.85
    assert crossed < 0.7


def _union_coverage(layout=None, spacing_um=2000.0, n=100_000, angle=35.0):
    """Share of a closed vane (barbs ``spacing_um`` apart, each ribbon ``1 + BARBULE_OVERLAP``
    wider than its authored half spacing) that the barbs' ramus and barbules cover, and the ramus'
    share."""
    rng = np.random.default_rng(2)
    h = 0.5 * spacing_um
    x = rng.uniform(0.0, spacing_um, n)
    s = rng.uniform(10_000, 30_000, n)
    covered, ramus = np.zeros(n, bool), np.zeros(n, bool)
    for k in range(-2, 3):
        a = x - k * spacing_um
        inside = np.abs(a) < h * (1.0 + bp.BARBULE_OVERLAP)
        point = _pattern(s, a, h=h, barb=float(k + 10), angle=angle, layout=layout)
        covered |= inside & point.present
        ramus |= inside & point.ramus
    return covered.mean(), ramus.mean()


@pytest.mark.parametrize("angle", [30.0, 40.0, 145.0])
def test_a_closed_vane_is_covered_with_gaps_between_the_barbules(angle):
    covered, ramus = _union_coverage(angle=angle)
    print(f"angle {angle}: covered {covered:.3f}, ramus {ramus:.3f}")
    assert 0.88 < covered < 0.99
    assert 0.0 < ramus <= bp.RAMUS_MAX_SHARE


def test_the_ramus_tapers_and_stays_a_thin_line():
    h = np.full(3, 1.0e5)  # a wide barb: the ramus' own width, not its cap
    r = bp.ramus_half_width(np.array([0.0, 20_000.0, 200_000.0]), h, bp.BarbuleLayout(), NUMPY)
    assert r[0] == pytest.approx(bp.RAMUS_BASE_UM) and r[0] > r[1] > r[2] >= bp.RAMUS_TIP_UM
    narrow = bp.ramus_half_width(np.array([0.0]), np.array([100.0]), bp.BarbuleLayout(), NUMPY)
    assert narrow[0] == pytest.approx(bp.RAMUS_MAX_SHARE * 100.0)


def test_the_two_sides_of_a_barb_twist_opposite_ways_with_the_twists_spread_kept():
    """A twist at the root mirrored across the barb (``SIDE_TWIST_SHARE``): the barbules on one
    side tilt on average by ``+√share·σ``, those on the other by ``−√share·σ`` (the lines along
    the barbs a pixel holding many barbules shows); over both sides the tilt angles keep the
    spread ``σ`` (so the average colour stays the smooth BSDF's)."""
    rng = np.random.default_rng(1)
    s = rng.uniform(0, 30_000, 200_000)
    a = rng.uniform(-1000, 1000, 200_000)
    point = _pattern(s, a, barb=rng.integers(0, 400, 200_000).astype(float), angle=0.0)
    on = point.present & ~point.ramus
    # angle 0: the barbule axis along the barb, the twist tilts the normal across it.
    tilt = np.degrees(np.arcsin(point.tilt_across[on]))
    side = point.side[on]
    sigma = bp.TWIST_SIGMA_DEG
    expected = math.sqrt(bp.SIDE_TWIST_SHARE) * sigma
    assert np.mean(tilt[side > 0]) == pytest.approx(expected, rel=0.05)
    assert np.mean(tilt[side < 0]) == pytest.approx(-expected, rel=0.05)
    assert np.sqrt(np.mean(tilt**2)) == pytest.approx(sigma, rel=0.05)


def test_the_twist_takes_its_share_of_the_crescent():
    twist, within = bp.split_crescent(15.0, 12.0)
    assert twist == 12.0 and twist**2 + within**2 == pytest.approx(15.0**2)
    twist, within = bp.split_crescent(5.0, 12.0)  # capped: the crescent keeps some spread
    assert twist == pytest.approx(bp.MAX_TWIST_SHARE * 5.0) and within > 0.0


@pytest.mark.parametrize(
    ("field", "value", "says"),
    [
        ("barbule_width_um", float("nan"), "must be finite"),
        ("barbule_pitch_um", 0.0, "must be positive"),
        ("tip_jitter", 1.5, "must lie in [0, 1]"),
        ("ramus_base_um", "wide", "expected a number"),
        ("twist_sigma_deg", -1.0, "must not be negative"),
    ],
)
def test_a_bad_layout_is_refused_naming_the_field(field, value, says):
    with pytest.raises(ValueError, match=rf"^{field}: .*") as info:
        bp.BarbuleLayout(**{field: value}).validate()
    assert says in str(info.value) and "\n" not in str(info.value)


def _curves(stage, path, barbules: bool):
    from pxr import Sdf, UsdGeom

    curves = UsdGeom.BasisCurves.Define(stage, path)
    curves.CreateTypeAttr("linear")
    curves.CreateCurveVertexCountsAttr([3])
    curves.CreatePointsAttr([(0, 0, 0), (1, 0, 0), (2, 0, 0)])
    curves.CreateNormalsAttr([(0, 0, 1)] * 3)
    curves.SetNormalsInterpolation("vertex")
    curves.CreateWidthsAttr([0.2] * 3)
    curves.SetWidthsInterpolation("vertex")
    api = UsdGeom.PrimvarsAPI(curves)
    api.CreatePrimvar("pavonine_barbId", Sdf.ValueTypeNames.IntArray, "uniform").Set([5])
    if barbules:
        api.CreatePrimvar("pavonine_barbules", Sdf.ValueTypeNames.Float, "constant").Set(0.8)
    return curves.GetPrim()


def test_barbs_with_barbules_are_three_vertices_across_wider_and_drooping(recwarn):
    from pxr import Usd

    from pavonine.render.curves import ribbon_surface
    from pavonine.render.diagnostics import Diagnostics
    from pavonine.render.mesh import BARB_COORDINATE, BARB_HALF_WIDTH

    stage = Usd.Stage.CreateInMemory()
    plain = ribbon_surface(_curves(stage, "/Plain", False), Usd.TimeCode.Default(), Diagnostics())
    barb = ribbon_surface(_curves(stage, "/Barb", True), Usd.TimeCode.Default(), Diagnostics())
    samples = len(plain.topology.points) // 2  # two vertices across a plain ribbon
    assert BARB_HALF_WIDTH not in plain.primvars
    points = barb.topology.points
    assert len(points) == 3 * samples
    wide = 0.1 * (1.0 + 0.8)  # the authored reach
    assert np.ptp(points[:, 1]) == pytest.approx(2 * wide)
    edges = points.reshape(samples, 3, 3)[:, [0, 2]]
    assert edges[..., 2] == pytest.approx(-math.tan(math.radians(bp.DROOP_DEG)) * wide)
    assert barb.primvars[BARB_HALF_WIDTH].values[:, 0] == pytest.approx(0.1)
    across = barb.primvars[BARB_COORDINATE].values[:, 1].reshape(samples, 3)
    assert across[:, 1] == pytest.approx(0.0) and across[:, 0] == pytest.approx(wide)
    assert [str(w.message) for w in recwarn] == []


@pytest.mark.render
def test_a_4mm_close_up_shows_fine_detail_both_seeds_share(tmp_path):
    import barbule_views as views

    from pavonine.render.imageio import write_png

    targets = views.targets()
    figures = {}
    for name, target in targets.items():
        stage = views.close_up(tmp_path, name, target, 0.4, CLOSE_RES)
        images = [views.render(stage, CLOSE_SPP, seed) for seed in (0, 1)]
        write_png(tmp_path / f"{name}.png", np.concatenate(images, 1))
        figures[name] = views.shared_detail(*images)
        print(
            f"{name}: shared fine detail {figures[name]:.3g} = "
            f"{figures[name] / BEFORE[name]:.0f}× the plain ribbons' {BEFORE[name]:.3g}"
        )
    for name, value in figures.items():
        assert value >= 8.0 * BEFORE[name], name
