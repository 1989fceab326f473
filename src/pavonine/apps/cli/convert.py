"""``pavonine convert RECIPE… -o OUTDIR``: feather recipes → USD component assets."""

from __future__ import annotations

import sys
from pathlib import Path

import click

from pavonine.apps.cli.options import (
    emit_json,
    json_option,
    output_option,
    progress_bar,
    requires,
    say,
)
from pavonine.apps.cli.values import max_pixels_option
from pavonine.base.errors import EXIT_BAD_INPUT, one_line_errors

EXIT_INTERNAL = 1

JSON_SCHEMA = {
    "type": "object",
    "required": ["converted", "failed"],
    "properties": {
        "converted": {
            "type": "array",
            "items": {
                "type": "object",
                "required": ["recipe", "asset", "triangles", "seconds"],
                "properties": {
                    "recipe": {"type": "string"},
                    "asset": {"type": "string", "description": "root layer of the asset written"},
                    "triangles": {
                        "type": "object",
                        "description": "triangles per LOD (high, medium, low)",
                        "additionalProperties": {"type": "integer"},
                    },
                    "seconds": {"type": "number", "description": "wall time of the conversion"},
                    "barbs": {
                        "type": "integer",
                        "description": "barbs in the geometry = barbs variant (0: none)",
                    },
                },
            },
        },
        "failed": {
            "type": "array",
            "items": {
                "type": "object",
                "required": ["recipe", "error", "bad_input"],
                "properties": {
                    "recipe": {"type": "string"},
                    "error": {"type": "string", "description": "one-line error"},
                    "bad_input": {
                        "type": "boolean",
                        "description": "true: the recipe or its maps are wrong (exit 2); "
                        "false: an internal error (exit 1)",
                    },
                },
            },
        },
    },
}


@click.command("convert")
@click.argument("recipes", nargs=-1, required=True, type=click.Path(dir_okay=False))
@output_option(folder=True, required=True, help="Assets are written to DIR/<name>/<name>.usd.")
@click.option(
    "-j",
    "--jobs",
    default=1,
    show_default=True,
    type=click.IntRange(1, 64),
    help="Convert this many recipes at once, in worker processes.",
)
@click.option("--force", is_flag=True, help="Replace assets that already exist.")
@click.option(
    "--scheduler",
    metavar="ADDRESS",
    help="Convert on an existing Dask cluster (tcp://host:8786) instead of local processes; "
    "recipes and maps must be on storage every worker sees at the same path (docs/farm.md).",
)
@json_option(JSON_SCHEMA)
@requires("pymeshlab", "xatlas")
@max_pixels_option
@one_line_errors
def convert(
    recipes: tuple[str, ...],
    output: Path,
    jobs: int,
    force: bool,
    scheduler: str | None,
    json_target: str | None,
) -> None:
    """Convert feather RECIPEs (TOML: maps, material, geometry) into USD assets.

    Each asset is written atomically; a failing recipe does not stop the others, and the
    summary names every failure. Exit status: 0 all converted, 2 bad input, 1 internal error.
    Meshes are cleaned and decimated with pymeshlab, or with NumPy when pymeshlab cannot load
    its system libraries (one warning); $PAVONINE_MESHING (auto, numpy, pymeshlab) chooses.
    Recipe reference: docs/pipeline.md.
    """
    from rich.progress import BarColumn, MofNCompleteColumn, TextColumn, TimeElapsedColumn

    from pavonine.pipeline.convert.batch import convert_many

    columns = (
        TextColumn("[bold]{task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        TimeElapsedColumn(),
    )
    with progress_bar(*columns) as progress:
        task = progress.add_task("converting", total=len(recipes))

        def on_stage(recipe: str, stage: str) -> None:
            progress.update(task, description=f"{Path(recipe).name}: {stage}")

        def on_done(result) -> None:
            progress.advance(task)

        if scheduler is not None:
            from pavonine.apps.farm.cluster import open_cluster
            from pavonine.apps.farm.convert import convert_on_cluster

            with open_cluster(scheduler=scheduler) as cluster:
                results = convert_on_cluster(
                    list(recipes), output, cluster.client, force=force, on_done=on_done
                )
        else:
            results = convert_many(
                list(recipes),
                output,
                jobs=jobs,
                force=force,
                on_done=on_done,
                on_stage=on_stage if jobs == 1 else None,
            )

    failed = [r for r in results if not r.ok]
    emit_json(
        json_target,
        {
            "converted": [
                {
                    "recipe": r.recipe,
                    "asset": str(r.root),
                    "triangles": dict(r.triangles),
                    "seconds": round(sum(r.seconds.values()), 3),
                    "barbs": r.barbs,
                }
                for r in results
                if r.ok
            ],
            "failed": [
                {"recipe": r.recipe, "error": r.error, "bad_input": r.bad_input} for r in failed
            ],
        },
    )
    if len(recipes) == 1 and failed:
        click.echo(f"error: {failed[0].error}", err=True)
        sys.exit(EXIT_BAD_INPUT if failed[0].bad_input else EXIT_INTERNAL)
    for r in results:
        if r.ok:
            tris = "/".join(f"{r.triangles[lod]:,}" for lod in ("high", "medium", "low"))
            total = sum(r.seconds.values())
            barbs = f"; {r.barbs:,} barbs" if r.barbs else ""
            say(f"ok      {r.root}  (triangles high/medium/low {tris}{barbs}; {total:.1f} s)")
    for r in failed:
        click.echo(f"FAILED  {r.recipe}: {r.error}", err=True)
    summary = f"{len(results) - len(failed)} converted, {len(failed)} failed"
    if failed:
        click.echo(summary, err=True)
        sys.exit(EXIT_INTERNAL if any(not r.bad_input for r in failed) else EXIT_BAD_INPUT)
    say(summary)
