"""``pavonine_path``: Mitsuba's ``volpath`` for scenes without media, with one intersection site.

Why: Dr.Jit traces every registered shape's ``compute_surface_interaction`` at each place an
integrator intersects the scene, and a point-instanced scene registers one shape per instance.
``volpath`` intersects in four places (in its path loop and in the loop its shadow rays run
through null surfaces, once for media and once for surfaces in each, all traced when a scene has
no media), so the 192-feather train's trace held ~500 MiB and took seconds per pass. Here the
shadow ray is a *state* of the one path loop: an iteration either extends the path or advances
its pending shadow ray, and both intersect through the same call (the train's kernel: 94,906 IR
operations against ``volpath``'s 177,808; docs/performance.md).

What it computes is ``volpath``'s estimator without media (Mitsuba 3.9.1,
``src/integrators/volpath.cpp``), step for step:

* next-event estimation at every vertex whose BSDF has a smooth lobe, the shadow ray passing
  null surfaces with the weight of their :meth:`eval_null_transmission` (``mask`` opacity,
  ``pavonine_front_only`` backs), multiple importance sampling by the power heuristic against
  the BSDF's pdf (Veach 1997, Eq. 9.13), delta lights unweighted;
* an emitter hit by a BSDF-sampled ray weighted against the emitter pdf seen from the last
  non-null scattering vertex; camera rays and specular chains count it whole;
* a ``Null`` BSDF sample (passing a mask or a back face) neither counts as a bounce nor moves
  the last scattering vertex; ``max_depth`` counts scattering vertices, ``rr_depth`` starts
  Russian roulette with continuation probability ``q = min(max(β)·η², 0.95)``;
* one addition, ``rr_threshold`` (θ, default :data:`RR_THRESHOLD`; 0 is ``volpath``'s roulette
  exactly): before ``rr_depth``, from the third vertex on, a path whose ``max(β)·η²`` has fallen
  below θ plays roulette with continuation probability ``max(β)·η²/θ``, and a survivor carries
  throughput θ (the lower bound of a *weight window*, as in particle transport's MCNP and in
  Vorba & Křivánek 2016, "Adjoint-driven Russian roulette and splitting in light transport
  simulation", ACM TOG 35(4)). Unbiased like any roulette, it stops paths that can bring little
  before they cost five more vertices (the train's time and variance with and without it:
  docs/performance.md);
* the sample is valid (film alpha) once a non-null scattering happened or when the scene has
  an environment emitter;
* ``max_depth`` -1 is no limit and 0 renders nothing; ``hide_emitters`` hides emitters from
  camera rays, which pass through area lights (``volpath``'s ``skip_area_emitters``).

Random numbers are drawn in ``volpath``'s order (roulette, light, BSDF), so with one seed the
two images nearly coincide; ``tests/render/test_integrator.py`` compares them with different seeds by
the statistical test ``pavonine compare --method stat`` uses, and against a closed form (a
half-present card lets half the sun into its shadow). Media are not handled (the delegate makes
none); scalar variants keep ``volpath`` (a Python integrator is called per sample there).
"""

from __future__ import annotations

import math

from pavonine.render.plugins import register_once

PLUGIN_NAME = "pavonine_path"
DEFAULT_MAX_DEPTH = 8  # Pavonine's default (Mitsuba's own is -1, no limit)
DEFAULT_RR_DEPTH = 5  # Mitsuba's
#: Default ``rr_threshold`` (module docstring): early roulette below this max(β)·η².
RR_THRESHOLD = 0.1


def mis_weight(pdf_a, pdf_b):
    """Power heuristic (Veach 1997, Eq. 9.13, β = 2) of strategy ``a`` against ``b``, 0 where
    it is not finite (both pdfs 0, or infinite)."""
    import drjit as dr

    a2, b2 = pdf_a * pdf_a, pdf_b * pdf_b
    w = a2 / (a2 + b2)
    return dr.select(dr.isfinite(w), w, 0.0)


