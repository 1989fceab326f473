"""Pavonine's Python plugins (the feather BSDF, the front-only wrapper, the path integrator, the
IES-shaped emitters) registered with Mitsuba once per variant.

Mitsuba's Python base classes (``mi.BSDF``, ...) exist once per variant, so a plugin written at
module level as a plain class (Mitsuba's own Python plugins' layout: the class with its
parameter docstring, registration at the bottom) is bound to the active variant's base by
:func:`variant_class` when it is registered.
"""

from __future__ import annotations

from collections.abc import Callable

_registered: set[tuple[str, str]] = set()

#: The Mitsuba base class of each plugin kind.
BASES = {"bsdf": "BSDF", "emitter": "Emitter", "integrator": "SamplingIntegrator"}


def variant_class(plugin: type, kind: str) -> type:
    """``plugin`` (a plain class whose methods are Mitsuba's interface of ``kind``, calling the
    base's ``__init__`` by name) as a subclass of the active variant's Mitsuba base class.

    nanobind classes take one base only, so the plugin's namespace (with its plain bases', its own
    winning) is copied onto a new class of that base rather than mixed in."""
    import mitsuba as mi

    namespace: dict = {}
    for klass in reversed(
        plugin.__mro__[:-1]
    ):  # a plain plugin built on another: both, its own last
        namespace.update(
            {k: v for k, v in vars(klass).items() if k not in ("__dict__", "__weakref__")}
        )
    return type(plugin.__name__, (getattr(mi, BASES[kind]),), namespace)


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
