"""``pavonine render`` beyond one image at one time: what to render (RenderProducts, cameras), and
the farm path (frames, turntables, sample shards) in this process or on a Dask cluster."""

from __future__ import annotations

import os
import warnings
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import click

from pavonine.apps.cli.options import log, say, show_progress
from pavonine.apps.farm.jobs import RenderJob, View, parse_frames, plan
from pavonine.base.errors import InputError
from pavonine.render.limits import DEFAULT_LIMITS, RenderLimits

if TYPE_CHECKING:
    from pavonine.materials.display import DisplayTransform
    from pavonine.render.settings import RenderSettingsSpec


def stage_settings(stage: Path) -> RenderSettingsSpec:
    """The stage's render settings, read before rendering (quietly: the render itself warns)."""
    from pavonine.render.delegate import open_stage
    from pavonine.render.diagnostics import Diagnostics
    from pavonine.render.settings import read_render_settings

    diag = Diagnostics()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return read_render_settings(open_stage(stage, diag), diag)


def render_views(
    settings: RenderSettingsSpec, products: tuple[str, ...], cameras: tuple[str, ...]
) -> list[View]:
    """What to render, before rendering: every RenderProduct of the stage's settings (or those
    ``--product`` names; a stage without products: one view), each through its own camera or,
    for every ``--camera`` given, through that one.

    A view's name is what sets it apart from the first (product, camera): the product's prim
    name for a later product, the camera's for a later camera, both for a later pair
    (``Tall.CamB``); only the first camera's view of a product keeps its ``productName``.
    """
    from pavonine.render.products import choose_products

    chosen = choose_products(settings.products, list(products) or None, False)
    views = []
    for i, product in enumerate(chosen):
        product_prim = (product.path or "").rsplit("/", 1)[-1]
        for j, camera in enumerate(cameras or (None,)):
            camera_prim = (camera or "").rsplit("/", 1)[-1]
            parts = (product_prim if i else "", camera_prim if j else "")
            name = ".".join(p for p in parts if p) or product_prim or camera_prim
            product_name = product.product_name if j == 0 else ""
            views.append(View(name, camera, product.path, product_name))
    return views


def needs_farm(
    frames: str | None,
    turntable: int | None,
    workers: int | None,
    scheduler: str | None,
    split: int | None,
    cameras: tuple[str, ...],
) -> bool:
    """Frames, turntables, workers, a scheduler, sample shards or several cameras go through
    :func:`render_batch`; one time code of one or more products renders in this process."""
    return bool(frames or turntable or workers or scheduler or split or len(cameras) > 1)


def default_workers(images: int, split: int | None) -> int:
    """Local workers when none were asked for: one per core if there is more than one task."""
    tasks = images * (split or 1)
    return 0 if tasks <= 1 else min(os.cpu_count() or 1, tasks)


@dataclass
class BatchPlan:
    """A farm call, checked before anything is rendered or written."""

    jobs: list[RenderJob]
    #: a turntable: its layer (written first) and the camera it starts from; job ``i`` renders
    #: frame ``i % frames`` through that frame's orbit camera
    turntable: tuple[Path, int, str | None] | None = None


def plan_batch(
    stage: Path,
    views: list[View],
    output: Path | None,
    png: bool,
    png_out: Path | None,
    size: tuple[int, int] | None,
    frames_text: str | None,
    turntable: int | None,
    variance: bool,
    workers: int | None,
    scheduler: str | None,
    time: float | None,
) -> BatchPlan:
    """The jobs of a farm call (names: :func:`~pavonine.apps.farm.jobs.view_outputs`)."""
    from pavonine.apps.farm.cluster import NO_FARM, farm_installed

    if workers is not None and scheduler is not None:
        raise InputError("--workers", "give --workers (local cluster) or --scheduler, not both")
    if (scheduler is not None or workers) and not farm_installed():
        raise InputError("--scheduler" if scheduler is not None else "--workers", NO_FARM)
    if turntable and (frames_text or len({v.camera for v in views}) > 1):
        raise InputError(
            "--turntable", "orbits one camera at one time: drop --frames and extra --camera"
        )
    frames = parse_frames(frames_text) if frames_text else None
    stage_path = stage.resolve()
    common = dict(resolution=size, png=png, variance=variance, named_after=stage)
    if not turntable:
        jobs = plan(str(stage_path), output, views, frames, time=time, **common)
        return BatchPlan(_with_png_out(jobs, png_out))
    first = plan(str(stage_path), output, views, None, **common)[0].output
    layer = first.with_name(f"{first.name.split('.')[0]}.turntable.usda")
    jobs = plan(str(layer.resolve()), output, views, list(range(turntable)), **common)
    jobs = [replace(job, time=time) for job in jobs]  # frame numbers, not time codes
    return BatchPlan(_with_png_out(jobs, png_out), (layer, turntable, views[0].camera))


def _with_png_out(jobs: list[RenderJob], png_out: Path | None) -> list[RenderJob]:
    if png_out is None:
        return jobs
    if len(jobs) > 1:
        raise InputError(
            "--png-out", "names one file; for a batch use --png (a PNG beside each EXR)"
        )
    return [replace(jobs[0], png=png_out)]


def render_batch(
    stage: Path,
    batch: BatchPlan,
    *,
    spp: int,
    workers: int | None,
    scheduler: str | None,
    split: int | None,
    seed: int,
    variant: str | None,
    display: DisplayTransform,
    on_image,
    limits: RenderLimits = DEFAULT_LIMITS,
    max_depth: int | None = None,
    motion_slices: int | None = None,
) -> dict[str, Any]:
    """Run a planned farm call (see :mod:`pavonine.apps.farm`); returns its report fields."""
    from pavonine.apps.farm.cluster import farm_installed, open_cluster
    from pavonine.apps.farm.render import FarmError, run_batch
    from pavonine.base.backend import thread_count

    jobs = batch.jobs
    if batch.turntable is not None:
        from pavonine.render.turntable import write_turntable_layer

        layer, frames, start = batch.turntable
        cameras = write_turntable_layer(
            stage.resolve(), layer, frames, camera=start, time=jobs[0].time
        )
        jobs = [replace(job, camera=cameras[i % frames]) for i, job in enumerate(jobs)]
    if scheduler is None and workers is None:
        workers = default_workers(len(jobs), split)
        if workers and not farm_installed():
            log.info("rendering in this process: local Dask workers need the [farm] extra")
            workers = 0
    use_cluster = scheduler is not None or (workers or 0) > 0
    options = dict(
        spp=spp, seed=seed, variant=variant, display=display, on_image=on_image, limits=limits,
        max_depth=max_depth, motion_slices=motion_slices,
    )  # fmt: skip
    try:
        if use_cluster:
            with open_cluster(workers, scheduler, threads=thread_count()) as cluster:
                shards = split or (cluster.workers if len(jobs) == 1 else 1)
                report = run_batch(
                    jobs, shards=shards, cluster=cluster, progress=show_progress(), **options
                )
        else:
            report = run_batch(jobs, shards=split or 1, progress=show_progress(), **options)
    except FarmError as exc:
        click.echo(f"error: farm: {exc}", err=True)
        raise SystemExit(1) from None
    where = (
        "in this process"
        if not use_cluster
        else f"on {report.workers} worker(s) ({report.scheduler})"
    )
    say(
        f"{len(report.images)} image(s), {len(report.tasks)} task(s) {where}, {report.seconds:.1f} s"
    )
    return {
        "images": report.images,
        "seconds": round(report.seconds, 3),
        "workers": report.workers,
        "scheduler": report.scheduler,
        "tasks": report.tasks,
    }
