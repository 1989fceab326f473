"""Run a batch of render jobs in this process or on a Dask cluster; write every image atomically.

Each job (an image) becomes one task, or ``shards`` tasks that split its samples (independent
seeds, merged exactly: :mod:`pavonine.apps.farm.merge`). Tasks are submitted at once and
collected as they finish (one progress bar over all of them); an image is written, by this
process only, as soon as its last shard is in. A worker that dies mid-task has its tasks
rescheduled by the Dask scheduler on the others (up to ``distributed.scheduler.allowed-failures``
times, 3 by default); a task that fails is reported and the batch stops, cancelling the rest.
"""

from __future__ import annotations

import pickle
import time
import uuid
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from pavonine.apps.farm.jobs import RenderJob, shard_seed, shards_for
from pavonine.apps.farm.merge import merge_means, merge_variances
from pavonine.apps.farm.tasks import RenderShard, RenderTask, render_task
from pavonine.base.errors import InputError
from pavonine.render.limits import DEFAULT_LIMITS, RenderLimits

if TYPE_CHECKING:
    from pavonine.materials.display import DisplayTransform


class FarmError(Exception):
    """A task failed for a reason other than bad input (a worker lost too often, a crash)."""


@dataclass
class BatchReport:
    """What a batch did: images written, and per task where it ran and what it cost."""

    images: list[dict[str, Any]] = field(default_factory=list)
    tasks: list[dict[str, Any]] = field(default_factory=list)
    seconds: float = 0.0
    workers: int = 0
    scheduler: str | None = None

    def to_json(self) -> dict[str, Any]:
        return {
            "images": self.images,
            "tasks": self.tasks,
            "seconds": round(self.seconds, 3),
            "workers": self.workers,
            "scheduler": self.scheduler,
        }


def make_tasks(
    jobs: list[RenderJob],
    *,
    spp: int,
    seed: int,
    shards: int,
    variant: str | None,
    threads: int | None,
    limits: RenderLimits = DEFAULT_LIMITS,
    max_depth: int | None = None,
    motion_slices: int | None = None,
) -> list[RenderTask]:
    """Every task of a batch; stage contents are hashed here, once per stage."""
    from pavonine import __version__
    from pavonine.apps.compare.baselines import stage_sha256

    hashes: dict[str, str] = {}
    tasks = []
    for index, job in enumerate(jobs):
        if job.stage not in hashes:
            hashes[job.stage] = stage_sha256(job.stage)
        moments = job.variance is not None
        for k, count in enumerate(shards_for(spp, moments, shards)):
            tasks.append(
                RenderTask(
                    stage=job.stage,
                    stage_sha256=hashes[job.stage],
                    spp=count,
                    seed=shard_seed(seed, k),
                    camera=job.camera,
                    product=job.product,
                    time=job.time,
                    resolution=job.resolution,
                    moments=moments,
                    variant=variant,
                    threads=threads,
                    limits=limits,
                    max_depth=max_depth,
                    motion_slices=motion_slices,
                    version=__version__,
                    job=index,
                    shard=k,
                )
            )
    return tasks


def write_image(
    job: RenderJob, parts: list[RenderShard], seed: int, display: DisplayTransform | None = None
) -> dict[str, Any]:
    """Merge a job's shards and write its EXR (+ PNG, + variance) atomically; returns its record.

    A product's AOV layers are merged like the beauty: the sample-weighted mean of the shards'.
    """
    from pavonine.render.imageio import RenderFiles, write_renders

    parts = sorted(parts, key=lambda s: s.shard)
    samples = [p.spp for p in parts]
    rgb = merge_means([p.rgb for p in parts], samples)
    layers = None
    if parts[0].layers is not None:
        layers = [
            (channels, merge_means([p.layers[i][1] for p in parts], samples))
            for i, (channels, _) in enumerate(parts[0].layers)
        ]
    metadata = dict(parts[0].metadata)
    metadata.update(
        spp=int(sum(samples)),
        seed=int(seed),
        shards=len(parts),
        shard_spp=samples,
        shard_seeds=[shard_seed(seed, p.shard) for p in parts],
        workers=sorted({p.worker for p in parts}),
        seconds=round(sum(p.seconds.get("task", 0.0) for p in parts), 3),
        sync_seconds=round(sum(p.seconds.get("sync", 0.0) for p in parts), 4),
    )
    metadata.pop("passes", None)
    variance = None
    if job.variance is not None:
        variance = merge_variances([p.variance for p in parts], samples)
    png = job.png if parts[0].has_beauty else None
    write_renders(
        [RenderFiles(job.output, rgb, metadata, png, layers, job.variance, variance)], display
    )
    return image_record(
        metadata,
        exr=job.output,
        png=png,
        variance=job.variance,
        label=job.label,
        channels=[c for names, _ in layers for c in names] if layers else ["R", "G", "B"],
        shards=len(parts),
        workers=metadata["workers"],
        warnings=sorted({w for p in parts for w in p.warnings}),
    )


