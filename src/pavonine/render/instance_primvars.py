"""Per-instance primvars → the feather BSDF, with one shape group per prototype.

A Mitsuba ``instance`` shares its shape group's meshes *and* their BSDFs, so a value that varies
per instance cannot live in the material. Instead each instance's value is looked up at shading
time: every Mitsuba object has a small integer id in Dr.Jit's registry, a hit through an instance
carries a pointer to it (``si.instance``, null for plain meshes), and reinterpreting that pointer
array as ``UInt32`` gives the registry id per lane. :func:`bind` builds, per primvar, one float
table indexed by registry id (the neutral value at index 0 and at every id that is not an
instance of this scene) and hands it to every feather BSDF of the scene, which gathers from it
(``pavonine.render.feather_bsdf``). Memory: one float per instance and primvar; prototypes stay
single copies (no per-variation shape groups, no quantisation).

The same lookup carries each instance's frame (world→instance and back): Mitsuba's
``Mesh.eval_attribute`` computes barycentric coordinates from the world-space hit point against
the prototype's own vertices, so without it a mesh attribute (the feather's barb tangent) read
through an instance is garbage and instanced feathers shade differently from the same feather
referenced in place.

Where the values come from:

* ``PointInstancer``: primvars authored on the instancer with ``vertex``/``varying``
  interpolation and one value per instance (``constant`` ones apply to every instance), as
  ``UsdGeomPointInstancer`` defines per-instance primvars;
* instanceable prims (native instancing): a constant primvar on the instance prim or an ancestor
  (inherited down namespace, as USD's constant primvars are).

Primvars the feather BSDF reads (:data:`FEATHER_PRIMVARS`); others authored per instance get a
warning naming them:

``pavonine:gradationOffset`` (float, neutral 0)
    added to the gradation map's ``t`` before the clip to [0, 1]: the barbules' stacks move
    between the class's black and white ends (Table 1's; in ``freyer2020`` the measured region
    scaled by 0.97 … 1.03), so the colour varies only within the class's range (the physical
    bound).
``pavonine:structuralScale`` (float, neutral 1)
    multiplies the melanin map's structural share ``w`` (clipped to [0, 1]): < 1 is a browner,
    worn feather.
``pavonine:glitterSeed`` (float holding a whole number, neutral 0)
    mixed into the material's ``pavonine:glitterSeed``: with glitter the instances' barbule
    blocks tilt differently, so two instances do not sparkle alike.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np
from pxr import Usd, UsdGeom

from pavonine.render.diagnostics import Diagnostics


@dataclass(frozen=True)
class InstancePrimvar:
    """A per-instance primvar the feather BSDF reads: its BSDF key and neutral value."""

    key: str
    neutral: float


FEATHER_PRIMVARS: dict[str, InstancePrimvar] = {
    "pavonine:gradationOffset": InstancePrimvar("gradation_offset", 0.0),
    "pavonine:structuralScale": InstancePrimvar("structural_scale", 1.0),
    "pavonine:glitterSeed": InstancePrimvar("glitter_seed", 0.0),
}
PER_INSTANCE = ("vertex", "varying")


def instancer_primvars(
    instancer: UsdGeom.PointInstancer, time: Usd.TimeCode, count: int, diag: Diagnostics
) -> dict[str, np.ndarray]:
    """Per-instance values (``count`` each) of the instancer's primvars the feather BSDF reads.

    Other authored primvars with per-instance interpolation get one warning each (they would
    otherwise vary nothing, silently); a supported one with the wrong number of values too.
    """
    where = str(instancer.GetPath())
    values: dict[str, np.ndarray] = {}
    for primvar in UsdGeom.PrimvarsAPI(instancer.GetPrim()).GetPrimvarsWithValues():
        name = primvar.GetPrimvarName()
        interpolation = primvar.GetInterpolation()
        if name not in FEATHER_PRIMVARS:
            if interpolation in PER_INSTANCE:
                diag.warn(
                    where,
                    f"per-instance primvar {name} is not supported by the Mitsuba delegate "
                    f"(supported: {', '.join(FEATHER_PRIMVARS)}); ignored",
                )
            continue
        data = primvar.ComputeFlattened(time)
        array = np.asarray(data if data is not None else [], dtype=np.float64).reshape(-1)
        if interpolation == UsdGeom.Tokens.constant and len(array) >= 1:
            array = np.full(count, array[0])
        elif interpolation not in PER_INSTANCE or len(array) != count:
            diag.warn(
                where,
                f"primvar {name} ({interpolation}) has {len(array)} values for {count} "
                "instances; ignored",
            )
            continue
        if not np.all(np.isfinite(array)):
            diag.warn(where, f"primvar {name} has NaN or infinite values; those use the neutral")
            array = np.where(np.isfinite(array), array, FEATHER_PRIMVARS[name].neutral)
        values[name] = array
    return values


def inherited_primvars(prim: Usd.Prim, time: Usd.TimeCode) -> dict[str, float]:
    """Constant feather primvars on ``prim`` or inherited from an ancestor (native instances)."""
    api = UsdGeom.PrimvarsAPI(prim)
    found: dict[str, float] = {}
    for name in FEATHER_PRIMVARS:
        primvar = api.FindPrimvarWithInheritance(name)
        if primvar and primvar.HasValue():
            value = primvar.Get(time)
            scalar = np.asarray(value, dtype=np.float64).reshape(-1)
            if scalar.size and np.isfinite(scalar[0]):
                found[name] = float(scalar[0])
    return found


def registry_id(shape) -> int:
    """Dr.Jit registry id of a Mitsuba object (what ``si.instance`` holds per lane)."""
    import drjit as dr
    import mitsuba as mi

    return int(dr.reinterpret_array(mi.UInt32, mi.ShapePtr(shape))[0])


def bind(scene, table, feather_bsdfs: Iterable) -> int:
    """Give every feather BSDF its per-instance tables; returns the number of instances bound.

    ``table``: the delegate's :class:`~pavonine.render.instancing.InstanceTable` (instance ids,
    their ``to_world`` and recorded primvars). Besides one table per primvar, the feathers get
    each instance's frame (``feather_bsdf.INSTANCE_FRAME``): world→instance affine rows and the
    instance→world linear part, with which the BSDF reads its mesh attributes through instances.
    """
    import drjit as dr
    import mitsuba as mi

    from pavonine.render.feather_encoding import INSTANCE_FRAME

    feathers = list(feather_bsdfs)
    if not feathers or not table.instances:
        return 0
    shapes = _instance_shapes(scene, table)
    frames = {key: _frame(table.instances[key]["to_world"]) for key in shapes}
    names = sorted({name for entry in table.primvars.values() for name in entry})
    lookups = {INSTANCE_FRAME: (_frame_lookup(shapes, frames), 0.0)}
    if dr.is_jit_v(mi.Float):
        ids = {key: registry_id(shape) for key, shape in shapes.items()}
        size = max(ids.values(), default=0) + 1
        for name in names:
            spec = FEATHER_PRIMVARS[name]
            values = np.full(size, spec.neutral, dtype=np.float32)
            for key, index in ids.items():
                values[index] = table.primvars.get(key, {}).get(name, spec.neutral)
            lookups[spec.key] = (mi.Float(values), spec.neutral)
    else:  # scalar variants: ``si.instance`` is the instance object itself
        for name in names:
            spec = FEATHER_PRIMVARS[name]
            values = {key: table.primvars.get(key, {}).get(name, spec.neutral) for key in shapes}
            lookups[spec.key] = (values, spec.neutral)
    for bsdf in feathers:
        for key, (lookup, neutral) in lookups.items():
            bsdf.set_instance_table(key, lookup, neutral)
    return len(shapes)


def refresh_frames(scene, table, feather_bsdfs: Iterable, params) -> None:
    """Give the feather BSDFs the instances' frames where ``params`` (``mi.traverse(scene)``,
    the instances moved in place: :mod:`.motion.blur`) has them now; without it a moved frame's
    BSDF would read its mesh attributes through the first frame's instance frames."""
    from pavonine.render.feather_encoding import INSTANCE_FRAME

    feathers = list(feather_bsdfs)
    if not feathers or not table.instances:
        return
    shapes = _instance_shapes(scene, table)
    frames = {key: _frame(_matrix(params[f"{key}.to_world"])) for key in shapes}
    lookup = _frame_lookup(shapes, frames)
    for bsdf in feathers:
        bsdf.set_instance_table(INSTANCE_FRAME, lookup, 0.0)


