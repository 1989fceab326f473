"""The rattle: a displaying peacock's shivering train, written as USD time samples.

A train recipe with a ``[rattle]`` table (``docs/pipeline.md``, *The rattle*) animates the
assembly ``pavonine assemble train`` writes; without one, nothing here runs and the assembly is
byte for byte what it was. The numbers are those of Dakin et al. 2016, "Biomechanics of the
Peacock's Display: How Feather Structure and Resonance Influence Multimodal Signaling", *PLoS
ONE* 11(4): e0152759 (high-speed video of 14 displaying males; laboratory shaker tests):

* **One drive frequency.** The train is rattled at 25.6 Hz on average; arrays of train feathers
  have a broad resonant peak over the range of rattling frequencies, so every feather moves at
  the drive frequency (``frequency_hz``), each with its own phase (``phase_spread``, seeded).
* **The eyespot nearly still** (at most 1.7 mm side to side in the field videos, "less than
  2 mm"): its barbs are hooked together (SEM: microhooks) into one heavy, stiff disc. The
  feather's rigid sway about its base (``orientationsf`` time samples of the PointInstancer) is
  sized so that the farthest point of the eyespot moves ``eyespot_mm``.
* **Standing waves with a node near the eyespot** ("like the strings of a guitar"): the rachis
  below the eyespot bends side to side as a half sine between its base and the eyespot's lower
  edge, ``sin(pi y / y_node)``; nothing above the node bends.
* **The loose barbs swing** (up to 9.6 mm, "even near the eyespots"): each barb is a cantilever
  from the rachis, bending in the vane's plane perpendicular to itself with the first cantilever
  mode shape of its distance from the rachis (so long barbs swing most and short ones little),
  lagging the rachis by up to a quarter period at its tip. Locked (eyespot) barbs do not swing.

The flex is real geometry motion that stays small on disk and in memory: two UsdSkel blend
shapes per deformed prim (the in-phase and quadrature offsets of the vibration, written once per
prototype into a ``class`` that its variants inherit), and ``phases`` variants of each prototype
(``<prototype>_rattle<k>``, a ``SkelRoot``) whose ``SkelAnimation`` drives the two weights with
``sin`` and ``cos`` of the drive at phase ``2 pi k / phases``. Each instance takes the variant
nearest its phase. Blend-shape weights and orientations are sampled ``samples_per_frame`` times a
frame (USD interpolates weights linearly and quaternions by slerp) from half a frame before the
first frame to half a frame after the last, so a renderer's shutter interval of up to a frame
around each frame finds dense samples: a 25.6 Hz motion seen at 24 fps is beyond the Nyquist
limit (12 Hz), and only motion blur over dense time samples shows it as the blur it is.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from pavonine.pipeline.assemble.fan import Fan, multiply_quaternions, prototype_parts, quaternions
from pavonine.pipeline.assemble.flex import (
    Shape,
    prototype_shape,
    read_geometry,
    scale_shapes,
    tip_height,
)
from pavonine.pipeline.assemble.rattle_recipe import Rattle

if TYPE_CHECKING:
    from pavonine.pipeline.assemble.recipe import TrainRecipe

#: The two blend shapes of every deformed prim, and their prims' names.
SHAPES = ("rattleSin", "rattleCos")
SHAPE_PRIMS = ("RattleSin", "RattleCos")
#: The sidecar layer holding the heavy, shared data (blend-shape offsets, orientations).
SIDECAR_SUFFIX = "_rattle.usdc"


# ------------------------------------------------------------------------------ the motion


def instance_phases(seed: int, count: int, spread: float) -> np.ndarray:
    """Per-instance phase (radians), uniform in ``[0, 2 pi spread)``, from its own stream of the
    recipe's seed (the fan's layout and looks do not move)."""
    rng = np.random.default_rng([seed & 0xFFFFFFFF, 0x7A77_1E])
    return 2.0 * np.pi * spread * rng.random(count)


def variant_of(phases: np.ndarray, variants: int) -> np.ndarray:
    """The phase variant nearest each phase: ``round(phase / (2 pi / variants)) mod variants``."""
    return np.mod(np.rint(phases * variants / (2.0 * np.pi)), variants).astype(np.int64)


@dataclass
class RattleResult:
    """What :func:`animate` wrote."""

    sidecar: Path
    frames: tuple[int, int]
    fps: float
    time_samples: int
    variants: int  # prototype variants (prototypes × phases)
    flexed_points: int  # points with blend-shape offsets, over every prototype
    extent: np.ndarray  # (2, 3) cm: the static extent padded by the largest displacement
    factor: float = 0.0  # cm of flex per unit shape
    shapes: list[Shape] = field(default_factory=list, repr=False)
    phases: np.ndarray | None = field(default=None, repr=False)  # per instance (radians)
    sway_rad: np.ndarray | None = field(default=None, repr=False)  # per instance amplitude

    def to_json(self) -> dict[str, Any]:
        return {
            "sidecar": str(self.sidecar),
            "frames": list(self.frames),
            "fps": self.fps,
            "time_samples": self.time_samples,
            "variants": self.variants,
            "flexed_points": self.flexed_points,
        }


def variant_name(prototype: str, k: int) -> str:
    return f"{prototype}_rattle{k}"


def plan(recipe: TrainRecipe, fan: Fan) -> RattleResult:
    """The rattle of ``recipe``'s fan (shapes, phases and sway), before anything is written."""

    rattle = recipe.rattle
    assert rattle is not None
    geometries = []
    for name in fan.prototypes:
        component, geometry = prototype_parts(name, recipe.components)
        geometries.append(read_geometry(name, recipe.components[component], recipe.lod, geometry))
    reach = max((g.loose_reach_cm for g in geometries), default=0.0)
    tip = max((tip_height(g) for g in geometries), default=1.0)
    shapes = [prototype_shape(g, reach, tip, recipe.seed) for g in geometries]
    lengths = {
        name: float(fan.scales[fan.proto_indices == i, 1].max(initial=0.0))
        for i, name in enumerate(fan.prototypes)
    }
    factor = scale_shapes(shapes, lengths, rattle.barb_mm, rattle.eyespot_mm)
    phases = instance_phases(recipe.seed, len(fan), rattle.phase_spread)
    radius = np.array([s.sway_radius_cm for s in shapes])[fan.proto_indices]
    sway = (rattle.eyespot_mm / 10.0) / (radius * fan.scales[:, 1])
    return RattleResult(
        Path(),
        (rattle.start_frame, rattle.end_frame),
        rattle.fps,
        len(rattle.times()),
        len(fan.prototypes) * rattle.phases,
        sum(len(d.indices) for s in shapes for d in s.deformed),
        np.zeros((2, 3)),
        factor,
        shapes,
        phases,
        sway,
    )


