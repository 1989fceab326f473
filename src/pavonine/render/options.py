"""What a render is asked for: one :class:`RenderOptions` object that the command line, the farm,
the baseline checks and Python callers fill once and :func:`pavonine.render.api.render_products`
reads, instead of a dozen keywords spelled out again by every caller."""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

from pavonine.base.errors import InputError
from pavonine.render.integrator_settings import MAX_DEPTH_LIMIT
from pavonine.render.limits import DEFAULT_LIMITS, RenderLimits

#: the view of a stage without a camera (see :func:`pavonine.render.api.render_products`)
FRAMINGS = ("usd", "portrait")


@dataclass(frozen=True)
class RenderOptions:
    """How to render a stage; every field has a default, and ``None`` means "as the stage says".

    ``spp`` samples per pixel (default: the settings' ``mitsuba:sample_count``, else
    :data:`~pavonine.render.integrator_settings.DEFAULT_SPP`); ``max_depth`` the path length
    (-1: no limit; default the settings' integrator); ``resolution`` and ``camera`` override
    every product's; ``seed`` the sampler's; ``framing`` the view of a stage without a camera
    (``"usd"``: USD's default view, ``"portrait"``: Pavonine's face-on framing of a flat asset);
    ``time`` the time code (default the stage's); ``variant`` Mitsuba's (default
    ``llvm_ad_spectral`` where it loads); ``moments`` per-pixel variance; ``progress`` a
    progress bar; ``products`` the RenderProducts to render (paths or unique names; default all,
    or the first with ``first_only``); ``limits`` the input limits (:mod:`.limits`);
    ``motion_slices`` the time slices of a blurred image (default
    :data:`~pavonine.render.motion.blur.DEFAULT_SLICES`, at most ``spp``).
    """

    spp: int | None = None
    max_depth: int | None = None
    resolution: tuple[int, int] | None = None
    seed: int = 0
    camera: str | None = None
    framing: str = "usd"
    time: float | None = None
    variant: str | None = None
    moments: bool = False
    progress: bool = True
    products: list[str] | None = None
    first_only: bool = False
    limits: RenderLimits = DEFAULT_LIMITS
    motion_slices: int | None = None

    def but(self, **changes: Any) -> RenderOptions:
        """A copy with ``changes`` (field names as keywords; an unknown one is a ``TypeError``)."""
        return replace(self, **changes) if changes else self

    def check(self) -> None:
        """Refuse what no stage can make right (an :class:`InputError` naming the option); the
        stage's own sample count and sizes are checked against ``limits`` once it is read."""
        if self.spp is not None:
            check_spp(self.spp, self.moments, self.limits)
        if self.max_depth is not None and not -1 <= self.max_depth <= MAX_DEPTH_LIMIT:
            raise InputError(
                "max_depth",
                f"must be -1 (no limit) or 0 to {MAX_DEPTH_LIMIT:,}, got {self.max_depth}",
            )
        if self.motion_slices is not None and self.motion_slices < 1:
            raise InputError("motion_slices", f"must be at least 1, got {self.motion_slices}")
        if self.framing not in FRAMINGS:
            raise InputError(
                "framing", f"must be one of {', '.join(FRAMINGS)}, got {self.framing!r}"
            )
        if self.resolution is not None:
            if len(self.resolution) != 2:
                raise InputError(
                    "resolution", f"must be two positive integers, got {self.resolution}"
                )
            self.limits.check_resolution(self.resolution, "resolution")


def check_spp(spp: int, moments: bool, limits: RenderLimits, where: str = "spp") -> None:
    """``spp`` within ``limits``, and at least 2 when per-pixel variance is asked for."""
    limits.check_spp(spp, where)
    if moments and spp < 2:
        raise InputError(where, "moments need at least 2 samples per pixel")
