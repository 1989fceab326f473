"""Pavonine: asset pipeline and spectral reference renderer for peacock-feather structural colour."""

__version__ = "0.1.0"

# Register the USD schema plugin (PavonineFeatherAPI) before any stage or schema registry exists:
# USD ignores schemas registered afterwards. Imports only pxr.Plug.
from pavonine.schemas.plugin import register as _register_usd_plugin

_register_usd_plugin()
