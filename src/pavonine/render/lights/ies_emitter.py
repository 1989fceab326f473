"""Mitsuba emitters whose emission follows a UsdLux shaping profile (an IES file), per direction.

Mitsuba has no IES emitter; these two Python plugins (JIT-compiled in the ``llvm`` variants like
the feather BSDF) scale a built-in emitter's emission by a factor read from a θ×φ table of the
light's directions (:func:`pavonine.render.lights.ies.profile_table`; θ from the light's −Z axis,
φ counter-clockwise from +X), bilinearly interpolated:

* ``pavonine_ies_point`` wraps Mitsuba's ``point`` emitter (a ``SphereLight`` treated as a point):
  ``I(ω) = I · f(ω)``, ω the direction from the light to the lit point;
* ``pavonine_ies_area`` is Mitsuba's ``area`` emitter (``src/emitters/area.cpp``, the same
  ``eval`` / ``sample_direction`` / ``pdf_direction`` / ``sample_ray`` contracts) with its radiance
  scaled by ``f`` of the direction the light leaves the surface in, relative to the light's axis:
  a sphere, rect, disk or cylinder light shaped as RenderMan, Karma and Cycles shape area lights
  by a profile (the whole light's axis, not each point's normal).

Both sample positions and directions as the emitters they extend (the profile is not importance
sampled): unbiased, noisier where the profile is narrow. The point emitter also starts light paths
(``sample_ray``: Mitsuba's ``ptracer`` and ``path`` agree on a floor it lights, 0.006355 against
0.006276 at 32², 64 spp); the area emitter does not (Pavonine's integrators never ask it to).
"""

from __future__ import annotations

import math

from pavonine.render.plugins import register_once

POINT_PLUGIN = "pavonine_ies_point"
AREA_PLUGIN = "pavonine_ies_area"


def register() -> None:
    """Register both plugins with Mitsuba for the active variant (once)."""
    register_once(POINT_PLUGIN, "emitter", _point_class)
    register_once(AREA_PLUGIN, "emitter", _area_class)


def emissive(texture: dict) -> dict:
    """A radiance texture dict as Mitsuba's emitters take it (``Properties::get_emissive_texture``
    wraps colours in the D65 illuminant in spectral variants); a Python emitter must do so itself."""
    if texture.get("type") == "d65":
        return texture
    if texture.get("type") == "rgb":
        return {"type": "d65", "color": texture["value"]}
    return {"type": "d65", "nested": texture}


def _profile(props):
    """The profile texture (from the ``profile`` bitmap) and the light's local axes in world space
    (the columns of its orthonormal ``light_to_world`` rotation)."""
    import drjit as dr
    import mitsuba as mi
    import numpy as np

    table = np.asarray(props["profile"], dtype=np.float32)
    texture = mi.Texture2f(
        mi.TensorXf(table.reshape(table.shape[0], table.shape[1], 1)),
        filter_mode=dr.FilterMode.Linear,
        wrap_mode=dr.WrapMode.Clamp,
    )
    matrix = np.asarray(props["light_to_world"].matrix, dtype=np.float64)[:3, :3]
    return texture, [mi.ScalarVector3f(*matrix[:, i].tolist()) for i in range(3)]


def _factor(texture, axes, direction):
    """The profile's factor for a world ``direction`` leaving the light."""
    import drjit as dr
    import mitsuba as mi

    unit = dr.normalize(direction)
    x, y, z = (dr.dot(axis, unit) for axis in axes)
    theta = dr.acos(dr.clip(-z, -1.0, 1.0))
    phi = dr.atan2(y, x)
    phi = dr.select(phi < 0, phi + 2.0 * math.pi, phi)
    uv = mi.Point2f(phi / (2.0 * math.pi), theta / math.pi)
    return texture.eval(uv)[0]


def _shifted(sample):
    """Mitsuba's ``sample_shifted`` (one sample → a wavelength sample per channel), spectral only;
    RGB variants draw no wavelengths."""
    import mitsuba as mi

    return mi.sample_shifted(sample) if mi.is_spectral else mi.Color0f()


