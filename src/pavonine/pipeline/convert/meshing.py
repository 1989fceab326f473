"""Which mesh library the converter cleans and decimates with: pymeshlab, or NumPy without it.

pymeshlab's wheel loads system libraries (Debian's ``libgl1`` for ``libGL.so.1``,
``libopengl0`` for its filter plugins) that a bare machine, or a user who cannot run apt, may
lack. Then the converter uses the NumPy implementations (:mod:`.collapse` for the quadric edge
collapse, :mod:`.cleaning` for the clean-up), which keep the same guarantees (locked
boundaries, exact attributes, manifold meshes, an unfolded atlas) but lay out the lower LODs'
triangles a little differently, and says so in one warning. ``PAVONINE_MESHING`` chooses:
``auto`` (default), ``pymeshlab`` (fail when it cannot load) or ``numpy`` (the same meshes on
every machine, e.g. a farm whose workers differ).
"""

from __future__ import annotations

import functools
import importlib
import logging
import os
from dataclasses import dataclass
from types import ModuleType

from pavonine import LOGGER_NAME
from pavonine.base.backend import debian_hint, first_import_error
from pavonine.base.native_output import silenced

#: Environment variable choosing the backend: ``auto``, ``pymeshlab`` or ``numpy``.
MESHING_ENV = "PAVONINE_MESHING"
CHOICES = ("auto", "pymeshlab", "numpy")


class MeshingUnavailable(ImportError):
    """``PAVONINE_MESHING=pymeshlab`` but pymeshlab cannot load (one line naming the library)."""


@dataclass(frozen=True)
class MeshingBackend:
    """What :func:`meshing_backend` chose: ``name`` is ``"pymeshlab"`` or ``"numpy"``;
    ``reason`` says why NumPy (``None`` for pymeshlab)."""

    name: str
    reason: str | None = None

    @property
    def pymeshlab(self) -> ModuleType:
        return importlib.import_module("pymeshlab")


def check_filters(module: ModuleType) -> None:
    """pymeshlab imports without its filter plugins when they cannot load libOpenGL."""
    if not hasattr(module.MeshSet(), "meshing_decimation_quadric_edge_collapse"):
        raise ImportError(
            "pymeshlab's meshing filters did not load (libOpenGL.so.0: cannot open shared object "
            "file)"
        )


def pymeshlab_error() -> str | None:
    """Why pymeshlab (with its filters) cannot be used here, one line; ``None`` when it can."""
    try:
        with silenced():  # its plugin loader prints a page to stdout without libOpenGL (--json -)
            check_filters(importlib.import_module("pymeshlab"))
    except Exception as exc:  # ImportError for a missing .so; anything else is as fatal
        return first_import_error(exc)
    return None


@functools.cache
def meshing_backend() -> MeshingBackend:
    """The backend for this process (probed once). Falling back to NumPy logs one warning on
    the ``pavonine`` logger, naming the library that is missing."""
    choice = os.environ.get(MESHING_ENV, "auto").strip().lower() or "auto"
    if choice not in CHOICES:
        from pavonine.base.errors import InputError

        raise InputError(MESHING_ENV, f"{choice!r} is not one of {', '.join(CHOICES)}")
    if choice == "numpy":
        return MeshingBackend("numpy", f"{MESHING_ENV}=numpy")
    error = pymeshlab_error()
    if error is None:
        return MeshingBackend("pymeshlab")
    if choice == "pymeshlab":
        raise MeshingUnavailable(f"{error} ({MESHING_ENV}=pymeshlab)")
    reason = f"pymeshlab cannot load: {error}{debian_hint(error)}"
    logging.getLogger(LOGGER_NAME).warning(
        "meshing with NumPy instead of pymeshlab (same checks; the decimated LODs differ a "
        "little): %s",
        reason,
    )
    return MeshingBackend("numpy", reason)
