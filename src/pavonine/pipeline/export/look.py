"""The glTF feather material's textures: the model's reflectance of every texel of the atlas at
the reference light and the face-on and tilted views (:mod:`pavonine.pipeline.bake.appearance`)
of a viewer at a finite distance (:func:`viewer_views`: the views differ from texel to texel;
from the shipped scene's camera, 36 cm away, they span 44° in elevation along the eye feather),
fitted by :func:`pavonine.pipeline.export.iridescence.fit_film` to what a glTF viewer draws
(base colour + ``KHR_materials_iridescence`` over a ``KHR_materials_specular`` substrate).

The film (weight, thickness, roughness, substrate) is searched on every ``step``-th texel of
the atlas in each direction (at most :data:`FIT_RESOLUTION`² texels: the search is the costly
part) and handed to every texel from the searched one near it (its nearest or a corner of its
grid cell) that fits its own reflectance best. The search runs twice: freely, then within
30 nm of the median of the free search's thicknesses around the texel, so that neighbouring
texels sit on one branch of the film's colour cycle (a texture filter averaging thicknesses of
two branches would draw a third colour); each texel's base colour is then fitted at full
resolution to its own reflectance (:func:`~pavonine.pipeline.export.iridescence.fit_base`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from pavonine.pipeline.bake.appearance import REFERENCE_LIGHT, reflectance_at_views
from pavonine.pipeline.bake.asset import feather_inputs, merge, mesh_data
from pavonine.pipeline.bake.texels import dilate, nearest_covered, scatter, surface_texels
from pavonine.pipeline.export.iridescence import FIT_TILTS_DEG, fit_base, fit_error, fit_film

#: The film search's atlas resolution at most (texels per side).
FIT_RESOLUTION = 128
#: Film indices the fit tries, on an eighth of the searched texels: from water's to keratin's
#: (the barbule's cortex: 1.56 at 500 nm, materials/dispersion.py).
IOR_CANDIDATES = (1.33, 1.45, 1.56)
#: Side (searched texels) of the median that picks each texel's film branch.
MEDIAN_SIZE = 5


@dataclass
class FittedLook:
    """Images ``[row, column]`` over the atlas (row 0 = top): ``base_rgba`` (linear Rec. 709 +
    opacity), iridescence ``weight``, ``thickness_nm``, perceptual ``roughness`` and the
    ``substrate``'s F0 (linear RGB); and the film's index ``film_ior``."""

    base_rgba: np.ndarray
    weight: np.ndarray
    thickness_nm: np.ndarray
    roughness: np.ndarray
    substrate: np.ndarray
    film_ior: float


def _searched(texels, step: int) -> tuple[np.ndarray, np.ndarray]:
    """The covered texels on the ``step`` grid, and for every covered texel the position (in
    that subset) of its nearest one."""
    from scipy import ndimage

    resolution = texels.resolution
    rows, cols = np.divmod(texels.index, resolution)
    on_grid = (rows % step == 0) & (cols % step == 0)
    grid = np.zeros((resolution, resolution), dtype=bool)
    grid[rows[on_grid], cols[on_grid]] = True
    _, (near_r, near_c) = ndimage.distance_transform_edt(~grid, return_indices=True)
    slot = np.full(resolution * resolution, -1)
    slot[texels.index[on_grid]] = np.arange(on_grid.sum())
    return np.flatnonzero(on_grid), slot[near_r[rows, cols] * resolution + near_c[rows, cols]]


def _local_median(texels, subset: np.ndarray, values: np.ndarray, step: int) -> np.ndarray:
    """``values`` (one per searched texel) median-filtered over :data:`MEDIAN_SIZE`² searched
    texels of the atlas (texels outside the charts take their nearest searched value)."""
    from scipy import ndimage

    size = -(-texels.resolution // step)
    rows, cols = np.divmod(texels.index[subset], texels.resolution)
    rows, cols = rows // step, cols // step
    image = np.zeros((size, size))
    known = np.zeros((size, size), dtype=bool)
    image[rows, cols], known[rows, cols] = values, True
    _, (near_r, near_c) = ndimage.distance_transform_edt(~known, return_indices=True)
    filled = ndimage.median_filter(image[near_r, near_c], size=MEDIAN_SIZE, mode="nearest")
    return filled[rows, cols]


def _around(texels, subset: np.ndarray, step: int, nearest_fit: np.ndarray) -> np.ndarray:
    """Per covered texel, the searched texels whose films it may take: its nearest and the
    (covered) corners of the ``step`` grid cell it lies in, ``(n, 5)`` (the nearest where a
    corner is not covered)."""
    size = -(-texels.resolution // step) + 1
    slots = np.full((size, size), -1)
    rows, cols = np.divmod(texels.index[subset], texels.resolution)
    slots[rows // step, cols // step] = np.arange(len(subset))
    rows, cols = np.divmod(texels.index, texels.resolution)
    corners = [slots[rows // step + dr, cols // step + dc] for dr in (0, 1) for dc in (0, 1)]
    return np.stack([nearest_fit, *(np.where(c >= 0, c, nearest_fit) for c in corners)], 1)


def _film_of(film, index: np.ndarray) -> tuple:
    """Weight, thickness, roughness and substrate of the searched ``film`` at ``index``."""
    return (
        film.weight[index],
        film.thickness_nm[index],
        film.roughness[index],
        film.substrate[index],
    )


def _best_films(found: LookTargets, film, candidates: np.ndarray, film_ior: float):
    """Per texel of ``found``, the one of its ``candidates`` (searched texels of ``film``,
    ``(n, c)``) whose film, completed by its base (:func:`fit_base`), fits the texel's reflectance
    best: that candidate and the base. Each distinct candidate of a texel is tried once."""
    target, light, views = found.target, found.light, found.views
    pick = candidates[:, 0].copy()
    best = np.full(len(target), np.inf)
    base = np.zeros((len(target), 3))
    for j in range(candidates.shape[1]):
        new = np.all(candidates[:, :j] != candidates[:, j : j + 1], axis=1)
        at, candidate = np.flatnonzero(new), candidates[new, j]
        weight, thickness, roughness, substrate = _film_of(film, candidate)
        fit = fit_base(
            target[at], light[at], views[at], weight, thickness, roughness, film_ior, substrate
        )
        error = fit_error(fit.reflectance, target[at])
        better = error < best[at]
        won = at[better]
        pick[won], best[won], base[won] = candidate[better], error[better], fit.base[better]
    return pick, base


def _best_index(target, light, views) -> float:
    """The film index (one of :data:`IOR_CANDIDATES`) whose free fit of every eighth searched
    texel leaves the smallest mean error (:func:`fit_error`)."""
    few = slice(None, None, 8)
    errors = {}
    for ior in IOR_CANDIDATES:
        fit = fit_film(target[few], light[few], views[few], ior)
        errors[ior] = np.mean(fit_error(fit.reflectance, target[few]))
    return min(errors, key=errors.get)


@dataclass
class LookTargets:
    """What the fit matches, per covered texel of the atlas (``texels``): the model's
    reflectance factors ``target`` ``(n, len(FIT_TILTS_DEG), 3)`` (clipped at 0), the reference
    ``light`` ``(n, 3)`` and ``views`` ``(n, len(FIT_TILTS_DEG), 3)`` in each texel's frame, and
    the texels' ``inputs`` (:func:`~pavonine.pipeline.bake.appearance.reflectance_at_views`)."""

    texels: object
    target: np.ndarray
    light: np.ndarray
    views: np.ndarray
    inputs: dict


