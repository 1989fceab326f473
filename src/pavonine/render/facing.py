"""``doubleSided = false``: back faces culled for the rays that look, kept for the shadows.

Mitsuba shapes have no culling switch, and its BSDFs are black from behind, so a single-sided
mesh seen from its back renders as an opaque black shape. :func:`cull_back_faces` wraps a BSDF
in this module's ``pavonine_front_only`` BSDF: where a ray arrives on the side the geometric
normal points to (the front, by the mesh's winding and ``orientation``) it is the nested BSDF;
behind, a ray sampled there continues unchanged (a ``Null`` event, as Mitsuba's ``mask`` does
with opacity 0). Shadow rays (next-event estimation) are different: the path integrator
(``pavonine_path``, as Mitsuba's ``volpath``) lets them through a surface by its
:meth:`eval_null_transmission`, which is the nested BSDF's
from either side, so a single-sided wall or card casts its shadow whichever side faces the
light, as in production ray tracers (a ``mask`` with a front-facing opacity would let light
through the back of every single-sided card).
"""

from __future__ import annotations

from pavonine.render.plugins import register_once

PLUGIN_NAME = "pavonine_front_only"


def _plugin_class():
    """The BSDF class for the active variant (Mitsuba classes are per variant)."""
    import drjit as dr
    import mitsuba as mi

    sides = mi.BSDFFlags.FrontSide | mi.BSDFFlags.BackSide

    class FrontOnly(mi.BSDF):
        """The nested ``bsdf`` on the front side; behind it rays pass straight through."""

        def __init__(self, props: mi.Properties):
            mi.BSDF.__init__(self, props)
            self.nested = props["bsdf"]
            count = self.nested.component_count()
            self.null_component = count
            self.m_components = [self.nested.flags(i) for i in range(count)]
            self.m_components.append(mi.BSDFFlags.Null | sides)
            self.m_flags = self.nested.flags() | mi.BSDFFlags.Null | sides

        @staticmethod
        def _front(si):
            return dr.dot(si.to_world(si.wi), si.n) > 0

        def sample(self, ctx, si, sample1, sample2, active=True):
            front = self._front(si)
            bs, weight = self.nested.sample(ctx, si, sample1, sample2, active & front)
            behind = active & (dr.dot(si.to_world(si.wi), si.n) <= 0)  # also in scalar variants
            bs.wo = dr.select(behind, -si.wi, bs.wo)
            bs.pdf = dr.select(behind, 1.0, bs.pdf)
            bs.eta = dr.select(behind, 1.0, bs.eta)
            bs.sampled_type = dr.select(behind, mi.UInt32(+mi.BSDFFlags.Null), bs.sampled_type)
            bs.sampled_component = dr.select(
                behind, mi.UInt32(self.null_component), bs.sampled_component
            )
            return bs, dr.select(behind, 1.0, weight)

        def eval(self, ctx, si, wo, active=True):
            front = self._front(si)
            return dr.select(front, self.nested.eval(ctx, si, wo, active & front), 0.0)

        def pdf(self, ctx, si, wo, active=True):
            front = self._front(si)
            return dr.select(front, self.nested.pdf(ctx, si, wo, active & front), 0.0)

        def eval_pdf(self, ctx, si, wo, active=True):
            front = self._front(si)
            value, pdf = self.nested.eval_pdf(ctx, si, wo, active & front)
            return dr.select(front, value, 0.0), dr.select(front, pdf, 0.0)

        def eval_null_transmission(self, si, active=True):
            return self.nested.eval_null_transmission(si, active)

        def eval_diffuse_reflectance(self, si, active=True):
            return self.nested.eval_diffuse_reflectance(si, active)

        def traverse(self, callback):
            pass

        def to_string(self):
            return f"FrontOnly[{self.nested}]"

    return FrontOnly


def register() -> None:
    """Register the BSDF plugin with Mitsuba (once per variant)."""
    register_once(PLUGIN_NAME, "bsdf", _plugin_class)


def cull_back_faces(bsdf: dict | object) -> dict:
    """``bsdf`` (a Mitsuba dict or a loaded BSDF) seen from the front only (module docstring)."""
    register()
    return {"type": PLUGIN_NAME, "bsdf": bsdf}
