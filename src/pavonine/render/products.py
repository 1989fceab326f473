"""The products of a render: which ``RenderProduct``\\ s are rendered, each one's sensor, film and
AOV layers (:class:`ProductJob`), and the sensors that products share.

:mod:`pavonine.render.api` builds one Mitsuba scene with a sensor per product
(:func:`sensor_dict`), sharing one where two products look through the same camera at the same
size (:func:`shared_sensors`), and finishes each product's AOVs after its passes
(:func:`finish_aovs`).
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from typing import Any

import numpy as np

from pavonine.base.errors import InputError
from pavonine.render import aovs as aov_layers
from pavonine.render import camera as camera_translator
from pavonine.render.delegate import StageDelegate
from pavonine.render.diagnostics import Diagnostics
from pavonine.render.limits import RenderLimits
from pavonine.render.settings import DEFAULT_RESOLUTION, ProductSpec


@dataclass
class ProductJob:
    """One product to render: its spec, AOV layers, image and film size, camera and sensor."""

    product: ProductSpec
    plan: aov_layers.AovPlan
    size: tuple[int, int]
    film_width: int
    camera: str | None
    sensor: camera_translator.Sensor


def choose_products(
    products: list[ProductSpec], wanted: list[str] | None, first_only: bool
) -> list[ProductSpec]:
    """The products named by ``wanted`` (prim paths, or prim names that name one product), in
    that order; an :class:`InputError` naming one that is not there. Else all, or the first."""
    if not wanted:
        return products[:1] if first_only else products
    by_path = {p.path: p for p in products if p.path}
    by_name: dict[str, list[ProductSpec]] = {}
    for p in by_path.values():
        by_name.setdefault(p.path.rsplit("/", 1)[-1], []).append(p)
    chosen = []
    for name in wanted:
        found = by_path.get(name)
        if found is None and len(by_name.get(name, [])) == 1:
            found = by_name[name][0]
        if found is None:
            known = ", ".join(by_path) or "none"
            raise InputError("--product", f"no RenderProduct at {name} (products: {known})")
        if found not in chosen:
            chosen.append(found)
    return chosen


def check_product_size(
    product: ProductSpec,
    resolution: tuple[int, int] | None,
    settings_path: str | None,
    limits: RenderLimits,
) -> None:
    """Refuse a product whose image (or square-pixel film) is beyond ``limits.pixels``."""
    where = "resolution" if resolution else f"{product.path or settings_path}.resolution"
    width, height = resolution or product.resolution or DEFAULT_RESOLUTION
    limits.check_resolution((width, height), where)
    film_width = max(1, round(width * product.pixel_aspect))
    if film_width != width:
        limits.check_resolution(
            (film_width, height), f"{product.path or settings_path}.pixelAspectRatio"
        )


def shared_sensors(sensor_dicts: list[dict]) -> list[str]:
    """The scene id of each product's sensor: ``sensor_{index}``, or the id of the first earlier
    product whose sensor (camera, lens, film, size) is the same.

    ``mi.load_dict`` builds one object for equal dictionaries, so two products through one camera
    at one size (a beauty and an AOV product) would find one ``sensor_0`` in the scene and no
    ``sensor_1``; they share the sensor and render each with its own integrator instead.
    """
    seen: dict[str, str] = {}
    ids = []
    for index, entry in enumerate(sensor_dicts):
        ids.append(seen.setdefault(_canonical(entry), f"sensor_{index}"))
    return ids


def sensor_index(scene, sensor_id: str, stage_path: str | os.PathLike) -> int:
    """Index of the sensor ``sensor_id`` in the Mitsuba scene (an :class:`InputError` if Mitsuba
    built none under that id, rather than a ``ValueError`` from deep inside)."""
    ids = [s.id() for s in scene.sensors()]
    if sensor_id not in ids:
        raise InputError(
            os.fspath(stage_path),
            f"Mitsuba's scene has no sensor {sensor_id} (sensors: {', '.join(ids) or 'none'})",
        )
    return ids.index(sensor_id)


def _canonical(value: Any) -> str:
    """A sensor dictionary as text that is equal exactly when the dictionaries are equal (Mitsuba
    transforms as their matrices)."""
    if isinstance(value, dict):
        return "{" + ",".join(f"{k}:{_canonical(value[k])}" for k in sorted(value)) + "}"
    if isinstance(value, (list, tuple)):
        return "[" + ",".join(_canonical(v) for v in value) + "]"
    if hasattr(value, "matrix"):
        return "T" + repr(np.asarray(value.matrix, dtype=np.float64).ravel().tolist())
    return repr(value)


def product_job(
    product: ProductSpec,
    delegate: StageDelegate,
    synced,
    view: tuple[str | None, str],
    resolution: tuple[int, int] | None,
    settings_path: str | None,
    time_code,
    diag: Diagnostics,
) -> ProductJob:
    """The sensor and layers of one product (``view``: the camera asked for, and the framing of a
    stage without one)."""
    camera, framing = view
    width, height = resolution or product.resolution or DEFAULT_RESOLUTION
    film_width = max(1, round(width * product.pixel_aspect))  # Mitsuba's pixels are square
    camera_path = camera or product.camera
    if camera_path is not None and camera_path not in synced.cameras:
        known = ", ".join(sorted(synced.cameras)) or "none"
        where = "--camera" if camera else f"{product.path or settings_path}.camera"
        raise InputError(
            where, f"no visible camera at {camera_path} (cameras in the stage: {known})"
        )
    if camera_path is None and synced.cameras:
        camera_path = sorted(synced.cameras)[0]
    if camera_path is not None:
        prim = synced.cameras[camera_path]
        try:
            sensor = camera_translator.translate_camera(
                prim,
                delegate.xforms.world(prim),
                time_code,
                (width, height),
                product.pixel_aspect,
                product.conform,
                diag,
            )
        except ValueError as exc:
            stack = prim.GetPrimStack()
            layer = stack[0].layer if stack else None
            where = f"{layer.realPath or layer.identifier}: {camera_path}" if layer else camera_path
            raise InputError(where, str(exc).split(": ", 1)[-1]) from None
        if product.disable_dof and sensor.sensor["type"] == "thinlens":
            sensor.sensor["type"] = "perspective"
            del sensor.sensor["aperture_radius"], sensor.sensor["focus_distance"]
    else:
        view = (framing, (width, height), (product.pixel_aspect, product.conform))
        sensor = camera_translator.default_view(delegate.stage, delegate.time, synced, *view, diag)
    plan = aov_layers.plan(product, diag)
    return ProductJob(product, plan, (width, height), film_width, camera_path, sensor)


def finish_aovs(job: ProductJob, images: dict[str, np.ndarray]) -> None:
    """Depth from the camera and white-balanced albedo (see :func:`aovs.finish`)."""
    from pavonine.render.passes import pixel_aspect_resampler

    cosines = None
    if job.plan.distances:
        cosines = aov_layers.pinhole_cosines(job.sensor.sensor, (job.film_width, job.size[1]))
        resample = pixel_aspect_resampler(job.film_width, job.size[0])
        if resample is not None:
            cosines = cosines @ resample.T
    white = aov_layers.albedo_white() if "albedo" in job.plan.aovs else None
    near = float(job.sensor.sensor.get("near_clip", 0.0))
    aov_layers.finish(job.plan, images, cosines, near, white)


def sensor_dict(job: ProductJob) -> dict:
    return {
        **job.sensor.sensor,
        "film": {
            "type": "hdrfilm",
            "width": int(job.film_width),
            "height": int(job.size[1]),
            "pixel_format": "rgba" if job.plan.alpha else "rgb",
            "rfilter": {"type": job.sensor.rfilter},
        },
        "sampler": {"type": "independent"},
    }