def viewer_views(points: np.ndarray, eye: Sequence[float], pivot: Sequence[float]) -> np.ndarray:
    """``(n, len(FIT_TILTS_DEG), 3)``: unit vectors from each of ``points`` (object space) toward
    the ``eye`` turned by each of :data:`~pavonine.pipeline.export.iridescence.FIT_TILTS_DEG`
    about the vertical (+Y) axis through ``pivot`` (as :func:`~pavonine.pipeline.export.
    iridescence.tilted_views` turns a distant viewer: ``R_y(t) = [[cos t, 0, sin t], [0, 1, 0],
    [−sin t, 0, cos t]]``)."""
    eye, pivot = np.asarray(eye, dtype=np.float64), np.asarray(pivot, dtype=np.float64)
    angles = np.radians(np.asarray(FIT_TILTS_DEG, dtype=np.float64))
    c, s = np.cos(angles), np.sin(angles)
    x, y, z = eye - pivot
    eyes = pivot + np.stack([x * c + z * s, np.full_like(c, y), -x * s + z * c], axis=-1)
    toward = eyes[None, :, :] - np.asarray(points, dtype=np.float64)[:, None, :]
    return toward / np.linalg.norm(toward, axis=-1, keepdims=True)


def look_targets(
    material, meshes: list, resolution: int, eye: Sequence[float], pivot: Sequence[float]
) -> LookTargets:
    """The model's reflectance over the atlas of the meshes bound to the feather ``material``
    (merged, their ``st`` atlas rasterised at ``resolution``) at the reference light and the
    views of a viewer at ``eye`` turned by
    :data:`~pavonine.pipeline.export.iridescence.FIT_TILTS_DEG` about the vertical through
    ``pivot`` (:func:`viewer_views`; both in the meshes' space and units)."""
    params, maps, _ = feather_inputs(material)
    vane = merge([mesh_data(prim) for prim in meshes])
    texels = surface_texels(vane, resolution)
    world_views = viewer_views(texels.position, eye, pivot)
    target, inputs = reflectance_at_views(texels, maps, params, REFERENCE_LIGHT, world_views)
    frames = inputs["frames"]
    light = frames @ REFERENCE_LIGHT
    views = np.einsum("nij,nkj->nki", frames, world_views)
    # clipped at 0: the gamut a viewer can show
    return LookTargets(texels, np.clip(target, 0.0, None), light, views, inputs)


def fitted_look(
    material, meshes: list, resolution: int, eye: Sequence[float], pivot: Sequence[float]
) -> FittedLook:
    """Fit the glTF look of the feather ``material`` over the meshes bound to it (merged, their
    ``st`` atlas rasterised at ``resolution``) for a viewer at ``eye`` turned about ``pivot``
    (:func:`look_targets`)."""
    found = look_targets(material, meshes, resolution, eye, pivot)
    texels, target, light, views = found.texels, found.target, found.light, found.views
    inputs = found.inputs
    step = max(1, resolution // FIT_RESOLUTION)
    subset, nearest_fit = _searched(texels, step)
    film_ior = _best_index(target[subset], light[subset], views[subset])
    sub = (target[subset], light[subset], views[subset], film_ior)
    first = fit_film(*sub)
    film = fit_film(*sub, prior_nm=_local_median(texels, subset, first.thickness_nm, step))
    pick, base = _best_films(found, film, _around(texels, subset, step, nearest_fit), film_ior)
    weight, thickness, roughness, substrate = _film_of(film, pick)
    nearest = nearest_covered(texels.covered)

    def image(values: np.ndarray) -> np.ndarray:
        return dilate(scatter(texels, values), nearest)

    return FittedLook(
        base_rgba=image(np.concatenate([base, inputs["alpha"][:, None]], axis=1)),
        weight=image(weight),
        thickness_nm=image(thickness),
        roughness=image(roughness),
        substrate=image(substrate),
        film_ior=film_ior,
    )
