"""``pavonine assemble train RECIPE -o DIR``: feather components → a whole peacock train."""

from __future__ import annotations

from pathlib import Path

import click

from pavonine.apps.cli.options import emit_json, json_option, output_option, say
from pavonine.base.errors import one_line_errors

JSON_SCHEMA = {
    "type": "object",
    "required": ["root", "layout", "instances", "prototypes", "extent_cm"],
    "properties": {
        "root": {"type": "string", "description": "the assembly's root layer written"},
        "layout": {"type": "string", "description": "top view of the fan (PNG)"},
        "instances": {"type": "integer", "description": "feathers in the PointInstancer"},
        "prototypes": {
            "type": "object",
            "description": "instances per prototype (component name → count)",
            "additionalProperties": {"type": "integer"},
        },
        "extent_cm": {
            "type": "array",
            "description": "the instancer's extent [[min x, y, z], [max x, y, z]] in cm",
            "items": {"type": "array", "items": {"type": "number"}, "minItems": 3, "maxItems": 3},
            "minItems": 2,
            "maxItems": 2,
        },
        "rattle": {
            "type": "object",
            "description": "the train animated ([rattle]; absent without one): sidecar layer, "
            "first and last frame, fps, time samples, prototype variants, flexed points",
        },
    },
}


@click.group("assemble")
def assemble() -> None:
    """Assemblies of feather components (USD, kind = assembly)."""


@assemble.command("train")
@click.argument("recipe", type=click.Path(dir_okay=False, path_type=Path))
@output_option(
    folder=True,
    required=True,
    help="The assembly is written to DIR/<name>/<name>.usda (with <name>_layout.png).",
)
@click.option("--force", is_flag=True, help="Replace an assembly that already exists.")
@json_option(JSON_SCHEMA)
@one_line_errors
def train(recipe: Path, output: Path, force: bool, json_target: str | None) -> None:
    """Lay out a displaying peacock train from RECIPE (TOML) as one PointInstancer.

    Prototypes are the recipe's feather components (each with its lod variant); rows, lengths,
    curvature and rotation jitter come from the recipe's seed; every instance gets
    primvars:pavonine:gradationOffset and primvars:pavonine:structuralScale. Recipe
    reference: docs/pipeline.md ("Train recipe").
    """
    from pavonine.pipeline.assemble.train import assemble_train

    result = assemble_train(recipe, output, force=force)
    counts = ", ".join(f"{name} {n}" for name, n in result.counts.items())
    size = result.extent[1] - result.extent[0]
    say(
        f"{result.root}: {result.instances} feathers ({counts}), "
        f"{size[0]:.0f} × {size[1]:.0f} × {size[2]:.0f} cm"
    )
    say(f"layout: {result.layout_png}")
    report = {
        "root": str(result.root),
        "layout": str(result.layout_png),
        "instances": result.instances,
        "prototypes": result.counts,
        "extent_cm": result.extent.round(3).tolist(),
    }
    if result.rattle is not None:
        rattle = result.rattle
        say(
            f"rattle: frames {rattle.frames[0]}-{rattle.frames[1]} at {rattle.fps:g} fps, "
            f"{rattle.time_samples} time samples, {rattle.variants} prototype variants, "
            f"{rattle.flexed_points:,} flexed points ({rattle.sidecar})"
        )
        report["rattle"] = rattle.to_json()
    emit_json(json_target, report)
