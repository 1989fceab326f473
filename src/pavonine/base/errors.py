"""One-line, non-zero-exit error reporting shared by every ``pavonine`` command."""

from __future__ import annotations

import errno
import functools
import os
import re
from collections.abc import Callable
from typing import Any, TypeVar

import click

F = TypeVar("F", bound=Callable[..., Any])

EXIT_BAD_INPUT = 2


def one_line(text: str) -> str:
    """``text`` with line breaks and other control characters escaped (``\\n``), so that an
    error naming a hostile key or value (``name = "eye\\n"``) stays one line."""
    if text.isprintable():
        return text
    return "".join(c if c.isprintable() else repr(c)[1:-1] for c in text)


class ParameterError(ValueError):
    """A physically meaningless parameter; ``field`` names it (e.g. ``class[2].long.radius``).

    ``kind`` classifies the problem (``NotFinite``, ``NotPositive``, ``TooFewLayers``,
    ``TooManyLayers``, ``RodsOverlap``, ``Invalid``) for tools that report findings by name, such
    as the USD validators.
    """

    def __init__(self, field_name: str, message: str, kind: str = "Invalid"):
        super().__init__(f"{field_name}: {message}")
        self.field = field_name
        self.reason = message
        self.kind = kind


class InputError(Exception):
    """Bad user input: ``where`` names the file and/or field, ``message`` says what is wrong."""

    def __init__(self, where: str, message: str):
        super().__init__(one_line(f"{where}: {message}"))
        self.where = where
        self.message = message

    def __reduce__(self):  # picklable, so a worker process can send it back to the client
        return (type(self), (self.where, self.message))


#: OS errors a user can cause while we write (full disk, size limit, permissions, read-only file
#: system, quota): named by their own words in one-line errors, including inside USD's messages.
WRITE_ERRNOS = (errno.ENOSPC, errno.EFBIG, errno.EACCES, errno.EROFS, errno.EDQUOT, errno.EPERM)

#: Hidden temporaries of our own making: ``.<name>.pavonine-<kind>-<pid>-<random>[suffix]``.
TEMPORARY_MARK = ".pavonine-"


def is_usd_error(exc: BaseException) -> bool:
    """Whether ``exc`` is USD's ``Tf.ErrorException`` (checked without importing ``pxr``)."""
    kind = type(exc)
    return kind.__name__ == "ErrorException" and kind.__module__.startswith("pxr")


def usd_reason(exc: BaseException) -> str:
    """What failed, in one line, from a USD ``Tf.ErrorException``: the OS error it carries
    (``No space left on device``, ``File too large``...) when it names one, else its first
    commentary."""
    text = str(exc)
    for number in WRITE_ERRNOS:
        if os.strerror(number) in text:
            return os.strerror(number)
    for part in re.split(r"(?:\n\s*|,\s*)(?=Error in ')", text):
        match = re.search(r" : '(.*)'\W*$", part.strip(), re.S)
        if match:
            return " ".join(match.group(1).split())[:300]
    return " ".join(text.split())[:300]


def diagnose_write_failure(path: str | os.PathLike) -> str | None:
    """Why writing ``path`` failed, for libraries that do not say (OpenImageIO): a full disk, a
    read-only file system, no write permission on its folder, or the file-size limit
    (``ulimit -f``) reached; ``None`` when none of these holds."""
    import resource

    folder = os.path.dirname(os.path.abspath(path))
    try:
        stats = os.statvfs(folder)
    except OSError:
        return None
    if stats.f_flag & os.ST_RDONLY:
        return os.strerror(errno.EROFS)
    if stats.f_bavail * stats.f_frsize < 1 << 20:
        return os.strerror(errno.ENOSPC)
    if not os.access(folder, os.W_OK):
        return os.strerror(errno.EACCES)
    limit = resource.getrlimit(resource.RLIMIT_FSIZE)[0]
    if limit != resource.RLIM_INFINITY and os.path.isfile(path):
        if os.path.getsize(path) >= limit:
            return os.strerror(errno.EFBIG)
    return None


def scrub_temporaries(message: str, target: str | os.PathLike) -> str:
    """``message`` with our hidden temporaries' paths replaced by ``target``."""
    return re.sub(r"\S*" + re.escape(TEMPORARY_MARK) + r"[^\s\"']*", str(target), message)


def write_error(
    exc: BaseException, target: str | os.PathLike, temporary: str | os.PathLike | None = None
) -> InputError | None:
    """``exc``, raised while writing ``target`` (through ``temporary``, a hidden file or staging
    folder), as a one-line :class:`InputError` naming ``target``; ``None`` if it is not a write
    error (a bug, or an error about another file, an input, that names itself).

    OS errors and USD's own write errors become ``<target>: cannot write: <what failed>``; an
    :class:`InputError` that names the temporary is renamed to name ``target``.
    """
    where = str(target)
    if isinstance(exc, InputError):
        if temporary is not None and exc.where.startswith(str(temporary)):
            return InputError(where + exc.where[len(str(temporary)) :], exc.message)
        return None
    exc = _first_copy_error(exc)
    if isinstance(exc, OSError):
        named = os.fspath(exc.filename) if exc.filename is not None else ""
        if exc.filename2 is not None and exc.errno in WRITE_ERRNOS:
            named = os.fspath(exc.filename2)  # a copy (shutil): the source first, then the output
        inside = temporary is not None and named.startswith(str(temporary))
        if named and not (inside or named.startswith(where) or TEMPORARY_MARK in named):
            return None  # about another file (an input): it names itself
        if inside and named != str(temporary):
            named = where + named[len(str(temporary)) :]
        if not named or TEMPORARY_MARK in named:
            named = where
        return InputError(named, f"cannot write: {exc.strerror or exc}")
    if is_usd_error(exc):
        return InputError(where, f"cannot write: {usd_reason(exc)}")
    return None


def _first_copy_error(exc: BaseException) -> BaseException:
    """``shutil.copytree``'s collected ``shutil.Error`` as the ``OSError`` of its first file
    (source, output) when that is a write error; ``exc`` itself otherwise."""
    import shutil

    if not isinstance(exc, shutil.Error) or not exc.args or not isinstance(exc.args[0], list):
        return exc
    for source, destination, why in exc.args[0]:
        for number in WRITE_ERRNOS:
            if os.strerror(number) in str(why):
                return OSError(number, os.strerror(number), source, None, destination)
    return exc


def one_line_errors(func: F) -> F:
    """Turn :class:`InputError`/:class:`ParameterError` into ``error: …`` on stderr and exit 2."""

    @functools.wraps(func)
    def wrapper(*args, **kwargs):
        try:
            return func(*args, **kwargs)
        except (InputError, ParameterError) as exc:
            click.echo(f"error: {exc}", err=True)
            raise SystemExit(EXIT_BAD_INPUT) from None
        except OSError as exc:  # unwritable output, a file where a folder should be, …
            where = exc.filename if exc.filename is not None else "output"
            if exc.filename2 is not None and exc.errno in WRITE_ERRNOS:
                where = exc.filename2  # a copy: the output, not its source
            click.echo(f"error: {where}: {exc.strerror or exc}", err=True)
            raise SystemExit(EXIT_BAD_INPUT) from None
        except RuntimeError as exc:  # USD's Tf.ErrorException: a layer it cannot read or write
            if not is_usd_error(exc):
                raise
            click.echo(f"error: usd: {usd_reason(exc)}", err=True)
            raise SystemExit(EXIT_BAD_INPUT) from None

    return wrapper  # type: ignore[return-value]
