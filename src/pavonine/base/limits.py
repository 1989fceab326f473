"""Input limits: what Pavonine agrees to read before it spends memory or time on it.

One place for the budgets that keep hostile or mistaken input from exhausting the machine
(``docs/reliability.md``, "Input limits"):

* :data:`DEFAULT_MAX_PIXELS`: the pixel budget of every image Pavonine reads (maps, ``compare``
  inputs, textures read by the pipeline) and of every render size given on the command line. It
  is checked from the image's *header* (OpenImageIO reads the spec before any pixel), so a small
  PNG declaring 30000x30000 pixels is refused before it is decoded. Override it with
  ``$PAVONINE_MAX_PIXELS`` or ``--max-pixels`` where a command reads images.
* :data:`MAX_IMAGE_CHANNELS`: channels per image.
* :data:`MIN_MAP_SIDE`, :data:`MAX_MAP_ASPECT`: the shape of a feather's maps.
* :data:`MAX_RECIPE_BYTES`: the size of a TOML recipe.
* :data:`SEED_RANGE`: every seed (Mitsuba's sampler seed is a 32-bit unsigned integer).
* :func:`name_too_long`: an asset name must fit the output's file system (``NAME_MAX`` with
  the characters Pavonine's own file names add, :data:`NAME_OVERHEAD`, and ``PATH_MAX``).

Files are checked to be *regular files* before they are opened for reading
(:func:`regular_file`, :func:`read_small_file`): a FIFO would block forever, ``/dev/zero``
never ends, a symlink loop is an ``ELOOP``; each is a one-line :class:`InputError` instead.
"""

from __future__ import annotations

import contextlib
import errno
import os
import stat
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

from pavonine.base.errors import InputError
from pavonine.base.native_output import captured

#: Pixels (width × height × depth) of the largest image read: 16384 × 16384, the largest map side
#: ``pavonine validate`` accepts (``schemas/map_validators.py``, ``MAX_MAP_SIZE``) squared. A
#: single-channel map of this size is 1 GiB as float32.
DEFAULT_MAX_PIXELS = 16384 * 16384
#: Environment variable overriding :data:`DEFAULT_MAX_PIXELS` (a positive integer).
MAX_PIXELS_ENV = "PAVONINE_MAX_PIXELS"
#: Most channels an image read by Pavonine may have (a render with many AOVs has a few dozen).
MAX_IMAGE_CHANNELS = 64
#: Smallest side of a feather's maps (``pavonine maps`` paints at least 8 pixels across).
MIN_MAP_SIDE = 8
#: Widest and tallest width:height of a feather's maps (the shipped kinds span 0.36 to 0.72). The
#: maps' height is the feather's length, so a 4000x1 map asks for a vane 4000 times wider than
#: long: xatlas charts that sliver without end.
MAX_MAP_ASPECT = 8.0
#: Two maps have "equal aspect" when width/height differ by less than this fraction.
ASPECT_TOLERANCE = 0.01
#: Largest recipe file (TOML); the shipped recipes are about 2 KiB.
MAX_RECIPE_BYTES = 1 << 20
#: Inclusive range of every seed (maps, renders, trains): Mitsuba's seed is a ``uint32``.
SEED_RANGE = (0, 2**32 - 1)

_override: int | None = None


#: Bytes Pavonine's own file names add to an asset name, the longest of them: ``NAME.mtlx``'s
#: temporary ``.NAME.pavonine-tmp-<pid>-<8 random>.mtlx`` (a Linux process id has at most 7
#: digits); the staging folder ``.NAME.pavonine-staging-<pid>-<8 random>`` adds 35.
NAME_OVERHEAD = len(".") + len(".pavonine-tmp-") + 7 + len("-") + 8 + len(".mtlx")
_STAGING_OVERHEAD = len(".") + len(".pavonine-staging-") + 7 + len("-") + 8


def name_too_long(name: str, outdir: str | os.PathLike) -> str | None:
    """Why an asset ``name`` cannot be written under ``outdir`` (its file names would pass the
    file system's ``NAME_MAX``, or its deepest path ``PATH_MAX``: ``os.pathconf`` of ``outdir``
    or its nearest existing parent), or ``None``."""
    folder = Path(os.path.abspath(outdir))
    while not os.path.isdir(folder) and folder != folder.parent:
        folder = folder.parent
    name_max, path_max = (_pathconf(folder, key, fallback) for key, fallback in
                          (("PC_NAME_MAX", 255), ("PC_PATH_MAX", 4096)))  # fmt: skip
    length = len(os.fsencode(name))
    if length + NAME_OVERHEAD > name_max:
        return (
            f"{length} characters is too long for a file name here: the file system allows "
            f"{name_max} (NAME_MAX of {folder}) and the asset's files add up to {NAME_OVERHEAD} "
            f"to the name; at most {name_max - NAME_OVERHEAD} characters"
        )
    base = len(os.fsencode(os.path.abspath(outdir))) + 2 + _STAGING_OVERHEAD + NAME_OVERHEAD
    if base + 2 * length >= path_max:  # the deepest path: the .mtlx temporary in the staging
        return (
            f"{length} characters makes the asset's deepest path {base + 2 * length} bytes "
            f"under {outdir}, past the file system's PATH_MAX of {path_max}; at most "
            f"{max(0, (path_max - 1 - base) // 2)} characters here"
        )
    return None


