"""Pavonine: asset pipeline and spectral reference renderer for peacock-feather structural colour."""

__version__ = "0.1.0"

# Register the USD schema plugin (PavonineFeatherAPI) before any stage or schema registry exists:
# USD ignores schemas registered afterwards. Now if pxr is already imported, else as soon as it is
# (pavonine.usd_import), so that `import pavonine` does not load USD itself.
from pavonine.schemas.plugin import register as _register_usd_plugin
from pavonine.usd_import import install as _install_usd_import

_install_usd_import(_register_usd_plugin)
