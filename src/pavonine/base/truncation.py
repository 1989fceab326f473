"""Is a file just written whole? Checked after every write, never trusted to the library.

libpng does not report a short write (a PNG cut to 64 KB on a full disk was committed with exit
0), nor does OpenEXR; USD's crate writer may stop early too. :func:`cut_short` reads the file's
own structure back, which costs a few small reads, not a decode:

* PNG: the chunks (length, type, data, CRC) are walked from the signature; the last must be
  ``IEND`` and end exactly at the end of the file (PNG specification, 3rd ed., §5.3).
* OpenEXR (single-part scanline or tiled): the header is read up to its terminating null byte,
  then every entry of the offset table must point at a chunk lying inside the file, with its
  data size (OpenEXR file layout, "Offset Tables" and "Chunk Layout").
* USD crate (``.usdc``, a ``.usd`` that is binary): the bootstrap names the table of contents,
  written last; it and every section it lists must lie inside the file (OpenUSD
  ``pxr/usd/sdf/crateFile.cpp``, ``_BootStrap`` and ``_TableOfContents``).
* Other images OpenImageIO reads (JPEG, TIFF, HDR …): decoded whole once.

Text layers (``usda``) are checked where they are saved (:func:`save_whole`): the file must
hold exactly what the layer exports to. :func:`refuse_cut_short` turns a finding into the
one-line write error naming the output.
"""

from __future__ import annotations

import mmap
import os
import struct
from pathlib import Path

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
EXR_MAGIC = 20000630
CRATE_MAGIC = b"PXR-USDC"
#: Scanlines per chunk by OpenEXR compression code (NONE, RLE, ZIPS, ZIP, PIZ, PXR24, B44,
#: B44A, DWAA, DWAB).
EXR_LINES_PER_CHUNK = {0: 1, 1: 1, 2: 1, 3: 16, 4: 32, 5: 16, 6: 32, 7: 32, 8: 32, 9: 256}
_EXR_TILED, _EXR_LONG_NAMES, _EXR_DEEP, _EXR_MULTIPART = 0x200, 0x400, 0x800, 0x1000
IMAGE_SUFFIXES = {".png", ".exr", ".jpg", ".jpeg", ".tif", ".tiff", ".hdr", ".tga", ".bmp"}


def cut_short(path: str | os.PathLike) -> str | None:
    """Why the file at ``path`` is incomplete (``"… of … bytes"``), or ``None`` if it is whole
    or of a kind not checked here."""
    path = Path(path)
    try:
        size = path.stat().st_size
    except OSError:
        return None
    suffix = path.suffix.lower()
    if suffix not in IMAGE_SUFFIXES and suffix not in (".usdc", ".usd"):
        return None
    if size == 0:
        return "the file is empty"
    with open(path, "rb") as handle, mmap.mmap(handle.fileno(), 0, access=mmap.ACCESS_READ) as data:
        if data[:8] == PNG_SIGNATURE:
            return _png(data, size)
        if size >= 4 and struct.unpack_from("<i", data)[0] == EXR_MAGIC:
            return _exr(data, size, path)
        if data[:8] == CRATE_MAGIC:
            return _crate(data, size)
    if suffix in (".png", ".exr", ".usdc"):
        return f"the file does not begin as a {suffix[1:].upper()} file does"
    if suffix == ".usd":
        return None  # a text layer
    return _decodes(path)


def _short(needed: int, size: int) -> str:
    return f"the file is cut short: {size:,} bytes, its structure needs {needed:,}"


def _png(data: mmap.mmap, size: int) -> str | None:
    position = len(PNG_SIGNATURE)
    while position + 12 <= size:
        length, kind = struct.unpack_from(">I4s", data, position)
        end = position + 12 + length
        if end > size:
            return _short(end, size)
        if kind == b"IEND":
            return None if end == size else f"{size - end:,} bytes after the PNG's end"
        position = end
    return _short(position + 12, size) + " (no IEND chunk)"


