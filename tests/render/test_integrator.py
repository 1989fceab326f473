"""``pavonine_path`` against Mitsuba's ``volpath`` and a closed form (render/integrator.py)."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest
from pxr import Gf, Sdf, UsdGeom, UsdShade
from test_geometry_images import SIZE, lit_stage

from pavonine.apps.compare.methods import stat_test
from pavonine.render import api, integrator
from pavonine.render.diagnostics import StageWarning

pytestmark = pytest.mark.render
SCENES = Path(__file__).resolve().parents[2] / "assets" / "scenes"
CARD_VIEW = (SIZE, SIZE)  # pixels of card_over_floor's square view, as strips() reads them


def render(stage_path, tracer: str, spp: int = 32, size=(64, 48)):
    """(mean, variance) of a moments render with ``tracer``: ours, or a Mitsuba integrator. Ours
    gets seed 1, Mitsuba's seed 0: both draw their random numbers in the same order, so with one
    seed the two would share their noise and a comparison would not be a two-sample test."""
    original = integrator.path_tracer
    if tracer != "pavonine_path":
        integrator.path_tracer = lambda depth, rr_threshold=0.0, **params: {
            "type": tracer,
            "max_depth": depth,
            **params,
        }
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", StageWarning)
            result = api.render_stage(
                str(stage_path),
                spp=spp,
                resolution=size,
                progress=False,
                moments=True,
                seed=1 if tracer == "pavonine_path" else 0,
            )
    finally:
        integrator.path_tracer = original
    return result.rgb, result.variance


def card_over_floor(path: Path, opacity: float) -> Path:
    """A white floor, a card of ``opacity`` (UsdPreviewSurface, ``presence``) 1 unit above it, an
    orthographic camera looking down and a sun 30° off the vertical (the card's shadow lands
    0.58 units aside, where the camera sees the floor directly)."""
    stage = lit_stage(path, sun_tilt=30.0)
    for name, z, size in (("Floor", 0.0, 2.0), ("Card", 1.0, 0.5)):
        mesh = UsdGeom.Mesh.Define(stage, f"/{name}")
        mesh.CreatePointsAttr(
            [(-size, -size, z), (size, -size, z), (size, size, z), (-size, size, z)]
        )
        mesh.CreateFaceVertexCountsAttr([4])
        mesh.CreateFaceVertexIndicesAttr([0, 1, 2, 3])
        mesh.CreateSubdivisionSchemeAttr("none")
        mesh.CreateDoubleSidedAttr(True)
    material = UsdShade.Material.Define(stage, "/Looks/Card")
    shader = UsdShade.Shader.Define(stage, "/Looks/Card/Surface")
    shader.CreateIdAttr("UsdPreviewSurface")
    shader.CreateInput("diffuseColor", Sdf.ValueTypeNames.Color3f).Set(Gf.Vec3f(0.5, 0.5, 0.5))
    shader.CreateInput("opacity", Sdf.ValueTypeNames.Float).Set(opacity)
    shader.CreateInput("opacityMode", Sdf.ValueTypeNames.Token).Set("presence")
    material.CreateSurfaceOutput().ConnectToSource(shader.ConnectableAPI(), "surface")
    UsdShade.MaterialBindingAPI.Apply(stage.GetPrimAtPath("/Card")).Bind(material)
    stage.Save()
    return path


def strips(image: np.ndarray) -> tuple[float, float]:
    """(in the card's shadow, in full sun): floor strips beside the card's footprint."""
    shadowed, lit = image[8:14, 18:30].mean(), image[34:40, 18:30].mean()
    return float(min(shadowed, lit)), float(max(shadowed, lit))


def test_a_half_present_card_lets_half_the_sun_into_its_shadow(tmp_path):
    """Closed form: a shadow ray through a card of presence 0.5 carries half the sun, so the floor
    in its shadow is half as bright as in full sun (up to light the card's underside sends back
    down). Mitsuba's ``path`` stops shadow rays at the card, which gives 0."""
    stage = card_over_floor(tmp_path / "card.usda", opacity=0.5)
    image, _ = render(stage, "pavonine_path", spp=16, size=CARD_VIEW)
    shadowed, lit = strips(image.mean(axis=2))
    assert lit > 0.3
    assert shadowed / lit == pytest.approx(0.5, abs=0.05)
    opaque_shadows, _ = render(stage, "path", spp=16, size=CARD_VIEW)
    shadowed, lit = strips(opaque_shadows.mean(axis=2))
    assert shadowed / lit < 0.05  # the closed form above tells the two apart


def test_the_statistical_comparison_tells_path_from_volpath(tmp_path):
    """The agreement test below can fail: ``path`` (opaque shadow rays) against ``volpath`` on the
    half-present card fails the same z-test that ``pavonine_path`` passes."""
    stage = card_over_floor(tmp_path / "card.usda", opacity=0.5)
    reference, reference_var = render(stage, "volpath", size=CARD_VIEW)
    opaque, opaque_var = render(stage, "path", size=CARD_VIEW)
    assert not stat_test(opaque, reference, opaque_var, reference_var).passed
    ours, ours_var = render(stage, "pavonine_path", size=CARD_VIEW)
    assert stat_test(ours, reference, ours_var, reference_var).passed


@pytest.mark.parametrize("scene", ["eye_feather_sun", "light_mesh", "light_dome"])
def test_agrees_with_volpath_on_shipped_scenes(scene):
    """Feather BSDF with its alpha map (null surfaces on camera and shadow rays), an emissive mesh
    (MIS between light and BSDF sampling), an environment light: the same image within noise."""
    ours, ours_var = render(SCENES / f"{scene}.usda", "pavonine_path")
    theirs, theirs_var = render(SCENES / f"{scene}.usda", "volpath")
    result = stat_test(ours, theirs, ours_var, theirs_var)
    assert result.passed, result.numbers


def test_scalar_variants_keep_volpath(monkeypatch):
    """A Python integrator is called per sample in a scalar variant: those keep Mitsuba's."""
    import mitsuba as mi

    params = {"max_depth": 8, "rr_depth": 5, "hide_emitters": False}
    monkeypatch.setattr(mi, "variant", lambda: "scalar_spectral")
    assert integrator.path_tracer(8) == {"type": "volpath", **params}
    monkeypatch.setattr(mi, "variant", lambda: "llvm_ad_spectral")
    monkeypatch.setattr(integrator, "register", lambda: None)
    ours = {"type": "pavonine_path", **params, "rr_threshold": integrator.RR_THRESHOLD}
    assert integrator.path_tracer(8) == ours


def test_the_scene_is_built_in_order_so_kernels_repeat(monkeypatch):
    """Registry ids are literals in the traced kernel; built on Mitsuba's thread pool they follow
    thread timing (the train's sky was emitter 1 or 2 from run to run), built in order they follow
    the scene dict, and a stage renders with the kernel Dr.Jit cached for it."""
    import mitsuba as mi

    calls = []
    load = mi.load_dict

    def recording(description, *args, **kwargs):
        if isinstance(description, dict) and description.get("type") == "scene":
            calls.append(kwargs.get("parallel", True))
        return load(description, *args, **kwargs)

    monkeypatch.setattr(mi, "load_dict", recording)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", StageWarning)
        api.render_stage(str(SCENES / "light_dome.usda"), spp=1, resolution=(8, 6), progress=False)
    assert calls == [False]


def furnace(albedo: float, seed: int, max_depth: int = -1, rr_threshold: float = 0.1):
    """Mean radiance seen from inside a closed sphere that emits 1 everywhere and reflects
    diffusely with ``albedo`` (``pavonine_path`` in a Mitsuba scene, 16×16 @ 64 spp)."""
    import mitsuba as mi

    from pavonine.base.backend import select_variant

    select_variant()
    integrator.register()
    scene = mi.load_dict(
        {
            "type": "scene",
            "integrator": {
                "type": integrator.PLUGIN_NAME,
                "max_depth": max_depth,
                "rr_threshold": rr_threshold,
            },
            "sensor": {
                "type": "perspective",
                "fov": 60.0,
                "film": {"type": "hdrfilm", "width": 16, "height": 16, "rfilter": {"type": "box"}},
            },
            "shell": {
                "type": "sphere",
                "flip_normals": True,
                "bsdf": {"type": "diffuse", "reflectance": {"type": "spectrum", "value": albedo}},
                "emitter": {"type": "area", "radiance": {"type": "spectrum", "value": 1.0}},
            },
        }
    )
    return float(np.asarray(mi.render(scene, spp=64, seed=seed))[..., :3].mean())


def test_early_roulette_keeps_the_furnace_closed_form():
    """Closed form: inside a uniformly emitting sphere of albedo ρ the radiance is Le/(1 − ρ) in
    every direction (Le Σ ρ^k). With ρ = 0.3 a path's throughput is 0.09 after two bounces, under
    ``rr_threshold`` 0.1, so from the third vertex on every path plays the early roulette. The
    test tells errors of 0.2 %: paths cut at max_depth 2 (Le(1 + ρ), 9 % low) fail it."""
    emitted = furnace(0.0, seed=0)  # Le in RGB: the sphere's emission alone
    means = np.array([furnace(0.3, seed=seed) for seed in range(8)]) / emitted
    error = means.std(ddof=1) / np.sqrt(len(means))
    assert error < 0.004
    assert abs(means.mean() - 1.0 / (1.0 - 0.3)) < 4.0 * error
    cut = furnace(0.3, seed=9, max_depth=2) / emitted
    assert abs(cut - 1.0 / (1.0 - 0.3)) > 8.0 * error
    assert furnace(0.3, seed=0, rr_threshold=0.0) != furnace(0.3, seed=0)  # the roulette ran


def test_the_path_loop_is_recorded_once(tmp_path, capfd):
    """The loop reads the scene, the integrator, the BSDF context and the pixel but keeps none of
    them in its state: Dr.Jit records the loop body once. With them in the state it recorded the
    body a second time to drop one of their variables, even with ``OptimizeLoops`` off as in
    scenes with instances (here a PointInstancer's quad; in the 192-feather train ~3 s a pass)."""
    import drjit as dr
    from motion_scene import motion_stage

    path = tmp_path / "instanced.usda"
    motion_stage(path, None, "instancer")
    level = dr.log_level()
    dr.set_log_level(dr.LogLevel.Debug)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", StageWarning)
            api.render_stage(str(path), spp=1, resolution=(16, 12), progress=False)
    finally:
        dr.set_log_level(level)
    captured = capfd.readouterr()
    log = captured.out + captured.err  # Dr.Jit logs on standard output
    assert "jit_var_loop(" in log  # the loop's log is read
    assert "re-recording loop" not in log
