"""What a worker runs: one render shard or one conversion, from paths on shared storage.

Tasks carry paths, never file contents: every machine must see the stage (or recipe) and all
it uses at the same path (shared storage; ``docs/farm.md``). Before working, a task hashes its
inputs by content where it runs (:func:`pavonine.apps.compare.baselines.stage_sha256`: every
layer and map the stage uses) and refuses to run if they differ from what the client hashed, so
a stale mount or a half-synced copy fails loudly instead of rendering something else. Results
travel back to the client, which alone writes outputs (atomically); a worker writes nothing
outside its own temporary folder.

One render runs at a time per worker process (a lock: Mitsuba's JIT and the feather BSDF's
Python callbacks are not meant to share a process between concurrent renders); its Dr.Jit
thread pool has ``threads`` threads (the client's choice for local workers, else
``PAVONINE_RENDER_THREADS``, else all cores).
"""

from __future__ import annotations

import contextlib
import logging
import os
import shutil
import socket
import tempfile
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from pavonine.base.errors import InputError
from pavonine.render.limits import DEFAULT_LIMITS, RenderLimits
from pavonine.render.options import RenderOptions

_RENDER_LOCK = threading.Lock()
THREADS_ENV = "PAVONINE_RENDER_THREADS"


class InputMismatch(InputError):
    """A task's input differs (by content) from what the client submitted."""


@dataclass(frozen=True)
class RenderTask:
    """One render (a frame, or one shard of a frame's samples)."""

    stage: str
    stage_sha256: str
    spp: int
    seed: int
    camera: str | None = None
    product: str | None = None  # the RenderProduct prim (its resolution, RenderVars)
    time: float | None = None
    resolution: tuple[int, int] | None = None
    moments: bool = False
    variant: str | None = None
    threads: int | None = None
    limits: RenderLimits = DEFAULT_LIMITS  # the client's render ceilings (--max-…)
    max_depth: int | None = None  # --max-depth (None: the stage's integrator settings)
    motion_slices: int | None = None  # --motion-slices (None: render.motion.blur.DEFAULT_SLICES)
    version: str = ""
    job: int = 0
    shard: int = 0

    def render_options(self) -> RenderOptions:
        """What :func:`pavonine.render.api.render_stage` is asked for (no progress bar: a worker
        reports its shard when it is done)."""
        return RenderOptions(
            spp=self.spp,
            max_depth=self.max_depth,
            resolution=self.resolution,
            seed=self.seed,
            camera=self.camera,
            time=self.time,
            variant=self.variant,
            moments=self.moments,
            progress=False,
            limits=self.limits,
            motion_slices=self.motion_slices,
        )


@dataclass
class RenderShard:
    """What comes back: pixels (and variance), the renderer's metadata, where and how long."""

    job: int
    shard: int
    spp: int
    rgb: np.ndarray
    variance: np.ndarray | None
    metadata: dict[str, Any]
    warnings: list[str]
    worker: str
    seconds: dict[str, float] = field(default_factory=dict)
    #: the product's EXR layers (channel names, pixels), beauty included; ``None``: ``rgb`` alone
    layers: list[tuple[tuple[str, ...], np.ndarray]] | None = None
    has_beauty: bool = True  # the layers hold the beauty (a display PNG makes sense)

    @property
    def nbytes(self) -> int:
        """Bytes of pixel data sent back to the client."""
        pixels = [self.rgb, self.variance, *(p for _, p in self.layers or [])]
        return int(sum(p.nbytes for p in pixels if p is not None))


def worker_name() -> str:
    """``host:pid`` of this process (and the Dask worker address when run by one)."""
    name = f"{socket.gethostname()}:{os.getpid()}"
    try:
        from distributed import get_worker

        return f"{get_worker().address} ({name})"
    except (ImportError, ValueError):
        return name


