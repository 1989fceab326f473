"""Mitsuba back-end selection: finding libLLVM and falling back with one warning."""

import subprocess
import sys

import pytest

from pavonine import backend


def test_llvm_major_parsing():
    assert backend._llvm_major("/usr/lib/x86_64-linux-gnu/libLLVM-19.so") == 19
    assert backend._llvm_major("/usr/lib/llvm-17/lib/libLLVM.so.17.0") == 17
    assert backend._llvm_major("/usr/lib/x86_64-linux-gnu/libLLVM-15.so.1") == 15


def test_found_llvm_is_new_enough():
    found = backend.find_libllvm()
    if found is not None:
        assert found[1] >= backend.MIN_LLVM_MAJOR


@pytest.mark.mitsuba
def test_fallback_to_scalar_warns_once():
    """With no usable LLVM, select_variant falls back to scalar_spectral with one warning."""
    code = (
        "import warnings, pavonine.backend as b\n"
        "b.find_libllvm = lambda min_major=16: None\n"
        "with warnings.catch_warnings(record=True) as w:\n"
        "    warnings.simplefilter('always')\n"
        "    chosen = b.select_variant()\n"
        "    b.select_variant()\n"
        "print(chosen.variant, len(w), str(w[0].message))\n"
    )
    env = {k: v for k, v in __import__("os").environ.items() if k != "DRJIT_LIBLLVM_PATH"}
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, env=env, check=True
    )
    variant, count, message = out.stdout.split(" ", 2)
    assert variant == "scalar_spectral" and count == "1"
    assert "libLLVM" in message and "scalar_spectral" in message
