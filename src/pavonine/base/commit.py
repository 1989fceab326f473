"""Crash-safe commits: a finished output replaces the old one in one atomic step for readers.

Every writer builds its output under a hidden temporary name *inside the output's own folder*
and commits it only when complete:

Folders (an asset, an assembly, a baseline): :func:`staged_folder`. A new folder is renamed
into place; an existing one is swapped with ``renameat2(RENAME_EXCHANGE)`` (Linux ≥ 3.15; ext4,
xfs, btrfs, tmpfs...) — one atomic step: a reader sees the complete old folder or the complete
new one, and the path never goes missing. The old folder, now at the hidden name, is deleted
after. Where the file system refuses the exchange (``EINVAL``/``ENOSYS``/``ENOTSUP``: NFS, some
FUSE), the fallback moves the new files over the old ones one ``rename`` at a time, then
deletes the old files the new version lacks: every file is always complete and the folder
never goes missing, but a reader *during* the commit may see some files new and some old. A
manifest written before the first move lets :func:`recover` finish an interrupted fallback.

Groups of files (a render's EXR + PNG + variance, a set of maps): :func:`commit_files`. All
files are first complete under temporary names; a journal naming every rename is written; the
renames follow in the caller's order; the journal is deleted. Each file is atomic on its own;
between the first and the last rename (microseconds, or after a crash until the next run) the
folder holds some files new and others old, and the journal says which renames are pending.
:func:`recover` (run by every writer on its output folder before it starts, and by every reader
of such a group: :mod:`pavonine.base.groups`) completes them; the files' ``pavonine:group``
marks let readers refuse a mix whose journal is gone.

Temporaries carry the writer's process id (``.<name>.pavonine-<kind>-<pid>-<random>``):
:func:`recover` removes those of dead processes only, so a run never touches the staging of a
live one. The guarantees cover process crashes (``SIGKILL``, out of memory); files are not
``fsync``-ed, so a power cut may lose recent writes. ``docs/reliability.md`` has the details.
"""

from __future__ import annotations

import contextlib
import ctypes
import errno
import functools
import json
import os
import shutil
import tempfile
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path

from pavonine.base.errors import TEMPORARY_MARK, InputError, write_error
from pavonine.base.faults import checkpoint
from pavonine.base.truncation import refuse_cut_short

#: ``renameat2`` flag (linux/fs.h): swap the two paths atomically.
RENAME_EXCHANGE = 2
_AT_FDCWD = -100
#: Errors meaning "this file system (or kernel) cannot exchange": take the fallback order.
_NO_EXCHANGE = (errno.EINVAL, errno.ENOSYS, errno.ENOTSUP, errno.EOPNOTSUPP)
#: Inside a staging folder during a fallback commit: the files it moves in, for :func:`recover`.
MANIFEST = ".pavonine-manifest.json"

STAGING = "staging"
JOURNAL = "journal"

#: Set by tests to exercise the fallback on file systems that can exchange.
exchange_supported = True


def temporary_prefix(name: str, kind: str) -> str:
    """``.<name>.pavonine-<kind>-<pid>-``: hidden, ours, and whose (see :func:`recover`)."""
    return f".{name}{TEMPORARY_MARK}{kind}-{os.getpid()}-"


@functools.cache
def _libc() -> ctypes.CDLL:
    return ctypes.CDLL(None, use_errno=True)


def exchange(a: str | os.PathLike, b: str | os.PathLike) -> bool:
    """Swap two existing paths atomically (``renameat2(RENAME_EXCHANGE)``).

    Returns ``False`` (nothing changed) when the kernel or file system cannot; raises
    ``OSError`` for any other failure.
    """
    if not exchange_supported:
        return False
    renameat2 = getattr(_libc(), "renameat2", None)
    if renameat2 is None:  # glibc < 2.28
        return False
    result = renameat2(_AT_FDCWD, os.fsencode(a), _AT_FDCWD, os.fsencode(b), RENAME_EXCHANGE)
    if result == 0:
        return True
    code = ctypes.get_errno()
    if code in _NO_EXCHANGE:
        return False
    raise OSError(code, os.strerror(code), os.fspath(b))


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def make_folder(folder: Path) -> list[Path]:
    """``mkdir -p folder``; returns the folders it created, deepest first (to undo it). A
    folder that cannot be made is a one-line :class:`InputError` naming it."""
    folder = Path(folder)
    missing = []
    while not os.path.lexists(folder) and folder != folder.parent:
        missing.append(folder)
        folder = folder.parent
    for path in reversed(missing):
        try:
            path.mkdir()
        except FileExistsError:
            pass
        except OSError as exc:
            remove_if_empty(missing)
            raise InputError(str(path), f"cannot write: {exc.strerror or exc}") from None
    return missing


