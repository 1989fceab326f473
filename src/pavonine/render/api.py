"""``render_stage`` / ``render_products``: a USD stage to scene-linear spectral images.

The stage is translated once by :class:`~pavonine.render.delegate.StageDelegate`; every
``RenderProduct`` of its render settings (:mod:`.settings`) gets its own Mitsuba sensor (camera,
resolution, pixel aspect) in one scene, and is rendered with the ``pavonine_path`` integrator
(:mod:`.integrator`; Mitsuba's ``volpath`` in scalar variants) — inside
an ``aov`` integrator when its ``RenderVar``\\ s ask for AOVs (:mod:`.aovs`) — in the chosen
spectral variant (``llvm_ad_spectral`` by default), with a box pixel filter so that each pixel is
the plain mean of its samples, progressively in passes (:mod:`.passes`).

:func:`render_stage` renders one product (the first, or the one named) and returns its
:class:`RenderResult`; :func:`render_products` renders them all.
"""

from __future__ import annotations

import gc
import os
import time as _time
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from pxr import Usd

from pavonine.base.backend import select_variant
from pavonine.base.errors import InputError
from pavonine.render import aovs as aov_layers
from pavonine.render import camera as camera_translator
from pavonine.render import displacement, instance_primvars, lights, sensors
from pavonine.render.delegate import StageDelegate, open_stage, render_time
from pavonine.render.diagnostics import Diagnostics, first_line
from pavonine.render.imageio import write_exr, write_png
from pavonine.render.integrator_settings import DEFAULT_SPP, check_variant
from pavonine.render.motion import blur
from pavonine.render.motion import reach as motion_reach
from pavonine.render.options import RenderOptions, check_spp
from pavonine.render.passes import render_passes
from pavonine.render.products import (
    ProductJob,
    check_product_size,
    choose_products,
    finish_aovs,
    product_job,
    sensor_dict,
    sensor_index,
    shared_sensors,
)
from pavonine.render.progress import SampleProgress
from pavonine.render.scene_ids import scene_keys, scene_objects
from pavonine.render.settings import ProductSpec, read_render_settings

__all__ = [
    "RenderOptions",
    "RenderResult",
    "render_products",
    "render_stage",
    "write_exr",
    "write_png",
]


@dataclass
class RenderResult:
    """A finished render of one product."""

    rgb: np.ndarray  # H×W×3 float32, scene-linear Rec.709 (sRGB primaries, D65): the beauty
    variance: np.ndarray | None  # H×W×3 variance of each pixel's estimate (``moments=True``)
    metadata: dict[str, Any]
    warnings: list[str] = field(default_factory=list)
    layers: list[aov_layers.Layer] = field(default_factory=list)  # the product's EXR, in order
    images: dict[str, np.ndarray] = field(default_factory=dict)  # layer name → H×W×C pixels
    product: ProductSpec = field(default_factory=ProductSpec)

    @property
    def has_beauty(self) -> bool:
        """True when the product's file holds the beauty image (so a display PNG makes sense)."""
        return any(layer.source == "beauty" for layer in self.layers)

    def exr_layers(self) -> list[tuple[tuple[str, ...], np.ndarray]]:
        """(channel names, H×W×C pixels) of every layer, in the product's order."""
        return [(layer.channels, self.images[layer.name]) for layer in self.layers]


def render_stage(
    stage_path: str | os.PathLike,
    options: RenderOptions | None = None,
    /,
    *,
    product: str | None = None,
    **changes: Any,
) -> RenderResult:
    """Render one product of ``stage_path``: the first, or the ``RenderProduct`` at ``product``.

    ``options`` (:class:`~pavonine.render.options.RenderOptions`), with ``changes`` to its fields
    as keywords (``spp``, ``max_depth``, ``resolution``, ``seed``, ``camera``, ``framing``,
    ``time``, ``variant``, ``moments``, ``progress``, ``limits``).
    """
    chosen = [product] if product else None
    options = (options or RenderOptions()).but(
        **changes, products=chosen, first_only=product is None
    )
    return render_products(stage_path, options)[0]


