"""A Dask cluster to run on: an embedded ``distributed.LocalCluster`` or an existing scheduler.

``--workers N`` starts N local worker processes (one thread each: one render at a time per
process), each rendering with ``cores // N`` Dr.Jit threads, bound to 127.0.0.1 and without a
dashboard. ``--scheduler ADDRESS`` connects to a running ``dask scheduler`` whose ``dask worker``
processes may be on other machines (``docs/farm.md``).
"""

from __future__ import annotations

import contextlib
import logging
import os
from collections.abc import Iterator
from dataclasses import dataclass

from pavonine.base.errors import InputError

CONNECT_TIMEOUT_S = 20


@dataclass
class Cluster:
    """A connected client, and what the client should tell its tasks."""

    client: object  # distributed.Client
    workers: int
    threads_per_render: int | None  # None: each worker decides (PAVONINE_RENDER_THREADS / cores)
    address: str
    local: bool


#: What a farm option says when Dask is not installed.
NO_FARM = "needs the [farm] extra (no module 'distributed'); install it with: pip install 'pavonine[farm]'"


def farm_installed() -> bool:
    """Dask's ``distributed`` can be imported (the ``[farm]`` extra)."""
    from pavonine.apps.cli.options import importable

    return importable("distributed")


def _distributed():
    try:
        import distributed
    except ImportError:
        raise InputError("--workers/--scheduler", NO_FARM) from None
    return distributed


@contextlib.contextmanager
def open_cluster(
    workers: int | None = None, scheduler: str | None = None, *, threads: int | None = None
) -> Iterator[Cluster]:
    """Connect to ``scheduler`` or start ``workers`` local ones; closes what it started.

    ``threads``: Dr.Jit threads per local render [default: cores // workers].
    """
    distributed = _distributed()
    if scheduler is not None:
        try:
            client = distributed.Client(scheduler, timeout=CONNECT_TIMEOUT_S)
        except (OSError, TimeoutError) as exc:
            raise InputError("--scheduler", f"cannot reach {scheduler}: {exc}") from None
        try:
            count = len(client.scheduler_info().get("workers", {}))
            yield Cluster(client, count, None, scheduler, local=False)
        finally:
            client.close()
        return
    count = max(1, int(workers or 1))
    threads = threads or max(1, (os.cpu_count() or 1) // count)
    cluster = distributed.LocalCluster(
        n_workers=count,
        threads_per_worker=1,
        processes=True,
        host="127.0.0.1",
        # no dashboard, and the scheduler's HTTP server (health, metrics) on a free port: with
        # dashboard_address=None distributed still serves it on 8787, and warns "Port 8787 is
        # already in use" on stderr when something else (a notebook's cluster) holds that port
        dashboard_address=":0",
        scheduler_kwargs={"dashboard": False},
        silence_logs=logging.ERROR,
        env={"PAVONINE_RENDER_THREADS": str(threads)},
    )
    try:
        client = distributed.Client(cluster)
        try:
            yield Cluster(client, count, threads, cluster.scheduler_address, local=True)
        finally:
            client.close()
    finally:
        cluster.close()
