"""Where the shipped assets are: feathers, recipes, scenes and render baselines.

In a source checkout they are the repository's ``assets/`` folder; an installed wheel carries the
ones the command line needs as package data under ``pavonine/assets/`` (``pyproject.toml`` maps
``assets/`` to ``pavonine.assets``). Code asks here instead of guessing from ``__file__``.
"""

from __future__ import annotations

from pathlib import Path

_PACKAGE = Path(__file__).resolve().parents[1]  # the ``pavonine`` package (this is pavonine.base)
#: The repository root when running from a source checkout (``src/pavonine``; ``None`` in an
#: installed wheel).
CHECKOUT = (
    _PACKAGE.parents[1]
    if _PACKAGE.parent.name == "src" and (_PACKAGE.parents[1] / "pyproject.toml").is_file()
    else None
)


def assets_dir() -> Path:
    """The shipped ``assets`` folder: the wheel's package data, else the checkout's."""
    packaged = _PACKAGE / "assets"
    if packaged.is_dir():
        return packaged
    if CHECKOUT is not None and (CHECKOUT / "assets").is_dir():
        return CHECKOUT / "assets"
    return packaged  # missing: callers name it in their error


def scenes_dir() -> Path:
    """Shipped scenes (``*.usda`` naming their render settings)."""
    return assets_dir() / "scenes"


def baselines_dir() -> Path:
    """Approved baseline renders, one folder per scene."""
    return assets_dir() / "baselines"


def recipes_dir() -> Path:
    """Shipped feather recipes (TOML) and the maps they name."""
    return assets_dir() / "recipes"


def is_packaged() -> bool:
    """The assets are an installed package's data (not a checkout's files)."""
    return assets_dir() == _PACKAGE / "assets"


def display_path(path: str | Path) -> str:
    """``path`` relative to the checkout (or the packaged assets' parent) when inside it."""
    root = CHECKOUT if CHECKOUT is not None else _PACKAGE
    try:
        return str(Path(path).resolve().relative_to(root))
    except ValueError:
        return str(path)
