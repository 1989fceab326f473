"""Scene-linear Rec.709 → display-referred pixels through OpenColorIO: one :class:`DisplayTransform`.

A display transform is an OCIO config, a display, a view and an exposure (stops, applied in
scene-linear before the view). Every PNG Pavonine writes from scene-linear pixels (renders,
swatches, figures, report images) goes through one, and PNG readers invert the one recorded in
the file.

The config is ``$OCIO`` when set (as every OCIO application does), else :data:`PINNED_CONFIG`: a
*versioned* built-in config. OpenColorIO ships its built-in configs inside the library and never
edits one once released (a new version gets a new name; ``cg-config-latest`` is an alias that
moves), so the pinned name means the same transforms in every OpenColorIO release that has it.
Measured: the 8-bit and float output of every view of this config is bit-identical from
OpenColorIO 2.5.0 to 2.6.0 (docs/compatibility.md).

Like OCIO's own ``GetCurrentConfig``/``SetCurrentConfig``, there is a *current* display transform
(:func:`current_display`, set for a block with :func:`use_display`; the command line sets it from
``--ocio-config``/``--display``/``--view``/``--exposure``). Comparisons use
:data:`REFERENCE_DISPLAY` instead, so that a user's ``$OCIO`` cannot move a CI verdict.

Without OpenColorIO installed (``pip install pavonine`` without the ``[render]`` extra) the
reference transform alone is still available: its ``Un-tone-mapped`` view on ``sRGB - Display``
is the IEC 61966-2-1 sRGB encoding of linear Rec.709, computed in closed form
(:func:`srgb_encode`); ``tests/materials/test_display.py`` checks the two agree.
"""

from __future__ import annotations

import contextlib
import contextvars
import functools
import math
import os
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

#: OpenColorIO's versioned built-in CG config (ACES 2.0); first shipped in OpenColorIO 2.5.0.
PINNED_CONFIG = "ocio://cg-config-v4.0.0_aces-v2.0_ocio-v2.5"
#: The environment variable every OCIO application reads its config from.
OCIO_ENV = "OCIO"
#: Pavonine's scene-linear space: Rec.709 primaries, D65 white (the renderer's ``rgb`` output).
SCENE_LINEAR = "Linear Rec.709 (sRGB)"
#: Names the CG configs give :data:`SCENE_LINEAR` (looked up in other configs too).
_SCENE_LINEAR_ALIASES = (SCENE_LINEAR, "lin_rec709_srgb", "lin_rec709", "lin_srgb")
DISPLAY = "sRGB - Display"
DEFAULT_VIEW = "Un-tone-mapped"

# PNG header attributes recording the transform (read back by :meth:`DisplayTransform.from_attributes`).
ATTRIBUTES = {
    "config": "pavonine:ocio_config",
    "display": "pavonine:display",
    "view": "pavonine:view",
    "exposure": "pavonine:exposure",
}


class DisplayError(ValueError):
    """A display transform that cannot be built: ``field`` names the option (``--view``, …)."""

    def __init__(self, field: str, message: str):
        super().__init__(f"{field}: {message}")
        self.field = field
        self.message = message


