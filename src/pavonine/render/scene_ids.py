"""Unique Mitsuba scene-dictionary ids for the shapes and emitters translated from a stage."""

from __future__ import annotations

import re
from typing import Any


def scene_objects(shapes: dict[str, Any], emitters: dict[str, Any]) -> dict[str, Any]:
    """Shapes and emitters keyed by unique Mitsuba scene-dict ids (:func:`scene_keys`)."""
    shape_keys, emitter_keys = scene_keys(shapes, emitters)
    objects = {shape_keys[name]: entry for name, entry in shapes.items()}
    objects.update({emitter_keys[name]: entry for name, entry in emitters.items()})
    return objects


def scene_keys(
    shapes: dict[str, Any], emitters: dict[str, Any]
) -> tuple[dict[str, str], dict[str, str]]:
    """The unique Mitsuba scene-dict id of each shape name and of each emitter name.

    Prim-derived names (``/a/b#0``, ``/Sun``) become ``mesh_a__b_0`` / ``light_Sun`` (Mitsuba
    ids may not contain ``.`` or ``/``); a name that maps onto an id already taken gets a ``_N``
    suffix, so ``/a/b`` and ``/a__b`` stay two objects. Internal ids (``shapegroup_N``,
    ``instance_N``, ``default_sun``) are kept verbatim, since instances refer to them.
    """
    items = [("mesh", name) for name in shapes]
    items += [("light", name) for name in emitters]
    taken = {name for _, name in items if not name.startswith("/")}
    keys: dict[str, dict[str, str]] = {"mesh": {}, "light": {}}
    for prefix, name in items:
        key = name
        if name.startswith("/"):
            base = f"{prefix}_" + re.sub(r"[^A-Za-z0-9_]", "_", name[1:].replace("/", "__"))
            key, n = base, 1
            while key in taken:
                key, n = f"{base}_{n}", n + 1
            taken.add(key)
        keys[prefix][name] = key
    return keys["mesh"], keys["light"]
