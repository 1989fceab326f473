"""Pavonine's reference renderer: a Hydra-style scene delegate from USD stages to Mitsuba 3.

One translator per USD prim kind: geometry (``mesh``, ``shapes`` for implicit prims,
``subdivision``, ``skel``, ``curves``, ``instancing``; ``primvars``, ``attributes`` and ``facing``
serve them), ``camera``, the ``lights`` and ``shading`` subpackages (``materials`` is the
delegate's entry into the latter), and ``settings``/``aovs``/``passes`` for UsdRender products. A
``delegate`` walks the stage and hands each prim to its translator, and ``api.render_stage`` /
``api.render_products`` render the result progressively. Nothing here imports Mitsuba at module
import time except through :func:`pavonine.base.backend.select_variant`.
"""

from __future__ import annotations

__all__ = ["RenderResult", "render_stage", "write_exr", "write_png"]


def __getattr__(name: str):
    if name in ("RenderResult", "render_stage"):
        from pavonine.render import api

        return getattr(api, name)
    if name in ("write_exr", "write_png"):
        from pavonine.render import imageio

        return getattr(imageio, name)
    raise AttributeError(name)