@dataclass(frozen=True)
class DisplayTransform:
    """Scene-linear Rec.709 → display: OCIO ``config``, ``display``, ``view``, ``exposure`` (stops)."""

    config: str = PINNED_CONFIG
    display: str = DISPLAY
    view: str = DEFAULT_VIEW
    exposure: float = 0.0

    def encode(self, linear_rgb: np.ndarray) -> np.ndarray:
        """Scene-linear H×W×3 (or N×3) → display-referred values in [0, 1] (float32)."""
        rgb = np.asarray(linear_rgb, dtype=np.float32)
        flat = np.ascontiguousarray(rgb.reshape(-1, 3), dtype=np.float32) * np.float32(
            2.0**self.exposure
        )
        if self._closed_form():
            out = srgb_encode(flat)
        else:
            out = flat.copy()
            for processor in _processors(self.config, self.display, self.view, inverse=False):
                processor.applyRGB(out)
        return np.clip(out, 0.0, 1.0).reshape(rgb.shape)

    def decode(self, display_rgb: np.ndarray) -> np.ndarray:
        """Display-referred values → scene-linear (the inverse of :meth:`encode`, float32)."""
        rgb = np.asarray(display_rgb, dtype=np.float32)
        flat = np.ascontiguousarray(rgb.reshape(-1, 3), dtype=np.float32).copy()
        if self._closed_form():
            flat = srgb_decode(flat)
        else:
            for processor in _processors(self.config, self.display, self.view, inverse=True):
                processor.applyRGB(flat)
        return (flat / np.float32(2.0**self.exposure)).reshape(rgb.shape)

    def check(self) -> DisplayTransform:
        """``self`` if the config loads and has the display and view, else :class:`DisplayError`."""
        if not math.isfinite(self.exposure):
            raise DisplayError(
                "--exposure", f"must be a finite number of stops, got {self.exposure}"
            )
        if self._closed_form():
            return self
        config = load_config(self.config)
        displays = list(config.getDisplays())
        if self.display not in displays:
            known = ", ".join(repr(d) for d in displays)
            raise DisplayError(
                "--display",
                f"unknown display {self.display!r} in {self.config} (displays: {known})",
            )
        views = list(config.getViews(self.display))
        if self.view not in views:
            known = ", ".join(repr(v) for v in views)
            raise DisplayError(
                "--view", f"unknown OCIO view {self.view!r} for {self.display!r} (views: {known})"
            )
        _processors(self.config, self.display, self.view, inverse=False)
        return self

    def views(self) -> list[str]:
        """The views of this transform's display in its config."""
        if self._closed_form():
            return [DEFAULT_VIEW]
        return list(load_config(self.config).getViews(self.display))

    def attributes(self) -> dict[str, str]:
        """Header attributes recording this transform in a PNG (see :data:`ATTRIBUTES`)."""
        return {
            ATTRIBUTES["config"]: self.config,
            ATTRIBUTES["display"]: self.display,
            ATTRIBUTES["view"]: self.view,
            ATTRIBUTES["exposure"]: f"{self.exposure:g}",
        }

    @classmethod
    def from_attributes(cls, attributes: Mapping[str, Any]) -> DisplayTransform | None:
        """The transform recorded in a PNG's header, or ``None`` when it records none.

        PNGs written before the config and display were recorded name only the view; they were
        encoded with ``sRGB - Display`` of a CG config, whose views match :data:`PINNED_CONFIG`'s.
        """
        view = attributes.get(ATTRIBUTES["view"])
        if not isinstance(view, str) or not view:
            return None
        try:
            exposure = float(attributes.get(ATTRIBUTES["exposure"], 0.0))
        except (TypeError, ValueError):
            exposure = 0.0
        return cls(
            config=str(attributes.get(ATTRIBUTES["config"]) or PINNED_CONFIG),
            display=str(attributes.get(ATTRIBUTES["display"]) or DISPLAY),
            view=view,
            exposure=exposure,
        )

    def _closed_form(self) -> bool:
        """The reference sRGB view, and OpenColorIO is not installed."""
        return (self.config, self.display, self.view) == (
            PINNED_CONFIG,
            DISPLAY,
            DEFAULT_VIEW,
        ) and not _have_ocio()


#: What comparisons and baselines encode with, whatever ``$OCIO`` says.
REFERENCE_DISPLAY = DisplayTransform()

_current: contextvars.ContextVar[DisplayTransform | None] = contextvars.ContextVar(
    "pavonine_display", default=None
)


def default_config() -> str:
    """``$OCIO`` if set, else :data:`PINNED_CONFIG`."""
    return os.environ.get(OCIO_ENV) or PINNED_CONFIG


def resolve(
    config: str | None = None,
    display: str | None = None,
    view: str | None = None,
    exposure: float = 0.0,
) -> DisplayTransform:
    """A checked transform; what is not given comes from the config.

    The pinned config defaults to ``sRGB - Display`` / ``Un-tone-mapped`` (Pavonine's look); any
    other config (``$OCIO``, ``--ocio-config``) to its own default display and view.
    """
    config = config or default_config()
    if config == PINNED_CONFIG:
        display = display or DISPLAY
        view = view or (DEFAULT_VIEW if display == DISPLAY else None)
    if display is None or view is None:
        loaded = load_config(config)
        display = display or loaded.getDefaultDisplay()
        view = view or loaded.getDefaultView(display)
    return DisplayTransform(config, display, view, float(exposure)).check()


def current_display() -> DisplayTransform:
    """The display transform in effect: the innermost :func:`use_display`, else the default."""
    chosen = _current.get()
    if chosen is not None:
        return chosen
    config = default_config()
    return REFERENCE_DISPLAY if config == PINNED_CONFIG else resolve(config)