def image_record(
    metadata: dict[str, Any],
    *,
    exr,
    png=None,
    variance=None,
    label: str = "",
    channels: list[str] | tuple[str, ...] = ("R", "G", "B"),
    shards: int = 1,
    workers: list[str] | tuple[str, ...] = (),
    warnings: list[str] | tuple[str, ...] = (),
) -> dict[str, Any]:
    """What ``pavonine render --json`` reports of one image written (its ``IMAGE_SCHEMA``)."""
    time_code = metadata.get("time")
    return {
        "exr": str(exr),
        "png": None if png is None else str(png),
        "variance": None if variance is None else str(variance),
        "label": label,
        "camera": metadata.get("camera"),
        "time": float(time_code) if isinstance(time_code, (int, float)) else None,
        "resolution": metadata.get("resolution"),
        "spp": int(metadata["spp"]),
        "variant": metadata.get("variant"),
        "product": metadata.get("product"),
        "channels": list(channels),
        "shards": shards,
        "workers": list(workers),
        "warnings": list(warnings),
        "seconds": _seconds(metadata.get("seconds")),
        "sync_seconds": metadata.get("sync_seconds"),
    }


def _seconds(value: Any) -> float | None:
    """An image's render time (its shards' summed task time on the farm), if recorded."""
    return round(float(value), 3) if isinstance(value, (int, float)) else None


def _task_record(task: RenderTask, shard: RenderShard, task_bytes: int) -> dict[str, Any]:
    return {
        "job": task.job,
        "shard": task.shard,
        "spp": task.spp,
        "worker": shard.worker,
        "seconds": {k: round(v, 4) for k, v in shard.seconds.items()},
        "bytes_in": task_bytes,
        "bytes_out": shard.nbytes,
    }


def run_batch(
    jobs: list[RenderJob],
    *,
    spp: int,
    seed: int = 0,
    shards: int = 1,
    variant: str | None = None,
    display: DisplayTransform | None = None,
    cluster=None,
    progress: bool = True,
    on_image: Callable[[dict[str, Any]], None] | None = None,
    limits: RenderLimits = DEFAULT_LIMITS,
    max_depth: int | None = None,
    motion_slices: int | None = None,
) -> BatchReport:
    """Render ``jobs`` (module docstring); ``cluster`` from :func:`~.cluster.open_cluster`, or
    ``None`` to render one task after another in this process."""
    from rich.console import Console
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        TextColumn,
        TimeElapsedColumn,
        TimeRemainingColumn,
    )

    started = time.perf_counter()
    threads = None if cluster is None else cluster.threads_per_render
    tasks = make_tasks(
        jobs, spp=spp, seed=seed, shards=shards, variant=variant, threads=threads, limits=limits,
        max_depth=max_depth, motion_slices=motion_slices,
    )  # fmt: skip
    per_job: dict[int, list[RenderShard]] = {}
    needed = {i: sum(1 for t in tasks if t.job == i) for i in range(len(jobs))}
    report = BatchReport(
        workers=0 if cluster is None else cluster.workers,
        scheduler=None if cluster is None else cluster.address,
    )
    where = "in this process" if cluster is None else f"on {cluster.workers} worker(s)"
    columns = (
        TextColumn(f"render {len(jobs)} image(s), {len(tasks)} task(s) {where}"),
        BarColumn(),
        MofNCompleteColumn(),
        TimeElapsedColumn(),
        TimeRemainingColumn(),
    )
    with Progress(*columns, console=Console(stderr=True), disable=not progress) as bar:
        bar_task = bar.add_task("tasks", total=len(tasks))

        def collect(task: RenderTask, shard: RenderShard) -> None:
            size = len(pickle.dumps(task))
            report.tasks.append(_task_record(task, shard, size))
            per_job.setdefault(task.job, []).append(shard)
            if len(per_job[task.job]) == needed[task.job]:
                record = write_image(jobs[task.job], per_job.pop(task.job), seed, display)
                report.images.append(record)
                if on_image is not None:
                    on_image(record)
            bar.advance(bar_task)

        if cluster is None:
            for task in tasks:
                collect(task, render_task(task))
        else:
            _run_on_cluster(cluster.client, tasks, collect)
    report.images.sort(key=lambda r: r["exr"])
    report.seconds = time.perf_counter() - started
    return report


def _run_on_cluster(client, tasks: list[RenderTask], collect) -> None:
    """Submit every task, collect each as it completes; on failure cancel the rest and raise."""
    from distributed import as_completed

    batch = uuid.uuid4().hex[:8]
    futures = {
        client.submit(
            render_task, task, key=f"pavonine-render-{batch}-{task.job}-{task.shard}", pure=False
        ): task
        for task in tasks
    }
    try:
        for future in as_completed(list(futures)):
            task = futures[future]
            try:
                shard = future.result()
            except InputError:
                raise
            except Exception as exc:  # KilledWorker, a crash in the renderer, ...
                name = type(exc).__name__
                raise FarmError(f"task {future.key} failed ({name}: {exc})") from None
            collect(task, shard)
            future.release()
    finally:
        client.cancel([f for f in futures if not f.done()])


def shard_bytes(width: int, height: int, variance: bool) -> int:
    """Bytes of pixels one task sends back: float32 RGB (and its variance)."""
    return int(width * height * 3 * np.dtype(np.float32).itemsize * (2 if variance else 1))
