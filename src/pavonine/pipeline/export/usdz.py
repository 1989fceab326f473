"""``pavonine package``: a feather asset as one ``.usdz`` file, with USD's own
``UsdUtils.CreateNewUsdzPackage``.

The package holds every layer and file the asset's composition reaches, over all variants (the
three LOD payloads, the material layer, the maps and the baked textures), by USD's own dependency
analysis. The ``.mtlx`` documents stay out: USD does not reference them (its networks are in the
material layer) and the usdz format allows only USD layers, images and audio. Readers find the
members through USD's asset resolver: ``pavonine validate`` and ``pavonine render`` read maps and
textures with :func:`pavonine.base.asset_io.local_file`.
"""

from __future__ import annotations

import os
from dataclasses import asdict, dataclass
from pathlib import Path

from pavonine.base.commit import atomic_path
from pavonine.base.errors import InputError
from pavonine.pipeline.bake.asset import root_layer_path


@dataclass
class PackageReport:
    """What :func:`package_asset` wrote."""

    asset: str
    output: str
    files: list[str]
    bytes: int

    def as_dict(self) -> dict:
        return asdict(self)


def package_asset(asset: str | os.PathLike, output: str | os.PathLike) -> PackageReport:
    """Pack ``asset`` (root layer or folder) into ``output`` (``.usdz``, written atomically).

    Raises :class:`InputError` when the output is not a ``.usdz`` or a dependency of the asset
    cannot be resolved (naming it), so a package never silently lacks a file.
    """
    from pxr import Sdf, Tf, UsdUtils

    root = root_layer_path(asset)
    output = Path(output)
    if output.suffix.lower() != ".usdz":
        raise InputError(str(output), "the package must be a .usdz file")
    try:
        _layers, _assets, unresolved = UsdUtils.ComputeAllDependencies(Sdf.AssetPath(str(root)))
    except Tf.ErrorException as exc:
        raise InputError(str(root), f"cannot read the asset: {str(exc).strip()}") from None
    if unresolved:
        raise InputError(str(root), f"unresolvable dependencies: {', '.join(unresolved)}")
    with atomic_path(output) as tmp:
        if not UsdUtils.CreateNewUsdzPackage(Sdf.AssetPath(str(root)), str(tmp)):
            raise InputError(str(output), "USD could not write the package")
        files = list(Sdf.ZipFile.Open(str(tmp)).GetFileNames())
    return PackageReport(str(root), str(output), files, output.stat().st_size)