@contextlib.contextmanager
def use_display(transform: DisplayTransform) -> Iterator[DisplayTransform]:
    """Make ``transform`` the current display transform inside the block."""
    token = _current.set(transform)
    try:
        yield transform
    finally:
        _current.reset(token)


def with_overrides(transform: DisplayTransform, **fields: Any) -> DisplayTransform:
    """``transform`` with the given fields replaced (``None`` values are ignored), checked."""
    given = {k: v for k, v in fields.items() if v is not None}
    return replace(transform, **given).check() if given else transform


# ------------------------------------------------------------------------- sRGB closed form
def srgb_encode(linear: np.ndarray) -> np.ndarray:
    """IEC 61966-2-1:1999 sRGB encoding (inverse EOTF) of linear values, clipped to [0, 1]."""
    x = np.clip(np.asarray(linear, dtype=np.float32), 0.0, 1.0)
    return np.where(
        x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1.0 / 2.4, dtype=np.float32) - 0.055
    ).astype(np.float32)


def srgb_decode(encoded: np.ndarray) -> np.ndarray:
    """IEC 61966-2-1:1999 sRGB EOTF: encoded values in [0, 1] → linear (inverse of the above)."""
    v = np.asarray(encoded, dtype=np.float32)
    return np.where(
        v <= 0.04045, v / 12.92, np.power((v + 0.055) / 1.055, 2.4, dtype=np.float32)
    ).astype(np.float32)


# ------------------------------------------------------------------------------- OpenColorIO
@functools.cache
def _have_ocio() -> bool:
    try:
        import PyOpenColorIO  # noqa: F401
    except ImportError:
        return False
    return True


@functools.cache
def load_config(config: str):
    """The OCIO config at ``config`` (a file or an ``ocio://`` built-in name), or :class:`DisplayError`."""
    import PyOpenColorIO as ocio

    try:
        return ocio.Config.CreateFromFile(config)
    except Exception as exc:  # ocio.Exception, ocio.ExceptionMissingFile (not a subclass)
        message = " ".join(str(exc).split())
        raise DisplayError(
            "--ocio-config", f"cannot load OCIO config {config!r}: {message}"
        ) from None


@functools.cache
def _processors(config: str, display: str, view: str, *, inverse: bool) -> tuple:
    """CPU processors taking :data:`SCENE_LINEAR` to ``display``/``view`` of ``config`` (or back).

    In a config that names linear Rec.709 (the CG configs do) the display/view transform starts
    there; in any other config, OCIO's interchange roles carry the pixels from the pinned
    config's linear Rec.709 into the config's ``scene_linear`` space first.
    """
    import PyOpenColorIO as ocio

    loaded = load_config(config)
    direction = ocio.TRANSFORM_DIR_INVERSE if inverse else ocio.TRANSFORM_DIR_FORWARD
    source = next(
        (cs.getName() for n in _SCENE_LINEAR_ALIASES if (cs := loaded.getColorSpace(n))), None
    )

    def view_processor(space: str):
        try:
            transform = ocio.DisplayViewTransform(
                src=space, display=display, view=view, direction=direction
            )
            return loaded.getProcessor(transform).getDefaultCPUProcessor()
        except ocio.Exception as exc:
            raise DisplayError(
                "--view", f"OCIO cannot build {display!r}/{view!r}: {' '.join(str(exc).split())}"
            ) from None

    if source is not None:
        return (view_processor(source),)
    scene_linear = loaded.getColorSpace(ocio.ROLE_SCENE_LINEAR)
    if scene_linear is None:
        raise DisplayError(
            "--ocio-config",
            f"{config} has neither a linear Rec.709 colour space ({SCENE_LINEAR!r}) nor a "
            "scene_linear role",
        )
    pinned, space = load_config(PINNED_CONFIG), scene_linear.getName()
    try:
        into = ocio.Config.GetProcessorFromConfigs(pinned, SCENE_LINEAR, loaded, space)
        back = ocio.Config.GetProcessorFromConfigs(loaded, space, pinned, SCENE_LINEAR)
    except ocio.Exception as exc:
        raise DisplayError(
            "--ocio-config",
            f"{config} has no {SCENE_LINEAR!r} colour space and no interchange roles to reach "
            f"it ({' '.join(str(exc).split())})",
        ) from None
    if inverse:
        return (view_processor(space), back.getDefaultCPUProcessor())
    return (into.getDefaultCPUProcessor(), view_processor(space))
