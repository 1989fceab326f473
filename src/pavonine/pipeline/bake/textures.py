"""The baked textures: what each file holds, baking them from a mesh and its maps, writing them
beside the asset and reading them back.

| file (``textures/``) | content | encoding |
|---|---|---|
| ``basecolor.png`` | base colour (RGB) and opacity (A) | 8-bit RGBA; RGB sRGB-encoded, A linear |
| ``roughness.png`` | GGX (perceptual) roughness | 16-bit grey, raw |
| ``film_thickness.png`` | thin-film thickness | 16-bit grey, raw: µm (0–1 µm) |
| ``film_ior.png`` | thin-film index | 16-bit grey, raw: ``(n − 1) / 2`` (n in 1–3) |
| ``film_weight.png`` | thin-film weight (structural share) | 16-bit grey, raw |

Every file appears atomically (written beside, then renamed).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, fields
from pathlib import Path

import numpy as np

from pavonine.base.image_files import write_image_file
from pavonine.base.map_files import write_map
from pavonine.materials import colour
from pavonine.materials.parameters import FeatherParameters
from pavonine.pipeline.bake.appearance import texel_appearance
from pavonine.pipeline.bake.texels import dilate, nearest_covered, scatter, surface_texels
from pavonine.pipeline.convert.mesh import MeshData

TEXTURE_FOLDER = "textures"
#: Texture key → file name inside ``textures/``.
FILES = {
    "base_color": "basecolor.png",
    "roughness": "roughness.png",
    "film_thickness": "film_thickness.png",
    "film_ior": "film_ior.png",
    "film_weight": "film_weight.png",
}
#: ``film_ior.png`` holds ``(n − IOR_RANGE[0]) / (IOR_RANGE[1] − IOR_RANGE[0])``.
IOR_RANGE = (1.0, 3.0)
#: ``film_thickness.png`` holds the thickness in µm, i.e. ``t / THICKNESS_MAX_NM``.
THICKNESS_MAX_NM = 1000.0
DEFAULT_RESOLUTION = 1024


@dataclass
class BakedTextures:
    """Baked images ``[row, column]`` (row 0 = the atlas' top, ``st`` v = 1), values as the
    files hold them: ``base_color`` ``(R, R, 4)`` linear RGB + alpha; the rest ``(R, R)``:
    ``roughness``, ``film_thickness`` (µm), ``film_ior`` (encoded), ``film_weight``."""

    base_color: np.ndarray
    roughness: np.ndarray
    film_thickness: np.ndarray
    film_ior: np.ndarray
    film_weight: np.ndarray

    @property
    def resolution(self) -> int:
        return int(self.base_color.shape[0])

    def film_index(self) -> np.ndarray:
        """The thin film's refractive index (decoded ``film_ior``)."""
        low, high = IOR_RANGE
        return low + (high - low) * self.film_ior


def bake_textures(
    vane: MeshData,
    maps: Mapping[str, np.ndarray],
    params: FeatherParameters,
    roughness: float,
    resolution: int = DEFAULT_RESOLUTION,
) -> BakedTextures:
    """Bake the vane (the feather material's mesh) over its atlas: see
    :mod:`pavonine.pipeline.bake.appearance` for what each texel holds."""
    texels = surface_texels(vane, resolution)
    look = texel_appearance(texels, maps, params, roughness)
    nearest = nearest_covered(texels.covered)
    low, high = IOR_RANGE

    def image(values: np.ndarray) -> np.ndarray:
        return dilate(scatter(texels, values), nearest)

    rgba = np.concatenate([look.base_color, look.alpha[:, None]], axis=1)
    return BakedTextures(
        base_color=image(rgba),
        roughness=image(look.roughness),
        film_thickness=image(np.clip(look.thickness_nm / THICKNESS_MAX_NM, 0.0, 1.0)),
        film_ior=image(np.clip((look.film_ior - low) / (high - low), 0.0, 1.0)),
        film_weight=image(look.film_weight),
    )


def asset_paths() -> dict[str, str]:
    """Texture key → ``./textures/<file>`` asset path (relative to the material layer)."""
    return {key: f"./{TEXTURE_FOLDER}/{name}" for key, name in FILES.items()}


def write_base_color(path: Path, rgba: np.ndarray) -> None:
    """8-bit RGBA PNG: colour sRGB-encoded (OpenColorIO, as ``pavonine render --png``), alpha
    linear; written atomically."""
    import OpenImageIO as oiio

    height, width = rgba.shape[:2]
    encoded = np.concatenate([colour.display_encode(rgba[..., :3]), rgba[..., 3:4]], axis=-1)
    pixels = np.round(np.clip(encoded, 0.0, 1.0) * 255.0).astype(np.uint8)
    spec = oiio.ImageSpec(width, height, 4, oiio.UINT8)
    spec.channelnames = ("R", "G", "B", "A")
    spec.alpha_channel = 3
    spec.attribute("oiio:ColorSpace", "sRGB")
    spec.attribute("oiio:UnassociatedAlpha", 1)
    spec.attribute("Software", "pavonine")
    write_image_file(path, np.ascontiguousarray(pixels), spec)


def write_textures(folder: Path, textures: BakedTextures) -> dict[str, str]:
    """Write every texture into ``folder/textures``; returns their ``./textures/…`` asset paths."""
    target = Path(folder) / TEXTURE_FOLDER
    target.mkdir(parents=True, exist_ok=True)
    write_base_color(target / FILES["base_color"], textures.base_color)
    for field in fields(BakedTextures):
        if field.name != "base_color":
            write_map(
                target / FILES[field.name],
                getattr(textures, field.name),
                description=f"pavonine baked {field.name.replace('_', ' ')}",
            )
    return asset_paths()


def read_data_textures(paths: Mapping[str, str]) -> dict[str, np.ndarray]:
    """The grey (data) textures as float images ``[row, column]``, read through USD's asset
    resolver (``.usdz`` members included); keys as in :data:`FILES` but ``base_color``."""
    from pavonine.base.asset_io import local_file
    from pavonine.base.map_files import read_map

    return {key: read_map(local_file(paths[key]), key) for key in FILES if key != "base_color"}
