"""``pavonine figures``: the paper's figures regenerated from the model."""

from __future__ import annotations

from pathlib import Path

import click

from pavonine.pipeline.errors import atomic_path, one_line_errors


@click.command()
@click.argument("outdir", type=click.Path(file_okay=False, path_type=Path))
@one_line_errors
def figures(outdir: Path) -> None:
    """Write analogues of Figures 5 (yellow, blue), 7, 10, a Table 1 swatch chart and the
    physical-mode check (paper mode, physical mode and RCWA of the rod lattice) to OUTDIR."""
    from rich.progress import Progress

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
