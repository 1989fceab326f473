"""Pavonine's Python plugins (the feather BSDF, the front-only wrapper, the path integrator, the
IES-shaped emitters) registered with Mitsuba once per variant."""

from __future__ import annotations

from collections.abc import Callable

_registered: set[tuple[str, str]] = set()


def register_once(name: str, kind: str, make_class: Callable[[], type]) -> None:
    """Register the Python plugin ``name`` of ``kind`` (``"bsdf"``, ``"emitter"`` or ``"integrator"``) with
    Mitsuba for the active variant, the class made by ``make_class``, unless it already is.

    Once per variant: registering again replaces the plugin's class object in Mitsuba while
    objects made from the old registration are still alive (a crash at render time)."""
    import mitsuba as mi

    key = (name, mi.variant())
    if key in _registered:
        return
    cls = make_class()
    register = {
        "bsdf": mi.register_bsdf,
        "emitter": mi.register_emitter,
        "integrator": mi.register_integrator,
    }[kind]
    register(name, lambda props: cls(props))
    _registered.add(key)
