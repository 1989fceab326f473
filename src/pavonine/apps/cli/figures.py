"""``pavonine figures``: the paper's figures regenerated from the model."""

from __future__ import annotations

from pathlib import Path

import click

from pavonine.apps.cli.options import (
    display_options,
    emit_json,
    json_option,
    log,
    output_option,
    progress_bar,
    say,
)
from pavonine.base.commit import atomic_path
from pavonine.base.errors import one_line_errors

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
@click.option(
    "--interference",
    type=click.Choice(["paper", "intensity", "physical"]),
    default="paper",
    show_default=True,
    help="Mode of the Figure 5 spectra and the class swatches (physical: the freyer2020 classes, "
    "Table 1's class 4 short axis does not fit a real rod lattice).",
)
@json_option(JSON_SCHEMA)
@display_options
@one_line_errors
def figures(output: Path, interference: str, json_target: str | None, display) -> None:
    """Write analogues of Figures 5 (yellow, blue), 7, 10, a class swatch chart and the
    physical-mode check (paper mode, physical mode and RCWA of the rod lattice).

    The RCWA figure marks a few wavelengths solved by the independent grcwa package too; without
    it (``pip install 'pavonine[dev]'``) the figure is drawn without them and a warning says so.
    Colours are display-referred through the display transform (--ocio-config, --view, …).
    """
    from pavonine.materials import plots
    from pavonine.materials.parameters import preset

    def material(name: str):
        return preset(name).with_(interference=interference)

    swatches = material("freyer2020" if interference == "physical" else "paper-table1")
    label = f" ({interference} mode)"
    jobs = [
        (
            "fig5_yellow.png",
            lambda p: plots.figure5(p, material("yellow"), "Figure 5A analogue: yellow" + label),
        ),
        (
            "fig5_blue.png",
            lambda p: plots.figure5(p, material("blue"), "Figure 5B analogue: blue" + label),
        ),
        ("fig7_rod_rows.png", plots.figure7),
        ("fig10_crescent.png", plots.figure10),
        ("table1_swatches.png", lambda p: plots.table1_swatches(p, swatches)),
        ("physical_vs_rcwa.png", plots.physical_comparison),
    ]
    written = []
    with progress_bar() as progress:
        task = progress.add_task("figures", total=len(jobs))
        for name, make in jobs:
            with atomic_path(output / name) as tmp:
                note = make(tmp)
            progress.advance(task)
            written.append(str(output / name))
            say(f"wrote {output / name}")
            if isinstance(note, str):
                log.warning("%s: %s (pip install 'pavonine[dev]')", name, note)
    emit_json(json_target, {"files": written})
