"""``pavonine render`` options beyond one image: products, frames, turntables, Dask."""

from __future__ import annotations

import click


def farm_options(command):
    """Add the product, batch and cluster options to a click command (``pavonine render``)."""
    options = [
        click.option(
            "--product",
            "products",
            metavar="PRIM",
            multiple=True,
            help="Render this RenderProduct (its prim path, or its name) [default: every product "
            "of the stage's RenderSettings]; repeatable.",
        ),
        click.option(
            "--frames",
            metavar="A-B[:STEP]",
            help="Render these USD time codes (animated cameras and lights): OUT.####.exr.",
        ),
        click.option(
            "--turntable",
            type=click.IntRange(min=1),
            metavar="N",
            help="Render N frames of the camera orbiting the stage's bounds (OUT.0000.exr …; "
            "the orbit is written to OUT.turntable.usda).",
        ),
        click.option(
            "--variance",
            is_flag=True,
            help="Also write each image's per-pixel variance (OUT.variance.exr), for "
            "'pavonine compare --method stat'.",
        ),
        click.option(
            "--workers",
            type=click.IntRange(min=0),
            default=None,
            help="Local Dask worker processes [default: one per core when there is more than one "
            "image or shard and the [farm] extra is installed]; 0 renders in this process.",
        ),
        click.option(
            "--scheduler",
            metavar="ADDRESS",
            help="Run on an existing Dask cluster (tcp://host:8786; the [farm] extra); inputs "
            "must be on storage every worker sees at the same path.",
        ),
        click.option(
            "--split",
            type=click.IntRange(min=1),
            default=None,
            help="Split each image's samples into this many tasks (independent seeds, merged "
            "exactly) [default: the worker count for a single image, else 1].",
        ),
    ]
    for option in reversed(options):
        command = option(command)
    return command