def _exr(data: mmap.mmap, size: int, path: Path) -> str | None:
    flags = struct.unpack_from("<i", data, 4)[0]
    if flags & (_EXR_DEEP | _EXR_MULTIPART):
        return _decodes(path)
    position, attributes = 8, {}
    while True:
        if position >= size:
            return _short(position + 1, size)
        if data[position] == 0:
            position += 1
            break
        name_end = data.find(b"\0", position)
        type_end = data.find(b"\0", name_end + 1) if name_end >= 0 else -1
        if type_end < 0 or type_end + 5 > size:
            return _short(size + 1, size)
        name = bytes(data[position:name_end])
        length = struct.unpack_from("<i", data, type_end + 1)[0]
        start = type_end + 5
        if start + length > size:
            return _short(start + length, size)
        attributes[name] = bytes(data[start : start + length])
        position = start + length
    try:
        _, y0, _, y1 = struct.unpack("<4i", attributes[b"dataWindow"])
        compression = attributes[b"compression"][0]
    except (KeyError, struct.error, IndexError):
        return "the EXR header lacks its dataWindow or compression"
    if flags & _EXR_TILED or compression not in EXR_LINES_PER_CHUNK:
        return _decodes(path)  # tiled: chunk count depends on the level mode; decode it
    lines = EXR_LINES_PER_CHUNK[compression]
    chunks = -(-(y1 - y0 + 1) // lines)
    table_end = position + 8 * chunks
    if table_end > size:
        return _short(table_end, size)
    needed = table_end
    for (offset,) in struct.iter_unpack("<Q", data[position:table_end]):
        if offset < table_end:  # never written (OpenEXR fills the table in last)
            return _short(table_end + 8 * chunks, size) + " (its offset table is unwritten)"
        if offset + 8 > size:
            return _short(offset + 8, size)
        needed = max(needed, offset + 8 + struct.unpack_from("<i", data, offset + 4)[0])
    return _short(needed, size) if needed > size else None


def _crate(data: mmap.mmap, size: int) -> str | None:
    if size < 24:
        return _short(24, size)
    (toc,) = struct.unpack_from("<q", data, 16)
    if toc < 24 or toc + 8 > size:
        return _short(max(toc, 24) + 8, size)
    (count,) = struct.unpack_from("<Q", data, toc)
    end = toc + 8 + 32 * count
    if end > size:
        return _short(end, size)
    needed = end
    for index in range(count):
        start, length = struct.unpack_from("<qq", data, toc + 8 + 32 * index + 16)
        needed = max(needed, start + length)
    return _short(needed, size) if needed > size else None


def _decodes(path: Path) -> str | None:
    """Decode the whole image (formats without a cheap structural check)."""
    import OpenImageIO as oiio

    image = oiio.ImageInput.open(os.fspath(path))
    if image is None:
        return f"the image does not read back ({' '.join(oiio.geterror().split())[:200]})"
    try:
        pixels = image.read_image(oiio.FLOAT)
        if pixels is None or image.has_error:
            return f"the image does not read back ({' '.join(image.geterror().split())[:200]})"
    finally:
        image.close()
    return None


def text_layer_cut_short(layer, path: str | os.PathLike) -> str | None:
    """Why the text (``usda``) layer ``layer``, just saved to ``path``, is not all on disk:
    the file must hold exactly the bytes the layer exports to. ``None`` for crate layers
    (:func:`cut_short` checks those from the file)."""
    path = Path(path)
    if path.suffix.lower() == ".usdc":
        return cut_short(path)
    with open(path, "rb") as handle:
        if handle.read(8) == CRATE_MAGIC:
            return cut_short(path)
    expected = len(layer.ExportToString().encode("utf-8"))
    size = path.stat().st_size
    return None if size == expected else _short(expected, size)


def refuse_cut_short(path: str | os.PathLike, where: str | os.PathLike | None = None) -> None:
    """Raise the one-line write error naming ``where`` (default ``path``) if the file just
    written at ``path`` is incomplete (:func:`cut_short`), with the cause the file system gives
    (a full disk, the file-size limit) where it gives one."""
    reason = cut_short(path)
    if reason is not None:
        raise short_write(path, where, reason)


def short_write(path: str | os.PathLike, where: str | os.PathLike | None, reason: str):
    """The :class:`~pavonine.base.errors.InputError` for a file found incomplete."""
    from pavonine.base.errors import InputError, diagnose_write_failure

    cause = diagnose_write_failure(path) or "a short write the library did not report"
    return InputError(
        os.fspath(where if where is not None else path), f"cannot write: {cause} ({reason})"
    )


def refuse_size_other_than(
    path: str | os.PathLike, expected: int, where: str | os.PathLike | None = None
) -> None:
    """Raise the one-line write error naming ``where`` unless the file at ``path`` holds
    exactly ``expected`` bytes (a writer that knows what it wrote: a MaterialX document)."""
    size = os.path.getsize(path)
    if size != expected:
        raise short_write(path, where, _short(expected, size))


def save_whole(layer, path: str | os.PathLike) -> None:
    """``layer.Save()``, then check the file at ``path`` is whole (crate structure, or for a
    text layer exactly the bytes it exports to); raise the one-line write error if not."""
    layer.Save()
    reason = text_layer_cut_short(layer, path)
    if reason is not None:
        raise short_write(path, None, reason)