def render_products(
    stage_path: str | os.PathLike, options: RenderOptions | None = None, /, **changes: Any
) -> list[RenderResult]:
    """Render every product of the stage's render settings (or the ones ``options.products``
    names), as ``options`` (:class:`~pavonine.render.options.RenderOptions`, with ``changes`` to
    its fields as keywords) asks.

    ``resolution`` and ``camera`` override every product's; a stage without settings renders one
    beauty image. A stage without a camera is seen through USD's default view (``framing="usd"``:
    usdrecord's camera, :func:`.camera.usd_view_camera`) or Pavonine's ``"portrait"`` framing of a
    flat asset (:func:`.camera.portrait_camera`); see :func:`.camera.default_view`. ``spp``
    defaults to the settings' ``mitsuba:sample_count``, else :data:`DEFAULT_SPP`; ``max_depth`` (-1: no limit) overrides the settings' integrator
    (:mod:`.integrator_settings`). Warnings are shared by all results. ``limits``
    (:mod:`.limits`) are checked before the stage is translated: image sizes and ``spp`` first,
    instance counts as instancers are met. An image with NaN or infinite pixels is an
    :class:`InputError`, never a result. A camera whose shutter is open over an interval blurs
    what moves in it (:mod:`.motion.blur`).
    """
    options = (options or RenderOptions()).but(**changes)
    return RenderSession(stage_path, options).render()


