"""Mitsuba back-end selection, shared by every part of Pavonine that renders or JIT-evaluates.

Mitsuba's fast ``llvm_*`` variants need a shared libLLVM >= 16 (Dr.Jit fails on LLVM 15 with
"Cannot select: fminimum"). :func:`find_libllvm` locates one and :func:`select_variant` points
``DRJIT_LIBLLVM_PATH`` at it *before* Dr.Jit loads, then picks ``llvm_ad_spectral``; without a
usable LLVM it falls back to ``scalar_spectral`` with one warning. :func:`set_threads` bounds the
worker threads of Dr.Jit, OpenImageIO and the BLAS/OpenMP libraries (``--threads``).
"""

from __future__ import annotations

import glob
import os
import re
import sys
import warnings
from dataclasses import dataclass

MIN_LLVM_MAJOR = 16
FAST_VARIANT = "llvm_ad_spectral"
FALLBACK_VARIANT = "scalar_spectral"

_SEARCH_GLOBS = (
    "/usr/lib/x86_64-linux-gnu/libLLVM-*.so*",
    "/usr/lib/aarch64-linux-gnu/libLLVM-*.so*",
    "/usr/lib/llvm-*/lib/libLLVM*.so*",
    "/usr/lib64/libLLVM*.so*",
    "/usr/local/lib/libLLVM*.so*",
    "/opt/homebrew/opt/llvm/lib/libLLVM*.dylib",
    "/usr/local/opt/llvm/lib/libLLVM*.dylib",
)


class BackendWarning(UserWarning):
    """Raised (as a warning) when Pavonine has to fall back to a slow scalar variant."""


@dataclass(frozen=True)
class Backend:
    """What :func:`select_variant` chose."""

    variant: str
    libllvm: str | None
    llvm_major: int | None
    reason: str


_selected: Backend | None = None
_threads: int | None = None

#: Read by OpenMP/BLAS libraries (NumPy, SciPy, pymeshlab) when they load, and by child processes.
THREAD_ENV_VARS = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")


def set_threads(count: int | None) -> None:
    """Use at most ``count`` worker threads (``None``: one per core, the libraries' default).

    Applies at once to Dr.Jit and OpenImageIO when loaded (and to Dr.Jit when
    :func:`select_variant` loads it later); sets :data:`THREAD_ENV_VARS` for libraries loaded after
    this call and for worker processes.
    """
    global _threads
    _threads = count
    if count is None:
        return
    for name in THREAD_ENV_VARS:
        os.environ[name] = str(count)
    if "drjit" in sys.modules:
        sys.modules["drjit"].set_thread_count(count)
    try:
        import OpenImageIO as oiio
    except ImportError:
        return
    oiio.attribute("threads", count)


def thread_count() -> int | None:
    """The thread limit set by :func:`set_threads` (``None``: one per core)."""
    return _threads


def _llvm_major(path: str) -> int | None:
    """LLVM major version encoded in a library file name (``libLLVM-19.so``, ``libLLVM.so.19.1``)."""
    name = os.path.basename(path)
    match = re.search(r"libLLVM[-.]?(\d+)", name) or re.search(r"\.so\.(\d+)", name)
    if match:
        return int(match.group(1))
    match = re.search(r"llvm-(\d+)", path)
    return int(match.group(1)) if match else None


def find_libllvm(min_major: int = MIN_LLVM_MAJOR) -> tuple[str, int] | None:
    """Newest shared libLLVM with major version >= ``min_major``, as ``(path, major)``.

    A ``DRJIT_LIBLLVM_PATH`` already set by the user wins when the file exists.
    """
    preset = os.environ.get("DRJIT_LIBLLVM_PATH")
    if preset and os.path.exists(preset):
        major = _llvm_major(preset)
        return preset, major if major is not None else min_major
    found: list[tuple[int, str]] = []
    for pattern in _SEARCH_GLOBS:
        for path in glob.glob(pattern):
            major = _llvm_major(path)
            if major is not None and major >= min_major and os.path.isfile(path):
                found.append((major, path))
    if not found:
        return None
    major, path = max(found, key=lambda item: (item[0], -len(item[1])))
    return path, major


def select_variant(preferred: str | None = None) -> Backend:
    """Set the Mitsuba variant once per process and return what was chosen.

    ``preferred`` (or ``PAVONINE_VARIANT``) forces a variant; a forced ``llvm_*`` variant without
    a usable LLVM still falls back to the scalar variant of the same colour mode, with a warning.
    """
    global _selected
    wanted = preferred or os.environ.get("PAVONINE_VARIANT") or FAST_VARIANT
    if _selected is not None and (_selected.variant == wanted or preferred is None):
        return _selected

    lib = find_libllvm()
    if wanted.startswith("llvm_") and lib is None:
        fallback = (
            "scalar_" + wanted.split("_", 2)[-1] if wanted.count("_") >= 2 else FALLBACK_VARIANT
        )
        warnings.warn(
            f"pavonine: no shared libLLVM >= {MIN_LLVM_MAJOR} found (install Debian's libllvm19 or set "
            f"DRJIT_LIBLLVM_PATH); falling back to the slow '{fallback}' Mitsuba variant",
            BackendWarning,
            stacklevel=2,
        )
        wanted, reason = fallback, "no usable libLLVM"
    else:
        reason = "requested" if preferred or os.environ.get("PAVONINE_VARIANT") else "default"
    if lib is not None:
        os.environ["DRJIT_LIBLLVM_PATH"] = lib[0]

    import drjit as dr
    import mitsuba as mi

    mi.set_variant(wanted)
    if _threads is not None:
        dr.set_thread_count(_threads)
    _selected = Backend(
        variant=wanted,
        libllvm=lib[0] if lib and wanted.startswith("llvm_") else None,
        llvm_major=lib[1] if lib and wanted.startswith("llvm_") else None,
        reason=reason,
    )
    return _selected
