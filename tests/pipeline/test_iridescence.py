"""The glTF look's model (pipeline/export/iridescence.py): its port of the
``KHR_materials_iridescence`` film against the Airy sum it approximates, and the fit recovering a
film it was given. (That three.js draws what the port says: tests/pipeline/test_gltf_threejs.py.)"""

from __future__ import annotations

import numpy as np
import pytest

from pavonine.materials import colour
from pavonine.materials.materialx import thin_film_reflectance
from pavonine.pipeline.export import iridescence as irid


@pytest.mark.parametrize("thickness", [150.0, 300.0, 450.0, 700.0])
@pytest.mark.parametrize("n_film", [1.33, 1.6])
def test_film_at_normal_incidence_is_the_airy_sum_seen_in_rec709(thickness, n_film):
    """Belcour & Barla's Fourier-space film vs the exact Airy reflectance of a free-standing film
    (substrate index 1, as F0 = 0 makes it) integrated against the CIE 1931 functions (equal
    energy, Y of a perfect reflector = 1) and taken to linear Rec. 709."""
    wavelengths = np.arange(360.0, 831.0, 1.0)
    spectrum = thin_film_reflectance(wavelengths, thickness, n_film, 1.0)
    cmf = colour.cmfs(wavelengths)
    xyz = spectrum @ cmf / cmf[:, 1].sum()
    exact = xyz @ irid.XYZ_TO_REC709.T
    fitted = irid.film_fresnel(np.array(1.0), n_film, np.array(thickness))
    # Orders 0–2 and Gaussian fits of the CIE functions: within 0.04 of the exact colour.
    assert np.max(np.abs(fitted - exact)) < 0.04, (fitted, exact)
    assert exact.max() > 0.05  # a coloured film, not a near-zero comparison


def test_film_vanishes_with_its_thickness_and_grows_toward_grazing():
    # The film's index goes to air's as t → 0; the reference's clamp of R12·R23 to 1e-5 leaves
    # under 0.01 (three.js then drops the film altogether).
    assert np.allclose(irid.film_fresnel(np.array(1.0), 1.6, np.array(0.0)), 0.0, atol=0.01)
    glancing = irid.film_fresnel(np.array([1.0, 0.2]), 1.6, np.array([400.0, 400.0]))
    assert glancing[1].mean() > glancing[0].mean()


def test_ggx_lobe_in_closed_form_at_the_mirror_configuration():
    """l = v = n: D = 1/(π α²) (Walter et al. 2007 Eq. 33 at θ_h = 0) and V = 1/4, so the lobe
    π·D·V = 1/(4 α²)."""
    for roughness in (0.3, 0.6):
        alpha = roughness**2
        n = np.array([[0.0, 0.0, 1.0]])
        lobe = irid.ggx_lobe(n, n, np.array([roughness]))
        # V(1, 1) = 1/4: π · 1/(π α²) · 1/4.
        assert lobe[0] == pytest.approx(1.0 / (4.0 * alpha**2), rel=1e-6)


@pytest.mark.parametrize("thickness", [200.0, 450.0])
@pytest.mark.parametrize("n_substrate", [1.2, 2.4])
def test_film_over_a_substrate_is_the_airy_sum_seen_in_rec709(thickness, n_substrate):
    """A film of index 1.56 on a substrate of index ``n_substrate`` (given as its F0 in air, as
    the extension derives the index back from it): against the exact Airy reflectance, lower
    and higher than the film (phase shift π and 0 at the base)."""
    wavelengths = np.arange(360.0, 831.0, 1.0)
    spectrum = thin_film_reflectance(wavelengths, thickness, 1.56, n_substrate)
    cmf = colour.cmfs(wavelengths)
    exact = (spectrum @ cmf / cmf[:, 1].sum()) @ irid.XYZ_TO_REC709.T
    f0 = ((n_substrate - 1.0) / (n_substrate + 1.0)) ** 2
    fitted = irid.film_fresnel(np.array(1.0), 1.56, np.array(thickness), np.full(3, f0))
    assert np.max(np.abs(fitted - exact)) < 0.04, (fitted, exact)
    assert np.ptp(exact) > 0.03  # coloured
    # Per channel, on one side of the film's index (the search relies on it): each channel of a
    # mixed substrate is that channel of its own uniform one.
    other = 0.3 if f0 > 0.05 else 0.02  # the film's own F0 is 0.048
    mixed = irid.film_fresnel(np.array(0.8), 1.56, np.array(thickness), np.array([f0, f0, other]))
    alone = irid.film_fresnel(np.array(0.8), 1.56, np.array(thickness), np.full(3, f0))
    assert np.allclose(mixed[:2], alone[:2]) and not np.isclose(mixed[2], alone[2])


@pytest.mark.parametrize("roughness", [0.35, 0.7, 1.0])
def test_specular_albedo_against_a_quadrature_over_light_directions(roughness):
    """The lobe's white-furnace albedo (importance sampled over half vectors) against a plain
    midpoint quadrature of ∫ D V (n·l) dω_l over the hemisphere of light directions."""
    theta = (np.arange(400) + 0.5) * (np.pi / 2) / 400
    phi = (np.arange(400) + 0.5) * (2 * np.pi) / 400
    t, p = np.meshgrid(theta, phi, indexing="ij")
    light = np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)], -1).reshape(-1, 3)
    solid = (np.sin(t) * (np.pi / 2 / 400) * (2 * np.pi / 400)).ravel()
    for cos_view in (1.0, 0.6, 0.25):
        view = np.array([np.sqrt(1 - cos_view**2), 0.0, cos_view])
        lobe = irid.ggx_lobe(
            light, np.broadcast_to(view, light.shape), np.full(len(light), roughness)
        )
        quadrature = np.sum(lobe / np.pi * light[:, 2] * solid)  # ggx_lobe is π D V
        sampled = irid.specular_albedo(np.array([roughness]), np.array([cos_view]))[0]
        assert sampled == pytest.approx(quadrature, rel=0.01), (cos_view, sampled, quadrature)
        assert 0.3 < sampled <= 1.0


