"""USD side of Pavonine: the codeless ``PavonineFeatherAPI`` schema, its authoring API and validators.

``from pavonine.schemas import create_feather_material, read_feather_parameters, resolve_maps``
(the authoring functions import ``pxr.Usd``; they load lazily so ``import pavonine`` stays light).
"""

from __future__ import annotations

from typing import Any

_AUTHORING = ("create_feather_material", "read_feather_parameters", "resolve_maps")


def __getattr__(name: str) -> Any:
    if name in _AUTHORING:
        from pavonine.schemas import authoring

        return getattr(authoring, name)
    raise AttributeError(f"module 'pavonine.schemas' has no attribute {name!r}")


__all__ = list(_AUTHORING)
