"""The feather material as Dr.Jit arrays: what :func:`~pavonine.materials.brdf.feather_brdf` needs
per lane, for the renderer's BSDF (:mod:`pavonine.render.feather_bsdf`) and the baker
(:mod:`pavonine.pipeline.bake.appearance`), one implementation for both.

Class tables (Table 1's black and white ends per class, lengths in nm) as Dr.Jit buffers, gathered
per lane and lerped by gradation (:func:`gather_stacks`); the physical mode's reflectance table
(:func:`~pavonine.materials.brdf.reflectance_table`) as a buffer; the melanin albedo as Mitsuba's
sRGB spectral model coefficients. Mitsuba is imported when a :class:`JitMaterial` is made.
"""

from __future__ import annotations

from pavonine.materials.brdf import (
    UM_TO_NM,
    MaterialConstants,
    feather_brdf,
    reflectance_table,
    srgb_model_eval,
)
from pavonine.materials.parameters import FeatherParameters

#: The stack quantities of Table 1, per axis.
QUANTITIES = ("interval", "radius", "count")


def class_tables(params: FeatherParameters, ops) -> dict:
    """Per-class (black, white) stack tables as Dr.Jit arrays, lengths in nm: ``{axis}_{quantity}``."""
    scale = {"interval": UM_TO_NM, "radius": UM_TO_NM, "count": 1.0}
    arrays = params.class_arrays()
    return {
        f"{axis}_{q}": ops.buffer(arrays[f"{axis}_{q}"] * scale[q])
        for axis in ("long", "short")
        for q in QUANTITIES
    }


def gather_stacks(tables: dict, ocellar_class, gradation, ops) -> list[tuple]:
    """``[long, short]`` stacks ``(interval_nm, radius_nm, count)`` per lane: Table 1 lerped by gradation."""
    base = ocellar_class * 2
    stacks = []
    for axis in ("long", "short"):
        values = []
        for q in QUANTITIES:
            table = tables[f"{axis}_{q}"]
            black = ops.gather(table, base)
            white = ops.gather(table, base + 1)
            values.append(black + (white - black) * gradation)
        stacks.append(tuple(values))
    return stacks


class JitMaterial:
    """The feather material's state as Dr.Jit arrays: what :func:`feather_brdf` needs per lane."""

    def __init__(self, params: FeatherParameters):
        import mitsuba as mi

        from pavonine.materials.arraymath import DrJitOps

        self.params = params.validate()
        self.ops = DrJitOps()
        self.constants = MaterialConstants.from_parameters(params)
        table = reflectance_table(params)
        self.table = table.with_values(self.ops.buffer(table.values))
        self.class_tables = class_tables(params, self.ops)
        self.melanin_coefficients = [
            float(c) for c in mi.srgb_model_fetch(mi.ScalarColor3f(*params.melanin_color))
        ]

    def stacks(self, ocellar_class, gradation) -> list[tuple]:
        """``[long, short]`` stacks per lane: Table 1 dimensions (:func:`gather_stacks`) in the
        paper modes, ``(table entry, gradation)`` in the physical mode."""
        if self.constants.interference == "physical":
            return [(self.table.entry(ocellar_class, axis), gradation) for axis in (0, 1)]
        return gather_stacks(self.class_tables, ocellar_class, gradation, self.ops)

    def brdf(self, wi, wo, wavelength_nm, long_stack, short_stack, share, block_slope=None):
        """BRDF (1/sr, no cosine) per lane for barbule-frame ``mi.Vector3f`` directions
        (``block_slope``: the lane's block, :func:`pavonine.materials.brdf.structural_brdf`)."""
        albedo = srgb_model_eval(self.melanin_coefficients, wavelength_nm, self.ops)
        return feather_brdf(
            self.constants,
            self.table,
            (wi.x, wi.y, wi.z),
            (wo.x, wo.y, wo.z),
            wavelength_nm,
            long_stack,
            short_stack,
            share,
            albedo,
            self.ops,
            block_slope,
        )
