"""``pavonine figures``: the paper's figures regenerated from the model."""

from __future__ import annotations

from pathlib import Path

import click

from pavonine.pipeline.errors import atomic_path, one_line_errors


@click.command()
@click.argument("outdir", type=click.Path(file_okay=False, path_type=Path))
@click.option(
    "--interference",
    type=click.Choice(["paper", "intensity", "physical"]),
    default="paper",
    show_default=True,
    help="Mode of the Figure 5 spectra and the class swatches (physical: the freyer2020 classes, "
    "Table 1's class 4 short axis does not fit a real rod lattice).",
)
@one_line_errors
def figures(outdir: Path, interference: str) -> None:
    """Write analogues of Figures 5 (yellow, blue), 7, 10, a class swatch chart and the
    physical-mode check (paper mode, physical mode and RCWA of the rod lattice) to OUTDIR.

    The RCWA figure marks a few wavelengths solved by the independent grcwa package too; without
    it (``pip install 'pavonine[dev]'``) the figure is drawn without them and a warning says so.
    """
    from rich.progress import Progress

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
    with Progress(transient=True) as progress:
        task = progress.add_task("figures", total=len(jobs))
        for name, make in jobs:
            with atomic_path(outdir / name) as tmp:
                note = make(tmp)
            progress.advance(task)
            click.echo(f"wrote {outdir / name}")
            if isinstance(note, str):
                click.echo(f"warning: {name}: {note} (pip install 'pavonine[dev]')", err=True)
