"""Files behind USD asset paths, read through the asset resolver (``Ar``).

USD resolves an asset path to an identifier that is not always a file: a texture inside a
``.usdz`` package resolves to ``/path/x.usdz[maps/alpha.png]``, and a custom resolver may return
URIs. OpenImageIO and Mitsuba open *files*, so every image Pavonine reads from a stage goes through
:func:`local_file`: a plain file path is returned as it is; anything else is read with
``ArGetResolver().OpenAsset`` and its bytes are written once per process to a private temporary
folder, which is removed when the process exits.
"""

from __future__ import annotations

import atexit
import hashlib
import os
import shutil
import tempfile
import threading
from pathlib import Path

_lock = threading.Lock()
_cache: dict[str, str] = {}
_folder: Path | None = None


class AssetReadError(OSError):
    """An asset path that the resolver cannot open; ``filename`` is the asset path."""


def is_plain_file(resolved: str) -> bool:
    """True when ``resolved`` names an ordinary file that OIIO and Mitsuba can open themselves."""
    from pxr import Ar

    return not Ar.IsPackageRelativePath(resolved) and os.path.isfile(resolved)


def read_bytes(resolved: str) -> bytes:
    """The whole content of a resolved asset path (a file, a package member, a resolver URI)."""
    if is_plain_file(resolved):
        return Path(resolved).read_bytes()
    from pxr import Ar

    asset = Ar.GetResolver().OpenAsset(Ar.ResolvedPath(resolved))
    if asset is None:
        raise AssetReadError(0, "cannot open through the USD asset resolver", resolved)
    return bytes(asset.GetBuffer())


def local_file(resolved: str) -> str:
    """A local file path with the content of ``resolved``, for readers that need a file.

    Plain files are returned unchanged. Package members (``x.usdz[tex.png]``) and other resolver
    identifiers are copied out once per process, keeping their file name (OIIO picks the format
    by its extension).
    """
    if is_plain_file(resolved):
        return resolved
    with _lock:
        cached = _cache.get(resolved)
        if cached is not None and os.path.isfile(cached):
            return cached
        data = read_bytes(resolved)
        from pxr import Ar

        inner = (
            Ar.SplitPackageRelativePathInner(resolved)[1]
            if Ar.IsPackageRelativePath(resolved)
            else resolved
        )
        name = Path(inner.rstrip("]")).name or "asset"
        digest = hashlib.sha1(resolved.encode("utf-8")).hexdigest()[:16]
        target = _private_folder() / digest / name
        target.parent.mkdir(parents=True, exist_ok=True)
        tmp = target.with_name(f".{name}.part")
        tmp.write_bytes(data)
        os.replace(tmp, target)
        _cache[resolved] = str(target)
        return str(target)


def _private_folder() -> Path:
    """This process's temporary folder for extracted assets, removed at exit."""
    global _folder
    if _folder is None:
        _folder = Path(tempfile.mkdtemp(prefix="pavonine-assets-"))
        atexit.register(shutil.rmtree, _folder, ignore_errors=True)
    return _folder
