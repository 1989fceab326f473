"""``pavonine package ASSET -o X.usdz``: a feather asset as one ``.usdz`` file."""

from __future__ import annotations

from pathlib import Path

import click

from pavonine.apps.cli.options import emit_json, json_option, output_option, say
from pavonine.base.errors import one_line_errors

JSON_SCHEMA = {
    "type": "object",
    "required": ["asset", "output", "files", "bytes"],
    "properties": {
        "asset": {"type": "string", "description": "root layer of the asset packed"},
        "output": {"type": "string", "description": "the .usdz written"},
        "files": {
            "type": "array",
            "items": {"type": "string"},
            "description": "the files inside the package",
        },
        "bytes": {"type": "integer", "description": "size of the .usdz"},
    },
}


@click.command("package")
@click.argument("asset", type=click.Path(path_type=Path))
@output_option(folder=False, required=True, help="The .usdz file to write.")
@json_option(JSON_SCHEMA)
@one_line_errors
def package(asset: Path, output: Path, json_target: str | None) -> None:
    """Pack ASSET (a root layer, or its folder) into one .usdz with USD's own packaging.

    Every layer, map and baked texture the asset reaches, in every variant, goes in (USD's
    dependency analysis; an unresolvable one is an error). Maps and textures inside are read
    through USD's asset resolver, so pavonine validate and render work on the package.
    Reference: docs/pipeline.md, "Packaging".
    """
    from pavonine.pipeline.export.usdz import package_asset

    report = package_asset(asset, output)
    say(f"wrote   {report.output}: {len(report.files)} files, {report.bytes:,} bytes")
    emit_json(json_target, report.as_dict())
