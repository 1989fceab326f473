"""How a render is split into passes (each pass is one traced ``mi.render`` call)."""

from __future__ import annotations

from pavonine.render.passes import LANES_PER_PASS, samples_per_pass


def test_a_full_size_train_frame_is_two_passes_not_sixteen():
    """Each pass re-traces the whole path tracer (per instance of a train), so a 1024×768 frame
    at 64 spp, the README's and the train benchmark's, is two passes of 32 samples."""
    assert samples_per_pass(64, 1024 * 768, moments=False) == 32


def test_passes_divide_spp_and_stay_within_the_lane_budget():
    for spp in (1, 3, 16, 64, 100, 256):
        for pixels in (12 * 12, 256 * 192, 1024 * 768, 3840 * 2160):
            per_pass = samples_per_pass(spp, pixels, moments=False)
            assert spp % per_pass == 0
            assert per_pass == 1 or per_pass * pixels <= LANES_PER_PASS


def test_moments_still_get_at_least_sixteen_passes():
    assert 64 // samples_per_pass(64, 1024 * 768, moments=True) >= 16
    assert 64 // samples_per_pass(64, 16 * 16, moments=True) >= 16
