"""Acceptance: the converted eye feather rendered with only its UsdPreviewSurface (the baked
textures, as a viewer that knows nothing of Pavonine sees it) matches the spectral render of the
same stage under the same light: per ocellus zone (tests/ocellus_zones.py), mean colours within
CIE ΔE2000 10.

The asset is converted here from the shipped recipe (so the bake follows whatever the optics
model is now) and placed in the shipped scene.

    pytest tests/pipeline/test_bake_preview.py -s   # prints the table, writes the side-by-side image
"""

from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np
import pytest
from ocellus_zones import zone_delta_e, zone_masks

REPO = Path(__file__).resolve().parents[2]
RECIPE = REPO / "assets" / "recipes" / "eye_feather.toml"
SCENE = REPO / "assets" / "scenes" / "eye_feather_sun.usda"
RESOLUTION = (128, 192)
SPP = 32
MAX_DELTA_E = 10.0


def _recipe(folder: Path) -> Path:
    """The shipped eye recipe with absolute map paths, lighter LODs and 512² textures."""
    data = tomllib.loads(RECIPE.read_text())
    lines = [f'name = "{data["name"]}"', "[maps]"]
    lines += [f'{k} = "{(RECIPE.parent / v).as_posix()}"' for k, v in data["maps"].items()]
    lines += ["[material]", f'preset = "{data["material"]["preset"]}"', "[geometry]"]
    geometry = data["geometry"]
    lines += [f"{k} = {v}" for k, v in geometry.items() if not isinstance(v, dict)]
    for table, values in geometry.items():
        if isinstance(values, dict) and table != "lod":
            lines += [f"[geometry.{table}]"] + [f"{k} = {v}" for k, v in values.items()]
    lines += ["[geometry.lod]", "high = 30000", "medium = 8000", "low = 2000"]
    lines += ["[bake]", "resolution = 512"]
    path = folder / "eye.toml"
    path.write_text("\n".join(lines) + "\n")
    return path


@pytest.mark.render
def test_preview_surface_matches_the_spectral_render_per_ocellus_zone(tmp_path, monkeypatch):
    from pavonine.pipeline.convert.batch import convert_recipe
    from pavonine.render import materials
    from pavonine.render.api import render_stage
    from pavonine.render.imageio import write_png

    root = convert_recipe(_recipe(tmp_path), tmp_path / "assets").root
    scene = tmp_path / "scene.usda"
    scene.write_text(
        SCENE.read_text().replace("@../feathers/eye_feather/eye_feather.usd@", f"@{root}@")
    )
    width, height = RESOLUTION
    spectral = render_stage(scene, spp=SPP, resolution=RESOLUTION, seed=0, progress=False)
    monkeypatch.setenv(materials.IGNORE_FEATHER_SCHEMA, "1")
    preview = render_stage(scene, spp=SPP, resolution=RESOLUTION, seed=0, progress=False)
    assert not [w for w in preview.warnings if "not found" in w or "rejected" in w], (
        preview.warnings
    )
    write_png(tmp_path / "spectral_vs_preview.png", np.concatenate([spectral.rgb, preview.rgb], 1))

    masks = zone_masks(scene, root.parent / "maps", width, height)
    delta_e = zone_delta_e(spectral.rgb, preview.rgb, masks)
    results = {k: (int(masks[k].sum()), delta_e[k]) for k in masks}
    print("\nzone  pixels  ΔE2000 (spectral vs UsdPreviewSurface)")
    for k, (pixels, de) in results.items():
        print(f"{k:>4}  {pixels:>6}  {de:6.2f}")
    assert set(results) >= {1, 2, 3, 4, 5}, results  # the ocellus and the vane around it
    assert all(de < MAX_DELTA_E for _, de in results.values()), results
    # Not a vacuous pass: the spectral render has colour, and the preview is not a grey card.
    assert np.ptp([spectral.rgb[masks[k]].mean(axis=0)[2] for k in results]) > 0.02
