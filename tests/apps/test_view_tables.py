"""The BRDF table ``pavonine view``'s shader samples agrees with the BRDF of materials/.

:func:`tables.table_brdf_rgb` is the shader's formula (``static/feather.js``) in NumPy; it is held
against :class:`pavonine.materials.brdf.FeatherModel` itself (spectral, then to linear RGB) at
random light and view directions for every class of the shipped eye, and the sky albedo against
an independent finer quadrature of the BRDF itself.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from pavonine.apps.view import tables
from pavonine.materials.brdf import direction
from pavonine.materials.colour import delta_e2000, linear_srgb_to_lab

EYE = (
    Path(__file__).resolve().parents[2] / "assets" / "feathers" / "eye_feather" / "eye_feather.usd"
)


@pytest.fixture(scope="module")
def eye():
    from pxr import Usd, UsdShade

    from pavonine.schemas import authoring

    stage = Usd.Stage.Open(str(EYE))
    material = UsdShade.Material(stage.GetPrimAtPath("/eye_feather/Materials/Feather"))
    params = authoring.read_feather_parameters(material).validate()
    return params, tables.build_table(params)


def _radiance(f: np.ndarray, wo: np.ndarray) -> np.ndarray:
    """``π f cos θ_o`` (the render's radiance under the shipped sun, E = π), clipped at 0."""
    return np.clip(math.pi * f * wo[..., 2:3], 0.0, None)


@pytest.mark.parametrize("gradation", [0.0, 0.37, 1.0])
def test_table_matches_the_brdf_at_random_angles(eye, gradation):
    params, table = eye
    rng = np.random.default_rng(7)
    count = 40
    wi = direction(rng.uniform(0, 75, count), rng.uniform(0, 360, count))
    wo = direction(rng.uniform(0, 75, count), rng.uniform(0, 360, count))
    for k in range(len(params.classes)):
        a = _radiance(tables.table_brdf_rgb(table, wi, wo, k, gradation), wo)
        b = _radiance(tables.brdf_rgb(params, wi, wo, k, gradation), wo)
        lit = b.max(axis=-1) > 1e-3  # ΔE of near-black pixels says nothing
        de = delta_e2000(linear_srgb_to_lab(a[lit]), linear_srgb_to_lab(b[lit]))
        assert lit.sum() > 10
        assert de.max() < 1.0, (k, float(de.max()))
        assert np.abs(a - b).max() < 0.02 * b.max() + 1e-3


def test_table_agrees_where_the_highlight_is(eye):
    """Near the mirror direction (the structural colour's peak), per class, to ΔE00 0.5."""
    params, table = eye
    wi = direction(np.array([20.0, 30.0, 45.0]), np.array([0.0, 60.0, 130.0]))
    wo = direction(np.array([22.0, 28.0, 44.0]), np.array([181.0, 238.0, 312.0]))
    for k in range(len(params.classes)):
        a = _radiance(tables.table_brdf_rgb(table, wi, wo, k, 0.5), wo)
        b = _radiance(tables.brdf_rgb(params, wi, wo, k, 0.5), wo)
        assert b.max() > 0.05
        assert delta_e2000(linear_srgb_to_lab(a), linear_srgb_to_lab(b)).max() < 0.5


def test_melanin_share_mixes_in_the_brown(eye):
    params, table = eye
    wi, wo = direction(10.0, 0.0), direction(30.0, 180.0)
    a = tables.table_brdf_rgb(table, wi, wo, 2, 0.5, share=0.3)
    b = tables.brdf_rgb(params, wi, wo, 2, 0.5, share=0.3)
    assert np.allclose(a, b, rtol=0.03, atol=1e-3)


def test_sky_albedo_matches_a_finer_quadrature_of_the_brdf(eye):
    """``A(k, t, θ_o)`` against a 48×96 cosine-weighted quadrature of the BRDF itself."""
    params, table = eye
    lights = tables._hemisphere(48, 96)
    steps = table.albedo.shape[2]
    for k in (0, 4):
        for i in (0, steps // 2):
            theta = 89.0 * i / (steps - 1)
            f = np.mean(
                [
                    tables.brdf_rgb(params, direction(theta, phi), lights, k, 0.5)
                    for phi in tables.ALBEDO_AZIMUTHS_DEG
                ],
                axis=0,
            )
            reference = math.pi * f.mean(axis=0)
            got = table.albedo[k, 5, i]
            assert np.abs(got - reference).max() < 0.05 * np.abs(reference).max() + 2e-3, (
                k,
                i,
                got,
                reference,
            )