def sway_orientations(fan: Fan, result: RattleResult, rattle: Rattle) -> np.ndarray:
    """(T, N, 4) instance orientations (w, x, y, z) at every time sample: the fan's, after a
    rotation about the feather's own Z (its vane's normal) by ``-sway · sin(wt + phase)``."""

    z = np.array([0.0, 0.0, 1.0])
    out = np.empty((len(rattle.times()), len(fan), 4))
    omega = 2.0 * np.pi * rattle.frequency_hz / rattle.fps  # radians per time code
    for j, t in enumerate(rattle.times()):
        angle = -result.sway_rad * np.sin(omega * t + result.phases)
        out[j] = multiply_quaternions(fan.orientations, quaternions(z, angle))
    return out


def animate(root_layer: Path, recipe: TrainRecipe, fan: Fan) -> RattleResult:
    """Add the rattle to the assembly layer at ``root_layer`` (written by ``write_train_layer``)
    and write its sidecar ``<name>_rattle.usdc`` beside it; returns what was written."""
    from pxr import Gf, Sdf, Vt

    rattle = recipe.rattle
    assert rattle is not None
    result = plan(recipe, fan)
    layer = Sdf.Layer.FindOrOpen(str(root_layer))
    name = recipe.name
    base = Sdf.Path(f"/{name}/Feathers")
    sidecar_path = root_layer.with_name(f"{name}{SIDECAR_SUFFIX}")
    sidecar = Sdf.Layer.CreateNew(str(sidecar_path))
    times = rattle.times()
    omega = 2.0 * np.pi * rattle.frequency_hz / rattle.fps

    # The shot's clock on the assembly (the scene that references it says the same).
    layer.timeCodesPerSecond = rattle.fps
    layer.framesPerSecond = rattle.fps
    layer.startTimeCode = rattle.start_frame
    layer.endTimeCode = rattle.end_frame
    layer.subLayerPaths.append(f"./{sidecar_path.name}")

    # Shared per prototype, in the sidecar: the blend shapes and the one-joint skeleton.
    Sdf.CreatePrimInLayer(sidecar, base)
    classes = Sdf.CreatePrimInLayer(sidecar, Sdf.Path(f"/{name}/Rattle"))
    classes.specifier = Sdf.SpecifierClass
    for shape in result.shapes:
        _author_class(sidecar, classes.path.AppendChild(shape.name), shape)

    # Per variant, in the assembly: a SkelRoot copy of the prototype, its animation.
    prototypes = base.AppendChild("Prototypes")
    targets = []
    for shape in result.shapes:
        source = prototypes.AppendChild(shape.name)
        for k in range(rattle.phases):
            path = prototypes.AppendChild(variant_name(shape.name, k))
            if not Sdf.CopySpec(layer, source, layer, path):
                raise OSError(f"{root_layer}: cannot copy {source}")
            spec = layer.GetPrimAtPath(path)
            spec.typeName = "SkelRoot"
            spec.inheritPathList.prependedItems = [classes.path.AppendChild(shape.name)]
            weights = [
                Vt.FloatArray([math.sin(omega * t + phase), math.cos(omega * t + phase)])
                for phase in [2.0 * np.pi * k / rattle.phases]
                for t in times
            ]
            _author_animation(layer, path, times, weights)
            targets.append(path)
        del layer.GetPrimAtPath(prototypes).nameChildren[shape.name]
    instancer = layer.GetPrimAtPath(base)
    instancer.relationships["prototypes"].targetPathList.explicitItems = targets
    variants = variant_of(result.phases, rattle.phases)
    indices = fan.proto_indices.astype(np.int64) * rattle.phases + variants
    instancer.attributes["protoIndices"].default = Vt.IntArray([int(i) for i in indices])

    # The rigid sway: orientationsf (float quaternions: a 1.7 mm sway is 0.006 rad, below
    # what the half-precision `orientations` resolve), its default the fan at rest.
    sway = sway_orientations(fan, result, rattle)
    over = sidecar.GetPrimAtPath(base)
    attr = Sdf.AttributeSpec(over, "orientationsf", Sdf.ValueTypeNames.QuatfArray)

    def quats(q: np.ndarray):
        return Vt.QuatfArray([Gf.Quatf(float(w), float(x), float(y), float(z)) for w, x, y, z in q])

    attr.default = quats(fan.orientations)
    for t, q in zip(times, sway, strict=True):
        sidecar.SetTimeSample(attr.path, float(t), quats(q))

    # Extent: the static one padded by the largest displacement anywhere.
    extent = np.array(instancer.attributes["extent"].default, dtype=np.float64)
    pad = (rattle.barb_mm + 2.0 * rattle.eyespot_mm) / 10.0
    extent = extent + np.array([[-pad] * 3, [pad] * 3])
    padded = Vt.Vec3fArray([Gf.Vec3f(*map(float, row)) for row in extent])
    instancer.attributes["extent"].default = padded
    root = layer.GetPrimAtPath(f"/{name}")
    if "extentsHint" in root.attributes:
        root.attributes["extentsHint"].default = padded
    root.documentation = (
        f"{root.documentation} Rattled at {rattle.frequency_hz:g} Hz "
        f"(frames {rattle.start_frame}-{rattle.end_frame} at {rattle.fps:g} fps, "
        f"{len(times)} time samples; docs/pipeline.md, 'The rattle')."
    )
    if not sidecar.Save() or not layer.Save():
        raise OSError(f"{root_layer}: cannot write the rattle")
    result.sidecar = sidecar_path
    result.extent = extent
    return result


