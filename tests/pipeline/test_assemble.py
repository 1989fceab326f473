"""``pavonine assemble train``: one PointInstancer, the recipe's counts, valid, rendered, varied."""

from __future__ import annotations

import json
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from pxr import Sdf, Usd, UsdGeom

from pavonine.apps.cli import cli
from pavonine.pipeline.assemble.fan import layout
from pavonine.pipeline.assemble.recipe import parse_train_recipe

REPO = Path(__file__).parents[2]
RECIPE = REPO / "assets" / "recipes" / "peacock_train.toml"
SHIPPED = REPO / "assets" / "assemblies" / "peacock_train" / "peacock_train.usda"


@pytest.fixture(scope="module")
def train(tmp_path_factory) -> tuple[Path, dict]:
    """The shipped recipe assembled into a fresh folder (its components resolved from there)."""
    recipe = tmp_path_factory.mktemp("recipe") / "train.toml"
    text = RECIPE.read_text().replace('"../feathers/', f'"{REPO / "assets" / "feathers"}/')
    recipe.write_text(text)
    out = tmp_path_factory.mktemp("out")
    result = CliRunner().invoke(
        cli, ["assemble", "train", str(recipe), "-o", str(out), "--json", "-"]
    )
    assert result.exit_code == 0, result.output
    return out / "peacock_train" / "peacock_train.usda", json.loads(result.output)


def test_stage_has_one_point_instancer_with_the_recipes_prototypes_and_instances(train):
    root, report = train
    recipe = parse_train_recipe(RECIPE)
    stage = Usd.Stage.Open(str(root))
    instancers = [p for p in stage.Traverse() if p.IsA(UsdGeom.PointInstancer)]
    assert len(instancers) == 1
    instancer = UsdGeom.PointInstancer(instancers[0])
    prototypes = instancer.GetPrototypesRel().GetTargets()
    assert len(prototypes) == len(recipe.components) == 4
    assert sorted(p.name for p in prototypes) == ["blue", "eye", "fishtail", "yellow"]
    count = recipe.feather_count
    assert count >= 150
    assert len(instancer.GetProtoIndicesAttr().Get()) == count == report["instances"]
    for name in ("positions", "orientations", "scales", "ids"):
        assert len(instancer.GetPrim().GetAttribute(name).Get()) == count, name
    for primvar in ("pavonine:gradationOffset", "pavonine:structuralScale"):
        values = UsdGeom.PrimvarsAPI(instancer).GetPrimvar(primvar)
        assert values.GetInterpolation() == UsdGeom.Tokens.vertex
        assert len(values.Get()) == count and np.ptp(np.array(values.Get())) > 0
    for target in prototypes:  # every prototype is a component with its lod variant selected
        proto = stage.GetPrimAtPath(target)
        assert proto.GetVariantSet("lod").GetVariantSelection() == recipe.lod
        assert Usd.ModelAPI(proto).GetKind() == "component"
    assert Usd.ModelAPI(stage.GetDefaultPrim()).GetKind() == "assembly"
    assert report["prototypes"] == {"blue": 14, "eye": 168, "fishtail": 14, "yellow": 24}


def test_the_assembly_validates_and_matches_the_shipped_one(train):
    root, _ = train
    done = subprocess.run(
        [sys.executable, "-m", "pavonine.apps.cli", "validate", str(root), str(SHIPPED)],
        capture_output=True,
        text=True,
    )
    assert done.returncode == 0, done.stdout + done.stderr
    ours, shipped = (Usd.Stage.Open(str(p)) for p in (root, SHIPPED))
    attr = "/peacock_train/Feathers.positions"
    assert np.array_equal(
        np.array(ours.GetAttributeAtPath(attr).Get()),
        np.array(shipped.GetAttributeAtPath(attr).Get()),
    ), "the shipped assembly is out of date: re-run pavonine assemble train"


def test_layout_is_seeded_and_physical():
    recipe = parse_train_recipe(RECIPE)
    a, b = layout(recipe), layout(recipe)
    assert np.array_equal(a.positions, b.positions) and np.array_equal(a.scales, b.scales)
    other = layout(parse_train_recipe(RECIPE).__class__(**{**recipe.__dict__, "seed": 8}))
    assert not np.array_equal(a.gradation_offset, other.gradation_offset)
    assert np.all(np.abs(a.gradation_offset) <= recipe.variation.gradation_offset)
    low, high = recipe.variation.structural_scale
    assert np.all((a.structural_scale >= low) & (a.structural_scale <= high))
    assert np.allclose(np.linalg.norm(a.orientations, axis=1), 1.0)
    # fishtails only at the rows' ends; the curvature jitter scales depth only
    assert (
        np.all(a.scales[:, 0] == a.scales[:, 1]) and np.ptp(a.scales[:, 2] / a.scales[:, 1]) > 0.3
    )


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (lambda t: t.replace("count = 32", "count = -4", 1), "rows.0.count: must be positive"),
        (
            lambda t: t.replace("bend = 3.0", "bend = 0.0", 1),
            "rows.0.bend: must lie in [0.25, 8], got 0",
        ),
        (
            lambda t: t.replace("edge_bend = 5.0", "edge_bend = nan", 1),
            "rows.0.edge_bend: must be finite, got nan",
        ),
        (
            lambda t: t.replace("edge_droop_deg = 2", 'edge_droop_deg = "8"', 1),
            "rows.0.edge_droop_deg:",
        ),
        (
            lambda t: t.replace('component = "blue"', 'component = "green"'),
            "rows.7.component: unknown component 'green'",
        ),
        (lambda t: t.replace("seed = 7", "seed = 7\ncolour = 1"), "colour: unknown key"),
        (
            lambda t: t.replace("gradation_offset = 0.3", "gradation_offset = 0.9"),
            "variation.gradation_offset: must lie in [0, 0.5]",
        ),
        (
            lambda t: t.replace("blue_feather.usd", "nope.usd"),
            "components.blue: no such component asset",
        ),
    ],
)
def test_bad_recipes_give_one_line_errors_and_no_output(tmp_path, edit, message):
    recipe = tmp_path / "bad.toml"
    recipe.write_text(
        edit(RECIPE.read_text()).replace('"../feathers/', f'"{REPO / "assets" / "feathers"}/')
    )
    result = CliRunner().invoke(
        cli, ["assemble", "train", str(recipe), "-o", str(tmp_path / "out")]
    )
    assert result.exit_code == 2
    assert message in result.output and result.output.count("\n") == 1
    assert not (tmp_path / "out").exists()


