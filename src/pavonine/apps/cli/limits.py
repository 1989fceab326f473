"""``--max-pixels``, ``--max-spp``, ``--max-instances``: the render ceilings on the command line.

One decorator, :func:`limit_options`, for every command that renders (``render``,
``check-renders``, ``baseline update``): the three values become one
:class:`pavonine.render.limits.RenderLimits`, passed as the parameter ``limits``. ``0`` lifts a
ceiling; the defaults are documented in :mod:`pavonine.render.limits` and docs/reliability.md.
On these commands ``--max-pixels`` is also the budget of the images they read (textures,
baselines: :mod:`pavonine.base.limits`), so one flag lifts both.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import Any

import click

from pavonine.apps.cli.values import apply_pixel_budget
from pavonine.base.limits import DEFAULT_MAX_PIXELS, MAX_PIXELS_ENV
from pavonine.render.limits import MAX_INSTANCES, MAX_PIXELS, MAX_SPP, RenderLimits

#: What ``--max-pixels 0`` makes the read budget: no image has this many pixels.
UNLIMITED_PIXELS = 2**62

F = Callable[..., Any]


def limit_options(func: F) -> F:
    """Add the three ceilings; the command receives ``limits`` (a :class:`RenderLimits`)."""

    @functools.wraps(func)
    def wrapper(*args, max_pixels, max_spp, max_instances, **kwargs):
        limits = RenderLimits.from_flags(max_pixels, max_spp, max_instances)
        # The images read, for this command only (0 lifts the budget too).
        apply_pixel_budget(None if max_pixels is None else max_pixels or UNLIMITED_PIXELS)
        return func(*args, limits=limits, **kwargs)

    options = [
        click.option(
            "--max-pixels",
            type=click.IntRange(min=0),
            metavar="N",
            help=f"Ceiling on the pixels of one image rendered (0: none) [default: {MAX_PIXELS:,}]"
            f", and of every image read [default: ${MAX_PIXELS_ENV}, else {DEFAULT_MAX_PIXELS:,}].",
        ),
        click.option(
            "--max-spp",
            type=click.IntRange(min=0),
            metavar="N",
            help=f"Ceiling on samples per pixel (0: none) [default: {MAX_SPP:,}].",
        ),
        click.option(
            "--max-instances",
            type=click.IntRange(min=0),
            metavar="N",
            help=f"Ceiling on instances in one scene (0: none) [default: {MAX_INSTANCES:,}].",
        ),
    ]
    for option in reversed(options):
        wrapper = option(wrapper)
    return wrapper  # type: ignore[return-value]
