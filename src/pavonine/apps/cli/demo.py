"""``pavonine demo``: the whole path on the shipped eye feather — maps → asset → render → PNG."""

from __future__ import annotations

from pathlib import Path

import click

from pavonine.apps.cli.options import (
    debian_hint,
    display_options,
    emit_json,
    json_option,
    log,
    output_option,
    requires,
    say,
    show_progress,
    threads_option,
    warnings_to_log,
)
from pavonine.apps.cli.values import SEED
from pavonine.base.commit import atomic_path
from pavonine.base.errors import InputError, one_line_errors
from pavonine.base.shipped import assets_dir

FEATHER = "eye_feather"
SCENE = "eye_feather_sun"

JSON_SCHEMA = {
    "type": "object",
    "required": ["maps", "asset", "scene", "exr", "png", "render_skipped", "triangles", "seconds"],
    "properties": {
        "maps": {"type": "string", "description": "folder of the six maps and the contact sheet"},
        "asset": {"type": "string", "description": "root layer of the USD component asset"},
        "scene": {"type": "string", "description": "the scene referencing the asset"},
        "exr": {"type": ["string", "null"], "description": "scene-linear render (null: skipped)"},
        "png": {"type": ["string", "null"], "description": "display render (null: skipped)"},
        "render_skipped": {
            "type": ["string", "null"],
            "description": "why the render was skipped (the renderer cannot load: a missing "
            "system library, named with its Debian package), or null when it ran",
        },
        "triangles": {
            "type": "object",
            "description": "triangles per LOD",
            "additionalProperties": {"type": "integer"},
        },
        "seconds": {
            "type": "object",
            "description": "wall time per step (maps, convert, render)",
            "additionalProperties": {"type": "number"},
        },
    },
}


def _shipped(*parts: str) -> Path:
    path = assets_dir().joinpath(*parts)
    if not path.exists():
        raise InputError(str(path), "shipped example not found (is pavonine installed completely?)")
    return path


#: What the demo renders when Mitsuba has only its scalar fallback (no libLLVM): about 2 minutes
#: on 2 cores instead of about 14 hours for the default size.
SCALAR_FALLBACK = (8, (96, 144))


def _fallback_size(spp: int, size: tuple[int, int]) -> tuple[int, tuple[int, int]]:
    """``spp`` and ``size``, or :data:`SCALAR_FALLBACK` when Mitsuba runs its scalar fallback and
    the user asked for neither (then says so)."""
    from click.core import ParameterSource

    from pavonine.base.backend import select_variant

    ctx = click.get_current_context()
    defaults = all(
        ctx.get_parameter_source(name) == ParameterSource.DEFAULT for name in ("spp", "resolution")
    )
    if not defaults or not select_variant().variant.startswith("scalar"):
        return spp, size
    fallback_spp, fallback_size = SCALAR_FALLBACK
    log.warning(
        "no libLLVM: Mitsuba's scalar fallback is slow, so the demo renders %dx%d at %d spp "
        "(install Debian's libllvm19 for %dx%d at %d spp)",
        *fallback_size, fallback_spp, *size, spp,
    )  # fmt: skip
    return fallback_spp, fallback_size


def write_scene(shipped_scene: Path, asset_root: Path, target: Path) -> None:
    """Copy the shipped scene to ``target`` with its feather reference pointing at ``asset_root``."""
    from pxr import Sdf

    layer = Sdf.Layer.FindOrOpen(str(shipped_scene))
    copy = Sdf.Layer.CreateAnonymous(".usda")
    copy.TransferContent(layer)
    references = copy.GetPrimAtPath("/World/Feather").referenceList
    references.ClearEdits()
    references.Prepend(Sdf.Reference(f"./{asset_root.relative_to(target.parent).as_posix()}"))
    with atomic_path(target) as tmp:  # beside the target: the relative reference holds
        copy.Export(str(tmp))


def _render(
    scene: Path, exr: Path, png: Path, *, spp: int, size: tuple[int, int], seed: int, display
) -> None:
    """Render ``scene`` to ``exr`` (scene-linear) and ``png`` (display)."""
    from pavonine.render.api import render_stage
    from pavonine.render.diagnostics import StageWarning
    from pavonine.render.imageio import write_render

    with warnings_to_log(StageWarning):
        rendered = render_stage(
            scene, spp=spp, resolution=size, seed=seed, progress=show_progress()
        )
    write_render(exr, rendered.rgb, rendered.metadata, png_path=png, display=display)