def remove_if_empty(folders: Sequence[Path]) -> None:
    """Remove the folders :func:`make_folder` created, where they are still empty."""
    for folder in folders:
        try:
            folder.rmdir()
        except OSError:
            return


@contextmanager
def _staging_in(folder: Path, name: str, target: Path) -> Iterator[Path]:
    """A hidden staging folder for ``name`` inside ``folder`` (after :func:`recover`), removed
    on exit; errors while writing it become one-line :class:`InputError` naming ``target``."""
    staging = None
    try:
        recover(folder)
        staging = Path(tempfile.mkdtemp(prefix=temporary_prefix(name, STAGING), dir=folder))
        staging.chmod(0o777 & ~_umask())  # mkdtemp makes 0700; an asset folder is shared
        yield staging
    except (OSError, RuntimeError, InputError) as exc:
        if isinstance(exc, FileExistsError) and exc.filename == str(target):
            raise
        mapped = write_error(exc, target, staging)
        if mapped is None:
            raise
        raise mapped from None
    finally:  # a fallback commit that could not finish keeps its manifest for recover()
        if staging is not None and os.path.lexists(staging) and _manifest(staging) is None:
            shutil.rmtree(staging, ignore_errors=True)


@contextmanager
def staged_folder(
    target: str | os.PathLike, *, replace: bool, subject: str | None = None
) -> Iterator[Path]:
    """Yield a hidden staging folder inside ``target``'s parent; commit it to ``target`` on
    success (:func:`commit_folder`), remove it on failure.

    The parent is created first (and removed again if the write fails and it is empty), so
    nothing is ever written outside it. Stale temporaries of dead runs there are cleaned first
    (:func:`recover`). Errors while writing (a full disk, a size limit, USD failing to save)
    become one-line :class:`InputError` naming ``target``. Without ``replace`` an existing
    ``target`` raises ``FileExistsError`` (the caller words it).
    """
    target = Path(target)
    created = make_folder(target.parent)
    try:
        with _staging_in(target.parent, target.name, target) as staging:
            yield staging
            refuse_files_cut_short(staging)
            checkpoint("staging.written", subject)
            commit_folder(staging, target, replace=replace, subject=subject)
    finally:
        if not os.path.lexists(target):  # False, not an error, for a name the path refuses
            remove_if_empty(created)


def refuse_files_cut_short(staging: Path) -> None:
    """Check every image and crate layer written into ``staging`` is whole before it is
    committed (:mod:`pavonine.base.truncation`): a library's unreported short write is a
    write error, never a committed file."""
    for path in sorted(staging.rglob("*")):
        if path.is_file() and not path.is_symlink():
            refuse_cut_short(path)


def commit_folder(
    staging: Path, target: Path, *, replace: bool, subject: str | None = None
) -> None:
    """Put the finished folder ``staging`` at ``target`` (same parent).

    A missing ``target`` is one ``rename``; without ``replace`` that rename is also the
    existence check (the kernel refuses to rename onto a non-empty folder), raising
    ``FileExistsError``. With ``replace`` an existing ``target`` is exchanged (one atomic step)
    or, where the file system cannot, replaced file by file (:func:`move_into`).
    """
    try:
        os.rename(staging, target)
        return
    except OSError as exc:
        if exc.errno not in (errno.EEXIST, errno.ENOTEMPTY, errno.ENOTDIR, errno.EISDIR):
            raise
        if not replace:
            raise FileExistsError(errno.EEXIST, "exists", str(target)) from None
    if exchange(staging, target):
        checkpoint("folder.exchanged", subject)
        shutil.rmtree(staging, ignore_errors=True)  # the old version, now at the hidden name
        return
    if not target.is_dir():
        raise OSError(errno.ENOTDIR, "not a folder; cannot replace it", str(target))
    move_into(staging, target, subject)


def move_into(staging: Path, target: Path, subject: str | None = None) -> None:
    """The fallback commit: move every file of ``staging`` over ``target``'s, then delete the
    files ``target`` has that ``staging`` lacks. The path never goes missing and each file is
    whole, but until it finishes ``target`` holds a mix; its manifest lets :func:`recover`
    finish the job after a crash."""
    files = sorted(
        str(p.relative_to(staging))
        for p in staging.rglob("*")
        if not p.is_dir() and p.name != MANIFEST
    )
    (staging / MANIFEST).write_text(json.dumps({"target": target.name, "files": files}))
    try:
        _finish_moves(staging, target, files, subject)
    except BaseException:  # Ctrl-C half-way: roll forward rather than leave a mix
        _finish_moves(staging, target, files)
        raise


