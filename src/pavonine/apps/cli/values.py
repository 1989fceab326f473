"""Checked values of command-line options: floats that refuse NaN and infinities, seeds within
Mitsuba's ``uint32``, and the ``--max-pixels`` budget of images read (``pavonine.base.limits``).

==========================  ====================================================================
``FiniteFloat(min, max)``   the type of every float option: NaN and ±inf are refused
``SEED``                    the type of every seed option: a whole number in ``SEED_RANGE``
``max_pixels_option``       ``--max-pixels N`` (else ``$PAVONINE_MAX_PIXELS``): pixel budget of
                            images read, checked from their headers (applied, no param)
``apply_pixel_budget``      applies a ``--max-pixels`` value for the running command only (also
                            used by ``limit_options``)
==========================  ====================================================================
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from typing import Any

import click

from pavonine.base.limits import SEED_RANGE

F = Callable[..., Any]


class FiniteFloat(click.ParamType):
    """A float option that refuses NaN and ±inf (and, optionally, values outside ``[min, max]``).

    ``float("nan")`` parses, and every comparison with it is false, so a plain ``type=float``
    lets NaN through checks such as ``value <= 0``; every float option uses this type instead.
    """

    name = "number"

    def __init__(self, min: float | None = None, max: float | None = None):
        self.min, self.max = min, max

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None):
        if isinstance(value, float) and math.isfinite(value):
            number = value
        else:
            try:
                number = float(value)
            except (TypeError, ValueError):
                self.fail(f"{value!r} is not a number", param, ctx)
        if not math.isfinite(number):
            self.fail(f"must be a finite number, got {value!r}", param, ctx)
        if (self.min is not None and number < self.min) or (
            self.max is not None and number > self.max
        ):
            low = "-inf" if self.min is None else f"{self.min:g}"
            high = "inf" if self.max is None else f"{self.max:g}"
            self.fail(f"{number:g} is not in the range [{low}, {high}]", param, ctx)
        return number

    def __repr__(self) -> str:
        return "FINITE_FLOAT"


#: Every seed option: a whole number in :data:`pavonine.base.limits.SEED_RANGE` (Mitsuba's ``uint32``).
SEED = click.IntRange(*SEED_RANGE)


def apply_pixel_budget(count: int | None) -> None:
    """Make ``count`` the pixel budget of images read for the running command only: the one way
    every command applies ``--max-pixels``. ``None`` (not given) leaves ``$PAVONINE_MAX_PIXELS``
    or the default. The budget before is restored when the command's click context closes, also
    when the command fails, so commands run in-process (tests, other tools) never inherit it.

    Call it from the command's body (as :func:`max_pixels_option` and ``limit_options`` do), never
    from a parameter callback: a usage error found after a callback ran leaves its context
    unclosed, so the budget would outlive the command."""
    from pavonine.base.limits import pixel_budget

    click.get_current_context().with_resource(pixel_budget(count))


def max_pixels_option(func: F) -> F:
    """``--max-pixels N`` (default ``$PAVONINE_MAX_PIXELS``): the pixel budget of images read,
    in force while the command's body runs (the function gets no parameter for it)."""
    from pavonine.base.limits import DEFAULT_MAX_PIXELS, MAX_PIXELS_ENV

    @functools.wraps(func)
    def wrapper(*args: Any, max_pixels: int | None, **kwargs: Any) -> Any:
        apply_pixel_budget(max_pixels)
        return func(*args, **kwargs)

    return click.option(
        "--max-pixels",
        type=click.IntRange(min=1),
        metavar="N",
        help=f"Pixel budget of every image read, checked from its header before decoding "
        f"[default: ${MAX_PIXELS_ENV}, else {DEFAULT_MAX_PIXELS:,}].",
    )(wrapper)
