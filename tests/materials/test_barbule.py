"""The paper's §5 red shift with observer tilt, with the barbule's macro-geometry (issue 24).

A tilted or twisted barbule moves where its lobe is bright, not the colour of a reflection: a
specular facet joining ω_i and ω_o meets the light at θ_d = half the angle between them, whatever
the facet's tilt, and the stacks' reflectance depends on θ_d alone. So the peak still moves to
the blue as the observer tilts (docs/model.md, "A claim of the paper neither mode reproduces").
"""

import numpy as np
import pytest

from pavonine.materials import optics
from pavonine.materials.parameters import ParameterError, preset

OBSERVE = [15.0, 30.0, 45.0, 60.0]


@pytest.mark.parametrize("tilt", [0.0, 15.0, 30.0])
@pytest.mark.parametrize("twist", [0.0, 10.0])
@pytest.mark.parametrize("azimuth", [0.0, 90.0])
def test_a_tilted_or_twisted_barbule_still_shifts_to_the_blue(tilt, twist, azimuth):
    params = preset("blue").with_(interference="physical")
    summaries = optics.summarise(
        params,
        0.0,
        OBSERVE,
        azimuth_deg=azimuth,
        barbule_tilt_deg=tilt,
        barbule_twist_deg=twist,
    )
    peaks = np.array([s.peak_nm for s in summaries])
    assert np.all(np.diff(peaks) < 0), peaks  # measured: 519.6, 515.6, 508.0, 499.9 nm
    assert peaks[0] - peaks[-1] > 15.0


def test_barbule_angles_are_checked():
    with pytest.raises(ParameterError) as info:
        optics.reflectance_spectra(preset("blue"), 0.0, [20.0], barbule_tilt_deg=75.0)
    assert info.value.field == "barbule_tilt"