class RenderSession:
    """A stage synced once into one Mitsuba scene, rendered at its time and then, for frames, at
    others: as a Hydra delegate syncs frames, only the time-varying prims are translated again
    (:class:`.motion.blur.MotionPlan`) and moved in the scene in place; when something varies
    that the plan cannot move (a light, a lens, changing topology, the framing of a stage without
    camera), the next frame is synced in full. ``sync_seconds`` holds each frame's sync time."""

    def __init__(self, stage_path: str | os.PathLike, options: RenderOptions):
        options.check()
        self.stage_path, self.options = stage_path, options
        self.sync_seconds: list[float] = []
        self.last_sync = "full"  # or "moved": only the time-varying prims, to this frame
        self._build(options.time)

    def _build(self, time: float | None) -> None:
        options, stage_path = self.options, self.stage_path
        camera, framing, variant = options.camera, options.framing, options.variant
        resolution, limits, spp = options.resolution, options.limits, options.spp
        self.backend = backend = _select(variant)
        import mitsuba as mi

        self.started = started = _time.perf_counter()
        self.diag = diag = Diagnostics()
        self.stage = stage = open_stage(stage_path, diag)
        self.time_code = time_code = render_time(stage, time)
        self.settings = settings = read_render_settings(stage, diag)
        if settings.path is not None:
            check_variant(stage.GetPrimAtPath(settings.path), backend.variant, diag)
        if spp is None:
            spp = settings.sample_count or DEFAULT_SPP
            check_spp(spp, options.moments, limits, settings.sample_count_field or "spp")
        self.spp = spp
        chosen = choose_products(settings.products, options.products, options.first_only)
        for product in chosen:
            check_product_size(product, resolution, settings.path, limits)
        self.delegate = delegate = StageDelegate(
            stage, time_code, diag, limits=limits, progress=options.progress
        )
        synced = delegate.sync()
        if synced.bounds is None:
            diag.warn(str(stage_path), "the stage has no renderable geometry")
        self.jobs = jobs = [
            product_job(
                p, delegate, synced, (camera, framing), resolution, settings.path, time_code, diag
            )
            for p in chosen
        ]
        emitters = dict(synced.emitters)
        default_lights = not emitters and not synced.mesh_lights and not synced.dark_lights
        if default_lights:
            up = np.eye(3)[2 if synced.up_axis == "Z" else 1]
            center, radius = delegate.bounding_sphere()
            emitters = lights.default_lights(jobs[0].sensor.to_world, up, center, radius)

        scene_dict: dict[str, Any] = {"type": "scene"}
        shapes = dict(synced.shapes)
        self.sensor_ids = sensor_ids = shared_sensors([sensor_dict(job) for job in jobs])
        for index, job in enumerate(jobs):
            if sensor_ids[index] != f"sensor_{index}":
                continue  # the same camera, film and size as an earlier product: its sensor
            if job.sensor.sensor["type"] != "irradiancemeter":
                scene_dict[f"sensor_{index}"] = sensor_dict(job)
                continue
            meter = sensors.attach_meter(shapes, stage, job.camera, sensor_dict(job), diag)
            if meter is None:  # warned: through the camera's lens instead
                prim = synced.cameras[job.camera]
                job.sensor = camera_translator.translate_camera(
                    prim,
                    delegate.xforms.world(prim),
                    time_code,
                    job.size,
                    job.product.pixel_aspect,
                    job.product.conform,
                    Diagnostics(),  # its settings were read (and warned about) once already
                    lens_only=True,
                )
                scene_dict[f"sensor_{index}"] = sensor_dict(job)
            else:
                meter.set_id(f"sensor_{index}")
        keys, _ = scene_keys(shapes, emitters)
        scene_dict.update(scene_objects(shapes, emitters))
        views = [
            displacement.view_of(j.sensor.sensor, j.sensor.to_world, (j.film_width, j.size[1]))
            for j in jobs
            if j.sensor.sensor["type"] != "irradiancemeter"
        ]
        displacement.resolve(scene_dict, views, synced.bounds, diag)
        gc.collect()  # see passes.render_pass
        try:
            # Built in order, not on Mitsuba's thread pool: registry ids (which Dr.Jit writes into
            # the kernel, e.g. the environment emitter's) then follow the dict, so the same stage
            # traces the same kernel and finds it in Dr.Jit's disk cache. In parallel the train's
            # sky got id 1 or 2 from run to run (2 of 5 runs), each form an LLVM compile of its own.
            self.scene = scene = mi.load_dict(scene_dict, parallel=False)
        except Exception as exc:
            raise InputError(
                os.fspath(stage_path), f"Mitsuba could not build the scene: {first_line(exc)}"
            ) from None
        instance_primvars.bind(scene, delegate.table, delegate.feather_bsdfs)
        self.shutters = [
            blur.read_shutter(
                synced.cameras.get(job.camera) if job.camera else None,
                time_code,
                job.product.disable_blur,
                diag,
            )
            for job in jobs
        ]
        self.frame = blur.frame_time(time_code)
        if self.frame is None and any(s.blurred for s in self.shutters):
            diag.warn(str(stage_path), "no numeric time code: rendered without motion blur")
            self.shutters = [blur.Shutter() for _ in jobs]
        self.params = None
        self.plan = None
        blurred = any(s.blurred for s in self.shutters)
        if blurred or self.frame is not None:
            cameras = [
                (synced.cameras[job.camera], sensor_ids[i], self._camera_mover(job))
                for i, job in enumerate(jobs)
                if job.camera and job.sensor.sensor["type"] != "irradiancemeter"
                and sensor_ids[i] == f"sensor_{i}"
            ]  # fmt: skip
            self.plan = blur.plan_motion(delegate, keys, cameras, diag, warn=blurred)
            self.plan.scene = scene
            if default_lights and (self.plan.cameras or not self.plan.static):
                self.plan.fixed.append("(the default lights, placed by the camera and bounds)")
            if any(job.camera is None for job in jobs) and not self.plan.static:
                self.plan.fixed.append("(the framing of a stage without camera)")
            if not self.plan.static:
                self.params = mi.traverse(scene)

        if options.max_depth is not None and settings.integrator.type == "direct":
            diag.warn(
                str(settings.path), "max_depth has no effect: the stage asks for direct light"
            )
        self.integrator_spec = settings.integrator.with_max_depth(options.max_depth).for_variant(
            backend.variant
        )
        path_tracer = self.integrator_spec.mitsuba_dict()
        self.integrators = [mi.load_dict(job.plan.integrator(path_tracer)) for job in jobs]
        self.sync_seconds.append(_time.perf_counter() - started)

    @staticmethod
    def _camera_mover(job: ProductJob):
        """``(prim, view, time) → to_world`` (Mitsuba layout) of the job's camera at another time."""

        def to_world(prim, view, time):
            try:
                sensor = camera_translator.translate_camera(
                    prim,
                    view.xforms.world(prim),
                    time,
                    job.size,
                    job.product.pixel_aspect,
                    job.product.conform,
                    Diagnostics(),
                )
            except ValueError:
                return None  # NaN at this time: the camera stays where it was
            return np.asarray(sensor.sensor["to_world"].matrix, dtype=np.float64)

        return to_world

    def render(
        self, time: float | None = None, seed: int | None = None, spp: int | None = None
    ) -> list[RenderResult]:
        """The images at ``time`` (default: the time the session was synced at)."""
        import drjit as dr

        seed = self.options.seed if seed is None else seed
        spp = self.spp if spp is None else spp
        started = _time.perf_counter()
        moved_frame = False
        if time is not None and blur.frame_time(render_time(self.stage, time)) != self.frame:
            if self.plan is None or not self.plan.complete or self.frame is None:
                self.sync_seconds.pop()  # replaced by this frame's full sync
                self._build(time)
                self.last_sync = "full"
            else:
                # The plan moves the scene when a product is first rendered at this frame: to
                # the frame's time, or straight to a blurred product's first slice (a retime to
                # the frame first would be undone by it); that retime is the frame's sync.
                self.frame = float(time)
                self.time_code = Usd.TimeCode(time)
                self.last_sync, moved_frame = "moved", True
        options, jobs = self.options, self.jobs
        results = []
        sizes = [job.size for job in jobs]
        moves: list[float] = []  # the seconds of each retime of this render, in order
        with SampleProgress(self.stage_path, sizes, spp, options.progress) as advance:
            for index, job in enumerate(jobs):
                image, variance, passes, times, reach = self._render_job(
                    index, job, spp, seed, advance, moves
                )
                images = job.plan.split(image)
                finish_aovs(job, images)
                results.append(
                    self._result(job, image, variance, images, passes, seed, spp, times, reach)
                )
        if moved_frame:  # its sync: the first retime, to the frame or to its first slice
            self.sync_seconds.append(moves[0] if moves else 0.0)
        dr.sync_thread()
        for result in results:
            check_finite_image(result, self.stage_path)
        seconds = round(_time.perf_counter() - min(started, self.started), 3)
        self.started = _time.perf_counter()
        for result in results:
            result.metadata["seconds"] = seconds
            result.metadata["sync_seconds"] = round(self.sync_seconds[-1], 4)
            result.metadata["sync"] = self.last_sync
            result.warnings = list(self.diag.messages)
        return results

    def _render_job(
        self, index: int, job: ProductJob, spp: int, seed: int, advance, moves: list[float]
    ):
        """(image, variance, passes, slice times, motion reach in pixels or None) of one product:
        its shutter's slices, each rendered where the plan moves the scene, samples split across
        them (:mod:`.motion.blur`)."""
        shutter = self.shutters[index]
        sensor = sensor_index(self.scene, self.sensor_ids[index], self.stage_path)
        reach = self._reach(shutter, sensor)
        needed = motion_reach.slices_for(reach)
        slices = blur.slice_count(
            shutter, spp, self.options.motion_slices, self.options.moments, needed
        )
        times = shutter.times(self.frame or 0.0, slices, seed) if shutter.blurred else [self.frame]
        counts = blur.slice_spp(spp, slices)
        total = variance_sum = None
        passes = 0
        for i, (when, count) in enumerate(zip(times, counts, strict=True)):
            if self.plan is not None and self.params is not None and when is not None:
                moves.append(self.plan.retime(self.params, when, self.diag, base=self.frame))
            image, variance, slice_passes = render_passes(
                self.scene,
                sensor,
                self.integrators[index],
                count,
                blur.slice_seed(seed, i, slices),
                (job.film_width, job.size[1]),
                job.size[0],
                self.options.moments,
                advance,
                trace_loops_once=bool(self.delegate.table.instances),
            )
            weight = count / spp
            if weight != 1.0:  # one slice (no blur): the image itself, no frame-sized copy
                image = image * weight
            total = image if total is None else total + image
            if variance is not None:
                part = variance * weight * weight
                variance_sum = part if variance_sum is None else variance_sum + part
            passes += slice_passes
        # The scene stays at the last slice's time: whatever renders next retimes it first.
        return total.astype(np.float32), variance_sum, passes, times, reach

    def _reach(self, shutter: blur.Shutter, sensor: int) -> float | None:
        """How far the moving scene travels in the image while the shutter is open, in pixels
        (:mod:`.motion.reach`; 0 when nothing varies), by which the slices are chosen; ``None``
        (the samples decide) when the slices are asked for or the motion cannot be followed."""
        if not shutter.blurred or self.options.motion_slices is not None or self.plan is None:
            return None
        if self.plan.static:
            return 0.0
        return motion_reach.reach_pixels(
            self.plan, self.scene.sensors()[sensor], self.frame or 0.0, shutter.open, shutter.close
        )

    def _result(
        self, job, image, variance, images, passes, seed, spp, times, reach
    ) -> RenderResult:
        width, height = job.size
        metadata = {
            "stage": os.fspath(self.stage_path),
            "variant": self.backend.variant,
            "spp": int(spp),
            "integrator": self.integrator_spec.describe(),
            "seed": int(seed),
            "resolution": [int(width), int(height)],
            "camera": job.camera or "(framing camera)",
            "sensor": job.sensor.sensor["type"],  # irradiancemeter: a meter's estimates
            "time": _time_label(self.time_code),
            "passes": int(passes),
            "colorspace": "lin_rec709_scene",
            "versions": _versions(),
        }
        shutter = self.shutters[self.jobs.index(job)]
        if shutter.blurred:
            metadata["shutter"] = [shutter.open, shutter.close]
            metadata["time_slices"] = len(times)
            if reach is not None:
                metadata["motion_reach_px"] = round(reach, 2)
        if job.product.path:
            metadata["product"] = job.product.path
            metadata["productName"] = job.product.product_name
            metadata["layers"] = {ly.name or "beauty": ly.var or "" for ly in job.plan.layers}
        return RenderResult(
            rgb=np.ascontiguousarray(image[..., :3]),
            variance=variance,
            metadata=metadata,
            layers=job.plan.layers,
            images=images,
            product=job.product,
        )