def _pathconf(folder: Path, key: str, fallback: int) -> int:
    try:
        value = os.pathconf(folder, key)
    except (OSError, ValueError):
        return fallback
    return value if value > 0 else fallback


def odd_aspects(
    sizes: Mapping[str, tuple[int, int]], reference: str = "alpha"
) -> tuple[str | None, list[str]]:
    """The reference map (``reference`` when ``sizes`` has it, else the first) and the maps
    whose width:height differs from its by more than :data:`ASPECT_TOLERANCE` (a fraction):
    such maps cannot span the same feather. ``sizes``: ``(width, height)`` by map name."""
    if reference not in sizes:
        reference = next(iter(sizes), None)
    if reference is None:
        return None, []
    ref_w, ref_h = sizes[reference]
    return reference, [
        name
        for name, (w, h) in sizes.items()
        if abs((w / h) / (ref_w / ref_h) - 1.0) > ASPECT_TOLERANCE
    ]


def set_max_pixels(count: int | None) -> None:
    """Use ``count`` as the pixel budget for the rest of the process (``None``: env or default)."""
    global _override
    if count is not None and count < 1:
        raise InputError("--max-pixels", f"must be a positive number of pixels, got {count}")
    _override = count


class pixel_budget(contextlib.AbstractContextManager):
    """Use ``count`` as the pixel budget inside the ``with`` block (``None``: leave it as it is),
    then restore the budget that was in force before, whether the block succeeded or raised.

    A class, not a generator: a generator-based context manager that is entered and then
    abandoned (its ``with`` never left, e.g. a click context that is never closed) runs its
    ``finally`` whenever the garbage collector finds it, which would put back an old budget in
    the middle of whatever command is running then. This one acts only in ``__exit__``.
    """

    def __init__(self, count: int | None) -> None:
        self._count = count
        self._before: int | None = None

    def __enter__(self) -> None:
        self._before = _override
        if self._count is not None:
            set_max_pixels(self._count)

    def __exit__(self, *exc_info: object) -> None:
        set_max_pixels(self._before)


def max_pixels() -> int:
    """The pixel budget in force: ``--max-pixels``, else ``$PAVONINE_MAX_PIXELS``, else default."""
    if _override is not None:
        return _override
    text = os.environ.get(MAX_PIXELS_ENV, "").strip()
    if not text:
        return DEFAULT_MAX_PIXELS
    try:
        value = int(text.replace("_", ""))
    except ValueError:
        value = 0
    if value < 1:
        raise InputError(MAX_PIXELS_ENV, f"must be a positive whole number of pixels, got {text!r}")
    return value


def _over_budget(count: int) -> str:
    return (
        f"{count:,} pixels exceed the pixel budget of {max_pixels():,} "
        f"(raise it with --max-pixels or ${MAX_PIXELS_ENV}; docs/reliability.md)"
    )


def check_pixel_count(where: str, width: int, height: int, depth: int = 1) -> None:
    """Raise :class:`InputError` at ``where`` when ``width × height × depth`` exceeds the budget."""
    count = int(width) * int(height) * max(1, int(depth))
    if count > max_pixels():
        raise InputError(where, f"{width}x{height}: {_over_budget(count)}")


# ------------------------------------------------------------------------------------ files
def _kind(mode: int) -> str:
    if stat.S_ISDIR(mode):
        return "a directory"
    if stat.S_ISFIFO(mode):
        return "a FIFO (named pipe)"
    if stat.S_ISCHR(mode) or stat.S_ISBLK(mode):
        return "a device"
    if stat.S_ISSOCK(mode):
        return "a socket"
    return "not a regular file"


def _stat_error(where: str, exc: OSError, missing: str = "file not found") -> InputError:
    if exc.errno == errno.ENOENT:
        return InputError(where, missing)
    if exc.errno == errno.ELOOP:
        return InputError(where, "symbolic link loop")
    return InputError(where, f"cannot read ({exc.strerror or exc})")


