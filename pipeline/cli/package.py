"""``pavonine package ASSET -o X.usdz``: a feather asset as one ``.usdz`` file."""

from __future__ import annotations

from pathlib import Path

import click

from pavonine.pipeline.cli.jsonout import json_option, say, write_json
from pavonine.pipeline.errors import one_line_errors


@click.command("package")
@click.argument("asset", type=click.Path(path_type=Path))
@click.option(
    "-o",
    "--output",
    required=True,
    type=click.Path(dir_okay=False, path_type=Path),
    help="The .usdz file to write.",
)
@json_option
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
    say(f"wrote   {report.output}: {len(report.files)} files, {report.bytes:,} bytes", json_target)
    write_json(report.as_dict(), json_target)
