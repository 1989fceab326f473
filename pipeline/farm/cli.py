"""``pavonine render`` for batches: expand frames, turntables, cameras and products into jobs,
pick where they run (this process, local workers, an existing scheduler), run, report."""

from __future__ import annotations

import os
from dataclasses import asdict, replace
from pathlib import Path
from typing import TYPE_CHECKING

import click

from pavonine.pipeline.cli.options import emit_json, log, say, show_progress
from pavonine.pipeline.errors import InputError
from pavonine.pipeline.farm.jobs import View, parse_frames, plan

if TYPE_CHECKING:
    from pavonine.materials.display import DisplayTransform


def product_views(stage_path: Path, products: tuple[str, ...], every: bool) -> list[View]:
    """A view per RenderProduct: its camera and resolution (falling back on its settings')."""
    from pxr import UsdRender

    from pavonine.render.delegate import open_stage
    from pavonine.render.diagnostics import Diagnostics
    from pavonine.render.settings import find_settings

    stage = open_stage(stage_path, Diagnostics())
    settings = find_settings(stage)
    paths = list(products)
    if every:
        if settings is None:
            raise InputError("--all-products", f"{stage_path} has no RenderSettings")
        paths += [
            str(p) for p in settings.GetProductsRel().GetForwardedTargets() if str(p) not in paths
        ]
        if not paths:
            raise InputError("--all-products", f"{settings.GetPath()} has no products")
    views = []
    for path in paths:
        prim = stage.GetPrimAtPath(path)
        if not prim or not prim.IsA(UsdRender.Product):
            raise InputError("--product", f"no RenderProduct at {path}")
        product = UsdRender.Product(prim)
        camera = resolution = None
        for source in (settings, product):
            if source is None:
                continue
            targets = source.GetCameraRel().GetForwardedTargets()
            camera = str(targets[0]) if targets else camera
            if source.GetResolutionAttr().HasAuthoredValue():
                resolution = tuple(int(v) for v in source.GetResolutionAttr().Get())
        if (
            product.GetPixelAspectRatioAttr().HasAuthoredValue()
            or product.GetAspectRatioConformPolicyAttr().HasAuthoredValue()
        ):
            log.warning(
                "%s: a product's pixelAspectRatio and aspectRatioConformPolicy are not applied "
                "per product (the RenderSettings' are)",
                path,
            )
        views.append(View(prim.GetName(), camera, resolution))
    return views


def default_workers(images: int, split: int | None) -> int:
    """Local workers when none were asked for: one per core if there is more than one task."""
    tasks = images * (split or 1)
    return 0 if tasks <= 1 else min(os.cpu_count() or 1, tasks)


