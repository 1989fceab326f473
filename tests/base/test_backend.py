"""Mitsuba back-end selection: finding libLLVM and falling back with one warning."""

import os
import subprocess
import sys
from pathlib import Path

import pytest

from pavonine.base import backend


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
        "import warnings, pavonine.base.backend as b\n"
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


LLVM15 = "/usr/lib/x86_64-linux-gnu/libLLVM-15.so.1"


def _select_with(libllvm: str, cache: Path) -> tuple[str, str, int]:
    """select_variant() in a fresh process with DRJIT_LIBLLVM_PATH=libllvm: variant, warnings,
    and the exit status (an unusable library used to abort the process natively)."""
    code = (
        "import warnings, pavonine.base.backend as b\n"
        "with warnings.catch_warnings(record=True) as w:\n"
        "    warnings.simplefilter('always')\n"
        "    chosen = b.select_variant()\n"
        "import mitsuba as mi\n"
        "v = mi.Vector3f(1.0, 2.0, 3.0)\n"
        "print(chosen.variant, mi.variant(), float(v[2]))\n"
        "print(' | '.join(str(m.message) for m in w))\n"
    )
    env = {**os.environ, "DRJIT_LIBLLVM_PATH": libllvm, "PAVONINE_CACHE_DIR": str(cache)}
    env.pop("PAVONINE_VARIANT", None)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env)
    lines = [*out.stdout.splitlines(), "", ""]
    return lines[0], lines[1], out.returncode


@pytest.mark.mitsuba
def test_user_libllvm_too_old_by_name_falls_back_to_scalar(tmp_path):
    fake = tmp_path / "libLLVM-15.so"
    fake.write_bytes(b"\x7fELF not really")
    variant, warned, status = _select_with(str(fake), tmp_path / "cache")
    assert status == 0 and variant.startswith("scalar_spectral")
    assert "is LLVM 15; Dr.Jit needs LLVM >= 16" in warned and "scalar_spectral" in warned


@pytest.mark.mitsuba
def test_user_libllvm_not_a_library_falls_back_to_scalar(tmp_path):
    lib = tmp_path / "libcustom.so"
    lib.write_text("not a library\n")
    variant, warned, status = _select_with(str(lib), tmp_path / "cache")
    assert status == 0 and variant.startswith("scalar_spectral"), warned
    assert f"{lib} is not usable" in warned


@pytest.mark.mitsuba
@pytest.mark.skipif(not os.path.exists(LLVM15), reason=f"needs Debian's LLVM 15 ({LLVM15})")
def test_user_libllvm_15_under_another_name_is_probed_and_falls_back(tmp_path):
    """LLVM 15 loads but aborts the process at the first kernel ('Cannot select: fminimum'):
    only the subprocess probe can tell, since the name carries no version."""
    lib = tmp_path / "libcustom.so"
    lib.symlink_to(LLVM15)
    variant, warned, status = _select_with(str(lib), tmp_path / "cache")
    assert status == 0 and variant.startswith("scalar_spectral"), warned
    assert "Cannot select" in warned or "signal" in warned


def test_probe_verdict_is_cached_per_path_and_mtime(tmp_path, monkeypatch):
    monkeypatch.setenv("PAVONINE_CACHE_DIR", str(tmp_path / "cache"))
    lib = tmp_path / "libcustom.so"
    lib.write_text("v1")
    calls = []
    monkeypatch.setattr(backend, "_run_probe", lambda path: calls.append(path) or (False, "no"))
    monkeypatch.setattr(backend, "_probed", {})
    assert backend.probe_libllvm(str(lib)) == (False, "no")
    backend._probed.clear()  # a new process: only the cache file remains
    assert backend.probe_libllvm(str(lib)) == (False, "no")
    assert len(calls) == 1 and backend.probe_cache_path().is_file()
    os.utime(lib, ns=(0, 10**18))  # replaced library: probed again
    backend.probe_libllvm(str(lib))
    assert len(calls) == 2


@pytest.mark.mitsuba
def test_user_libllvm_that_does_not_exist_falls_back_with_a_warning(tmp_path):
    variant, warned, status = _select_with(str(tmp_path / "libLLVM-19.so"), tmp_path / "cache")
    assert status == 0 and variant.startswith("scalar_spectral")
    assert "is not a file" in warned


def test_drjit_that_cannot_load_is_not_a_verdict_on_the_libllvm(tmp_path, monkeypatch):
    """When the probe cannot even import Dr.Jit (libatomic missing), that is no verdict on the
    library (``probe_libllvm`` raises :class:`RendererUnavailable`), nothing is cached against the
    libLLVM (installing libatomic1 must take effect at once) and ``select_variant`` raises
    :class:`RendererUnavailable` naming the library, once per process, without probing again."""
    monkeypatch.setenv("PAVONINE_CACHE_DIR", str(tmp_path / "cache"))
    lib = tmp_path / "libLLVM-19.so"
    lib.write_text("v1")
    monkeypatch.setenv("DRJIT_LIBLLVM_PATH", str(lib))
    calls = []

    def no_drjit(args, **kwargs):
        calls.append(args)
        message = "Dr.Jit cannot load: libatomic.so.1: cannot open shared object file\n"
        return subprocess.CompletedProcess(args, backend.NO_DRJIT_STATUS, "", message)

    monkeypatch.setattr(backend.subprocess, "run", no_drjit)
    for name, value in (("_probed", {}), ("_selected", None), ("_unavailable", None)):
        monkeypatch.setattr(backend, name, value)
    with pytest.raises(backend.RendererUnavailable, match=r"libatomic\.so\.1"):
        backend.probe_libllvm(str(lib))
    assert not backend.probe_cache_path().exists() and not backend._probed
    for _ in range(2):
        with pytest.raises(backend.RendererUnavailable, match=r"libatomic\.so\.1"):
            backend.select_variant()
    assert len(calls) == 2  # the probe above, then one in select_variant: remembered after it
