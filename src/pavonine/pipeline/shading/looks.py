"""An asset's portable looks: bake the textures, write the MaterialX document, author the USD
materials. Used by ``pavonine convert`` (into its staging folder) and ``pavonine bake``.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from pavonine.materials.parameters import FeatherParameters
from pavonine.pipeline.bake.textures import DEFAULT_RESOLUTION, bake_textures, write_textures
from pavonine.pipeline.convert.mesh import MeshData
from pavonine.pipeline.shading import mtlx
from pavonine.schemas.authoring import BAKE_KEY, parameters_digest


def _relative(paths: Mapping[str, str | None]) -> dict[str, str | None]:
    """``./maps/x.png`` asset paths → ``maps/x.png`` MaterialX file names (same folder)."""
    return {k: (v[2:] if v and v.startswith("./") else v) for k, v in paths.items()}


@dataclass
class Looks:
    """What :meth:`bake` wrote and :meth:`author` puts into USD."""

    params: FeatherParameters
    textures: dict[str, str]
    document: Any
    resolution: int

    @classmethod
    def bake(
        cls,
        folder: Path,
        name: str,
        vane: MeshData,
        maps: Mapping[str, np.ndarray],
        map_paths: Mapping[str, str | None],
        params: FeatherParameters,
        resolution: int = DEFAULT_RESOLUTION,
    ) -> Looks:
        """Bake ``vane`` (with ``maps``: grey images by key) into ``folder/textures`` and write
        ``folder/<name>.mtlx`` (+ the node definition) referencing ``map_paths``."""
        from pavonine.schemas.authoring import preview_roughness

        textures = bake_textures(vane, maps, params, preview_roughness(params), resolution)
        paths = write_textures(folder, textures)
        document = mtlx.asset_document(params, _relative(map_paths), _relative(paths))
        mtlx.write_document(document, folder, name)
        return cls(params, paths, document, resolution)

    def author(self, stage, feather_path, portable_path) -> tuple[Any, Any]:
        """Author the feather material at ``feather_path`` (MaterialX network + baked preview;
        it must already carry ``PavonineFeatherAPI``) and its portable twin at
        ``portable_path``; returns both ``UsdShade.Material``s."""
        from pavonine.pipeline.shading.usd import author_baked_preview, author_mtlx_network

        authored = []
        for path, material_name in (
            (feather_path, mtlx.FEATHER_MATERIAL),
            (portable_path, mtlx.PORTABLE_MATERIAL),
        ):
            material = author_mtlx_network(stage, path, self.document, material_name)
            author_baked_preview(material, self.textures)
            authored.append(material)
        feather, portable = authored
        feather.GetPrim().SetCustomDataByKey(
            BAKE_KEY,
            {"parameters": parameters_digest(self.params), "resolution": self.resolution},
        )
        portable.GetPrim().SetDocumentation(
            "Standard-node twin of the feather material for hosts without Pavonine's MaterialX "
            "node: OpenPBR with a thin film, from the baked textures (preview-purpose binding)."
        )
        return feather, portable
