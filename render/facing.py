"""``doubleSided = false``: back faces culled for every ray, as viewers cull them for the camera.

Mitsuba shapes have no culling switch, and its BSDFs are black from behind, so a single-sided
mesh seen from its back renders as an opaque black shape. :func:`cull_back_faces` wraps a BSDF
in Mitsuba's ``mask`` with this module's ``pavonine_front_facing`` texture as opacity: 1 where
the ray arrives on the side the geometric normal points to (the front, by the mesh's winding and
``orientation``), 0 behind, so a ray through a back face continues unchanged. Rays toward
emitters (next-event estimation) still stop at back faces: a single-sided wall keeps casting its
shadow, as it does in production ray tracers.
"""

from __future__ import annotations

PLUGIN_NAME = "pavonine_front_facing"
_registered: set[str] = set()


def register() -> None:
    """Register the texture plugin with Mitsuba (once per variant)."""
    import mitsuba as mi

    variant = mi.variant()
    if variant in _registered:
        return

    class FrontFacing(mi.Texture):
        """1 on the front side of a surface (``dot(n_geometric, wi_world) > 0``), else 0."""

        def __init__(self, props):
            super().__init__(props)

        def eval_1(self, si, active=True):
            import drjit as dr

            facing = dr.dot(si.to_world(si.wi), si.n) > 0
            return dr.select(facing, mi.Float(1.0), mi.Float(0.0))

        def eval(self, si, active=True):
            return mi.UnpolarizedSpectrum(self.eval_1(si, active))

        def mean(self):
            return 0.5

        def is_spatially_varying(self):
            return True

        def traverse(self, callback):
            pass

        def to_string(self):
            return "FrontFacing[]"

    mi.register_texture(PLUGIN_NAME, lambda props: FrontFacing(props))
    _registered.add(variant)


def cull_back_faces(bsdf: dict) -> dict:
    """``bsdf`` (a Mitsuba dict) seen from the front only; rays pass through its back."""
    register()
    return {"type": "mask", "opacity": {"type": PLUGIN_NAME}, "bsdf": bsdf}
