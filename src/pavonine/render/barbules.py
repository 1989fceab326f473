"""``pavonine_barbules``: the feather BSDF on barb ribbons, with the barb's ramus and barbules.

Curves that author ``primvars:pavonine_barbules`` (``pavonine convert``'s barbs: the barbules'
reach past the authored edge) are tessellated with it (:mod:`pavonine.render.curves.ribbons`:
three vertices across, wider than authored, edges drooping) and shaded with it; other ribbons bound to a feather material
keep the plain feather BSDF.

The feather BSDF (:mod:`pavonine.render.feather_bsdf`) shades a ribbon as one smooth strip of
barbules. This plugin is that BSDF (same properties, same per-point material) plus the structure
under the barb (:mod:`pavonine.materials.barbule_pattern`), found at render time from the barb's
own coordinate and the ribbon's half width (the mesh attributes ``vertex_barb_coordinate`` and
``vertex_barb_half_width``, read in the hit instance's space as the feather BSDF reads its own):

* between barbules (a gap) the surface is not there: a ``Null`` event and, for shadow rays,
  :meth:`eval_null_transmission` 1 (as Mitsuba's ``mask`` with opacity 0). Shadow rays also
  pass a barb hit within :data:`~pavonine.materials.barbule_pattern.LAYER_UM` of their origin:
  the barbules of neighbouring barbs overlap in one layer (coplanar ribbons here), and would
  otherwise shadow each other at random;
* on the ramus the structural share is 0 (the feather's melanin pigment, its diffuse brown) and
  the shading normal is tilted across the barb by the ramus' round cross-section;
* on a barbule the feather BSDF, with the shading normal tilted by that barbule's twist about
  its axis. The pattern's barbules are a fishbone (``±φ`` either side of the barb), but the BSDF
  keeps the angle map's one axis on both sides, as the sheet does: mirroring it on one side
  changes the average colour the coarse levels show (the map holds one axis per place). The twist takes its share
  of the crescent's spread across the barbule (paper Eq. 6, θ0): the BSDF within a barbule keeps
  ``√(θ0² − σ_twist²)`` (:func:`~pavonine.materials.barbule_pattern.split_crescent`), so the
  barbules' average is the smooth BSDF's, which the sheet and the plain ribbons show.

The tilts turn the shading frame (as Mitsuba's ``normalmap`` does); directions are carried into
the tilted frame and back. Nothing is stored per barbule: memory is the ribbons'.
"""

from __future__ import annotations

from pavonine.materials import barbule_pattern
from pavonine.render.feather_bsdf import FeatherBSDF
from pavonine.render.feather_encoding import BARB_COORDINATE_ATTRIBUTE
from pavonine.render.plugins import register_once, variant_class
from pavonine.schemas.primvars import BARBULES_PRIMVAR

PLUGIN_NAME = "pavonine_barbules"
#: The mesh attribute of a ribbon's half width at each vertex (scene units, world-scaled).
HALF_WIDTH_ATTRIBUTE = "vertex_barb_half_width"
#: The plugin's pattern properties (floats) and their defaults: :class:`BarbuleLayout`'s fields.
LAYOUT_PROPERTIES = tuple(barbule_pattern.BarbuleLayout._fields)