def check_finite_image(result: RenderResult, stage_path: str | os.PathLike) -> None:
    """An :class:`InputError` if any pixel of any layer is NaN or infinite.

    Non-finite input is caught where it is read (warnings naming prim and attribute); this is the
    last guard, so that a NaN image is never written and reported as a success.
    """
    images = {"beauty": result.rgb, **result.images}
    for name, pixels in images.items():
        bad = int(np.count_nonzero(~np.isfinite(pixels)))
        if bad:
            raise InputError(
                os.fspath(stage_path),
                f"the render's {name} has {bad} NaN or infinite values (non-finite input the "
                "renderer did not catch); nothing written",
            )


def _time_label(time_code) -> Any:
    if time_code.IsDefault():
        return "default"
    return "earliest" if time_code.IsEarliestTime() else float(time_code.GetValue())


def _select(variant: str | None):
    try:
        return select_variant(variant)
    except (ImportError, ValueError, AttributeError) as exc:
        raise InputError(
            "--variant", f"cannot use Mitsuba variant {variant!r}: {first_line(exc)}"
        ) from None


def _versions() -> dict[str, str]:
    import drjit
    import mitsuba
    from pxr import Usd

    from pavonine import __version__

    return {
        "pavonine": __version__,
        "mitsuba": mitsuba.__version__,
        "drjit": drjit.__version__,
        "usd": ".".join(str(v) for v in Usd.GetVersion()),
    }
