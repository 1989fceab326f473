"""``pavonine assemble train``: a whole peacock train as one USD assembly over one PointInstancer.

Layout of ``OUTDIR/NAME/``::

    NAME.usda          /NAME: Xform, kind = assembly, assetInfo, metersPerUnit 0.01, upAxis Y
                       /NAME/Feathers: PointInstancer; protoIndices, positions, orientations,
                       scales, ids, extent; primvars:pavonine:gradationOffset,
                       primvars:pavonine:structuralScale and primvars:pavonine:glitterSeed
                       (float[], vertex: one per instance)
                       /NAME/Feathers/Prototypes/<component>: Xform referencing the component
                       asset with its ``lod`` variant selected (the recipe's ``lod``)
    NAME_layout.png    the fan seen from the front: every feather's base and tip by prototype,
                       its gradation offset as colour

Component references are relative to the assembly (``./../../feathers/eye_feather/...``), so the
assembly and the components move together. The folder appears atomically (written under a
hidden name beside it, then renamed), as converted assets do.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from pavonine.base.errors import InputError
from pavonine.pipeline.assemble.fan import Fan, layout, prototype_parts
from pavonine.pipeline.assemble.recipe import TrainRecipe, parse_train_recipe
from pavonine.pipeline.convert.asset import staging_folder

METERS_PER_UNIT = 0.01
UP_AXIS = "Y"
INSTANCER = "Feathers"
PRIMVARS = {
    "pavonine:gradationOffset": "gradation_offset",
    "pavonine:structuralScale": "structural_scale",
    "pavonine:glitterSeed": "glitter_seed",
}


@dataclass
class TrainResult:
    """What ``assemble_train`` wrote."""

    root: Path
    layout_png: Path
    counts: dict[str, int]
    extent: np.ndarray  # (2, 3) cm
    rattle: Any = None  # pipeline.assemble.rattle.RattleResult when the recipe has [rattle]

    @property
    def instances(self) -> int:
        return sum(self.counts.values())


def asset_path(target: Path, folder: Path) -> str:
    """``target`` as an asset path relative to ``folder`` (``./``-prefixed), else absolute."""
    try:
        relative = os.path.relpath(target, folder)
    except ValueError:  # another drive
        return target.as_posix()
    return relative if relative.startswith("..") else f"./{relative}"


def write_train_layer(path: Path, recipe: TrainRecipe, fan: Fan, final_folder: Path) -> np.ndarray:
    """Write the assembly layer; returns the instancer's extent (cm).

    Authored on an in-memory stage with absolute references (so the extent can be computed),
    then copied into a detached layer whose references are made relative to ``final_folder``
    (the staging folder it is written into is elsewhere, so it is never composed there).
    """
    from pxr import Sdf, Usd, UsdGeom

    memory = Usd.Stage.CreateInMemory()
    instancer = _author(memory, recipe, fan)
    extent = instancer.ComputeExtentAtTime(Usd.TimeCode.Default(), Usd.TimeCode.Default())
    if extent is None or not np.all(np.isfinite(np.array(extent))) or extent[0][0] > extent[1][0]:
        raise InputError(str(recipe.path), "cannot compute the train's extent (empty components?)")
    instancer.CreateExtentAttr(extent)
    UsdGeom.ModelAPI.Apply(memory.GetDefaultPrim()).SetExtentsHint(extent)
    layer = Sdf.Layer.CreateAnonymous(".usda")
    layer.TransferContent(memory.GetRootLayer())
    for name in fan.prototypes:
        spec = layer.GetPrimAtPath(f"/{recipe.name}/{INSTANCER}/Prototypes/{name}")
        component, _ = prototype_parts(name, recipe.components)
        spec.referenceList.prependedItems = [
            Sdf.Reference(asset_path(recipe.components[component], final_folder))
        ]
    if not layer.Export(str(path)):
        raise OSError(f"{path}: cannot write USD layer")
    return np.array(extent, dtype=np.float64)


def _author(stage, recipe: TrainRecipe, fan: Fan):
    """Author the assembly on ``stage`` (components referenced by absolute path)."""
    from pxr import Gf, Kind, Sdf, Usd, UsdGeom, Vt

    UsdGeom.SetStageMetersPerUnit(stage, METERS_PER_UNIT)
    UsdGeom.SetStageUpAxis(stage, UP_AXIS)
    root = UsdGeom.Xform.Define(stage, f"/{recipe.name}").GetPrim()
    stage.SetDefaultPrim(root)
    model = Usd.ModelAPI(root)
    model.SetKind(Kind.Tokens.assembly)
    model.SetAssetName(recipe.name)
    model.SetAssetVersion(recipe.version)
    model.SetAssetIdentifier(Sdf.AssetPath(f"./{recipe.name}.usda"))
    root.SetDocumentation(
        f"Peacock train: {len(fan)} feathers through one PointInstancer, made by "
        f"'pavonine assemble train' from {recipe.path.name} (seed {recipe.seed})."
    )
    base = f"/{recipe.name}/{INSTANCER}"
    instancer = UsdGeom.PointInstancer.Define(stage, base)
    UsdGeom.Scope.Define(stage, f"{base}/Prototypes")
    targets = []
    for name in fan.prototypes:
        proto = UsdGeom.Xform.Define(stage, f"{base}/Prototypes/{name}").GetPrim()
        component, geometry = prototype_parts(name, recipe.components)
        proto.GetReferences().AddReference(recipe.components[component].as_posix())
        proto.GetVariantSets().AddVariantSet("lod").SetVariantSelection(recipe.lod)
        if geometry != "sheet":
            variants = proto.GetVariantSets().GetVariantSet("geometry")
            if geometry not in variants.GetVariantNames():
                raise InputError(
                    str(recipe.path),
                    f"component {component!r} has no geometry {geometry!r} variant "
                    "(convert it with [geometry.barbs] enabled)",
                )
            variants.SetVariantSelection(geometry)
        targets.append(proto.GetPath())
    instancer.CreatePrototypesRel().SetTargets(targets)
    instancer.CreateProtoIndicesAttr(Vt.IntArray.FromNumpy(fan.proto_indices))
    instancer.CreateIdsAttr(Vt.Int64Array.FromNumpy(np.arange(len(fan), dtype=np.int64)))
    instancer.CreatePositionsAttr(Vt.Vec3fArray.FromNumpy(fan.positions.astype(np.float32)))
    quats = [
        Gf.Quath(float(w), Gf.Vec3h(float(x), float(y), float(z)))
        for w, x, y, z in fan.orientations
    ]
    instancer.CreateOrientationsAttr(Vt.QuathArray(quats))
    instancer.CreateScalesAttr(Vt.Vec3fArray.FromNumpy(fan.scales.astype(np.float32)))
    primvars = UsdGeom.PrimvarsAPI(instancer)
    for primvar, attribute in PRIMVARS.items():
        values = getattr(fan, attribute).astype(np.float32)
        created = primvars.CreatePrimvar(
            primvar, Sdf.ValueTypeNames.FloatArray, UsdGeom.Tokens.vertex
        )
        created.Set(Vt.FloatArray.FromNumpy(values))
    return instancer


def component_height(asset: Path) -> float:
    """Top of a component (its ``extentsHint`` max Y, cm), 30 cm when it has none.

    The hint holds a (min, max) pair per purpose (default, render, proxy, guide); a purpose with
    no geometry has the empty pair (+FLT_MAX, −FLT_MAX), which is skipped.
    """
    from pxr import Usd, UsdGeom

    stage = Usd.Stage.Open(str(asset), Usd.Stage.LoadNone)
    hint = UsdGeom.ModelAPI(stage.GetDefaultPrim()).GetExtentsHint() if stage else None
    pairs = np.array(hint, dtype=np.float64).reshape(-1, 2, 3) if hint else np.zeros((0, 2, 3))
    tops = [high[1] for low, high in pairs if np.all(low <= high)]
    return float(max(tops)) if tops else 30.0


def write_layout_png(path: Path, recipe: TrainRecipe, fan: Fan) -> None:
    """The fan from the front: a line per feather (base → tip), colour = gradation offset."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    # tip: the component's height (extentsHint) along its +Y, through the instance's rotation
    w, x, y, z = fan.orientations.T
    up = np.stack([2 * (x * y - w * z), 1 - 2 * (x * x + z * z), 2 * (y * z + w * x)], axis=1)
    heights = np.array(
        [
            component_height(recipe.components[prototype_parts(n, recipe.components)[0]])
            for n in fan.prototypes
        ]
    )
    tips = fan.positions + up * (heights[fan.proto_indices] * fan.scales[:, 1])[:, None]
    fig, ax = plt.subplots(figsize=(9, 5.5), dpi=110)
    markers = ("o", "s", "^", "D", "v", "P")
    limit = max(recipe.variation.gradation_offset, 1e-6)
    for i, name in enumerate(fan.prototypes):
        mine = fan.proto_indices == i
        for base, tip in zip(fan.positions[mine], tips[mine], strict=True):
            ax.plot([base[0], tip[0]], [base[1], tip[1]], color="0.75", lw=0.6, zorder=1)
        scatter = ax.scatter(
            tips[mine, 0],
            tips[mine, 1],
            c=fan.gradation_offset[mine],
            cmap="coolwarm",
            vmin=-limit,
            vmax=limit,
            marker=markers[i % len(markers)],
            s=26,
            edgecolors="k",
            linewidths=0.3,
            label=f"{name} ({int(mine.sum())})",
            zorder=2,
        )
    fig.colorbar(scatter, ax=ax, label="gradation offset (per instance)")
    ax.set_aspect("equal")
    ax.set_xlabel("x (cm)")
    ax.set_ylabel("y (cm)")
    ax.set_title(f"{recipe.name}: {len(fan)} feathers, seed {recipe.seed} (tips marked)")
    ax.legend(loc="upper right", fontsize=8)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def assemble_train(
    recipe_path: str | os.PathLike, outdir: str | os.PathLike, *, force: bool = False
) -> TrainResult:
    """Build ``OUTDIR/<name>/<name>.usda`` (and its layout plot) from a train recipe."""
    recipe = parse_train_recipe(recipe_path)
    fan = layout(recipe)
    outdir = Path(outdir)
    final = outdir.resolve() / recipe.name
    with staging_folder(outdir, recipe.name, force) as folder:
        extent = write_train_layer(folder / f"{recipe.name}.usda", recipe, fan, final)
        rattle = None
        if recipe.rattle is not None:  # the train animated: pipeline/assemble/rattle.py
            from pavonine.pipeline.assemble.rattle import animate

            rattle = animate(folder / f"{recipe.name}.usda", recipe, fan)
            rattle.sidecar = outdir / recipe.name / rattle.sidecar.name
            extent = rattle.extent
        write_layout_png(folder / f"{recipe.name}_layout.png", recipe, fan)
    return TrainResult(
        outdir / recipe.name / f"{recipe.name}.usda",
        outdir / recipe.name / f"{recipe.name}_layout.png",
        fan.counts(),
        extent,
        rattle,
    )