def regular_file(path: str | os.PathLike, where: str | None = None) -> Path:
    """``path`` when it is (a link to) a regular file, else :class:`InputError` at ``where``.

    Never opens the file: a FIFO, a device (``/dev/zero``), a directory or a symlink loop is
    refused from its ``stat``.
    """
    path = Path(path)
    where = where or str(path)
    try:
        mode = os.stat(path).st_mode
    except OSError as exc:
        raise _stat_error(where, exc) from None
    except ValueError as exc:  # an embedded NUL byte
        raise InputError(where, f"not a usable path ({exc})") from None
    if not stat.S_ISREG(mode):
        raise InputError(where, f"is {_kind(mode)}, expected a regular file")
    return path


def read_small_file(
    path: str | os.PathLike,
    where: str | None = None,
    limit: int = MAX_RECIPE_BYTES,
    missing: str = "file not found",
) -> bytes:
    """The bytes of a regular file of at most ``limit`` bytes, or :class:`InputError`.

    Opened non-blocking and checked with ``fstat`` on the open descriptor, so a FIFO cannot block
    and a device cannot stream forever; ``missing`` is the message for a file that does not exist.
    """
    where = where or str(path)
    flags = os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_NOCTTY", 0)
    try:
        fd = os.open(os.fspath(path), flags)
    except OSError as exc:
        raise _stat_error(where, exc, missing) from None
    except ValueError as exc:
        raise InputError(where, f"not a usable path ({exc})") from None
    try:
        info = os.fstat(fd)
        if not stat.S_ISREG(info.st_mode):
            raise InputError(where, f"is {_kind(info.st_mode)}, expected a regular file")
        if info.st_size > limit:
            raise InputError(where, f"is {info.st_size:,} bytes; at most {limit:,} are read")
        with os.fdopen(fd, "rb", closefd=False) as handle:
            data = handle.read(limit + 1)
    except OSError as exc:
        raise InputError(where, f"cannot read ({exc.strerror or exc})") from None
    finally:
        os.close(fd)
    if len(data) > limit:
        raise InputError(where, f"is more than {limit:,} bytes")
    return data


# ----------------------------------------------------------------------------------- images
def check_image_spec(where: str, spec: Any) -> None:
    """Refuse an OpenImageIO ``ImageSpec`` beyond the pixel budget or :data:`MAX_IMAGE_CHANNELS`."""
    if spec.width < 1 or spec.height < 1:
        raise InputError(where, f"image is {spec.width}x{spec.height}: no pixels")
    if spec.depth > 1:
        raise InputError(where, f"is a volume image (depth {spec.depth}); expected a 2-D image")
    check_pixel_count(where, spec.width, spec.height)
    if spec.nchannels > MAX_IMAGE_CHANNELS:
        raise InputError(
            where, f"has {spec.nchannels} channels; at most {MAX_IMAGE_CHANNELS} are read"
        )


@contextlib.contextmanager
def open_image(
    path: str | os.PathLike, where: str | None = None, *, unassociated_alpha: bool = False
) -> Iterator[Any]:
    """An OpenImageIO ``ImageInput`` on ``path`` whose header passed :func:`check_image_spec`.

    ``path`` must be a regular file; an unreadable header is an :class:`InputError` at ``where``
    (default: the path). The input is closed on leaving the block. ``unassociated_alpha`` reads
    colour as stored where the format stores it unassociated (PNG), not multiplied by alpha.
    """
    import OpenImageIO as oiio

    where = where or str(path)
    regular_file(path, where)
    config = oiio.ImageSpec()
    if unassociated_alpha:
        config.attribute("oiio:UnassociatedAlpha", 1)
    # libpng prints its own "libpng error: …" lines to stderr while OpenImageIO reads; OpenImageIO's
    # geterror() says the same, and it is reported as one line (here, or by the caller)
    with captured(2):
        image = oiio.ImageInput.open(os.fspath(path), config)
        if image is None:
            reason = oiio.geterror().strip().splitlines()
            raise InputError(
                where, f"cannot read image ({reason[-1] if reason else 'unknown format'})"
            )
        try:
            check_image_spec(where, image.spec())
            yield image
        finally:
            image.close()


def image_error(text: str, empty: str = "no pixels") -> str:
    """OpenImageIO's error text as one reason: its first line (the later ones repeat it through
    the format library's words), or ``empty`` when it said nothing."""
    lines = [line.strip() for line in text.splitlines() if line.strip()]
    return lines[0] if lines else empty


def check_image(path: str | os.PathLike, where: str | None = None) -> tuple[int, int]:
    """Check an image's header against the budget without decoding it; its (width, height)."""
    with open_image(path, where) as image:
        spec = image.spec()
        return spec.width, spec.height


def check_seed(where: str, value: int) -> int:
    """``value`` when it lies in :data:`SEED_RANGE`, else :class:`InputError` at ``where``."""
    low, high = SEED_RANGE
    if isinstance(value, bool) or not isinstance(value, int) or not low <= value <= high:
        raise InputError(where, f"must be a whole number in [{low}, {high}], got {value!r}")
    return value