def _author_class(layer, path, shape: Shape) -> None:
    """``class`` with the one-joint skeleton, the rigid binding and the blend shapes."""
    from pxr import Gf, Sdf, Vt

    spec = Sdf.CreatePrimInLayer(layer, path)
    spec.specifier = Sdf.SpecifierClass
    spec.SetInfo("apiSchemas", Sdf.TokenListOp.Create(prependedItems=["SkelBindingAPI"]))
    skeleton = Sdf.PrimSpec(spec, "Skel", Sdf.SpecifierDef, "Skeleton")
    _attr(skeleton, "joints", Sdf.ValueTypeNames.TokenArray, Vt.TokenArray(["root"]), True)
    identity = Vt.Matrix4dArray([Gf.Matrix4d(1.0)])
    _attr(skeleton, "bindTransforms", Sdf.ValueTypeNames.Matrix4dArray, identity, True)
    _attr(skeleton, "restTransforms", Sdf.ValueTypeNames.Matrix4dArray, identity, True)
    _rel(spec, "skel:skeleton", [skeleton.path])
    for primvar, kind, value in (
        ("primvars:skel:jointIndices", Sdf.ValueTypeNames.IntArray, Vt.IntArray([0])),
        ("primvars:skel:jointWeights", Sdf.ValueTypeNames.FloatArray, Vt.FloatArray([1.0])),
    ):
        attr = _attr(spec, primvar, kind, value)
        attr.SetInfo("interpolation", "constant")
        attr.SetInfo("elementSize", 1)
    for deformed in shape.deformed:
        target = Sdf.CreatePrimInLayer(layer, path.AppendPath(Sdf.Path(deformed.path)))
        target.SetInfo("apiSchemas", Sdf.TokenListOp.Create(prependedItems=["SkelBindingAPI"]))
        _attr(target, "skel:blendShapes", Sdf.ValueTypeNames.TokenArray, Vt.TokenArray(SHAPES),
              True)  # fmt: skip
        shapes = []
        for prim_name, offsets in zip(SHAPE_PRIMS, (deformed.sin, deformed.cos), strict=True):
            blend = Sdf.PrimSpec(target, prim_name, Sdf.SpecifierDef, "BlendShape")
            _attr(blend, "offsets", Sdf.ValueTypeNames.Vector3fArray,
                  Vt.Vec3fArray.FromNumpy(offsets.astype(np.float32)), True)  # fmt: skip
            _attr(blend, "pointIndices", Sdf.ValueTypeNames.IntArray,
                  Vt.IntArray.FromNumpy(deformed.indices.astype(np.int32)), True)  # fmt: skip
            shapes.append(blend.path)
        _rel(target, "skel:blendShapeTargets", shapes)


