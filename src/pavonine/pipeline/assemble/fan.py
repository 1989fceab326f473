"""The displaying fan: where each feather of a train goes, and how it varies.

Fan space is the components' own: centimetres, Y up, the fan facing +Z (the viewer), its centre
(the bird's rump) at the origin. A feather component stands on its base at its origin, pointing
+Y with its iridescent front facing +Z (``docs/pipeline.md``, *Placement*). Feather ``i`` of a
row of ``n`` points at ``θ = −span/2 + span · (i + ½ + stagger) / n`` from straight up (positive
to the right), its base on the row's circle. Its transform, applied to the component, is

    S · R_y(twist) · R_x(dish + tilt) · R_z(−θ) · T(base)      (USD's row-vector order)

(θ including its rotation jitter) with ``S = diag(l, l, l · b · c)``: the length ``l`` scales the
whole feather, the row's ``bend`` ``b`` and the curvature jitter ``c`` only its depth, which is
exactly the sagitta of its bend and cup (``P_z = −bend·v² − cup·(2u−1)²``, so the scaled feather
is the component converted with ``b · c`` times its ``bend_cm`` and ``cup_cm``): a curved
feather, and a jittered curvature, need no new geometry (one prototype per component, however
bent). A row's edge feathers (fishtails) take its ``edge_bend`` and are turned
``edge_droop_deg`` further from straight up, outward (they droop at the fan's rim). Every jitter
and variation is drawn uniformly from one ``numpy.random.default_rng(seed)``, in a fixed order: the same recipe gives the same fan.
Each feather's glitter seed (``pavonine:glitterSeed``, so that no two sparkle alike) is a hash of
the recipe's seed and its index, drawn outside that stream (adding it moved no other value).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from pavonine.pipeline.assemble.recipe import TrainRecipe


@dataclass
class Fan:
    """One entry per feather: prototype index, transform parts and per-instance look."""

    prototypes: list[str]  # prototype names, in PointInstancer order
    proto_indices: np.ndarray  # (N,) int
    positions: np.ndarray  # (N, 3) cm
    orientations: np.ndarray  # (N, 4) unit quaternions (w, x, y, z)
    scales: np.ndarray  # (N, 3)
    gradation_offset: np.ndarray  # (N,)
    structural_scale: np.ndarray  # (N,)
    row: np.ndarray  # (N,) row index (for the layout plot)
    glitter_seed: np.ndarray | None = None  # (N,) whole numbers below 2**24 (exact as float32)

    def __len__(self) -> int:
        return len(self.proto_indices)

    def counts(self) -> dict[str, int]:
        """Instances per prototype."""
        return {
            name: int(np.sum(self.proto_indices == i)) for i, name in enumerate(self.prototypes)
        }


def quaternions(axis: np.ndarray, angle_rad: np.ndarray) -> np.ndarray:
    """(N, 4) quaternions (w, x, y, z) of rotations by ``angle_rad`` about a fixed unit ``axis``."""
    half = np.asarray(angle_rad) / 2.0
    q = np.zeros((len(half), 4))
    q[:, 0] = np.cos(half)
    q[:, 1:] = np.sin(half)[:, None] * axis[None, :]
    return q


def multiply_quaternions(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product of (N, 4) quaternions: the rotation ``b`` first, then ``a``."""
    w1, x1, y1, z1 = a.T
    w2, x2, y2, z2 = b.T
    return np.stack(
        [
            w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
            w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
            w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
            w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2,
        ],
        axis=1,
    )


#: Suffix of a prototype that selects its component's ``barbs`` geometry variant.
BARBS_SUFFIX = "_barbs"


def prototype_name(component: str, geometry: str) -> str:
    """The prototype of ``component`` at ``geometry``: the component's name for the sheet,
    ``<component>_barbs`` for the barbs."""
    return component if geometry == "sheet" else f"{component}{BARBS_SUFFIX}"


