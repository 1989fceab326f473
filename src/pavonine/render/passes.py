"""Progressive rendering in passes: the per-pass seeds, the lane budget, per-pixel moments.

Passes use seeds ``seed · 65537 + i`` and are averaged; the same seed gives the same image. With
``moments`` the image is rendered in at least min(spp, 16) passes and the per-pixel variance of the
final estimate is ``s² / P``, ``s²`` the unbiased variance of the P pass means (in linear Rec.709,
so exact for the RGB that is reported; Mitsuba's ``moment`` integrator would give XYZ moments).

Ctrl-C: Mitsuba's integrator catches SIGINT itself, stops ("winding down") and raises a
``KeyboardInterrupt`` that Dr.Jit wraps in a ``RuntimeError``; :func:`render_pass` unwraps it,
so the caller sees a plain ``KeyboardInterrupt``; Mitsuba logs only errors while a pass renders,
so its own warning about the signal is not printed (the command line reports the interrupt on
one line, exit status 130).
"""

from __future__ import annotations

import contextlib
import gc
import logging
import sys
from collections.abc import Callable, Iterator

import numpy as np

from pavonine import LOGGER_NAME

#: Samples per pass at most. Each pass is one ``mi.render`` call, which traces and generates the
#: whole path tracer again; the trace grows with the scene's virtual-call targets (every
#: ``instance`` of a train is one), so passes are few: the 192-feather train at 256×192 × 16 spp
#: took 87 s of CPU in 4 passes and 21 s in 1 (load average 6.5). A pass holds no per-sample
#: state in Dr.Jit's symbolic (megakernel) mode: the eye feather at 1024×768 × 64 spp peaked at
#: 415 MiB in one pass, 450 MiB in 16.
LANES_PER_PASS = 1 << 25
MIN_MOMENT_PASSES = 16
SEED_STRIDE = 65537


def render_passes(
    scene,
    sensor: int,
    integrator,
    spp: int,
    seed: int,
    film_size: tuple[int, int],
    width: int,
    moments: bool,
    advance: Callable[[int], None],
    trace_loops_once: bool = False,
) -> tuple[np.ndarray, np.ndarray | None, int]:
    """(mean H×W×C image, variance of its first three channels or ``None``, passes).

    ``trace_loops_once``: trace each pass with ``JitFlag.OptimizeLoops`` off (see
    :func:`render_pass`); the caller sets it for scenes that hold instances.
    """
    import mitsuba as mi

    film_width, height = film_size
    spp_pass = samples_per_pass(spp, film_width * height, moments)
    passes = spp // spp_pass
    resample = pixel_aspect_resampler(film_width, width)
    total = total_sq = None
    for index in range(passes):
        pass_seed = (seed * SEED_STRIDE + index) & 0xFFFFFFFF
        image = render_pass(mi, scene, sensor, integrator, spp_pass, pass_seed, trace_loops_once)
        if resample is not None:
            image = np.einsum("jk,ikc->ijc", resample, image.astype(np.float64))
        total = accumulate(total, image)
        if moments:
            beauty = image[..., :3].astype(np.float64)
            total_sq = beauty * beauty if total_sq is None else total_sq + beauty * beauty
        del image
        advance(spp_pass)
    mean = total
    mean /= passes  # in place, the same IEEE division as ``total / passes`` (÷ 1: exact)
    variance = None
    if total_sq is not None:
        sample_var = np.maximum(total_sq / passes - mean[..., :3] ** 2, 0.0) * passes / (passes - 1)
        variance = (sample_var / passes).astype(np.float32)
    return mean.astype(np.float32), variance, passes


def accumulate(total: np.ndarray | None, image: np.ndarray) -> np.ndarray:
    """``total + image`` with the float64 sums of the pass images, at the least memory.

    The first pass's image is kept as it comes (float32 from the film in single-precision
    variants: every float32 is exact in float64, so holding it rather than a float64 copy changes
    no sum); from the second pass on the sum is float64 and is added into in place, NumPy
    converting ``image`` to float64 in buffered chunks rather than as a whole frame-sized copy.
    Each sum is the same IEEE double addition of the same values as adding float64 copies, so
    the image is bit for bit what it was with float64 passes.
    """
    if total is None:
        return image
    if total.dtype == np.float64:
        return np.add(total, image, out=total)
    return np.add(total, image, dtype=np.float64)