def render_batch(
    stage: Path,
    output: Path | None,
    png: bool,
    png_out: Path | None,
    spp: int,
    size: tuple[int, int] | None,
    cameras: tuple[str, ...],
    products: tuple[str, ...],
    all_products: bool,
    frames_text: str | None,
    turntable: int | None,
    variance: bool,
    workers: int | None,
    scheduler: str | None,
    split: int | None,
    time: float | None,
    seed: int,
    variant: str | None,
    display: DisplayTransform,
    json_target: str | None = None,
) -> None:
    """The batch path of ``pavonine render`` (see :mod:`pavonine.pipeline.farm`)."""
    from pavonine.backend import thread_count
    from pavonine.pipeline.farm.cluster import NO_FARM, farm_installed, open_cluster
    from pavonine.pipeline.farm.render import FarmError, run_batch
    from pavonine.render.imageio import check_writable

    if not stage.is_file():
        raise InputError(str(stage), "no such file")
    if workers is not None and scheduler is not None:
        raise InputError("--workers", "give --workers (local cluster) or --scheduler, not both")
    if (scheduler is not None or workers) and not farm_installed():
        raise InputError("--scheduler" if scheduler is not None else "--workers", NO_FARM)
    if turntable and (frames_text or len(cameras) > 1 or products or all_products):
        raise InputError(
            "--turntable", "orbits one camera at one time: drop --frames/--product/extra --camera"
        )
    if (products or all_products) and cameras:
        raise InputError("--product", "a product names its own camera: drop --camera")
    output = output or Path(stage.stem + ".exr")
    if output.suffix.lower() != ".exr":
        raise InputError(str(output), "output must be an .exr file (use --png for a display image)")
    if png_out is not None and png_out.suffix.lower() != ".png":
        raise InputError(f"--png-out {png_out}", "must name a .png file")
    frames = parse_frames(frames_text) if frames_text else None
    stage_path = stage.resolve()
    if turntable:
        from pavonine.render.turntable import write_turntable_layer

        check_writable(output)
        if png_out is not None and turntable > 1:
            raise InputError(
                "--png-out", "names one file; for a batch use --png (a PNG beside each EXR)"
            )
        layer = output.with_name(f"{output.name.split('.')[0]}.turntable.usda")
        paths = write_turntable_layer(
            stage_path, layer, turntable, camera=cameras[0] if cameras else None, time=time
        )
        stage_path = layer.resolve()
        views = [View("", None)]
        frames = list(range(turntable))
        jobs = [
            replace(job, camera=paths[i], time=time)
            for i, job in enumerate(
                plan(
                    str(stage_path),
                    output,
                    views,
                    frames,
                    resolution=size,
                    png=png,
                    variance=variance,
                )
            )
        ]
    else:
        if products or all_products:
            views = product_views(stage_path, products, all_products)
        else:
            views = [View(c.rsplit("/", 1)[-1], c) for c in cameras] or [View("", None)]
        jobs = plan(
            str(stage_path),
            output,
            views,
            frames,
            time=time,
            resolution=size,
            png=png,
            variance=variance,
        )
    if png_out is not None:
        if len(jobs) > 1:
            raise InputError(
                "--png-out", "names one file; for a batch use --png (a PNG beside each EXR)"
            )
        jobs = [replace(jobs[0], png=png_out)]
    for job in jobs:
        for path in (job.output, job.png, job.variance):
            if path is not None:
                check_writable(path)

    if scheduler is None and workers is None:
        workers = default_workers(len(jobs), split)
        if workers and not farm_installed():
            log.info("rendering in this process: local Dask workers need the [farm] extra")
            workers = 0
    use_cluster = scheduler is not None or (workers or 0) > 0

    def show(record) -> None:
        written = " + ".join(
            str(p) for p in (record["exr"], record["png"], record["variance"]) if p
        )
        w, h = record["resolution"]
        say(
            f"{written}: {w}×{h}, {record['spp']} spp"
            + (f" in {record['shards']} shards" if record["shards"] > 1 else "")
        )
        for message in record["warnings"]:
            log.warning("%s", message)

    try:
        if use_cluster:
            with open_cluster(workers, scheduler, threads=thread_count()) as cluster:
                shards = split or (cluster.workers if len(jobs) == 1 else 1)
                report = run_batch(
                    jobs,
                    spp=spp,
                    seed=seed,
                    shards=shards,
                    variant=variant,
                    display=display,
                    cluster=cluster,
                    progress=show_progress(),
                    on_image=show,
                )
        else:
            report = run_batch(
                jobs,
                spp=spp,
                seed=seed,
                shards=split or 1,
                variant=variant,
                display=display,
                progress=show_progress(),
                on_image=show,
            )
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
    warnings = sorted({w for image in report.images for w in image["warnings"]})
    emit_json(
        json_target,
        {
            "images": report.images,
            "spp": spp,
            "seed": seed,
            "variant": report.images[0]["variant"] if report.images else variant,
            "seconds": round(report.seconds, 3),
            "display": asdict(display) if any(i["png"] for i in report.images) else None,
            "warnings": warnings,
            "workers": report.workers,
            "scheduler": report.scheduler,
            "tasks": report.tasks,
        },
    )
