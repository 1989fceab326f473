"""``pavonine maps KIND -o OUTDIR``: paint the six scale-C maps (paper §3.3) of a shipped feather kind."""

from __future__ import annotations

from pathlib import Path

import click

from pavonine.apps.cli.options import (
    emit_json,
    json_option,
    output_option,
    progress_bar,
    say,
)
from pavonine.apps.cli.values import SEED
from pavonine.base.errors import InputError, one_line_errors

KIND_NAMES = ("eye", "blue", "yellow", "fishtail")

JSON_SCHEMA = {
    "type": "object",
    "required": ["kind", "width", "height", "seed", "maps", "contact_sheet"],
    "properties": {
        "kind": {"type": "string", "enum": list(KIND_NAMES)},
        "width": {"type": "integer", "description": "pixels across"},
        "height": {"type": "integer", "description": "pixels along the feather"},
        "seed": {"type": "integer"},
        "maps": {
            "type": "object",
            "description": "map name (alpha, ocellar, gradation, angle, displacement, melanin) "
            "→ file written",
            "additionalProperties": {"type": "string"},
        },
        "contact_sheet": {"type": ["string", "null"], "description": "the contact sheet, if any"},
    },
}


@click.command("maps")
@click.argument("kind", type=click.Choice(KIND_NAMES))
@output_option(folder=True, help="Folder for the maps [default: out/maps/KIND].")
@click.option(
    "--size",
    default=1024,
    show_default=True,
    type=click.IntRange(16, 16384),
    help="Pixels along the feather (map height); the width follows the kind's aspect.",
)
@click.option("--seed", default=0, show_default=True, type=SEED, help="Seed of the noise.")
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
    help="Also write contact_sheet.png showing the six maps.",
)
@json_option(JSON_SCHEMA)
@one_line_errors
def maps(
    kind: str,
    output: Path | None,
    size: int,
    seed: int,
    fmt: str,
    contact_sheet: bool,
    json_target: str | None,
) -> None:
    """Write alpha, ocellar, gradation, angle, displacement and melanin maps of KIND.

    KIND is eye (a train eye feather with its ocellus in six classes), blue (a blue body
    feather), yellow (a yellow covert) or fishtail (a T-shaped feather from the train's edge).
    Encodings: docs/pipeline.md.
    """
    from pavonine.base.commit import staged_files
    from pavonine.pipeline.maps.paint import (
        KINDS,
        MAP_NAMES,
        generate_maps,
        write_contact_sheet,
        write_maps,
    )

    outdir = output or Path("out/maps") / kind
    if outdir.exists() and not outdir.is_dir():
        raise InputError(str(outdir), "exists and is not a directory")
    ext = f".{fmt}"
    with progress_bar() as progress:
        task = progress.add_task(f"painting {kind} maps", total=3 if contact_sheet else 2)
        images = generate_maps(kind, size, seed)
        progress.advance(task)
        # Every file is written into a staging folder inside OUTDIR first, then renamed into
        # place as one group: a full disk leaves no file, a crash no half-replaced map.
        with staged_files(outdir, subject=kind) as staging:
            write_maps(images, staging, ext)
            progress.advance(task)
            if contact_sheet:
                write_contact_sheet(
                    images, staging / "contact_sheet.png", f"{kind}: {KINDS[kind].description}"
                )
                progress.advance(task)
    paths = {name: outdir / f"{name}{ext}" for name in MAP_NAMES}
    sheet = outdir / "contact_sheet.png" if contact_sheet else None
    height, width = images["alpha"].shape
    for name, path in paths.items():
        say(f"{name:<13} {path}")
    if sheet is not None:
        say(f"{'contact sheet':<13} {sheet}")
    say(f"{len(paths)} maps, {width}x{height}, seed {seed}")
    emit_json(
        json_target,
        {
            "kind": kind,
            "width": width,
            "height": height,
            "seed": seed,
            "maps": {name: str(path) for name, path in paths.items()},
            "contact_sheet": None if sheet is None else str(sheet),
        },
    )
