"""``pavonine figures``: the paper's figures regenerated from the model."""

from __future__ import annotations

from pathlib import Path

import click

from pavonine.pipeline.cli.options import (
    display_options,
    emit_json,
    json_option,
    output_option,
    progress_bar,
    say,
)
from pavonine.pipeline.errors import atomic_path, one_line_errors

DEFAULT_OUTPUT = Path("out/figures")

JSON_SCHEMA = {
    "type": "object",
    "required": ["files"],
    "properties": {
        "files": {
            "type": "array",
            "items": {"type": "string"},
            "description": "the PNG files written, in order",
        }
    },
}


@click.command()
@output_option(folder=True, default=DEFAULT_OUTPUT, help="Folder for the figures.")
@json_option(JSON_SCHEMA)
@display_options
@one_line_errors
def figures(output: Path, json_target: str | None, display) -> None:
    """Write analogues of Figures 5 (yellow, blue), 7, 10 and a Table 1 swatch chart.

    Colours are display-referred through the display transform (--ocio-config, --view, …).
    """
    from pavonine.materials import plots
    from pavonine.materials.parameters import preset

    jobs = [
        (
            "fig5_yellow.png",
            lambda p: plots.figure5(p, preset("yellow"), "Figure 5A analogue: yellow"),
        ),
        ("fig5_blue.png", lambda p: plots.figure5(p, preset("blue"), "Figure 5B analogue: blue")),
        ("fig7_rod_rows.png", plots.figure7),
        ("fig10_crescent.png", plots.figure10),
        ("table1_swatches.png", lambda p: plots.table1_swatches(p, preset("paper-table1"))),
    ]
    written = []
    with progress_bar() as progress:
        task = progress.add_task("figures", total=len(jobs))
        for name, make in jobs:
            with atomic_path(output / name) as tmp:
                make(tmp)
            progress.advance(task)
            written.append(str(output / name))
            say(f"wrote {output / name}")
    emit_json(json_target, {"files": written})