def _finish_moves(
    staging: Path, target: Path, files: Sequence[str], subject: str | None = None
) -> None:
    for i, relative in enumerate(files):
        source, destination = staging / relative, target / relative
        if not os.path.lexists(source):
            continue  # moved before a crash
        if destination.is_dir() and not destination.is_symlink():
            shutil.rmtree(destination)
        destination.parent.mkdir(parents=True, exist_ok=True)
        os.replace(source, destination)
        if i == len(files) // 2:
            checkpoint("folder.moving", subject)
    keep = set(files)
    for path in sorted(target.rglob("*"), reverse=True):  # children before their folders
        relative = str(path.relative_to(target))
        if relative in keep:
            continue
        if path.is_dir() and not path.is_symlink():
            if not any(f.startswith(relative + os.sep) for f in keep):
                shutil.rmtree(path, ignore_errors=True)
        else:
            path.unlink(missing_ok=True)
    shutil.rmtree(staging, ignore_errors=True)


@contextmanager
def staged_files(folder: str | os.PathLike, subject: str | None = None) -> Iterator[Path]:
    """Yield a hidden staging folder inside ``folder`` (created, and removed again if the write
    fails and it is empty); on success every file written into it is renamed into ``folder``
    as one journalled group (:func:`commit_files`, in name order). For outputs that share a
    folder with other files (a set of maps): each file is replaced atomically, the set is
    completed by :func:`recover` if a crash interrupts it. Write errors become one-line
    :class:`InputError` naming ``folder``."""
    folder = Path(folder)
    created = make_folder(folder)
    committed = False
    try:
        with _staging_in(folder, folder.name, folder) as staging:
            yield staging
            refuse_files_cut_short(staging)
            names = sorted(p.name for p in staging.iterdir() if not p.is_dir())
            checkpoint("staging.written", subject)
            commit_files([(staging / n, folder / n) for n in names], subject)
            committed = True
    finally:
        if not committed:
            remove_if_empty(created)


@contextmanager
def temporary_file(target: str | os.PathLike) -> Iterator[Path]:
    """Yield a hidden temporary path beside ``target`` (its folder created), for
    :func:`commit_files` or :func:`atomic_path`; removed on exit if
    still there. Write errors about it become one-line :class:`InputError` naming ``target``
    (:func:`pavonine.base.errors.write_error`)."""
    target = Path(target)
    created = make_folder(target.parent)
    try:
        fd, name = tempfile.mkstemp(
            prefix=temporary_prefix(target.stem, "tmp"), suffix=target.suffix, dir=target.parent
        )
    except OSError as exc:
        remove_if_empty(created)
        raise InputError(str(target), f"cannot write: {exc.strerror or exc}") from None
    os.close(fd)
    tmp = Path(name)
    tmp.chmod(0o666 & ~_umask())  # mkstemp makes 0600; give it the permissions open() would
    try:
        yield tmp
    except (OSError, RuntimeError, InputError) as exc:
        mapped = write_error(exc, target, tmp)
        if mapped is None:
            raise
        raise mapped from None
    finally:
        if os.path.lexists(tmp):
            tmp.unlink()
        if not os.path.lexists(target):  # False, not an error, for a name the path refuses
            remove_if_empty(created)


def commit_files(moves: Sequence[tuple[Path, Path]], subject: str | None = None) -> None:
    """Rename complete temporaries over their targets, in the given order, as one group.

    A journal (``.<first target>.pavonine-journal-<pid>-*.json`` beside the first target)
    names every rename before the first one; :func:`recover` completes an interrupted group.
    """
    if not moves:
        return
    folder = moves[0][1].parent
    fd, journal = tempfile.mkstemp(
        prefix=temporary_prefix(moves[0][1].name, JOURNAL), suffix=".json", dir=folder
    )
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as out:
            json.dump([[os.path.abspath(a), os.path.abspath(b)] for a, b in moves], out)
    except BaseException:
        os.unlink(journal)
        raise
    checkpoint("files.journal", subject)
    try:
        for i, (tmp, target) in enumerate(moves):
            try:
                os.replace(tmp, target)
            except OSError as exc:
                raise InputError(str(target), f"cannot write: {exc.strerror or exc}") from None
            if i < len(moves) - 1:  # between two renames (PAVONINE_FAULT=files.renaming#N)
                checkpoint("files.renaming", subject)
    except BaseException:  # Ctrl-C or a failed rename: the journal is the commit point
        for tmp, target in moves:
            if os.path.lexists(tmp):
                with contextlib.suppress(OSError):
                    os.replace(tmp, target)
        raise
    finally:
        os.unlink(journal)


