"""Image files written whole: the one writer of every image Pavonine makes (maps, baked textures,
renders, heat-maps), through OpenImageIO, atomically, and never a cut-short file.

The render outputs' formats (EXR layers, display PNGs, metadata) are
:mod:`pavonine.render.imageio`'s; the data maps' decoding is :mod:`pavonine.base.map_files`'.
"""

from __future__ import annotations

import errno
import os
from pathlib import Path

import numpy as np

from pavonine.base.commit import atomic_path
from pavonine.base.errors import (
    InputError,
    diagnose_write_failure,
    scrub_temporaries,
)


def write_image_file(path: str | os.PathLike, pixels: np.ndarray, spec) -> None:
    """Write ``pixels`` (H×W×C) with OpenImageIO ``spec`` to ``path`` atomically.

    OpenImageIO reports some failures only when the file is closed (OpenEXR writes its chunks
    then), so ``close()`` is checked too: a full disk or a file-size limit never commits a
    truncated image. Its errors name ``path`` and, where OpenImageIO does not, the cause
    (:func:`pavonine.base.errors.diagnose_write_failure`).
    """
    import OpenImageIO as oiio

    with atomic_path(path) as tmp:
        out = oiio.ImageOutput.create(os.fspath(tmp))
        if out is None:
            raise InputError(os.fspath(path), f"cannot write this image format: {oiio.geterror()}")
        written = out.open(os.fspath(tmp), spec) and out.write_image(pixels)
        error = out.geterror()
        closed = out.close()
        if not (written and closed):
            message = error or out.geterror() or "the image library gave no reason"
            reason = diagnose_write_failure(tmp) or scrub_temporaries(message, path)
            raise InputError(os.fspath(path), f"cannot write image: {reason}")
        reason = _silently_truncated(tmp)
        if reason is not None:
            raise InputError(os.fspath(path), f"cannot write image: {reason}")


def _silently_truncated(path: Path) -> str | None:
    """Why a file OpenImageIO reported as written is incomplete, or ``None``.

    Neither libpng nor OpenEXR reports a short write: a file that reached the file-size limit
    is refused here by its size, and every image is read back from its own structure before it
    is committed (:func:`pavonine.base.truncation.cut_short`, run by ``atomic_path``), so a
    full disk never commits a cut-short PNG or EXR.
    """
    import resource

    limit = resource.getrlimit(resource.RLIMIT_FSIZE)[0]
    if limit != resource.RLIM_INFINITY and path.stat().st_size >= limit:
        return os.strerror(errno.EFBIG)
    return None
