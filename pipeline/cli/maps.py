"""``pavonine maps KIND OUTDIR``: paint the six scale-C maps (paper §3.3) of a shipped feather kind."""

from __future__ import annotations

from pathlib import Path

import click

from pavonine.pipeline.errors import InputError, one_line_errors

KIND_NAMES = ("eye", "blue", "yellow", "fishtail")


@click.command("maps")
@click.argument("kind", type=click.Choice(KIND_NAMES))
@click.argument("outdir", type=click.Path(file_okay=False, path_type=Path))
@click.option(
    "--size",
    default=1024,
    show_default=True,
    type=click.IntRange(16, 16384),
    help="Pixels along the feather (map height); the width follows the kind's aspect.",
)
@click.option(
    "--seed", default=0, show_default=True, type=click.IntRange(min=0), help="Seed of the noise."
)
@click.option(
    "--format",
    "fmt",
    type=click.Choice(["png", "exr"]),
    default="png",
    show_default=True,
    help="16-bit PNG or half-float EXR (both single-channel, colour space Raw).",
)
@click.option(
    "--contact-sheet/--no-contact-sheet",
    default=True,
    show_default=True,
    help="Also write OUTDIR/contact_sheet.png showing the six maps.",
)
@one_line_errors
def maps(kind: str, outdir: Path, size: int, seed: int, fmt: str, contact_sheet: bool) -> None:
    """Write alpha, ocellar, gradation, angle, displacement and melanin maps of KIND to OUTDIR.

    KIND is eye (a train eye feather with its ocellus in six classes), blue (a blue body
    feather), yellow (a yellow covert) or fishtail (a T-shaped feather from the train's edge).
    Encodings: docs/pipeline.md.
    """
    from rich.progress import Progress

    from pavonine.pipeline.maps.paint import KINDS, generate_maps, write_contact_sheet, write_maps

    if outdir.exists() and not outdir.is_dir():
        raise InputError(str(outdir), "exists and is not a directory")
    with Progress(transient=True) as progress:
        task = progress.add_task(f"painting {kind} maps", total=3 if contact_sheet else 2)
        images = generate_maps(kind, size, seed)
        progress.advance(task)
        paths = write_maps(images, outdir, f".{fmt}")
        progress.advance(task)
        if contact_sheet:
            write_contact_sheet(
                images, outdir / "contact_sheet.png", f"{kind}: {KINDS[kind].description}"
            )
            progress.advance(task)
    height, width = images["alpha"].shape
    for name, path in paths.items():
        click.echo(f"{name:<13} {path}")
    if contact_sheet:
        click.echo(f"{'contact sheet':<13} {outdir / 'contact_sheet.png'}")
    click.echo(f"{len(paths)} maps, {width}x{height}, seed {seed}")
