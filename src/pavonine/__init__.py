"""Pavonine: asset pipeline and spectral reference renderer for peacock-feather structural colour."""

# In the `pavonine` command, Ctrl-C is one line and exit 130 from here on (pavonine.console);
# any other program importing pavonine keeps its own SIGINT handling (pavonine.base.interrupt).
from pavonine.base.interrupt import arm_if_console as _arm_if_console

_arm_if_console()

__version__ = "0.1.0"

#: The logger every part of Pavonine reports through (the command line prints it on stderr).
LOGGER_NAME = "pavonine"

# Register the USD schema plugin (PavonineFeatherAPI) before any stage or schema registry exists:
# USD ignores schemas registered afterwards. Now if pxr is already imported, else as soon as it is
# (pavonine.base.usd_import), so that `import pavonine` does not load USD itself.
from pavonine.base.usd_import import install as _install_usd_import  # noqa: E402
from pavonine.schemas.plugin import register as _register_usd_plugin  # noqa: E402 (after arming)

_install_usd_import(_register_usd_plugin)