class Barbules(FeatherBSDF):
    """The ``pavonine_barbules`` BSDF (module docstring); bound with :class:`FeatherBSDF`'s
    methods to the variant's ``mi.BSDF`` when registered."""

    def __init__(self, props):
        import mitsuba as mi

        defaults = barbule_pattern.BarbuleLayout()
        layout = barbule_pattern.BarbuleLayout(
            **{name: float(props.get(name, getattr(defaults, name))) for name in LAYOUT_PROPERTIES}
        ).validate()
        # The crescent's spread of normals across a barbule (paper Eq. 6, θ0) is the whole
        # spread the coarse levels see; here part of it is each barbule's own twist, so the
        # spread within a barbule is what remains: θ0² = θ_within² + σ_twist².
        crescent = float(props["crescent_sigma_deg"])
        twist, within = barbule_pattern.split_crescent(crescent, layout.twist_sigma_deg)
        self.layout = layout._replace(twist_sigma_deg=twist)
        props["crescent_sigma_deg"] = within
        FeatherBSDF.__init__(self, props)
        self._pattern_point = None
        sides = mi.BSDFFlags.FrontSide | mi.BSDFFlags.BackSide
        self.null_component = len(self.m_components)
        self.m_components = [*self.m_components, mi.BSDFFlags.Null | sides]
        self.m_flags = self.m_flags | mi.BSDFFlags.Null

    # -- the pattern at a point ---------------------------------------------------------------
    def _pattern(self, si, active):
        """The barbule pattern at ``si`` (:class:`~pavonine.materials.barbule_pattern.
        BarbulePoint`), read in the hit instance's own space."""
        import drjit as dr
        import mitsuba as mi

        local, linear = self._instance_local(si, active)
        scale = self.world_unit_um
        if linear is not None:
            scale = scale * dr.cbrt(dr.abs(dr.det(mi.Matrix3f(*linear))))
        c = mi.Vector3f(si.shape.eval_attribute_3(BARB_COORDINATE_ATTRIBUTE, local, active))
        half = mi.Float(si.shape.eval_attribute_1(HALF_WIDTH_ATTRIBUTE, local, active))
        angle = FeatherBSDF._map(self, "angle", si, active) * 180.0
        ok = dr.isfinite(c.x) & dr.isfinite(c.y) & dr.isfinite(half)
        s_um = dr.select(ok, c.x * scale, 0.0)
        a_um = dr.select(ok, c.y * scale, 0.0)
        h_um = dr.select(ok, half * scale, 0.0)
        barb = dr.select(dr.isfinite(c.z), dr.round(c.z), 0.0)
        point = barbule_pattern.barbule_pattern(
            s_um, a_um, h_um, barb, angle, self.layout, self.material.ops
        )
        # A failed attribute read (NaN: a needle triangle) shows the barbule, never a hole.
        return point._replace(present=point.present | ~ok)

    def _map(self, name, si, active):
        """The feather BSDF's map value, the pattern applied: the ramus without structural
        colour."""
        import drjit as dr

        value = FeatherBSDF._map(self, name, si, active)
        point = self._pattern_point
        if point is None:
            return value
        if name == "melanin":
            return dr.select(point.ramus, 0.0, value)
        return value

    def _tilted(self, si, point, active):
        """``si`` with its shading frame turned by the pattern's tilt (towards the in-plane
        direction ``tilt_along``·barb + ``tilt_across``·(n × barb), by ``asin |tilt|``)."""
        import drjit as dr
        import mitsuba as mi

        barb = si.sh_frame.to_local(self._barb_tangent(si, active))
        norm = dr.sqrt(dr.square(barb.x) + dr.square(barb.y))
        usable = norm > 1e-6
        bx = dr.select(usable, barb.x / norm, 1.0)
        by = dr.select(usable, barb.y / norm, 0.0)
        tx = point.tilt_along * bx - point.tilt_across * by
        ty = point.tilt_along * by + point.tilt_across * bx
        tz = dr.sqrt(dr.maximum(1.0 - dr.square(tx) - dr.square(ty), 0.0))
        n = si.sh_frame.to_world(mi.Vector3f(tx, ty, tz))
        tilted = mi.SurfaceInteraction3f(si)
        tilted.sh_frame = mi.Frame3f(dr.normalize(n))
        tilted.wi = tilted.sh_frame.to_local(si.to_world(si.wi))
        return tilted

    def _begin(self, si, active):
        point = self._pattern(si, active)
        self._pattern_point = point
        return point, self._tilted(si, point, active)

    def _end(self):
        self._pattern_point = None

    # -- Mitsuba BSDF interface ---------------------------------------------------------------
    def _through_tilt(self, method, ctx, si, wo, active):
        """``method`` (the feather's ``eval``, ``pdf`` or ``eval_pdf``) in the barbule's tilted
        frame at ``si``, and where its result stands (a barbule there, ``wo`` on ``wi``'s side)."""
        point, tilted = self._begin(si, active)
        wo_t = tilted.sh_frame.to_local(si.to_world(wo))
        result = method(self, ctx, tilted, wo_t, active & point.present)
        self._end()
        return result, point.present & (si.wi.z * wo.z > 0.0)

    def eval(self, ctx, si, wo, active=True):
        import drjit as dr

        value, ok = self._through_tilt(FeatherBSDF.eval, ctx, si, wo, active)
        return dr.select(ok, value, 0.0)

    def pdf(self, ctx, si, wo, active=True):
        import drjit as dr

        pdf, ok = self._through_tilt(FeatherBSDF.pdf, ctx, si, wo, active)
        return dr.select(ok, pdf, 0.0)

    def eval_pdf(self, ctx, si, wo, active=True):
        import drjit as dr

        (value, pdf), ok = self._through_tilt(FeatherBSDF.eval_pdf, ctx, si, wo, active)
        return dr.select(ok, value, 0.0), dr.select(ok, pdf, 0.0)

    def sample(self, ctx, si, sample1, sample2, active=True):
        import drjit as dr
        import mitsuba as mi

        point, tilted = self._begin(si, active)
        bs, weight = FeatherBSDF.sample(self, ctx, tilted, sample1, sample2, active & point.present)
        self._end()
        wo = si.to_local(tilted.sh_frame.to_world(bs.wo))
        # A direction the tilted frame allows but the surface's own side does not: none.
        valid = point.present & (si.wi.z * wo.z > 0.0)
        gap = active & ~point.present
        bs.wo = dr.select(gap, -si.wi, wo)
        bs.pdf = dr.select(gap, 1.0, dr.select(valid, bs.pdf, 0.0))
        bs.eta = dr.select(gap, 1.0, bs.eta)
        bs.sampled_type = dr.select(gap, mi.UInt32(+mi.BSDFFlags.Null), bs.sampled_type)
        bs.sampled_component = dr.select(gap, mi.UInt32(self.null_component), bs.sampled_component)
        weight = dr.select(gap, 1.0, dr.select(valid, weight, 0.0))
        return bs, weight

    def eval_null_transmission(self, si, active=True):
        import drjit as dr
        import mitsuba as mi

        point = self._pattern(si, active)
        # A blocker within the barbule layer's thickness of the shadow ray's origin is the same
        # layer (neighbouring barbs' barbules overlap, coplanar here): it casts no shadow.
        same_layer = si.t * self.world_unit_um < barbule_pattern.LAYER_UM
        return mi.Spectrum(dr.select(active & (~point.present | same_layer), 1.0, 0.0))

    def to_string(self):
        return f"Barbules[{FeatherBSDF.to_string(self)}]"


def carries_barbules(prim) -> bool:
    """True when the curves ``prim`` author ``primvars:pavonine_barbules`` (inherited too)."""
    from pxr import UsdGeom

    primvar = UsdGeom.PrimvarsAPI(prim).FindPrimvarWithInheritance(BARBULES_PRIMVAR)
    return bool(primvar) and primvar.HasValue()


def register() -> None:
    """Register ``pavonine_barbules`` (and the feather BSDF it builds on) for the active variant."""
    from pavonine.render import feather_bsdf

    feather_bsdf.register()
    register_once(PLUGIN_NAME, "bsdf", lambda: variant_class(Barbules, "bsdf"))
