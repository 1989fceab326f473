"""``pavonine_feather``: the peacock-feather BSDF as a Mitsuba 3 plugin (spectral, two-sided).

``eval`` runs :func:`pavonine.materials.brdf.feather_brdf` — the analysis model's own code — on
Dr.Jit arrays, so in an ``llvm_*`` variant it is JIT-compiled with the rest of the integrator.
Per shading point it reads four maps through Mitsuba textures at ``si.uv`` (data, raw):

* ``ocellar``: grey g → class ``k = round((1 − g)(n − 1))`` (white = class 0 … black = class n−1),
  the grey smoothed first and read bilinearly (:mod:`pavonine.materials.ocellus`), so ring
  boundaries are smooth curves below the texel, not staircases of texels
* ``gradation``: t ∈ [0, 1] between the class's black (0) and white (1) ends (Table 1)
* ``angle``: grey g → barbule long axis at ``g · 180°`` counter-clockwise (seen from the front)
  from the barb direction: the mesh attribute ``vertex_barb_tangent`` when ``barb_tangents`` is
  set (the render delegate guarantees it on feather meshes), else the surface tangent ``dp/du``
* ``melanin``: structural share w (1 = full structural colour, 0 = melanin brown)

Each map has a primvar-fed twin, ``<map>_primvar`` (:data:`PRIMVAR_SLOTS`: a ``mesh_attribute``
texture or a constant; barbs carry their inputs as vertex primvars), in the primvar's units:
ocellar class index, gradation t, share w, barbule angle in degrees. A bound twin wins over its
map, and is read on the hit instance's own mesh (as the barb tangent is, below).

Per-instance primvars (``pavonine:gradationOffset`` added to t, ``pavonine:structuralScale``
multiplying w, ``pavonine:glitterSeed`` mixed into the blocks' seed) are gathered per lane from
tables bound after the scene is built (:mod:`pavonine.render.instance_primvars`).

With ``glitter`` > 0 each shading point lies on one barbule block (:mod:`pavonine.materials.glitter`)
whose tilt offsets its lobe: the block comes from the feather coordinate ``si.uv`` scaled to µm by
the surface's ``|dp/du|``, ``|dp/dv|`` and ``world_unit_um`` (µm per scene unit), turned into the
barbule axis. Where the integrator gave the interaction the pixel's footprint (``si.duv_dx``,
``si.duv_dy``: :func:`pavonine.render.integrator.uv_partials`), the lobe is what the footprint
holds (:class:`pavonine.materials.glitter.Footprint`): the block's, blended by the level of detail
with the counts of the cells of about as many blocks as the footprint covers. Glossy sampling
draws the block's shifted Beckmann slopes (all normals, not only the visible ones) with the
block's weight, the smooth lobe's visible normals otherwise; at ``glitter`` 0 nothing of this
runs and the BSDF is the smooth one.

The alpha map becomes a ``mask`` wrapper and the displacement map a ``bumpmap`` wrapper (shading
detail); :func:`~pavonine.render.feather_encoding.feather_bsdf_dict` builds that nesting
(:mod:`pavonine.render.feather_encoding`: the plugin's properties and scene description; its
public names are importable from here too). Sampling: visible normals of the
structural lobe's anisotropic Beckmann distribution (``mi.MicrofacetDistribution``) with
probability w, cosine-weighted hemisphere for the melanin part otherwise.
"""

from __future__ import annotations

import math

import drjit as dr
import mitsuba as mi

from pavonine.base.backend import select_variant
from pavonine.materials import barbule, glitter
from pavonine.materials.jit import JitMaterial
from pavonine.render.feather_encoding import (
    BARB_COORDINATE_ATTRIBUTE,
    BARB_TANGENT_ATTRIBUTE,
    DATA_MAPS,
    DISPERSIONS,
    FRAME_FLOATS,
    INSTANCE_FRAME,
    MAP_DEFAULTS,
    PLUGIN_NAME,
    PRIMVAR_SLOTS,
    SAMPLING_WAVELENGTH_NM,
    WORLD_UNIT_UM,
    decode_parameters,
    encode_parameters,
    feather_bsdf_dict,
    load_with_feathers,
)
from pavonine.render.plugins import register_once, variant_class

