"""One-line, non-zero-exit error reporting shared by every ``pavonine`` command."""

from __future__ import annotations

import functools
import os
import tempfile
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any, TypeVar

import click

from pavonine.materials.parameters import ParameterError

F = TypeVar("F", bound=Callable[..., Any])

EXIT_BAD_INPUT = 2


def one_line(text: str) -> str:
    """``text`` with line breaks and other control characters escaped (``\\n``), so that an
    error naming a hostile key or value (``name = "eye\\n"``) stays one line."""
    if text.isprintable():
        return text
    return "".join(c if c.isprintable() else repr(c)[1:-1] for c in text)


class InputError(Exception):
    """Bad user input: ``where`` names the file and/or field, ``message`` says what is wrong."""

    def __init__(self, where: str, message: str):
        super().__init__(one_line(f"{where}: {message}"))
        self.where = where
        self.message = message

    def __reduce__(self):  # picklable, so a worker process can send it back to the client
        return (type(self), (self.where, self.message))


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
            click.echo(f"error: {where}: {exc.strerror or exc}", err=True)
            raise SystemExit(EXIT_BAD_INPUT) from None

    return wrapper  # type: ignore[return-value]


@contextmanager
def atomic_path(target: str | os.PathLike) -> Iterator[Path]:
    """Yield a temporary path beside ``target``; rename it over ``target`` only on success.

    An ``OSError`` about the temporary file (or its folder) is reported as an
    :class:`InputError` naming ``target``, which is what the user asked to write.
    """
    target = Path(target)
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(
            prefix=f".{target.stem}.", suffix=target.suffix, dir=target.parent
        )
    except OSError as exc:
        raise InputError(str(target), f"cannot write: {exc.strerror or exc}") from None
    os.close(fd)
    tmp_path = Path(tmp)
    try:
        yield tmp_path
        if tmp_path.exists():  # mkstemp creates 0600: give the file the permissions open() would
            umask = os.umask(0)
            os.umask(umask)
            tmp_path.chmod(0o666 & ~umask)
        os.replace(tmp_path, target)
    except OSError as exc:
        if exc.filename not in (str(tmp_path), str(target)):
            raise
        raise InputError(str(target), f"cannot write: {exc.strerror or exc}") from None
    finally:
        if tmp_path.exists():
            tmp_path.unlink()
