"""``pavonine assemble train RECIPE -o OUTDIR``: feather components → a whole peacock train."""

from __future__ import annotations

import json
from pathlib import Path

import click

from pavonine.pipeline.errors import atomic_path, one_line_errors


@click.group("assemble")
def assemble() -> None:
    """Assemblies of feather components (USD, kind = assembly)."""


@assemble.command("train")
@click.argument("recipe", type=click.Path(dir_okay=False, path_type=Path))
@click.option(
    "-o",
    "--output",
    "outdir",
    required=True,
    type=click.Path(file_okay=False, path_type=Path),
    help="The assembly is written to OUTDIR/<name>/<name>.usda (with <name>_layout.png).",
)
@click.option("--force", is_flag=True, help="Replace an assembly that already exists.")
@click.option(
    "--json",
    "json_path",
    default=None,
    metavar="FILE|-",
    help="Write a report (root, layout, instances per prototype, extent) as JSON; '-' = stdout.",
)
@one_line_errors
def train(recipe: Path, outdir: Path, force: bool, json_path: str | None) -> None:
    """Lay out a displaying peacock train from RECIPE (TOML) as one PointInstancer.

    Prototypes are the recipe's feather components (each with its lod variant); rows, lengths,
    curvature and rotation jitter come from the recipe's seed; every instance gets
    primvars:pavonine:gradationOffset and primvars:pavonine:structuralScale. Recipe
    reference: docs/pipeline.md ("Train recipe").
    """
    from pavonine.pipeline.assemble.train import assemble_train

    result = assemble_train(recipe, outdir, force=force)
    report = {
        "root": str(result.root),
        "layout": str(result.layout_png),
        "instances": result.instances,
        "prototypes": result.counts,
        "extent_cm": result.extent.round(3).tolist(),
    }
    if json_path == "-":
        click.echo(json.dumps(report, indent=2))
        return
    if json_path is not None:
        with atomic_path(json_path) as tmp:
            tmp.write_text(json.dumps(report, indent=2) + "\n", encoding="utf-8")
    counts = ", ".join(f"{name} {n}" for name, n in result.counts.items())
    size = result.extent[1] - result.extent[0]
    click.echo(
        f"{result.root}: {result.instances} feathers ({counts}), "
        f"{size[0]:.0f} × {size[1]:.0f} × {size[2]:.0f} cm"
    )
    click.echo(f"layout: {result.layout_png}")
