"""Files that belong together (a render's EXR, variance and PNG; a set of maps; a baseline's
images): how a writer marks them, and what every Pavonine reader does before it reads one.

A group is committed by several renames (:func:`pavonine.base.commit.commit_files`), so
between two of them, and after a crash between two of them until recovery, the folder holds some
files of the new group beside some of the old. Each file is whole; the group is not. Two things
make the group consistent for readers:

* **One mark per group.** Every file of a group carries the header attribute
  ``pavonine:group``, ``{"id": <one id per commit>, "files": [<the group's files, relative to
  this one's folder>]}`` (:func:`group_attribute`). Two files that name each other but carry
  different ids are a mix; a file whose partner no longer names it (re-written alone later) is
  not. Any tool can check this; OpenImageIO shows it (``oiiotool --info -v``).
* **Readers settle, then verify** (:func:`check_group`, called by every Pavonine reader of such
  files: ``compare``, baselines for ``check-renders`` and ``baseline``, maps for ``convert``,
  ``bake``, ``validate``, ``export``). Settling finishes what a crashed writer left in the
  folder (:func:`pavonine.base.commit.recover`: its journal is the commit point, so the new
  group is completed) and waits while a *live* writer is between the renames of a group naming
  the file. A mix that remains (its journal lost, or the folder read-only) is refused with one
  line naming both files.
"""

from __future__ import annotations

import json
import os
import time
import uuid
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

from pavonine.base.commit import JOURNAL, owner_alive, owner_pid, recover
from pavonine.base.errors import TEMPORARY_MARK, InputError

#: The header attribute marking a file as one of a group (JSON: ``id``, ``files``).
GROUP_ATTRIBUTE = "pavonine:group"
#: How long a reader waits for a live writer to finish renaming a group (seconds).
SETTLE_TIMEOUT = 30.0


def new_group_id() -> str:
    """A fresh id for one commit of a group."""
    return uuid.uuid4().hex


def content_group_id(parts: Iterable) -> str:
    """A group id that is a hash of the group's contents, so the same content gives the same
    files: SHA-256 over ``parts`` in order (bytes as they are, arrays as contiguous float32),
    its first 32 hex digits."""
    import hashlib

    import numpy as np

    digest = hashlib.sha256()
    for part in parts:
        if not isinstance(part, bytes):
            part = np.ascontiguousarray(part, dtype=np.float32).tobytes()
        digest.update(part)
    return digest.hexdigest()[:32]


def group_attribute(group_id: str, member: str | os.PathLike, files: Iterable) -> str:
    """The ``pavonine:group`` value for ``member``: the group's ``files`` relative to its folder."""
    folder = Path(os.path.abspath(member)).parent
    names = sorted({os.path.relpath(os.path.abspath(f), folder) for f in files})
    return json.dumps({"id": group_id, "files": names}, separators=(",", ":"))


def group_marks(group_id: str, files: Iterable) -> dict[Path, str]:
    """The ``pavonine:group`` value of each of ``files`` (:func:`group_attribute`), by path."""
    files = [Path(f) for f in files]
    return {f: group_attribute(group_id, f, files) for f in files}


@dataclass(frozen=True)
class GroupMark:
    """A file's ``pavonine:group``: its commit's ``id`` and the group's files (absolute)."""

    id: str
    files: tuple[Path, ...]


def read_mark(path: str | os.PathLike) -> GroupMark | None:
    """The group mark in ``path``'s header (no pixels decoded), or ``None`` if it has none."""
    import OpenImageIO as oiio

    from pavonine.base.native_output import captured

    with captured(2):  # libpng's own lines about a broken file: the file's reader reports it
        image = oiio.ImageInput.open(os.fspath(path))
        if image is None:
            oiio.geterror()
            return None
        try:
            text = image.spec().get_string_attribute(GROUP_ATTRIBUTE, "")
        finally:
            image.close()
    try:
        record = json.loads(text) if text else None
        folder = Path(os.path.abspath(path)).parent
        return GroupMark(str(record["id"]), tuple(folder / name for name in record["files"]))
    except (ValueError, TypeError, KeyError):
        return None


def _live_journals(folder: Path, paths: set[str]) -> list[str]:
    """Journals in ``folder`` of live writers that rename onto any of ``paths`` (or that cannot
    be read yet: still being written)."""
    try:
        names = os.listdir(folder)
    except OSError:
        return []
    pending = []
    for name in names:
        if f"{TEMPORARY_MARK}{JOURNAL}-" not in name or not owner_alive(name):
            continue
        try:
            moves = json.loads((folder / name).read_text(encoding="utf-8"))
            targets = {os.path.abspath(target) for _, target in moves}
        except FileNotFoundError:
            continue  # finished meanwhile
        except (OSError, ValueError, TypeError):
            targets = paths  # being written: assume the worst
        if targets & paths:
            pending.append(name)
    return pending


def settle(paths: Sequence[str | os.PathLike], timeout: float | None = None) -> None:
    """Make the folders of ``paths`` safe to read as groups: complete the commits of crashed
    writers (:func:`recover`; skipped where the folder cannot be written), then wait while a
    live writer is renaming a group onto any of ``paths`` (at most ``timeout`` seconds, default
    :data:`SETTLE_TIMEOUT`; then a one-line :class:`InputError`)."""
    wanted = {os.path.abspath(p) for p in paths}
    folders = {Path(p).parent for p in wanted}
    for folder in folders:
        try:
            recover(folder)
        except OSError:
            pass  # read-only: the marks still expose a mix (check_group)
    deadline = time.monotonic() + (SETTLE_TIMEOUT if timeout is None else timeout)
    for folder in sorted(folders):
        while pending := _live_journals(folder, wanted):
            if time.monotonic() > deadline:
                raise InputError(
                    str(sorted(wanted)[0]),
                    f"is being replaced by process {owner_pid(pending[0])}, which has not finished in "
                    f"{SETTLE_TIMEOUT if timeout is None else timeout:g} s; try again",
                )
            time.sleep(0.005)


def check_group(
    path: str | os.PathLike, where: str | None = None, timeout: float | None = None
) -> GroupMark | None:
    """Before reading ``path``: :func:`settle` it, then refuse it (one-line :class:`InputError`
    at ``where``, default the path, naming the other file) if a file of its group that names it
    in turn is from another commit. Returns its mark (``None`` for a file of no group)."""
    path = Path(path)
    settle([path], timeout)
    mark = read_mark(path) if path.is_file() else None
    if mark is None:
        return None
    here = Path(os.path.abspath(path))
    for other in mark.files:
        if other == here or not other.is_file():
            continue
        theirs = read_mark(other)
        if theirs is not None and theirs.id != mark.id and here in theirs.files:
            raise InputError(
                where or str(path),
                f"is from another write than {other.name}, written with it as one group "
                f"(pavonine:group {mark.id[:8]} vs {theirs.id[:8]}): the files are a mix of "
                "two versions; write them again",
            )
    return mark
