"""How close one ``KHR_materials_iridescence`` film over a ``KHR_materials_specular`` substrate and
a Lambertian base can come to the model,
per ocellus zone, before any viewer draws it: ΔE2000 of each zone's mean colour, the model's
reflectance factor against the fitted glTF model's (``pipeline/export/iridescence.py`` Eq. 1),
at the face-on and tilted 40° views of the viewer the export fits for (``--eye``, as
``pavonine export --eye``; default where ``pavonine view`` frames the asset), on the texels the
export's film search uses.

Rows, for each film index the export considers: the export's search (six views: face-on and
tilted, ±8° about each, then the search near the local median thickness), then as a bound the
same grid search given only the two views the acceptance checks (no neighbours to hold, a free
search). Yardstick: zones of the export's own fit.

    python benchmarks/gltf_fit_bound.py ASSET.usd [--eye X Y Z]
"""

from __future__ import annotations

import argparse

import numpy as np


def _feather(asset: str):
    """The asset's stage, the first feather material of its default prim, the meshes bound to
    it."""
    from pxr import Usd, UsdShade

    from pavonine.pipeline.bake.asset import bound_meshes

    stage = Usd.Stage.Open(asset)
    default = stage.GetDefaultPrim()
    for prim in Usd.PrimRange(default):
        bound, _ = UsdShade.MaterialBindingAPI(prim).ComputeBoundMaterial()
        if bound and "PavonineFeatherAPI" in bound.GetPrim().GetAppliedSchemas():
            return stage, bound, bound_meshes(stage, default, bound)
    raise SystemExit(f"error: {asset}: no feather material")


def main() -> None:
    from pavonine.materials.colour import delta_e2000, linear_srgb_to_lab
    from pavonine.pipeline.export import iridescence as irid
    from pavonine.pipeline.export import look
    from pavonine.pipeline.export.gltf import fit_viewer

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("asset")
    parser.add_argument("--resolution", type=int, default=256)
    parser.add_argument("--eye", type=float, nargs=3, default=None, metavar=("X", "Y", "Z"))
    args = parser.parse_args()
    stage, material, meshes = _feather(args.asset)  # the stage outlives its prims' use
    eye, pivot = fit_viewer(stage, args.eye)
    found = look.look_targets(material, meshes, args.resolution, eye, pivot)
    step = max(1, args.resolution // look.FIT_RESOLUTION)
    subset, _ = look._searched(found.texels, step)
    target, light, views = found.target[subset], found.light[subset], found.views[subset]
    k, alpha = found.inputs["k"][subset], found.inputs["alpha"][subset]
    face, tilted = 1, 4  # FIT_TILTS_DEG: 0° and TILT_DEG
    zones = [z for z in range(1, 6) if ((k == z) & (alpha > 0.9)).sum() >= 20]

    def row(name: str, ior: float, fit: irid.FilmFit) -> None:
        model = irid.glTF_reflectance(
            fit.base, fit.weight, fit.thickness_nm, light, views, fit.roughness, ior, fit.substrate
        )
        cells = []
        for view in (face, tilted):
            for z in zones:
                m = (k == z) & (alpha > 0.9)
                a, b = (np.clip(x[m, view], 0.0, 1.0).mean(axis=0) for x in (target, model))
                cells.append(float(delta_e2000(linear_srgb_to_lab(a), linear_srgb_to_lab(b))))
        print(f"{name:<28} {ior:4.2f}  " + "  ".join(f"{c:4.1f}" for c in cells))

    print(f"zones {zones}: face-on ΔE2000 per zone, then tilted 40°")
    two = [face, tilted]
    for ior in look.IOR_CANDIDATES:
        first = look.fit_film(target, light, views, ior)
        prior = look._local_median(found.texels, subset, first.thickness_nm, step)
        row("export's search (6 views)", ior, look.fit_film(target, light, views, ior, prior))
        bound = irid.fit_film(target[:, two], light, views[:, two], ior, view_weights=np.ones(2))
        row("bound: 2 views, free", ior, bound)


if __name__ == "__main__":
    main()