@click.command()
@output_option(folder=True, default=Path("out/demo"), help="Folder for everything the demo makes.")
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
    "--seed", default=1, show_default=True, type=SEED, help="Seed for the maps and the render."
)
@display_options
@threads_option
@json_option(JSON_SCHEMA)
@requires("mitsuba", "drjit", "pymeshlab", "xatlas", may_not_load=("mitsuba", "drjit"))
@one_line_errors
def demo(
    output: Path,
    size: int,
    spp: int,
    resolution: str,
    seed: int,
    display,
    json_target: str | None,
) -> None:
    """Paint the eye feather's maps, convert them to a USD asset and render it lit by the sun.

    Writes DIR/maps/eye/ (six maps and a contact sheet), DIR/eye_feather.toml (the recipe),
    DIR/assets/eye_feather/ (the USD component asset), DIR/eye_feather_sun.usda (the scene) and
    DIR/eye_feather_sun.{exr,png}.
    Works from an installed package: the recipe and scene are package data. When Mitsuba cannot
    load (a missing system library: Debian's libatomic1), it makes everything but the render,
    says why in one warning, and exits 0.
    """
    import time

    from pavonine.base.backend import BackendWarning, RendererUnavailable, select_variant
    from pavonine.pipeline.convert.batch import convert_recipe
    from pavonine.pipeline.maps.paint import generate_maps, write_contact_sheet, write_maps
    from pavonine.render.settings import parse_resolution

    width, height = parse_resolution(resolution)
    skipped = None
    with warnings_to_log(BackendWarning):
        try:
            select_variant()
        except RendererUnavailable as exc:
            skipped = f"{exc}{debian_hint(str(exc))}"
        else:
            spp, (width, height) = _fallback_size(spp, (width, height))
    recipe_text = _shipped("recipes", f"{FEATHER}.toml").read_text()
    shipped_scene = _shipped("scenes", f"{SCENE}.usda")
    seconds = {}

    log.info("[1/4] painting the eye feather's maps (%d px)", size)
    start = time.perf_counter()
    maps_dir = output / "maps" / "eye"
    images = generate_maps("eye", size, seed)
    write_maps(images, maps_dir)
    write_contact_sheet(images, maps_dir / "contact_sheet.png", "eye feather maps")
    seconds["maps"] = time.perf_counter() - start

    log.info("[2/4] converting to a USD component asset (mesh, atlas, displacement, LODs)")
    start = time.perf_counter()
    recipe = output / f"{FEATHER}.toml"
    recipe.write_text(recipe_text)
    result = convert_recipe(
        recipe, output / "assets", force=True, report=lambda stage: log.info("      %s", stage)
    )
    triangles = ", ".join(f"{lod} {n:,}" for lod, n in result.triangles.items())
    log.info("      %s (%s triangles)", result.root, triangles)
    seconds["convert"] = time.perf_counter() - start

    log.info("[3/4] writing the scene: sun from the right, as in the paper's Figure 13")
    scene = output / f"{SCENE}.usda"
    write_scene(shipped_scene, result.root, scene)

    exr = png = None
    if skipped is None:
        log.info("[4/4] rendering %d×%d at %d spp", width, height, spp)
        start = time.perf_counter()
        exr, png = output / f"{SCENE}.exr", output / f"{SCENE}.png"
        _render(scene, exr, png, spp=spp, size=(width, height), seed=seed, display=display)
        seconds["render"] = time.perf_counter() - start
        say(f"wrote {png}")
    else:
        log.warning("[4/4] skipped the render: %s", skipped)
        say(f"wrote {scene} (not rendered: the renderer cannot load here)")
    emit_json(
        json_target,
        {
            "maps": str(maps_dir),
            "asset": str(result.root),
            "scene": str(scene),
            "exr": None if exr is None else str(exr),
            "png": None if png is None else str(png),
            "render_skipped": skipped,
            "triangles": dict(result.triangles),
            "seconds": {k: round(v, 3) for k, v in seconds.items()},
        },
    )
