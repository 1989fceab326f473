"""Deep namespaces: USD calls that recurse natively once per level of prim nesting, guarded.

USD composes, parses, bounds and flattens a stage recursively, one C++ stack frame (or several)
per level of namespace: on a stage of 3000 nested ``Xform`` prims (valid USD; usd-core opens it)
``UsdGeomBBoxCache::ComputeWorldBound`` of the pseudo-root overflowed the main thread's 8 MiB
stack and the process died with a segmentation fault (exit 139), something no ``try`` can catch.

So that never happens:

* :func:`deep_call` runs such a call on a thread with a :data:`STACK_BYTES` stack (reserved
  address space; only the pages used are committed) and, on a stage deeper than
  :data:`SHALLOW`, with USD's work dispatcher limited to that one thread (``Work``'s concurrency
  limit; its TBB workers have small stacks of their own, and ``BBoxCache`` recurses in them);
* :func:`check_nesting` refuses a stage deeper than :data:`MAX_NESTING` with one line naming the
  limit, before any such call.

Measured (usd-core 26.11, ``tests/apps/test_fuzz_usd.py`` and ``benchmarks/deep_stages.py``):
with the main thread's 8 MiB, the world bound of a 3000-deep stage crashed; on a 512 MiB thread
with one work thread it was computed at 30,000 levels, and opening a 100,000-deep ``.usda`` worked
(its bound then crashed). :data:`MAX_NESTING` is 10,000: a margin of 3 below what was measured to
work, and far above any real asset (the 192-feather train is 7 deep).
"""

from __future__ import annotations

import contextlib
import threading
from collections.abc import Callable, Iterator
from typing import Any, TypeVar

from pavonine.base.errors import InputError

#: Stack of the thread a deep call runs on (address space reserved, not memory committed).
STACK_BYTES = 512 << 20
#: Deepest prim nesting a stage may have (path elements of its deepest prim, prototypes included).
MAX_NESTING = 10_000
#: Up to this depth USD's calls run as they are, in parallel (a crash needed ~3000 levels).
SHALLOW = 256

T = TypeVar("T")


def deep_call(fn: Callable[..., T], *args: Any, depth: int | None = None, **kwargs: Any) -> T:
    """``fn(*args, **kwargs)`` on a thread with a :data:`STACK_BYTES` stack; with ``depth`` (the
    stage's nesting, when known) above :data:`SHALLOW`, or unknown, USD's work dispatcher runs
    on that thread alone. Its result is returned and its exception raised here."""
    outcome: dict[str, Any] = {}

    def run() -> None:
        try:
            with _serial_work(depth is None or depth > SHALLOW):
                outcome["value"] = fn(*args, **kwargs)
        except BaseException as exc:  # re-raised in the caller's thread
            outcome["error"] = exc

    previous = threading.stack_size()
    threading.stack_size(STACK_BYTES)
    try:
        thread = threading.Thread(target=run, name="pavonine-deep-call", daemon=True)
        thread.start()
    finally:
        threading.stack_size(previous)
    thread.join()
    if "error" in outcome:
        raise outcome["error"]
    return outcome["value"]


@contextlib.contextmanager
def _serial_work(serial: bool) -> Iterator[None]:
    if not serial:
        yield
        return
    from pxr import Work

    limit = Work.GetConcurrencyLimit()
    Work.SetConcurrencyLimit(1)
    try:
        yield
    finally:
        Work.SetConcurrencyLimit(limit)


def nesting_depth(stage) -> tuple[int, str]:
    """(depth, path) of the stage's deepest prim: path elements, counting an instance prototype's
    own depth on top of the deepest instance's (iterative: no native recursion)."""
    from pxr import Usd

    def deepest(root) -> tuple[int, str]:
        found = (0, "")
        for prim in Usd.PrimRange(root, Usd.PrimAllPrimsPredicate):
            depth = prim.GetPath().pathElementCount
            if depth > found[0]:
                found = (depth, str(prim.GetPath()))
        return found

    depth, path = deepest(stage.GetPseudoRoot())
    prototypes = [deepest(p) for p in stage.GetPrototypes()]
    if prototypes:
        inner = max(prototypes)
        depth, path = depth + inner[0], f"{path} (and {inner[1]} in an instance)"
    return depth, path


def check_nesting(stage, where: str, limit: int | None = None) -> int:
    """The stage's nesting depth; an :class:`InputError` naming the limit (default
    :data:`MAX_NESTING`) if it is beyond."""
    limit = MAX_NESTING if limit is None else limit
    depth, path = nesting_depth(stage)
    if depth > limit:
        raise InputError(
            where,
            f"prims nested {depth:,} deep (at {_short(path)}) is beyond the limit of {limit:,} "
            "levels (MAX_NESTING): USD's bounds, transforms and flattening recurse once per level",
        )
    return depth


def _short(path: str, keep: int = 60) -> str:
    """A prim path cut to its first and last ``keep`` characters (a 3000-deep path is 20 kB)."""
    return path if len(path) <= 2 * keep + 5 else f"{path[:keep]}/…/{path[-keep:]}"