def _author_animation(layer, path, times: np.ndarray, weights: list) -> None:
    """The variant's ``SkelAnimation`` (the two weights' time samples) and its skeleton's
    ``skel:animationSource``."""
    from pxr import Gf, Sdf, Vt

    spec = layer.GetPrimAtPath(path)
    motion = Sdf.PrimSpec(spec, "Motion", Sdf.SpecifierDef, "SkelAnimation")
    _attr(motion, "joints", Sdf.ValueTypeNames.TokenArray, Vt.TokenArray(["root"]), True)
    _attr(motion, "translations", Sdf.ValueTypeNames.Float3Array, Vt.Vec3fArray([Gf.Vec3f(0)]))
    _attr(motion, "rotations", Sdf.ValueTypeNames.QuatfArray, Vt.QuatfArray([Gf.Quatf(1.0)]))
    _attr(motion, "scales", Sdf.ValueTypeNames.Half3Array, Vt.Vec3hArray([Gf.Vec3h(1.0)]))
    _attr(motion, "blendShapes", Sdf.ValueTypeNames.TokenArray, Vt.TokenArray(SHAPES), True)
    attr = _attr(motion, "blendShapeWeights", Sdf.ValueTypeNames.FloatArray, None)
    for t, w in zip(times, weights, strict=True):
        layer.SetTimeSample(attr.path, float(t), w)
    skel = Sdf.PrimSpec(spec, "Skel", Sdf.SpecifierOver)
    skel.SetInfo("apiSchemas", Sdf.TokenListOp.Create(prependedItems=["SkelBindingAPI"]))
    _rel(skel, "skel:animationSource", [motion.path])


def _attr(spec, name: str, kind, value, uniform: bool = False):
    from pxr import Sdf

    variability = Sdf.VariabilityUniform if uniform else Sdf.VariabilityVarying
    attr = Sdf.AttributeSpec(spec, name, kind, variability)
    if value is not None:
        attr.default = value
    return attr


def _rel(spec, name: str, targets: list) -> None:
    from pxr import Sdf

    rel = Sdf.RelationshipSpec(spec, name, custom=False)
    rel.targetPathList.explicitItems = targets
