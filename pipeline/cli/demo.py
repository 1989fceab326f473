"""``pavonine demo``: the whole path on the shipped eye feather — maps → asset → render → PNG."""

from __future__ import annotations

from pathlib import Path

import click

from pavonine.pipeline.errors import InputError, one_line_errors

FEATHER = "eye_feather"


def _shipped(*parts: str) -> Path:
    from pavonine.pipeline.compare.baselines import REPO_ROOT

    path = REPO_ROOT.joinpath("assets", *parts)
    if not path.exists():
        raise InputError(str(path), "shipped example not found (run from a source checkout)")
    return path


def write_scene(shipped_scene: Path, asset_root: Path, target: Path) -> None:
    """Copy the shipped scene to ``target`` with its feather reference pointing at ``asset_root``."""
    from pxr import Sdf

    layer = Sdf.Layer.FindOrOpen(str(shipped_scene))
    copy = Sdf.Layer.CreateAnonymous(".usda")
    copy.TransferContent(layer)
    references = copy.GetPrimAtPath("/World/Feather").referenceList
    references.ClearEdits()
    references.Prepend(Sdf.Reference(f"./{asset_root.relative_to(target.parent).as_posix()}"))
    copy.Export(str(target))


@click.command()
@click.argument(
    "outdir", type=click.Path(file_okay=False, path_type=Path), default=Path("out/demo")
)
@click.option(
    "--size",
    default=1024,
    show_default=True,
    type=click.IntRange(64, 8192),
    help="Map height in pixels.",
)
@click.option(
    "--spp",
    default=128,
    show_default=True,
    type=click.IntRange(1, 65536),
    help="Samples per pixel.",
)
@click.option("--resolution", default="512x768", show_default=True, help="Render size WxH.")
@click.option(
    "--seed", default=1, show_default=True, type=int, help="Seed for the maps and the render."
)
@one_line_errors
def demo(outdir: Path, size: int, spp: int, resolution: str, seed: int) -> None:
    """Paint the eye feather's maps, convert them to a USD asset and render it lit by the sun.

    Writes OUTDIR/maps/eye/ (six maps and a contact sheet), OUTDIR/assets/eye_feather/ (the USD
    component asset), OUTDIR/eye_feather_sun.usda (the scene) and OUTDIR/eye_feather_sun.{exr,png}.
    """
    from rich.console import Console

    from pavonine.pipeline.convert.batch import convert_recipe
    from pavonine.pipeline.maps.paint import generate_maps, write_contact_sheet, write_maps
    from pavonine.render.api import render_stage
    from pavonine.render.imageio import write_render
    from pavonine.render.settings import parse_resolution

    width, height = parse_resolution(resolution)
    recipe_text = _shipped("recipes", f"{FEATHER}.toml").read_text()
    shipped_scene = _shipped("scenes", "eye_feather_sun.usda")
    console = Console(stderr=True)

    console.print(f"[1/4] painting the eye feather's maps ({size} px)")
    maps_dir = outdir / "maps" / "eye"
    images = generate_maps("eye", size, seed)
    write_maps(images, maps_dir)
    write_contact_sheet(images, maps_dir / "contact_sheet.png", "eye feather maps")

    console.print("[2/4] converting to a USD component asset (mesh, atlas, displacement, LODs)")
    recipe = outdir / f"{FEATHER}.toml"
    recipe.write_text(recipe_text)
    result = convert_recipe(
        recipe, outdir / "assets", force=True, report=lambda stage: console.print(f"      {stage}")
    )
    triangles = ", ".join(f"{lod} {n:,}" for lod, n in result.triangles.items())
    console.print(f"      {result.root} ({triangles} triangles)")

    console.print("[3/4] writing the scene: sun from the right, as in the paper's Figure 13")
    scene = outdir / "eye_feather_sun.usda"
    write_scene(shipped_scene, result.root, scene)

    console.print(f"[4/4] rendering {width}×{height} at {spp} spp")
    rendered = render_stage(scene, spp=spp, resolution=(width, height), seed=seed)
    exr, png = outdir / "eye_feather_sun.exr", outdir / "eye_feather_sun.png"
    write_render(exr, rendered.rgb, rendered.metadata, png_path=png)
    click.echo(f"wrote {png}")