def prototype_parts(name: str, components) -> tuple[str, str]:
    """``(component, geometry)`` of a prototype name (inverse of :func:`prototype_name`)."""
    if name not in components and name.endswith(BARBS_SUFFIX):
        return name[: -len(BARBS_SUFFIX)], "barbs"
    return name, "sheet"


def _row_parts(row) -> list[str]:
    return [row.component] + ([row.edge] if row.edge_count else [])


def layout(recipe: TrainRecipe) -> Fan:
    """Every feather of ``recipe``'s fan (module docstring)."""
    prototypes = sorted(recipe.components)
    barbed = sorted({c for row in recipe.rows if row.geometry == "barbs" for c in _row_parts(row)})
    prototypes += [prototype_name(c, "barbs") for c in barbed]
    index = {name: i for i, name in enumerate(prototypes)}
    rng = np.random.default_rng(recipe.seed)
    jitter, variation = recipe.jitter, recipe.variation
    parts: dict[str, list[np.ndarray]] = {
        key: [] for key in ("proto", "theta", "radius", "length", "dish", "depth", "row", "bend")
    }
    for r, row in enumerate(recipe.rows):
        n = row.count
        steps = (np.arange(n) + 0.5 + row.stagger) / n
        theta = math.radians(row.span_deg) * (steps - 0.5)
        proto = np.full(n, index[prototype_name(row.component, row.geometry)])
        bend = np.full(n, row.bend)
        if row.edge_count:
            edge = np.zeros(n, dtype=bool)
            edge[: row.edge_count] = edge[n - row.edge_count :] = True
            proto[edge] = index[prototype_name(row.edge, row.geometry)]
            bend[edge] = row.bend if row.edge_bend is None else row.edge_bend
            theta = theta + edge * np.sign(theta) * math.radians(row.edge_droop_deg)
        parts["proto"].append(proto)
        parts["theta"].append(theta)
        parts["radius"].append(np.full(n, row.radius_cm))
        parts["length"].append(np.full(n, row.length))
        parts["dish"].append(np.full(n, math.radians(row.dish_deg)))
        parts["depth"].append(np.full(n, row.depth_cm))
        parts["row"].append(np.full(n, r))
        parts["bend"].append(bend)
    p = {key: np.concatenate(values) for key, values in parts.items()}
    count = len(p["proto"])

    def spread(amount: float) -> np.ndarray:
        return rng.uniform(-amount, amount, count)

    length = p["length"] * (1.0 + spread(jitter.length))
    curvature = 1.0 + spread(jitter.curvature)
    theta = p["theta"] + np.radians(spread(jitter.rotation_deg))
    twist = np.radians(spread(jitter.twist_deg))
    tilt = p["dish"] + np.radians(spread(jitter.tilt_deg))
    gradation = spread(variation.gradation_offset)
    structural = rng.uniform(*variation.structural_scale, count)

    # USD applies scale, then orientation, then translation (p' = p·S·R + t, row vectors):
    # the twist about the feather's own axis first, then the tilt, then the turn in the fan.
    x, y, z = np.eye(3)
    q = multiply_quaternions(
        quaternions(z, -theta), multiply_quaternions(quaternions(x, tilt), quaternions(y, twist))
    )
    positions = np.stack(
        [p["radius"] * np.sin(theta), p["radius"] * np.cos(theta), p["depth"]], axis=1
    )
    scales = np.stack([length, length, length * curvature * p["bend"]], axis=1)
    return Fan(
        prototypes,
        p["proto"].astype(np.int32),
        positions,
        q / np.linalg.norm(q, axis=1, keepdims=True),
        scales,
        gradation,
        structural,
        p["row"].astype(np.int32),
        instance_seeds(recipe.seed, count),
    )


def instance_seeds(seed: int, count: int) -> np.ndarray:
    """Per-instance glitter seeds: ``lowbias32(seed ⊕ lowbias32(i))`` kept to 24 bits."""
    from pavonine.materials.glitter import lowbias32

    index = lowbias32(np.arange(count, dtype=np.uint64))
    return (lowbias32(index ^ np.uint64(seed & 0xFFFFFFFF)) & 0xFFFFFF).astype(np.float64)
