"""Farm scaling: an 8-frame turntable on 1 and 2 local Dask workers, and what a task costs.

1. Scaling: the turntable on 1 worker and on 2 workers, each worker rendering with one Dr.Jit
   thread (a worker stands for a machine's worth of cores): speed-up = T(1) / T(2), target
   >= 1.6 on 2 cores. For reference, also 1 worker with every core (what one process does).
   Each cluster is warmed up first (one frame per worker: imports, kernel compilation); cluster
   start-up is timed separately.
2. Per-task overhead: the Dask round trip of a no-op task (scheduler and transport), and the
   fixed cost of a pavonine task (input hash, USD open and sync, scene build: a 1-spp 8x8 frame),
   bytes sent to the worker (the pickled task) and back (pixels).
3. Throughput of the train for projections: seconds per megapixel-sample on one worker.

Usage: python benchmarks/bench_farm.py [--scene peacock_train] [--resolution 256x192] [--spp 16]
"""

from __future__ import annotations

import argparse
import os
import pickle
import statistics
import tempfile
import time
from dataclasses import replace
from pathlib import Path

SCENES = Path(__file__).parents[1] / "assets" / "scenes"


def noop(x: int) -> int:
    return x


def turntable_jobs(scene: Path, folder: Path, frames: int, size: tuple[int, int]):
    from pavonine.apps.farm.jobs import View, plan
    from pavonine.render.turntable import write_turntable_layer

    layer = folder / "tt.turntable.usda"
    cameras = write_turntable_layer(scene, layer, frames)
    jobs = plan(
        str(layer), folder / "tt.exr", [View("", None)], list(range(frames)), resolution=size
    )
    return [replace(job, camera=cameras[i], time=None) for i, job in enumerate(jobs)]


def timed_batch(workers: int, threads: int, jobs, warm, spp: int) -> tuple[float, float, object]:
    """(start-up seconds, batch seconds, report) on a fresh local cluster."""
    from pavonine.apps.farm.cluster import open_cluster
    from pavonine.apps.farm.render import run_batch

    start = time.perf_counter()
    with open_cluster(workers, threads=threads) as cluster:
        cluster.client.wait_for_workers(workers)
        up = time.perf_counter() - start
        run_batch(warm[:workers], spp=1, cluster=cluster, progress=False)
        begin = time.perf_counter()
        report = run_batch(jobs, spp=spp, cluster=cluster, progress=False)
        return up, time.perf_counter() - begin, report


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scene", default="peacock_train")
    parser.add_argument("--resolution", default="256x192")
    parser.add_argument("--spp", type=int, default=16)
    parser.add_argument("--frames", type=int, default=8)
    args = parser.parse_args()
    size = tuple(int(v) for v in args.resolution.split("x"))
    cores = os.cpu_count() or 1
    scene = SCENES / f"{args.scene}.usda"
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        jobs = turntable_jobs(scene, folder / "a", args.frames, size)
        warm = turntable_jobs(scene, folder / "w", 2, (8, 8))
        up1, one, report1 = timed_batch(1, 1, jobs, warm, args.spp)
        up2, two, report2 = timed_batch(2, 1, jobs, warm, args.spp)
        upw, whole, _ = timed_batch(1, cores, jobs, warm, args.spp)
        print(
            f"{args.frames}-frame turntable of {args.scene}, {args.resolution} @ {args.spp} spp "
            f"({cores} cores):"
        )
        print(f"  1 worker  x 1 thread : {one:6.1f} s  (cluster start {up1:.1f} s)")
        print(f"  2 workers x 1 thread : {two:6.1f} s  (cluster start {up2:.1f} s)")
        print(f"  1 worker  x {cores} threads: {whole:6.1f} s  (cluster start {upw:.1f} s)")
        print(f"  speed-up 2 workers vs 1: {one / two:.2f}x (target >= 1.6)")
        print(f"  speed-up 2 workers vs 1 worker using every core: {whole / two:.2f}x")

        from pavonine.apps.farm.cluster import open_cluster
        from pavonine.apps.farm.render import make_tasks
        from pavonine.apps.farm.tasks import render_task

        with open_cluster(1, threads=1) as cluster:
            client = cluster.client
            client.gather(client.map(noop, range(5), pure=False))
            begin = time.perf_counter()
            client.gather(client.map(noop, range(200), pure=False))
            round_trip = (time.perf_counter() - begin) / 200
            tiny = make_tasks(warm[:1], spp=1, seed=0, shards=1, variant=None, threads=1)[0]
            tiny = replace(tiny, resolution=(8, 8))
            client.submit(render_task, tiny, pure=False).result()
            fixed = []
            for _ in range(5):
                begin = time.perf_counter()
                shard = client.submit(render_task, tiny, pure=False).result()
                fixed.append((time.perf_counter() - begin, shard.seconds["hash"]))
        task_bytes = statistics.mean(
            len(pickle.dumps(t))
            for t in make_tasks(jobs, spp=args.spp, seed=0, shards=1, variant=None, threads=1)
        )
        out_bytes = statistics.mean(t["bytes_out"] for t in report2.tasks)
        per_frame = statistics.mean(t["seconds"]["render"] for t in report1.tasks)
        print(f"  Dask round trip of a no-op task: {round_trip * 1000:.1f} ms")
        print(
            f"  fixed cost of a pavonine task (1 spp, 8x8): {statistics.median(f for f, _ in fixed):.2f} s, "
            f"of which input hash {statistics.median(h for _, h in fixed) * 1000:.0f} ms"
        )
        print(
            f"  bytes per task: {task_bytes:.0f} to the worker, {out_bytes:,.0f} back (float32 RGB)"
        )
        mps = size[0] * size[1] * args.spp / 1e6
        print(
            f"  one render thread: {per_frame:.2f} s per frame = {per_frame / mps:.3f} s per "
            f"megapixel-sample ({args.scene})"
        )


if __name__ == "__main__":
    main()