__all__ = [
    "BARB_COORDINATE_ATTRIBUTE",
    "BARB_TANGENT_ATTRIBUTE",
    "DATA_MAPS",
    "DISPERSIONS",
    "FRAME_FLOATS",
    "INSTANCE_FRAME",
    "MAP_DEFAULTS",
    "PLUGIN_NAME",
    "PRIMVAR_SLOTS",
    "SAMPLING_WAVELENGTH_NM",
    "WORLD_UNIT_UM",
    "FeatherBSDF",
    "JitMaterial",
    "decode_parameters",
    "encode_parameters",
    "feather_bsdf_dict",
    "load_with_feathers",
    "register",
]

_IDENTITY_FRAME = (1.0, 0, 0, 0, 0, 1.0, 0, 0, 0, 0, 1.0, 0, 1.0, 0, 0, 0, 1.0, 0, 0, 0, 1.0)


class FeatherBSDF:
    """The ``pavonine_feather`` BSDF (module docstring), bound to the active variant's
    ``mi.BSDF`` when registered (:func:`pavonine.render.plugins.register_once`).

    Properties (:func:`~pavonine.render.feather_encoding.feather_bsdf_dict` writes them): the
    feather's parameters (:func:`~pavonine.render.feather_encoding.encode_parameters`); the maps
    ``ocellar``, ``gradation``, ``angle``, ``melanin`` (textures, data); their primvar twins
    ``<map>_primvar`` (:data:`PRIMVAR_SLOTS`); ``barb_tangents`` and ``barb_coordinates``
    (bool: the mesh carries :data:`BARB_TANGENT_ATTRIBUTE` / :data:`BARB_COORDINATE_ATTRIBUTE`);
    ``world_unit_um`` (µm per scene unit, default :data:`WORLD_UNIT_UM`).
    """

    def __init__(self, props: mi.Properties):
        mi.BSDF.__init__(self, props)
        self.material = JitMaterial(decode_parameters(props))
        self.params, self.constants = self.material.params, self.material.constants
        self.n_classes = len(self.params.classes)
        self.maps = {name: props.get(name, None) for name in DATA_MAPS}
        self.primvars = {name: props.get(slot, None) for name, slot in PRIMVAR_SLOTS.items()}
        self.barb_tangents = bool(props.get("barb_tangents", False))
        self.barb_coordinates = bool(props.get("barb_coordinates", False))
        self.alpha_y = barbule.SQRT2 * math.tan(self.constants.crescent_sigma)
        self.alpha_x_sampling = float(
            barbule.beckmann_alpha(
                barbule.along_sigma(
                    self.constants.block_sigma,
                    self.constants.rod_length_nm,
                    SAMPLING_WAVELENGTH_NM,
                )
            )
        )
        self.glitter = float(self.constants.glitter)
        self.world_unit_um = float(props.get("world_unit_um", WORLD_UNIT_UM))
        if self.glitter > 0.0:
            sampling_sigma = barbule.along_sigma(
                self.constants.block_sigma,
                self.constants.rod_length_nm,
                SAMPLING_WAVELENGTH_NM,
            )
            speckle, within = glitter.grain_split(
                self.constants, self.glitter, sampling_sigma, SAMPLING_WAVELENGTH_NM
            )
            # A grain sits at tilt + z·speckle(λ), speckle ∝ λ: over 380–780 nm it strays
            # from its 550 nm place by up to ~0.4 z·speckle, so each grain is sampled with
            # a lobe widened by a third of the speckle spread (sampling only).
            self.grain_speckle = float(speckle)
            self.block_alpha_x = float(barbule.SQRT2 * math.hypot(within, speckle / 3.0))
            self.grains = glitter.grain_count(
                self.params.block_length_um, self.params.rod_length_um
            )
            # The footprint's counts (glitter.cell_counts): the grains' places' deviation σ_μ
            # and the whole lobe's σ_t at 550 nm choose the bins; the bins are λ-independent.
            self.count_spread = float(
                math.hypot(math.sqrt(self.glitter) * math.tan(self.constants.block_sigma), speckle)
            )
            self.count_total = float(math.hypot(self.count_spread, within))
            self.count_model = glitter.count_model(
                self.count_spread, float(within), float(speckle), self.grains
            )
        lobes = mi.BSDFFlags.GlossyReflection | mi.BSDFFlags.DiffuseReflection
        sided = mi.BSDFFlags.FrontSide | mi.BSDFFlags.BackSide
        self.m_components = [
            mi.BSDFFlags.GlossyReflection
            | mi.BSDFFlags.Anisotropic
            | sided
            | mi.BSDFFlags.SpatiallyVarying,
            mi.BSDFFlags.DiffuseReflection | sided | mi.BSDFFlags.SpatiallyVarying,
        ]
        self.m_flags = lobes | sided | mi.BSDFFlags.Anisotropic | mi.BSDFFlags.SpatiallyVarying
        self.instance_tables: dict[str, tuple] = {}

    def set_instance_table(self, key: str, table, neutral: float) -> None:
        """Per-instance values of ``key`` by registry id (``pavonine.render.instance_primvars``).

        The table's entry count enters the kernel as an *opaque* value: the registry ids,
        hence the table's length, differ from one scene build to the next, and a literal
        length would make every build trace a new kernel (a full LLVM compile of the
        whole path tracer, the dominant cost of rendering a train twice in one process).
        """
        entries = None
        if not isinstance(table, dict):
            stride = FRAME_FLOATS if key == INSTANCE_FRAME else 1
            entries = dr.opaque(mi.UInt32, dr.width(table) // stride)
        self.instance_tables[key] = (table, float(neutral), entries)

    def _barb_tangent(self, si, active):
        """The mesh's barb-tangent attribute at ``si``, in world space."""
        local, linear = self._instance_local(si, active)
        a = mi.Vector3f(si.shape.eval_attribute_3(BARB_TANGENT_ATTRIBUTE, local, active))
        if linear is None:
            return a
        return mi.Vector3f(
            *(
                linear[3 * r] * a.x + linear[3 * r + 1] * a.y + linear[3 * r + 2] * a.z
                for r in range(3)
            )
        )

    def _instance_local(self, si, active):
        """``si`` in the hit instance's own space, and the instance's linear part (9 floats,
        row-major; ``None`` when no instance frames are bound).

        Mitsuba's ``Mesh.eval_attribute`` finds barycentric coordinates from ``si.p``
        against the mesh's own vertices, so a hit through an ``instance`` (``si.p`` in world
        space, the vertices in prototype space) reads garbage. The hit point is taken into
        the instance's space first (``INSTANCE_FRAME`` table); attributes read there.
        """
        entry = self.instance_tables.get(INSTANCE_FRAME)
        if entry is None:
            return si, None
        table, _, entries = entry
        if isinstance(table, dict):  # scalar variants: the instance object itself
            frame = table.get(si.instance.id()) if si.instance is not None else None
            m = frame if frame is not None else _IDENTITY_FRAME
        else:
            index = dr.reinterpret_array(mi.UInt32, si.instance)
            inside = index < entries
            base = dr.select(inside, index, 0) * FRAME_FLOATS
            m = [dr.gather(mi.Float, table, base + k, active) for k in range(FRAME_FLOATS)]
        p = si.p
        local = dr.zeros(mi.SurfaceInteraction3f)
        local.prim_index = si.prim_index
        local.shape = si.shape
        local.p = mi.Point3f(
            *(
                m[4 * r] * p.x + m[4 * r + 1] * p.y + m[4 * r + 2] * p.z + m[4 * r + 3]
                for r in range(3)
            )
        )
        return local, m[12:]

    def _per_instance(self, key: str, si, active):
        """The value of ``key`` for the instance each lane hit (``None``: nothing bound)."""
        entry = self.instance_tables.get(key)
        if entry is None:
            return None
        table, neutral, entries = entry
        if isinstance(table, dict):  # scalar variants: the instance object itself
            instance = si.instance
            return table.get(instance.id(), neutral) if instance is not None else neutral
        index = dr.reinterpret_array(mi.UInt32, si.instance)
        inside = index < entries
        return dr.select(inside, dr.gather(mi.Float, table, index, active & inside), neutral)

    # -- per-point material state ------------------------------------------------------
    def _map(self, name: str, si, active):
        """The map's value at ``si`` (its grey level), from its primvar twin when bound."""
        primvar = self.primvars[name]
        if primvar is not None:
            if isinstance(primvar, float):
                value = mi.Float(primvar)
            else:
                value = primvar.eval_1(self._instance_local(si, active)[0], active)
                # NaN where Mitsuba's barycentric solve fails (a needle triangle): neutral,
                # never a NaN class or table index (see curves.sampling.conditioned_triangles)
                value = dr.select(dr.isfinite(value), value, self._neutral_value(name))
            if name == "ocellar":  # class index → grey (class k at 1 − k/(n − 1))
                return 1.0 - value / max(self.n_classes - 1, 1)
            if name == "angle":  # degrees → grey (the axis is a line: 180° periodic)
                return value / 180.0 - dr.floor(value / 180.0)
            return value
        texture = self.maps[name]
        if texture is None:
            return mi.Float(MAP_DEFAULTS[name])
        return texture.eval_1(si, active)

    def _neutral_value(self, name: str) -> float:
        """The primvar value of the map's neutral grey (class index, gradation, share,
        degrees)."""
        grey = MAP_DEFAULTS[name]
        if name == "ocellar":
            return (1.0 - grey) * max(self.n_classes - 1, 1)
        return grey * 180.0 if name == "angle" else grey

    def _point(self, si, active):
        """Barbule-frame rotation (cos, sin), the two stacks and the structural share at ``si``."""
        grey = dr.clip(self._map("ocellar", si, active), 0.0, 1.0)
        cls = dr.clip(dr.round((1.0 - grey) * (self.n_classes - 1)), 0, self.n_classes - 1)
        t = self._map("gradation", si, active)
        offset = self._per_instance("gradation_offset", si, active)
        t = dr.clip(t if offset is None else t + offset, 0.0, 1.0)
        stacks = self.material.stacks(cls, t)
        angle = dr.clip(self._map("angle", si, active), 0.0, 1.0) * dr.pi
        from_barb = angle
        if self.barb_tangents:
            barb = si.sh_frame.to_local(self._barb_tangent(si, active))
            usable = dr.square(barb.x) + dr.square(barb.y) > 1e-12
            angle += dr.select(usable, dr.atan2(barb.y, barb.x), 0.0)
        share = self._map("melanin", si, active)
        scale = self._per_instance("structural_scale", si, active)
        share = dr.clip(share if scale is None else share * scale, 0.0, 1.0)
        glint = None
        if self.glitter > 0.0:
            glint = self._block_slope(si, from_barb if self.barb_coordinates else angle, active)
        return dr.cos(angle), dr.sin(angle), stacks[0], stacks[1], share, glint

    def _footprint_level(self, si):
        """Level of detail of the pixel's footprint at ``si`` (:func:`glitter.footprint_level`):
        its area from the uv partials the integrator computed from the camera ray's
        differentials (``si.duv_dx``, ``si.duv_dy``; zero elsewhere: one block), in µm²."""
        dp_dx = si.dp_du * si.duv_dx.x + si.dp_dv * si.duv_dx.y
        dp_dy = si.dp_du * si.duv_dy.x + si.dp_dv * si.duv_dy.y
        area = dr.norm(dr.cross(dp_dx, dp_dy)) * (self.world_unit_um * self.world_unit_um)
        area = dr.select(dr.isfinite(area), area, 0.0)
        return glitter.footprint_level(
            area, self.params.block_length_um, self.params.barbule_width_um, self.material.ops
        )

    def _block_slope(self, si, angle, active):
        """The block under ``si`` (:mod:`pavonine.materials.glitter`): its tilt and grains.

        On the vane sheet the block comes from the feather coordinate ``si.uv`` in µm
        (``u |dp/du|``, ``v |dp/dv|``) in the frame of the barbule axis ``angle`` (radians
        from ``dp/du`` in the shading frame). On a tessellated barb (``barb_coordinates``)
        it comes from the barb's own coordinate (``BARB_COORDINATE_ATTRIBUTE``: length along
        the barb and place across it, turned into the barbule axis ``angle`` from the barb),
        and the barb's id goes into the seed.
        """
        ops = self.material.ops
        scale = self.world_unit_um
        barb = None
        if self.barb_coordinates:
            local, linear = self._instance_local(si, active)
            c = mi.Vector3f(si.shape.eval_attribute_3(BARB_COORDINATE_ATTRIBUTE, local, active))
            if linear is not None:  # an instance's own scale (mean of its linear part)
                scale = scale * dr.cbrt(dr.abs(dr.det(mi.Matrix3f(*linear))))
            u_um, v_um = c.x * scale, c.y * scale
            barb = ops.to_uint32(dr.round(c.z))
        else:
            u_um = si.uv.x * dr.norm(si.dp_du) * scale
            v_um = si.uv.y * dr.norm(si.dp_dv) * scale
            flip = dr.dot(si.dp_dv, si.sh_frame.t) < 0.0
            angle = dr.select(flip, -angle, angle)
        along, across, step = glitter.sheet_coordinates(u_um, v_um, angle, ops)
        barbule_index, block_index = glitter.block_cell(
            along, across, self.params.block_length_um, self.params.barbule_width_um, ops
        )
        seed = self.params.glitter_seed
        instance = self._per_instance("glitter_seed", si, active)
        if instance is not None:
            seed = seed ^ ops.to_uint32(instance)
        seed = glitter.lowbias32(seed ^ ((step * 0x9E3779B1) & glitter.MASK32))
        if barb is not None:
            seed = glitter.lowbias32(seed ^ ((barb * 0x2545F491) & glitter.MASK32))
        block = glitter.block_state(
            self.glitter,
            self.constants.block_sigma,
            barbule_index,
            block_index,
            seed,
            self.grains,
            ops,
        )
        return block, along, across, seed, self._footprint_level(si)

    def _block_weight(self, glint):
        """1 where the point's block is its own lobe at the footprint's level, else 0
        (:func:`glitter.level_choice`)."""
        _, along, across, seed, level = glint
        return glitter.footprint_block_weight(
            level,
            along,
            across,
            self.params.block_length_um,
            self.params.barbule_width_um,
            seed,
            self.material.ops,
        )

    def _footprint(self, glint, wi, wo):
        """What the pixel's footprint holds for the barbule-frame pair (``wi``, ``wo``): the
        block and the cells' counts around the half-vector (:func:`glitter.footprint_at`)."""
        block, along, across, seed, level = glint
        h = wi + wo
        slope_x = -h.x / dr.maximum(h.z, 1e-6)
        return glitter.footprint_at(
            block,
            level,
            along,
            across,
            seed,
            slope_x,
            self.count_model,
            self.count_spread,
            self.count_total,
            self.params.block_length_um,
            self.params.barbule_width_um,
            self.material.ops,
        )

    @staticmethod
    def _to_barbule(v, c, s):
        return mi.Vector3f(c * v.x + s * v.y, -s * v.x + c * v.y, v.z)

    @staticmethod
    def _from_barbule(v, c, s):
        return mi.Vector3f(c * v.x - s * v.y, s * v.x + c * v.y, v.z)

    def _brdf(self, si, wi, wo, state, active):
        """Spectral BRDF value (no cosine) for barbule-frame directions."""
        _, _, long_stack, short_stack, share, glint = state
        block = None if glint is None else self._footprint(glint, wi, wo)
        out = [
            self.material.brdf(wi, wo, si.wavelengths[k], long_stack, short_stack, share, block)
            for k in range(len(si.wavelengths))
        ]
        return mi.Spectrum(out)

    def _lobe_pdf(self, wi, wo, share, glint=None):
        """Mixture density of the sampling strategies (barbule frame, upper hemisphere): the
        smooth lobe's visible normals, with glitter the block's lobes by the footprint's block
        weight and the smooth lobe by the rest."""
        m = dr.normalize(wi + wo)
        distr = mi.MicrofacetDistribution(
            mi.MicrofacetType.Beckmann, self.alpha_x_sampling, self.alpha_y, True
        )
        glossy = distr.pdf(wi, m)
        if glint is not None:
            block_weight = self._block_weight(glint)
            glossy = (
                block_weight * self._block_normal_pdf(m, glint[0]) + (1.0 - block_weight) * glossy
            )
        glossy = glossy / (4.0 * dr.abs(dr.dot(wo, m)))
        diffuse = mi.warp.square_to_cosine_hemisphere_pdf(wo)
        pdf = share * dr.select(dr.dot(wo, m) > 0, glossy, 0.0) + (1.0 - share) * diffuse
        return dr.select((wi.z > 0) & (wo.z > 0), pdf, 0.0)

    def _block_normal_pdf(self, m, block):
        """Density (per solid angle) of the normals the block's sampling draws: its grains'
        shifted Beckmann lobes at 550 nm, widened (``D(m) m_z``)."""
        d = glitter.block_ndf(
            m.x,
            m.y,
            m.z,
            self.block_alpha_x,
            self.alpha_y,
            block,
            self.grain_speckle,
            self.material.ops,
        )
        return d * m.z

    def _sample_block_normal(self, u, sample2, block):
        """A normal of the block's sampling lobes: grain by its share (``u`` uniform), then
        Box–Muller on ``sample2``."""
        centre = block.tilt + block.grains[0] * self.grain_speckle
        cumulative = block.weights[0]
        for z, w in zip(block.grains[1:], block.weights[1:], strict=True):
            centre = dr.select(u >= cumulative, block.tilt + z * self.grain_speckle, centre)
            cumulative = cumulative + w
        radius = dr.sqrt(-2.0 * dr.log(dr.maximum(1.0 - sample2.x, 1e-30)))
        phi = 2.0 * dr.pi * sample2.y
        slope_x = centre + self.block_alpha_x * barbule.SQRT2 * 0.5 * radius * dr.cos(phi)
        slope_y = self.alpha_y * barbule.SQRT2 * 0.5 * radius * dr.sin(phi)
        return dr.normalize(mi.Vector3f(-slope_x, -slope_y, 1.0))

    def _upper(self, si, wo, state):
        """Both directions in the barbule frame, mirrored to the upper side when lit from below."""
        c, s = state[0], state[1]
        sign = dr.select(si.wi.z < 0, -1.0, 1.0)
        wi = self._to_barbule(si.wi, c, s)
        wo = self._to_barbule(wo, c, s)
        return mi.Vector3f(wi.x, wi.y, wi.z * sign), mi.Vector3f(wo.x, wo.y, wo.z * sign)

    # -- Mitsuba BSDF interface ---------------------------------------------------------
    def eval(self, ctx, si, wo, active=True):
        state = self._point(si, active)
        wi_b, wo_b = self._upper(si, wo, state)
        value = self._brdf(si, wi_b, wo_b, state, active) * dr.abs(wo_b.z)
        return dr.select(active & (wi_b.z > 0) & (wo_b.z > 0), value, 0.0)

    def pdf(self, ctx, si, wo, active=True):
        state = self._point(si, active)
        wi_b, wo_b = self._upper(si, wo, state)
        return dr.select(active, self._lobe_pdf(wi_b, wo_b, state[4], state[5]), 0.0)

    def eval_pdf(self, ctx, si, wo, active=True):
        state = self._point(si, active)
        wi_b, wo_b = self._upper(si, wo, state)
        ok = active & (wi_b.z > 0) & (wo_b.z > 0)
        value = self._brdf(si, wi_b, wo_b, state, active) * dr.abs(wo_b.z)
        return dr.select(ok, value, 0.0), dr.select(
            ok, self._lobe_pdf(wi_b, wo_b, state[4], state[5]), 0.0
        )

    def sample(self, ctx, si, sample1, sample2, active=True):
        state = self._point(si, active)
        c, s, share = state[0], state[1], state[4]
        sign = dr.select(si.wi.z < 0, -1.0, 1.0)
        wi_b = self._to_barbule(si.wi, c, s)
        wi_b = mi.Vector3f(wi_b.x, wi_b.y, wi_b.z * sign)
        glossy = sample1 < share
        glint = state[5]
        distr = mi.MicrofacetDistribution(
            mi.MicrofacetType.Beckmann, self.alpha_x_sampling, self.alpha_y, True
        )
        m, _ = distr.sample(wi_b, sample2)
        from_block = mi.Bool(False)
        if glint is not None:
            # the block's lobes with the footprint's block weight, else the smooth lobe
            block_weight = self._block_weight(glint)
            u = sample1 / dr.maximum(share, 1e-30)
            from_block = u < block_weight
            u_block = u / dr.maximum(block_weight, 1e-30)
            m = dr.select(from_block, self._sample_block_normal(u_block, sample2, glint[0]), m)
        wo_glossy = mi.reflect(wi_b, m)
        wo_diffuse = mi.warp.square_to_cosine_hemisphere(sample2)
        wo_b = dr.select(glossy, wo_glossy, wo_diffuse)
        pdf = self._lobe_pdf(wi_b, wo_b, share, glint)
        value = self._brdf(si, wi_b, wo_b, state, active) * dr.abs(wo_b.z)
        ok = active & (wi_b.z > 0) & (wo_b.z > 0) & (pdf > 0)
        if glint is not None:
            ok &= ~(glossy & from_block) | (dr.dot(wi_b, m) > 0.0)

        bs = dr.zeros(mi.BSDFSample3f)
        wo_local = self._from_barbule(wo_b, c, s)
        bs.wo = mi.Vector3f(wo_local.x, wo_local.y, wo_local.z * sign)
        bs.pdf = dr.select(ok, pdf, 0.0)
        bs.eta = 1.0
        bs.sampled_type = dr.select(
            glossy,
            mi.UInt32(+mi.BSDFFlags.GlossyReflection),
            mi.UInt32(+mi.BSDFFlags.DiffuseReflection),
        )
        bs.sampled_component = dr.select(glossy, mi.UInt32(0), mi.UInt32(1))
        weight = dr.select(ok, value / dr.select(ok, pdf, 1.0), 0.0)
        return bs, weight

    def traverse(self, callback):
        pass

    def to_string(self):
        return f"FeatherBSDF[classes={self.n_classes}, interference={self.params.interference}]"


def register() -> None:
    """Register the ``pavonine_feather`` BSDF with Mitsuba for the active (or default) variant."""
    select_variant()
    register_once(PLUGIN_NAME, "bsdf", lambda: variant_class(FeatherBSDF, "bsdf"))