def _instance_shapes(scene, table) -> dict:
    """The scene's instance shapes that ``table`` made, by id."""
    return {shape.id(): shape for shape in scene.shapes() if shape.id() in table.instances}


def _frame_lookup(shapes: dict, frames: dict[str, np.ndarray]):
    """The feathers' ``INSTANCE_FRAME`` table: the frames by registry id in a JIT variant (the
    identity frame elsewhere), by instance id in a scalar one (``si.instance`` is the object)."""
    import drjit as dr
    import mitsuba as mi

    from pavonine.render.feather_encoding import FRAME_FLOATS

    if not dr.is_jit_v(mi.Float):
        return {key: tuple(frames[key]) for key in shapes}
    ids = {key: registry_id(shape) for key, shape in shapes.items()}
    frame_table = np.tile(_frame(None), max(ids.values(), default=0) + 1)
    for key, index in ids.items():
        frame_table[index * FRAME_FLOATS : (index + 1) * FRAME_FLOATS] = frames[key]
    return mi.Float(frame_table)


def _matrix(to_world) -> np.ndarray:
    """A Mitsuba transform's 4×4 matrix (a JIT variant's ``Transform4f`` holds one lane)."""
    matrix = np.array(to_world.matrix, dtype=np.float64)
    return matrix.reshape(4, 4) if matrix.size == 16 else matrix


def _frame(to_world) -> np.ndarray:
    """21 floats: world→instance affine rows (3×4), then the instance→world linear part (3×3)
    (``to_world``: a Mitsuba transform, or its 4×4 matrix)."""
    if to_world is None:
        matrix = np.eye(4)
    elif isinstance(to_world, np.ndarray):
        matrix = to_world
    else:
        matrix = _matrix(to_world)
    inverse = np.linalg.inv(matrix)
    return np.concatenate([inverse[:3, :4].ravel(), matrix[:3, :3].ravel()]).astype(np.float32)