def _plugin_class():
    """The integrator class for the active variant (Mitsuba classes are per variant)."""
    import drjit as dr
    import mitsuba as mi

    class PavoninePath(mi.SamplingIntegrator):
        """Unidirectional path tracer, shadow rays through null surfaces (module docstring)."""

        def __init__(self, props: mi.Properties):
            mi.SamplingIntegrator.__init__(self, props)
            self.depth_limit = int(props.get("max_depth", DEFAULT_MAX_DEPTH))
            self.rr_depth = int(props.get("rr_depth", DEFAULT_RR_DEPTH))
            self.hide_emitters = bool(props.get("hide_emitters", False))
            self.rr_threshold = float(props.get("rr_threshold", RR_THRESHOLD))
            if self.depth_limit < -1:
                raise ValueError("max_depth must be -1 (no limit) or at least 0")
            if self.rr_depth < 1:
                raise ValueError("rr_depth must be at least 1")
            if not 0.0 <= self.rr_threshold < 1.0:
                raise ValueError("rr_threshold must be in [0, 1)")
            # -1 is Mitsuba's "no limit": the largest depth a UInt32 holds.
            self.max_depth = self.depth_limit if self.depth_limit >= 0 else 0xFFFFFFFF

        def sample(self, scene, sampler, ray, medium=None, active=True):
            if self.max_depth == 0:  # volpath: no light at all; valid where it sees the sky
                has_env = scene.environment() is not None
                return mi.Spectrum(0.0), mi.Bool(has_env and not self.hide_emitters) & active, []
            return self.trace(scene, sampler, ray, active, pixel_differential(ray, sampler))

        @dr.syntax
        def trace(self, scene, sampler, ray, active, pixel=None):
            """The path loop of :meth:`sample` (module docstring); ``pixel``: the camera ray's
            differentials spanning one pixel (:func:`pixel_differential`), or ``None``."""
            import drjit as dr  # dr.syntax recompiles the body without the enclosing scope
            import mitsuba as mi

            ctx = mi.BSDFContext()
            ray = mi.Ray3f(ray)
            hide = self.hide_emitters
            has_env = scene.environment() is not None
            result = mi.Spectrum(0.0)
            throughput = mi.Spectrum(1.0)
            eta = mi.Float(1.0)
            depth = mi.UInt32(0)
            valid = mi.Bool(has_env and not hide) & mi.Bool(active)
            specular_chain = mi.Bool(active) & mi.Bool(not hide)
            last_event = dr.zeros(mi.Interaction3f)
            last_pdf = mi.Float(1.0)
            walking = mi.Bool(active)  # the path goes on
            # The pending shadow ray: its ray, length to the light, length done, weight.
            shadow = mi.Bool(False)
            shadow_ray = dr.zeros(mi.Ray3f)
            shadow_length = mi.Float(0.0)
            shadow_done = mi.Float(0.0)
            shadow_weight = mi.Spectrum(0.0)

            # The loop only reads the scene, the integrator, the context and the pixel: as loop
            # state they were traversed into it, and one loop-invariant variable of theirs whose
            # size is not the loop's made Dr.Jit record the whole body twice ("re-recording loop
            # to eliminate 1/83 redundant loop state variables"), even with OptimizeLoops off.
            # Outside it, the body is traced once: the rattle shot's trace 5.6 → 2.3 s a pass,
            # the image bit for bit the same (tests/render/test_integrator.py).
            while dr.hint(walking | shadow, exclude=[scene, self, ctx, pixel]):
                was_shadow = mi.Bool(shadow)  # this iteration advances the shadow ray
                stepping = walking & ~shadow  # this iteration extends the path
                # Russian roulette and the depth limit, at the top of a path step (volpath).
                stepping &= dr.any(mi.unpolarized_spectrum(throughput) != 0.0)
                q = dr.minimum(dr.max(mi.unpolarized_spectrum(throughput)) * eta * eta, 0.95)
                roulette = stepping & (depth > self.rr_depth)
                if dr.hint(self.rr_threshold > 0.0, mode="scalar"):
                    # The weight window's lower bound (module docstring): survivors carry θ.
                    theta = self.rr_threshold
                    early = stepping & ~roulette & (depth > 1) & (q < theta)
                    q[early] = q / theta
                    roulette |= early
                stepping &= (sampler.next_1d(stepping) < q) | ~roulette
                throughput[roulette] = throughput * dr.rcp(q)
                stepping &= depth < self.max_depth
                walking &= shadow | stepping

                # One intersection: the pending shadow ray, else the path's ray.
                current = dr.select(shadow, shadow_ray, ray)
                current.maxt = dr.select(shadow, shadow_length - shadow_done, current.maxt)
                si = scene.ray_intersect(current, shadow | stepping)
                if dr.hint(pixel is not None, mode="scalar"):
                    # The pixel's footprint on the surface the camera sees (uv partials), for
                    # the feather BSDF's glints; none after the first scattering.
                    seen = stepping & (depth == 0)
                    duv_dx, duv_dy = uv_partials(si, pixel)
                    si.duv_dx = dr.select(seen, duv_dx, 0.0)
                    si.duv_dy = dr.select(seen, duv_dy, 0.0)
                bsdf = si.bsdf(current)

                # ---- shadow step: through null surfaces by their transmission (volpath).
                blocker = shadow & si.is_valid()
                shadow_done[shadow] = shadow_done + si.t
                shadow_weight[blocker] = shadow_weight * bsdf.eval_null_transmission(si, blocker)
                shadow_ray[blocker] = si.spawn_ray(current.d)
                through = dr.any(mi.unpolarized_spectrum(shadow_weight) != 0.0)
                arrived = shadow & (~si.is_valid() | (shadow_length - shadow_done <= 0.0))
                result[arrived & through] = result + shadow_weight
                shadow &= ~arrived & through

                # ---- path step: emission found by the path's ray.
                emitter = si.emitter(scene)
                lit = stepping & (emitter != None)  # noqa: E711 (a Dr.Jit pointer array)
                if dr.hint(hide, mode="scalar"):
                    # hide_emitters (volpath): a camera ray sees no emitter and passes through
                    # area lights, neither scattering nor counting a bounce.
                    passing = lit & (depth == 0) & si.is_valid()
                    lit &= depth != 0
                    ray[passing] = si.spawn_ray(current.d)
                    stepping &= ~passing
                ds = mi.DirectionSample3f(scene, si, last_event)
                emitter_pdf = scene.pdf_emitter_direction(last_event, ds, lit & ~specular_chain)
                weight = dr.select(specular_chain, 1.0, mis_weight(last_pdf, emitter_pdf))
                result[lit] = result + throughput * weight * emitter.eval(si, lit)
                stepping &= si.is_valid()

                # Next-event estimation: sample a light, queue its shadow ray.
                sample_light = (
                    stepping
                    & mi.has_flag(bsdf.flags(), mi.BSDFFlags.Smooth)
                    & (depth + 1 < self.max_depth)
                )
                ds, light = scene.sample_emitter_direction(
                    si, sampler.next_2d(sample_light), False, sample_light
                )
                sample_light &= ds.pdf != 0.0
                wo = si.to_local(ds.d)
                bsdf_value, bsdf_pdf = bsdf.eval_pdf(ctx, si, wo, sample_light)
                light_weight = mis_weight(ds.pdf, dr.select(ds.delta, 0.0, bsdf_pdf))
                queued = throughput * bsdf_value * light_weight * light
                sample_light &= dr.any(mi.unpolarized_spectrum(queued) != 0.0)
                towards = si.spawn_ray_to(ds.p)
                shadow_ray[sample_light] = towards
                shadow_length[sample_light] = towards.maxt
                shadow_done[sample_light] = 0.0
                shadow_weight[sample_light] = queued
                shadow |= sample_light

                # BSDF sampling: the path's next ray.
                bs, bsdf_weight = bsdf.sample(
                    ctx, si, sampler.next_1d(stepping), sampler.next_2d(stepping), stepping
                )
                throughput[stepping] = throughput * bsdf_weight
                eta[stepping] = eta * bs.eta
                ray[stepping] = si.spawn_ray(si.to_world(bs.wo))
                scattered = stepping & ~mi.has_flag(bs.sampled_type, mi.BSDFFlags.Null)
                depth[scattered] = depth + 1
                last_event[scattered] = mi.Interaction3f(si)
                last_pdf[scattered] = bs.pdf
                valid |= scattered
                delta = mi.has_flag(bs.sampled_type, mi.BSDFFlags.Delta)
                specular_chain[scattered & delta] = True
                specular_chain[stepping & mi.has_flag(bs.sampled_type, mi.BSDFFlags.Smooth)] = False
                walking = dr.select(was_shadow, walking, stepping)
                if dr.hint(hide, mode="scalar"):
                    walking |= ~was_shadow & passing

            return result, valid, []

        def aov_names(self):
            return []

        def to_string(self):
            return (
                f"PavoninePath[max_depth={self.depth_limit}, rr_depth={self.rr_depth}, "
                f"rr_threshold={self.rr_threshold}, hide_emitters={self.hide_emitters}]"
            )

    return PavoninePath


