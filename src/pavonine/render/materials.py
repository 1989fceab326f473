"""USD materials → Mitsuba: the delegate's entry point into :mod:`pavonine.render.shading`.

Kept as a module of its own so that the delegate (and scripts) can keep importing
``pavonine.render.materials``; the translators live in the :mod:`~pavonine.render.shading`
subpackage, one per module, and this module re-exports its public names.
"""

from __future__ import annotations

from pavonine.render.shading import *  # noqa: F403 (re-exported: see shading.__all__)
from pavonine.render.shading import __all__  # noqa: F401
