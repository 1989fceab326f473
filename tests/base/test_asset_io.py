"""Assets behind USD asset paths, read through Ar: plain files and members of ``.usdz`` packages."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import OpenImageIO as oiio
import pytest
from pxr import Sdf, Usd, UsdUtils

from pavonine.base.asset_io import AssetReadError, local_file, read_bytes


def _packaged_texture(tmp_path: Path) -> tuple[Path, str]:
    """A .usdz holding one 4×3 texture with a ramp; returns (texture file, resolved member path)."""
    texture = tmp_path / "tex.png"
    pixels = np.arange(12, dtype=np.uint8).reshape(3, 4, 1) * 20
    buf = oiio.ImageBuf(oiio.ImageSpec(4, 3, 1, oiio.UINT8))
    buf.set_pixels(oiio.ROI(0, 4, 0, 3), pixels)
    assert buf.write(str(texture))
    layer = tmp_path / "a.usda"
    stage = Usd.Stage.CreateNew(str(layer))
    prim = stage.DefinePrim("/A")
    prim.CreateAttribute("tex", Sdf.ValueTypeNames.Asset).Set("./tex.png")
    stage.SetDefaultPrim(prim)
    stage.Save()
    package = tmp_path / "a.usdz"
    assert UsdUtils.CreateNewUsdzPackage(str(layer), str(package))
    texture.unlink()  # only the package holds it now
    packaged = Usd.Stage.Open(str(package))
    return texture, packaged.GetPrimAtPath("/A").GetAttribute("tex").Get().resolvedPath


def test_plain_file_is_returned_unchanged(tmp_path):
    path = tmp_path / "x.txt"
    path.write_text("abc")
    assert local_file(str(path)) == str(path)
    assert read_bytes(str(path)) == b"abc"


def test_package_member_is_copied_out_and_readable(tmp_path):
    _, resolved = _packaged_texture(tmp_path)
    assert resolved.endswith("a.usdz[tex.png]")
    local = local_file(resolved)
    assert Path(local).name == "tex.png" and Path(local).is_file()
    assert local_file(resolved) == local  # once per process
    pixels = oiio.ImageBuf(local).get_pixels(oiio.UINT8)
    assert pixels.shape == (3, 4, 1) and int(pixels[2, 3, 0]) == 11 * 20


def test_missing_member_raises_naming_the_path(tmp_path):
    _, resolved = _packaged_texture(tmp_path)
    missing = resolved.replace("tex.png", "nope.png")
    with pytest.raises(AssetReadError) as info:
        local_file(missing)
    assert info.value.filename == missing