def check_version(version: str) -> None:
    """Refuse to run for a client of another pavonine version (results would not be comparable)."""
    from pavonine import __version__

    if version and version != __version__:
        raise InputError(
            worker_name(),
            f"worker runs pavonine {__version__}, the client {version}; install the same",
        )


def check_inputs(path: str, expected: str) -> None:
    """Hash ``path`` and all it uses here; :class:`InputMismatch` unless it is ``expected``."""
    from pavonine.apps.compare.baselines import stage_sha256

    if not os.path.isfile(path):
        raise InputMismatch(
            path, f"not found on worker {worker_name()} (inputs must be on shared storage)"
        )
    found = stage_sha256(path)
    if found != expected:
        raise InputMismatch(
            path,
            f"content differs on worker {worker_name()} from the client's "
            f"(sha256 {found[:12]} vs {expected[:12]}): stale or partial shared storage",
        )


#: Exceptions a task raises for bad input: the client prints them as one line, so the worker
#: does not log them (``distributed.worker``'s "Compute Failed" record, with a traceback).
INPUT_ERRORS = ("InputError(", "InputMismatch(", "ParameterError(")


class _InputErrorFilter(logging.Filter):
    """Drops ``distributed.worker``'s "Compute Failed" records of input errors (any other failure,
    a bug, is still logged with its traceback)."""

    def filter(self, record: logging.LogRecord) -> bool:
        if not str(record.msg).startswith("Compute Failed") or not isinstance(record.args, tuple):
            return True
        return not any(str(arg).startswith(INPUT_ERRORS) for arg in record.args)


def quiet_input_errors() -> None:
    """Install :class:`_InputErrorFilter` in this worker process (once)."""
    logger = logging.getLogger("distributed.worker")
    if not any(isinstance(f, _InputErrorFilter) for f in logger.filters):
        logger.addFilter(_InputErrorFilter())


@contextlib.contextmanager
def _usd_warnings_dropped():
    """USD's raw ``Warning: in …`` lines stay off the worker's stderr (an embedded cluster's is
    the user's terminal): what matters of them comes back as the shard's stage warnings."""
    from pxr import UsdUtils

    delegate = UsdUtils.CoalescingDiagnosticDelegate()
    try:
        yield
    finally:
        del delegate


def _set_threads(threads: int | None) -> None:
    import drjit as dr

    count = threads or int(os.environ.get(THREADS_ENV, "0") or 0) or os.cpu_count() or 1
    if dr.thread_count() != count:
        dr.set_thread_count(count)


#: The render session of the last task this process ran (one: a session holds a Mitsuba scene):
#: a later task of the same stage, view and settings at another time (the next frame) moves
#: only the stage's time-varying prims there instead of syncing it again
#: (:class:`pavonine.render.api.RenderSession`).
_SESSION: dict[str, Any] = {}


def session_key(task: RenderTask) -> tuple:
    """What a task's session is made of: everything but its time, seed and samples."""
    return (
        task.stage, task.stage_sha256, task.camera, task.product, task.resolution, task.moments,
        task.variant, task.max_depth, task.limits, task.motion_slices, task.version,
    )  # fmt: skip


def render_with_session(task: RenderTask):
    """The task's image, from the session of the previous task when it is the same view of the
    same stage (only what varies synced again), else from a new one."""
    from pavonine.render.api import RenderSession

    key = session_key(task)
    session = _SESSION.get("session") if _SESSION.get("key") == key else None
    if session is None:
        _SESSION.clear()  # the previous scene goes before the next is built
        options = task.render_options().but(
            products=[task.product] if task.product else None, first_only=task.product is None
        )
        session = RenderSession(task.stage, options)
        _SESSION.update(key=key, session=session)
        return session.render(seed=task.seed, spp=task.spp)[0]
    try:
        return session.render(time=task.time, seed=task.seed, spp=task.spp)[0]
    except BaseException:
        _SESSION.clear()
        raise