@pytest.mark.render
def test_the_train_renders_and_its_per_instance_variation_shows(train, tmp_path):
    from pavonine.render.api import render_stage
    from pavonine.render.diagnostics import StageWarning

    root, _ = train
    neutral = tmp_path / "neutral.usda"  # the same train with every per-instance primvar neutral
    layer = Sdf.Layer.CreateNew(str(neutral))
    layer.subLayerPaths.append(str(root))
    layer.Save()
    stage = Usd.Stage.Open(str(neutral))
    stage.SetEditTarget(stage.GetRootLayer())
    primvars = UsdGeom.PrimvarsAPI(stage.GetPrimAtPath("/peacock_train/Feathers"))
    count = len(primvars.GetPrimvar("pavonine:gradationOffset").Get())
    primvars.GetPrimvar("pavonine:gradationOffset").Set([0.0] * count)
    primvars.GetPrimvar("pavonine:structuralScale").Set([1.0] * count)
    stage.Save()

    def render(path, seed=0):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", StageWarning)
            result = render_stage(path, spp=8, resolution=(80, 60), seed=seed, progress=False)
        assert result.metadata["camera"] == "(framing camera)" and not result.warnings
        return result.rgb

    varied, plain = render(root), render(neutral)  # the same seed: the same random numbers
    background = varied[0, 0]
    feather = np.abs(varied - background).sum(axis=2) > 0.02
    assert feather.mean() > 0.3  # the fan fills the framed image
    # Only the per-instance primvars differ, so every difference is theirs: a visible share of
    # the feather pixels changes by more than 5 %.
    change = np.abs(varied - plain).sum(axis=2) / np.maximum(plain.sum(axis=2), 1e-3)
    assert np.mean(change[feather] > 0.05) > 0.1, np.mean(change[feather] > 0.05)


def test_every_instance_has_its_own_glitter_seed():
    """Per-instance glitter seeds (``pavonine:glitterSeed``): distinct, exact as float32, the
    same for the same recipe, drawn outside the jitter stream (positions do not depend on it)."""
    from pavonine.pipeline.assemble.fan import instance_seeds

    recipe = parse_train_recipe(RECIPE)
    seeds = layout(recipe).glitter_seed
    assert len(np.unique(seeds)) == len(seeds) == recipe.feather_count
    assert np.all(seeds < 2**24) and np.array_equal(seeds.astype(np.float32), seeds)
    assert np.array_equal(seeds, instance_seeds(recipe.seed, recipe.feather_count))
    assert not np.array_equal(seeds, instance_seeds(recipe.seed + 1, recipe.feather_count))


def test_the_layout_plot_reads_each_components_height_from_its_extents_hint():
    """The hint's first pair is the default purpose's, empty (+FLT_MAX, -FLT_MAX) when all the
    geometry is render/proxy: the height is the tallest non-empty pair's, the vane's top."""
    from pavonine.pipeline.assemble.train import component_height

    eye = REPO / "assets" / "feathers" / "eye_feather" / "eye_feather.usd"
    stage = Usd.Stage.Open(str(eye))
    vane = UsdGeom.Mesh(next(p for p in stage.Traverse() if p.GetName() == "Vane"))
    top = np.array(vane.GetPointsAttr().Get())[:, 1].max()
    assert component_height(eye) == pytest.approx(top, abs=1e-3)


def test_a_rows_bend_scales_depth_and_its_edge_feathers_droop_outward():
    """``bend`` multiplies the depth scale only; ``edge_bend``/``edge_droop_deg`` touch only the
    edge feathers, turning each further from straight up on its own side."""
    from dataclasses import replace

    recipe = parse_train_recipe(RECIPE)
    row = recipe.rows[0]
    assert row.edge_count == 2 and row.bend == 3.0 and row.edge_droop_deg == 2
    flat = replace(row, bend=1.0, edge_bend=1.0, edge_droop_deg=0.0)
    a = layout(recipe)
    b = layout(replace(recipe, rows=(flat, *recipe.rows[1:])))
    mine = a.row == 0
    edge = np.zeros(row.count, dtype=bool)
    edge[:2] = edge[-2:] = True
    ratio = a.scales[mine, 2] / b.scales[mine, 2]
    assert np.allclose(ratio[~edge], 3.0) and np.allclose(ratio[edge], row.edge_bend)
    assert np.array_equal(a.scales[mine, :2], b.scales[mine, :2])
    turn = np.degrees(
        np.arctan2(a.positions[mine, 0], a.positions[mine, 1])
        - np.arctan2(b.positions[mine, 0], b.positions[mine, 1])
    )
    assert np.allclose(turn[~edge], 0.0, atol=1e-9)
    assert np.allclose(np.abs(turn[edge]), 2.0) and np.all(np.sign(turn[edge]) == [-1, -1, 1, 1])
    assert np.array_equal(a.positions[~mine], b.positions[~mine])