def pixel_differential(ray, sampler):
    """The camera ray with differentials spanning a whole pixel, or ``None`` without them.

    Mitsuba's ``SamplingIntegrator`` scales the sensor's differentials (one pixel apart) by
    ``1/√spp`` before ``sample`` (``diff_scale_factor``, ``src/render/integrator.cpp``); the
    glints' footprint is the pixel's, whatever the sample count or how the samples are split
    into passes or among workers, so that scale is undone (``scale_differential`` moves the
    offset rays' origins and directions linearly about the main ray's).
    """
    import mitsuba as mi

    if not isinstance(ray, mi.RayDifferential3f) or not ray.has_differentials:
        return None
    # (RayDifferential3f's copy constructor keeps the main ray only: copy field by field)
    pixel = mi.RayDifferential3f(mi.Ray3f(ray))
    pixel.o_x, pixel.o_y, pixel.d_x, pixel.d_y = ray.o_x, ray.o_y, ray.d_x, ray.d_y
    pixel.has_differentials = True
    pixel.scale_differential(math.sqrt(sampler.sample_count()))
    return pixel


def uv_partials(si, pixel):
    """``(duv_dx, duv_dy)`` at ``si`` for the offset rays of ``pixel`` (a ``RayDifferential3f``):
    Mitsuba's ``SurfaceInteraction::compute_uv_partials`` (``include/mitsuba/render/
    interaction.h``; Pharr et al., *PBRT* 3rd ed. §10.1.1) written out, because inside the path
    loop's symbolic ``while`` the bound method returns zeros (Dr.Jit 1.5 / Mitsuba 3.9.1). The
    offset rays meet the tangent plane at ``p + dp_dx``, ``p + dp_dy``; the least-squares
    solution of ``dp = dp_du du + dp_dv dv`` gives the partials (zero where ``dp_du``, ``dp_dv``
    are degenerate or the offset ray runs parallel to the plane)."""
    import drjit as dr
    import mitsuba as mi

    d = dr.dot(si.n, si.p)

    def offset(o, direction):
        t = (d - dr.dot(si.n, o)) / dr.dot(si.n, direction)
        return dr.fma(direction, t, o) - si.p

    dp_dx, dp_dy = offset(pixel.o_x, pixel.d_x), offset(pixel.o_y, pixel.d_y)
    a00, a01, a11 = (
        dr.dot(si.dp_du, si.dp_du),
        dr.dot(si.dp_du, si.dp_dv),
        dr.dot(si.dp_dv, si.dp_dv),
    )
    inv_det = dr.rcp(a00 * a11 - a01 * a01)
    out = []
    for dp in (dp_dx, dp_dy):
        b0, b1 = dr.dot(si.dp_du, dp), dr.dot(si.dp_dv, dp)
        duv = mi.Vector2f(a11 * b0 - a01 * b1, a00 * b1 - a01 * b0) * inv_det
        out.append(dr.select(dr.all(dr.isfinite(duv)), duv, 0.0))
    return out[0], out[1]


def register() -> None:
    """Register the integrator with Mitsuba (once per variant)."""
    register_once(PLUGIN_NAME, "integrator", _plugin_class)


def runs_pavonine_path(variant: str) -> bool:
    """Whether ``variant`` renders the path tracer with ``pavonine_path`` (JIT variants) rather
    than Mitsuba's ``volpath`` (scalar ones: a Python integrator is called per sample there)."""
    return variant.startswith(("llvm_", "cuda_"))


def path_tracer(
    max_depth: int,
    rr_depth: int = DEFAULT_RR_DEPTH,
    hide_emitters: bool = False,
    rr_threshold: float = RR_THRESHOLD,
) -> dict:
    """The path tracer's Mitsuba dict for the active variant: ``pavonine_path`` in JIT variants,
    Mitsuba's ``volpath`` in scalar ones, without ``rr_threshold`` (module docstring).
    ``max_depth`` -1: no limit."""
    import mitsuba as mi

    params = {"max_depth": max_depth, "rr_depth": rr_depth, "hide_emitters": hide_emitters}
    if not runs_pavonine_path(mi.variant()):
        return {"type": "volpath", **params}
    register()
    return {"type": PLUGIN_NAME, **params, "rr_threshold": rr_threshold}