def render_task(task: RenderTask) -> RenderShard:
    """Run one :class:`RenderTask` (module docstring)."""
    import warnings

    from pavonine.render.diagnostics import StageWarning

    quiet_input_errors()
    with _RENDER_LOCK, _usd_warnings_dropped():
        start = time.perf_counter()
        check_version(task.version)
        check_inputs(task.stage, task.stage_sha256)
        hashed = time.perf_counter()
        _set_threads(task.threads)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", StageWarning)  # returned in .warnings instead
            result = render_with_session(task)
        done = time.perf_counter()
    return RenderShard(
        task.job,
        task.shard,
        task.spp,
        result.rgb,
        result.variance,
        dict(result.metadata),
        list(result.warnings),
        worker_name(),
        {
            "hash": hashed - start,
            "render": done - hashed,
            "task": done - start,
            "sync": float(result.metadata.get("sync_seconds", 0.0)),
            "synced_all": float(result.metadata.get("sync") == "full"),
        },
        layers=_extra_layers(result),
        has_beauty=result.has_beauty,
    )


def _extra_layers(result) -> list[tuple[tuple[str, ...], np.ndarray]] | None:
    """A product's layers when it has more than the plain RGB beauty (``None`` otherwise)."""
    layers = result.exr_layers()
    if len(layers) == 1 and tuple(layers[0][0]) == ("R", "G", "B") and result.has_beauty:
        return None
    return [(tuple(channels), pixels) for channels, pixels in layers]


@dataclass(frozen=True)
class ConvertTask:
    """One feather recipe to convert on a worker."""

    recipe: str
    inputs_sha256: str
    version: str = ""


@dataclass
class ConvertedAsset:
    """A converted asset's files (relative path → bytes), for the client to write."""

    recipe: str
    name: str
    files: dict[str, bytes]
    triangles: dict[str, int]
    seconds: dict[str, float]
    worker: str
    barbs: int = 0  # barbs in the ``geometry = barbs`` variant (0: none written)

    @property
    def nbytes(self) -> int:
        return sum(len(b) for b in self.files.values())


def recipe_inputs(recipe_path: str) -> list[str]:
    """The files a recipe is made of: itself and its six maps."""
    from pavonine.pipeline.convert.recipe import parse_recipe

    recipe = parse_recipe(recipe_path)
    return [str(recipe.path), *(str(p) for p in recipe.maps.values())]


def files_sha256(paths: list[str]) -> str:
    """SHA-256 over the files' digests in order (what :class:`ConvertTask` checks)."""
    import hashlib

    from pavonine.apps.compare.baselines import file_sha256

    missing = [p for p in paths if not os.path.isfile(p)]
    if missing:
        raise InputMismatch(
            missing[0], f"not found on {worker_name()} (inputs must be on shared storage)"
        )
    return hashlib.sha256("\n".join(file_sha256(p) for p in paths).encode()).hexdigest()


def convert_task(task: ConvertTask) -> ConvertedAsset:
    """Convert one recipe into a private temporary folder and return the asset's files."""
    from pavonine.pipeline.convert.batch import convert_recipe

    quiet_input_errors()
    check_version(task.version)
    found = files_sha256(recipe_inputs(task.recipe))
    if found != task.inputs_sha256:
        raise InputMismatch(
            task.recipe, f"recipe or maps differ on worker {worker_name()} from the client's"
        )
    scratch = Path(tempfile.mkdtemp(prefix="pavonine-convert-"))
    try:
        result = convert_recipe(task.recipe, scratch / "out")
        folder = scratch / "out" / result.name
        files = {
            str(p.relative_to(folder)): p.read_bytes()
            for p in sorted(folder.rglob("*"))
            if p.is_file()
        }
    finally:
        shutil.rmtree(scratch, ignore_errors=True)
    return ConvertedAsset(
        task.recipe,
        result.name,
        files,
        result.triangles,
        result.seconds,
        worker_name(),
        barbs=result.barbs,
    )