def owner_pid(name: str) -> int | None:
    """The process id in temporary ``name`` (``-<kind>-<pid>-``), ``None`` if it has none."""
    try:
        return int(name.rsplit(TEMPORARY_MARK, 1)[1].split("-")[1])
    except (IndexError, ValueError):
        return None


def owner_alive(name: str) -> bool:
    """Whether the process that made temporary ``name`` still runs (``-<kind>-<pid>-``)."""
    pid = owner_pid(name)
    if pid is None:
        return True  # not one of ours after all: leave it
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def _manifest(staging: Path) -> dict | None:
    """The fallback commit's manifest in ``staging``, if complete (one cut short by a crash
    was written before any file moved: the staging folder is then simply deleted)."""
    try:
        record = json.loads((staging / MANIFEST).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    return record if isinstance(record, dict) and {"target", "files"} <= set(record) else None


def recover(folder: str | os.PathLike) -> list[str]:
    """Finish or remove what crashed runs left in ``folder``: complete journalled renames and
    fallback commits (:func:`commit_files`, :func:`move_into`), delete staging folders and
    temporary files. Only temporaries of dead processes are touched. Returns what it did."""
    folder = Path(folder)
    try:
        names = sorted(n for n in os.listdir(folder) if n.startswith(".") and TEMPORARY_MARK in n)
    except (FileNotFoundError, NotADirectoryError):
        return []
    stale = [n for n in names if not owner_alive(n)]
    done = []
    for name in (n for n in stale if f"{TEMPORARY_MARK}{JOURNAL}-" in n):
        path = folder / name
        try:
            moves = json.loads(path.read_text(encoding="utf-8"))
        except (OSError, ValueError):
            moves = []  # written by a process killed mid-write: no rename had started
        for tmp, target in moves:
            if os.path.lexists(tmp):
                os.replace(tmp, target)
                done.append(f"completed {target}")
        path.unlink(missing_ok=True)
    for name in (n for n in stale if f"{TEMPORARY_MARK}{JOURNAL}-" not in n):
        path = folder / name
        record = _manifest(path)
        if record is not None:
            _finish_moves(path, folder / record["target"], record["files"])
            done.append(f"completed {folder / record['target']}")
        elif path.is_dir() and not path.is_symlink():
            shutil.rmtree(path, ignore_errors=True)
            done.append(f"removed {path}")
        elif os.path.lexists(path):
            path.unlink(missing_ok=True)
            done.append(f"removed {path}")
    return done


def check_writable(path: str | os.PathLike) -> None:
    """Raise a one-line :class:`InputError` unless a file can be created at ``path``.

    Probes the output's folder with a temporary file, so that an unwritable output is found
    before a long render or conversion rather than after it. Folders on the way that do not
    exist yet are made for the probe (as :func:`atomic_path` would make them) and removed again;
    nothing is written outside the output's folder.
    """
    target = Path(path)
    if target.is_dir():
        raise InputError(str(path), "is a folder, expected a file name")
    folder = target.parent
    while not folder.exists() and folder != folder.parent:
        folder = folder.parent
    if not folder.is_dir():
        raise InputError(str(path), f"cannot write here: {folder} is not a folder")
    if folder != target.parent:
        if os.statvfs(folder).f_flag & os.ST_RDONLY:
            raise InputError(str(path), f"cannot write here ({os.strerror(errno.EROFS)})")
        if not os.access(folder, os.W_OK | os.X_OK):
            raise InputError(str(path), f"cannot write here ({os.strerror(errno.EACCES)})")
    try:
        created = make_folder(target.parent)
    except InputError as exc:
        raise InputError(str(path), f"cannot write here: {exc.where}: {exc.message}") from None
    try:
        fd, probe = tempfile.mkstemp(prefix=temporary_prefix("probe", "tmp"), dir=target.parent)
        os.close(fd)
        os.unlink(probe)
    except OSError as exc:
        raise InputError(str(path), f"cannot write here ({exc.strerror or exc})") from None
    finally:
        remove_if_empty(created)


@contextmanager
def atomic_path(target: str | os.PathLike) -> Iterator[Path]:
    """Yield a temporary path beside ``target``; rename it over ``target`` only on success.

    An ``OSError`` or a USD error about the temporary file (or its folder) is reported as an
    :class:`InputError` naming ``target``, which is what the user asked to write
    (:func:`temporary_file`).
    """
    target = Path(target)
    recover(target.parent)  # what killed writers left here
    with temporary_file(target) as tmp:
        yield tmp
        if tmp.exists():  # a writer may have replaced it: the permissions open() would give
            umask = os.umask(0)
            os.umask(umask)
            tmp.chmod(0o666 & ~umask)
            refuse_cut_short(tmp, target)  # libraries do not all report a short write
        os.replace(tmp, target)