def test_fit_recovers_a_film_it_was_given():
    rng = np.random.default_rng(3)
    n = 40
    light = np.tile(irid.tilted_views([25.0]), (n, 1))
    views = np.tile(irid.VIEWS[None], (n, 1, 1))
    base = rng.uniform(0.0, 0.3, (n, 3))
    weight = rng.choice(irid.WEIGHT_GRID, n)
    thickness = rng.choice(np.arange(200.0, 800.0, irid.FREE_STEP_NM), n)
    roughness = rng.choice(irid.ROUGHNESS_GRID[:4], n)
    _, above = irid.substrate_grid(1.56)
    substrate = rng.choice(above, (n, 3))
    substrate[: n // 2] = 0.0  # half free-standing films
    target = irid.glTF_reflectance(
        base, weight, thickness, light, views, roughness, 1.56, substrate
    )
    fit = irid.fit_film(target, light, views, 1.56)
    assert np.max(np.abs(fit.reflectance - target)) < 0.01
    assert np.mean(np.abs(fit.thickness_nm - thickness) < 1.0) > 0.9
    assert np.mean(np.all(fit.substrate == substrate, axis=1)) > 0.9
    near = irid.fit_film(target, light, views, 1.56, prior_nm=thickness + 20.0)
    assert np.all(np.abs(near.thickness_nm - thickness - 20.0) <= 30.0)
    again = irid.fit_base(
        target, light, views, fit.weight, fit.thickness_nm, fit.roughness, 1.56, fit.substrate
    )
    assert np.allclose(again.base, fit.base, atol=0.01)


def test_base_of_a_given_film_is_the_one_the_search_keeps_where_no_film_fits_exactly():
    """Where the target is not a glTF look (here: one scaled view by view), the base that
    completes a film is a compromise between the views; :func:`fit_base` must weigh them as the
    search does (its relative error, the view weights), or the texels handed a film get another
    base than the search chose (an unweighted base shifted the eye's outer ring by ΔE 3 face-on)."""
    rng = np.random.default_rng(7)
    n = 40
    light = np.tile(irid.tilted_views([25.0]), (n, 1))
    views = np.tile(irid.VIEWS[None], (n, 1, 1))
    film = irid.glTF_reflectance(
        rng.uniform(0.05, 0.3, (n, 3)),
        rng.choice(irid.WEIGHT_GRID, n),
        rng.choice(np.arange(200.0, 800.0, irid.FREE_STEP_NM), n),
        light,
        views,
        rng.choice(irid.ROUGHNESS_GRID[:4], n),
        1.45,
        np.zeros((n, 3)),
    )
    target = film * rng.uniform(0.3, 3.0, (n, len(irid.VIEWS), 1))
    fit = irid.fit_film(target, light, views, 1.45)
    again = irid.fit_base(
        target, light, views, fit.weight, fit.thickness_nm, fit.roughness, 1.45, fit.substrate
    )
    assert np.allclose(again.base, fit.base, atol=0.01)
    assert np.allclose(
        irid.fit_error(again.reflectance, target),
        irid.fit_error(fit.reflectance, target),
        rtol=0.05,
    )
    assert np.mean(irid.fit_error(fit.reflectance, target)) > 0.05  # not an exact fit


def test_viewer_views_turn_the_eye_about_the_vertical_and_tend_to_the_distant_views():
    """The views a viewer at a finite distance gives the fit (pipeline/export/look.py): toward the
    eye, face-on and turned by each fit tilt about the vertical through the pivot; from far
    away, the distant viewer's :data:`~pavonine.pipeline.export.iridescence.VIEWS`."""
    from pavonine.pipeline.export.look import viewer_views

    points = np.array([[0.0, 0.0, 0.0], [3.0, 22.0, -1.0]])
    pivot = np.array([0.5, 15.0, -1.0])
    far = viewer_views(points, pivot + np.array([0.0, 0.0, 1e7]), pivot)
    assert np.allclose(far, irid.VIEWS[None], atol=1e-5)
    near = viewer_views(points, (0.0, 17.0, 36.0), pivot)
    face = irid.FIT_TILTS_DEG.index(0.0)
    toward = np.array([-3.0, -5.0, 37.0])
    assert np.allclose(near[1, face], toward / np.linalg.norm(toward))
    # turned by TILT_DEG about +Y through the pivot: the eye keeps its height and its distance
    # from the axis, and moves to the feather's left (−X) for a negative tilt
    tilted = irid.FIT_TILTS_DEG.index(irid.TILT_DEG)
    eye = points[0] + near[0, tilted] * (17.0 / near[0, tilted, 1])
    assert np.isclose(np.hypot(*(eye - pivot)[[0, 2]]), np.hypot(-0.5, 37.0))
    assert eye[0] < 0.0
    angle = np.degrees(np.arctan2(eye[0] - pivot[0], eye[2] - pivot[2]))
    start = np.degrees(np.arctan2(-0.5, 37.0))
    assert np.isclose(angle - start, irid.TILT_DEG)