def render_pass(
    mi, scene, sensor: int, integrator, spp: int, seed: int, trace_loops_once: bool = False
) -> np.ndarray:
    """One ``mi.render`` pass as an H×W×C array of its own in the film's precision (float32 in
    single-precision variants), with Python's cyclic garbage collector paused.

    Dr.Jit traces every registered BSDF instance when it records a virtual call; a Python-defined
    BSDF (the feather) of an earlier, unreachable scene freed by a collector run *during* that
    tracing leaves a dangling pointer and Mitsuba segfaults. The caller collects before building
    the scene, and no collection runs while a pass is traced.

    With ``trace_loops_once`` the pass is traced with ``JitFlag.OptimizeLoops`` off. With it on,
    Dr.Jit records a symbolic loop body again when the first recording shows state the loop never
    changes (to drop it), and ``volpath`` (the path integrator before ``pavonine_path``) nests its
    emitter-sampling loop in the path loop, so each virtual call in them was traced up to four
    times; in a train every
    ``Shape::compute_surface_interaction`` call holds ~200 registered shapes, 196 of which
    (instances, shape groups) nest the same call again. Measured on the 192-feather train (64×48,
    1 spp): 3,940 → 1,182 such calls traced, 21–25 s → 6–10 s of tracing per pass, the kernel's
    size and speed unchanged (177,944 → 177,808 IR operations), the image bitwise the same. With
    ``pavonine_path``, one loop, it matters less: the same render took 6.6–7.0 s with the flag
    off and 7.0–8.5 s with it on (whole call, scene build included, 94,906 IR operations). Only
    scenes with instances get it (where the trace is large): with the flag off, Dr.Jit 1.5.0
    emitted one callable twice in the LLVM module for a single textured emissive quad
    ("invalid redefinition of function func_…", then an abort of the process), a Dr.Jit bug.
    """
    import drjit as dr

    enabled = gc.isenabled()
    gc.disable()
    try:
        optimize_loops = dr.scoped_set_flag(dr.JitFlag.OptimizeLoops, not trace_loops_once)
        with _quiet_interrupt_log(mi), optimize_loops, _native_lines_as_warnings():
            image = mi.render(scene, sensor=sensor, integrator=integrator, spp=spp, seed=seed)
    except Exception as exc:
        if interrupted(exc):
            raise KeyboardInterrupt from None
        raise
    finally:
        if enabled:
            gc.enable()
    pixels = np.array(image)  # a copy: Dr.Jit's buffer is reused by the next pass
    return pixels if pixels.dtype in (np.float32, np.float64) else pixels.astype(np.float64)


def interrupted(exc: BaseException) -> bool:
    """``exc`` is, or was caused by, a ``KeyboardInterrupt`` (Dr.Jit wraps it in errors)."""
    seen: set[int] = set()
    current: BaseException | None = exc
    while current is not None and id(current) not in seen:
        if isinstance(current, KeyboardInterrupt):
            return True
        seen.add(id(current))
        current = current.__cause__ or current.__context__
    return False


@contextlib.contextmanager
def _native_lines_as_warnings() -> Iterator[None]:
    """Lines that native code prints on stderr during a pass (Dr.Jit's "jit_kernel_write(): I/O
    error ..." when its kernel cache cannot be written, on a full disk or under a file-size
    limit) become ``pavonine`` warnings, so a command's stderr stays ``level: message`` lines.
    On a terminal they are left as they are (progress bars draw there, from another thread)."""
    from pavonine.base.native_output import captured

    if sys.stderr is None or sys.stderr.isatty():
        yield
        return
    lines: list[str] = []
    try:
        with captured(2) as lines:
            yield
    finally:
        for line in lines:
            logging.getLogger(LOGGER_NAME).warning("%s", line)


@contextlib.contextmanager
def _quiet_interrupt_log(mi) -> Iterator[None]:
    """While a pass renders, Mitsuba logs errors only: its SIGINT handler's warning ("Received
    interrupt signal, winding down..") is not printed (the command line's one-line interrupt
    message is). Filtering by level is all a signal handler may safely do, so it is by level."""
    logger = mi.logger()
    if logger is None:
        yield
        return
    level = logger.log_level()
    logger.set_log_level(mi.LogLevel.Error)
    try:
        yield
    finally:
        logger.set_log_level(level)


def samples_per_pass(spp: int, pixels: int, moments: bool) -> int:
    """Largest divisor of ``spp`` within the lane budget (and giving enough passes for moments)."""
    limit = max(1, LANES_PER_PASS // max(pixels, 1))
    if moments:
        limit = min(limit, max(1, spp // MIN_MOMENT_PASSES))
    return max(d for d in range(1, min(spp, limit) + 1) if spp % d == 0)


def pixel_aspect_resampler(film_width: int, width: int) -> np.ndarray | None:
    """Box-resampling matrix (width × film_width) from square film pixels to wide/narrow pixels."""
    if film_width == width:
        return None
    edges = np.linspace(0.0, film_width, width + 1)
    lo, hi = edges[:-1, None], edges[1:, None]
    k = np.arange(film_width)[None, :]
    overlap = np.clip(np.minimum(hi, k + 1) - np.maximum(lo, k), 0.0, None)
    return overlap / overlap.sum(axis=1, keepdims=True)
