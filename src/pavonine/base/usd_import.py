"""USD's Python modules (``pxr``) load with Pavonine's schema plugin registered first, and with
Ctrl-C held until each module is complete.

USD builds its schema registry once, from the plugins known when a stage or
``Usd.SchemaRegistry`` is first used, and silently ignores plugins registered later
(:mod:`pavonine.schemas.plugin`). ``import pavonine`` must therefore register
``PavonineFeatherAPI`` before any USD use in the process (users' scripts included), but loading
USD takes a tenth of a second or more, and doing it inside ``import pavonine`` left the ``pavonine``
command without its Ctrl-C handling for that long (a ``KeyboardInterrupt`` traceback).

So ``import pavonine`` calls :func:`install`: if ``pxr`` is already imported it registers at
once; otherwise it puts a finder first on ``sys.meta_path`` that registers the plugin right after
the ``pxr`` package itself is executed, before any ``pxr`` submodule (``Usd``, ``Sdf``...) can
exist, and stays to load each ``pxr`` submodule with Ctrl-C held (below). Every stage and registry is made through ``pxr.Usd``, which imports
``pxr`` first, so the registration still precedes them.

While a ``pxr`` module loads (in the main thread, with Python's default SIGINT handling), Ctrl-C
is held and re-raised as ``KeyboardInterrupt`` once the module is complete: USD's C++ module
loader catches a Python exception raised inside it and prints it as a ``Warning: in
Tf_PyPostProcessModule`` line, so an interrupt there was lost (the command ran on) or left a
half-initialised module.
"""

from __future__ import annotations

import importlib.util
import signal
import sys
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from types import ModuleType
from typing import Any

PACKAGE = "pxr"


@contextmanager
def interrupts_held() -> Iterator[None]:
    """Hold Ctrl-C (SIGINT) inside the block and raise ``KeyboardInterrupt`` after it, if one
    came. Only in the main thread and while Python's default handler is in place (a program's
    own SIGINT handler is left alone); elsewhere a plain block."""
    if (
        threading.current_thread() is not threading.main_thread()
        or signal.getsignal(signal.SIGINT) is not signal.default_int_handler
    ):
        yield
        return
    came: list[int] = []
    signal.signal(signal.SIGINT, lambda signum, frame: came.append(signum))
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, signal.default_int_handler)
    if came:
        raise KeyboardInterrupt


class _HeldLoader:
    """Wraps a ``pxr`` module's loader: executes the module with Ctrl-C held, then (for the
    ``pxr`` package) runs ``after``. Everything else is the real loader's."""

    def __init__(self, real: Any, after: Callable[[], None] | None):
        self._real, self._after = real, after

    def __getattr__(self, name: str) -> Any:
        return getattr(self._real, name)

    def create_module(self, spec: Any) -> ModuleType | None:
        return self._real.create_module(spec)

    def exec_module(self, module: ModuleType) -> None:
        module.__loader__ = module.__spec__.loader = self._real  # no trace of the wrapper
        with interrupts_held():
            self._real.exec_module(module)
            if self._after is not None:
                self._after()


class PxrFinder:
    """A ``sys.meta_path`` finder for ``pxr`` and its submodules: loads them through
    :class:`_HeldLoader`, and registers Pavonine's plugin right after the ``pxr`` package."""

    def __init__(self, register: Callable[[], None]):
        self._register = register
        self._busy = threading.local()

    def find_spec(self, name: str, path: Any = None, target: Any = None) -> Any:
        if name != PACKAGE and not name.startswith(PACKAGE + "."):
            return None
        if getattr(self._busy, "name", None) == name:
            return None  # our own look-up below: let the other finders answer
        self._busy.name = name
        try:
            spec = importlib.util.find_spec(name)
        finally:
            self._busy.name = None
        if spec is None or spec.loader is None:
            return spec
        spec.loader = _HeldLoader(spec.loader, self._register if name == PACKAGE else None)
        return spec


def install(register: Callable[[], None]) -> None:
    """Make ``register`` (Pavonine's USD plugin registration) run before any USD use: now if
    ``pxr`` is already imported, else right after it is (:class:`PxrFinder`, first on
    ``sys.meta_path``, once per process)."""
    if PACKAGE in sys.modules:
        register()
    if not any(isinstance(finder, PxrFinder) for finder in sys.meta_path):
        sys.meta_path.insert(0, PxrFinder(register))