def _point_class() -> type:
    import mitsuba as mi

    class IesPoint(mi.Emitter):
        """Mitsuba's ``point`` emitter (``inner``) with its intensity shaped by ``profile``."""

        def __init__(self, props: mi.Properties):
            super().__init__(props)
            self.inner = props["inner"]
            self.texture, self.axes = _profile(props)
            self.m_flags = mi.EmitterFlags.DeltaPosition

        def sample_direction(self, it, sample, active=True):
            ds, weight = self.inner.sample_direction(it, sample, active)
            ds.emitter = mi.EmitterPtr(self)
            return ds, weight * _factor(self.texture, self.axes, -ds.d)

        def pdf_direction(self, it, ds, active=True):
            return self.inner.pdf_direction(it, ds, active)

        def eval_direction(self, it, ds, active=True):
            value = self.inner.eval_direction(it, ds, active)
            return value * _factor(self.texture, self.axes, -ds.d)

        def sample_ray(self, time, wavelength_sample, sample2, sample3, active=True):
            ray, weight = self.inner.sample_ray(time, wavelength_sample, sample2, sample3, active)
            return ray, weight * _factor(self.texture, self.axes, ray.d)

        def sample_position(self, time, sample, active=True):
            return self.inner.sample_position(time, sample, active)

        def pdf_position(self, ps, active=True):
            return self.inner.pdf_position(ps, active)

        def sample_wavelengths(self, si, sample, active=True):
            return self.inner.sample_wavelengths(si, sample, active)

        def eval(self, si, active=True):
            return self.inner.eval(si, active)

        def bbox(self):
            return self.inner.bbox()

        def traverse(self, callback):
            pass

        def to_string(self):
            return "IesPoint[]"

    return IesPoint


def _area_class() -> type:
    import drjit as dr
    import mitsuba as mi

    class IesArea(mi.Emitter):
        """Mitsuba's ``area`` emitter with its radiance shaped by ``profile``."""

        def __init__(self, props: mi.Properties):
            super().__init__(props)
            self.radiance = props["radiance"]
            self.texture, self.axes = _profile(props)
            self.m_flags = mi.EmitterFlags.Surface

        def _shaped(self, si, direction, active):
            value = self.radiance.eval(si, active)
            return value * _factor(self.texture, self.axes, direction)

        def eval(self, si, active=True):
            active = active & (mi.Frame3f.cos_theta(si.wi) > 0)
            value = self._shaped(si, si.to_world(si.wi), active)
            return dr.select(active, value, 0.0)

        def sample_direction(self, it, sample, active=True):
            ds = self.get_shape().sample_direction(it, sample, active)
            active = active & (dr.dot(ds.d, ds.n) < 0) & (ds.pdf != 0)
            si = mi.SurfaceInteraction3f(ds, it.wavelengths)
            value = self._shaped(si, -ds.d, active) / ds.pdf
            ds.emitter = mi.EmitterPtr(self)
            return ds, dr.select(active, value, 0.0)

        def pdf_direction(self, it, ds, active=True):
            active = active & (dr.dot(ds.d, ds.n) < 0)
            value = self.get_shape().pdf_direction(it, ds, active)
            return dr.select(active, value, 0.0)

        def eval_direction(self, it, ds, active=True):
            active = active & (dr.dot(ds.d, ds.n) < 0)
            si = mi.SurfaceInteraction3f(ds, it.wavelengths)
            return dr.select(active, self._shaped(si, -ds.d, active), 0.0)

        def sample_ray(self, time, wavelength_sample, sample2, sample3, active=True):
            raise NotImplementedError(
                f"{AREA_PLUGIN}: light tracing (Mitsuba's ptracer) is not supported; Pavonine "
                "renders with its path tracer, which samples emitters by direction"
            )

        def sample_position(self, time, sample, active=True):
            return self.get_shape().sample_position(time, sample, active)

        def pdf_position(self, ps, active=True):
            return self.get_shape().pdf_position(ps, active)

        def sample_wavelengths(self, si, sample, active=True):
            return self.radiance.sample_spectrum(si, _shifted(sample), active)

        def bbox(self):
            return self.get_shape().bbox()

        def traverse(self, callback):
            pass

        def to_string(self):
            return "IesArea[]"

    return IesArea
