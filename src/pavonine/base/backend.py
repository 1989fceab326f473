"""Mitsuba back-end selection, shared by every part of Pavonine that renders or JIT-evaluates.

Mitsuba's fast ``llvm_*`` variants need a shared libLLVM >= 16 (Dr.Jit fails on LLVM 15 with
"Cannot select: fminimum"). :func:`find_libllvm` locates one and :func:`select_variant` points
``DRJIT_LIBLLVM_PATH`` at it *before* Dr.Jit loads, then picks ``llvm_ad_spectral``; without a
usable LLVM it falls back to ``scalar_spectral`` with one warning. A library that is too old or
not a library at all aborts the process natively (``LLVM ERROR``, SIGFPE) the first time Dr.Jit
compiles a kernel, so :func:`probe_libllvm` first compiles one in a *subprocess*; its verdict is
cached per (path, size, mtime, Dr.Jit version) in :func:`probe_cache_path`, so it costs once. :func:`set_threads` bounds the
worker threads of Dr.Jit, OpenImageIO and the BLAS/OpenMP libraries; :class:`thread_limit` does
it for one block and puts the previous limits back (``--threads``).
"""

from __future__ import annotations

import contextlib
import glob
import importlib.util
import json
import os
import re
import subprocess
import sys
import tempfile
import warnings
from dataclasses import dataclass
from pathlib import Path

MIN_LLVM_MAJOR = 16
FAST_VARIANT = "llvm_ad_spectral"
FALLBACK_VARIANT = "scalar_spectral"

_SEARCH_GLOBS = (
    "/usr/lib/x86_64-linux-gnu/libLLVM-*.so*",
    "/usr/lib/aarch64-linux-gnu/libLLVM-*.so*",
    "/usr/lib/llvm-*/lib/libLLVM*.so*",
    "/usr/lib64/libLLVM*.so*",
    "/usr/local/lib/libLLVM*.so*",
    "/opt/homebrew/opt/llvm/lib/libLLVM*.dylib",
    "/usr/local/opt/llvm/lib/libLLVM*.dylib",
)


class BackendWarning(UserWarning):
    """Raised (as a warning) when Pavonine has to fall back to a slow scalar variant."""


class RendererUnavailable(ImportError):
    """Dr.Jit (so Mitsuba) is installed but cannot load: a system library it needs is missing
    (Debian's ``libatomic1``). The message is one line naming the library."""


@dataclass(frozen=True)
class Backend:
    """What :func:`select_variant` chose."""

    variant: str
    libllvm: str | None
    llvm_major: int | None
    reason: str


_selected: Backend | None = None
#: Why Dr.Jit cannot load in this process, once :func:`select_variant` found out.
_unavailable: str | None = None
_threads: int | None = None

#: Read by OpenMP/BLAS libraries (NumPy, SciPy, pymeshlab) when they load, and by child processes.
THREAD_ENV_VARS = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")


def set_threads(count: int | None) -> None:
    """Use at most ``count`` worker threads (``None``: one per core, the libraries' default).

    Applies at once to Dr.Jit and OpenImageIO when loaded (and to Dr.Jit when
    :func:`select_variant` loads it later); sets :data:`THREAD_ENV_VARS` for libraries loaded after
    this call and for worker processes.
    """
    global _threads
    _threads = count
    if count is None:
        return
    for name in THREAD_ENV_VARS:
        os.environ[name] = str(count)
    if "drjit" in sys.modules:
        sys.modules["drjit"].set_thread_count(count)
    try:
        import OpenImageIO as oiio
    except ImportError:
        return
    oiio.attribute("threads", count)


def thread_count() -> int | None:
    """The thread limit set by :func:`set_threads` (``None``: one per core)."""
    return _threads


class thread_limit(contextlib.AbstractContextManager):
    """Use at most ``count`` worker threads inside the ``with`` block (``None``: leave them as
    they are), then restore what was in force before, whether the block succeeded or raised:
    :func:`thread_count`, the :data:`THREAD_ENV_VARS`, Dr.Jit's pool (back to one thread per
    core when Dr.Jit loaded inside the block) and OpenImageIO's ``threads`` attribute.

    A class, not a generator, for the reason :class:`pavonine.base.limits.pixel_budget` gives: an
    abandoned generator would restore old limits whenever the garbage collector finds it.
    """

    def __init__(self, count: int | None) -> None:
        self._count = count
        self._before: tuple | None = None

    def __enter__(self) -> None:
        if self._count is None:
            return
        drjit = sys.modules.get("drjit")
        self._before = (
            _threads,
            {name: os.environ.get(name) for name in THREAD_ENV_VARS},
            drjit.thread_count() if drjit is not None else None,
            _oiio_threads(),
        )
        set_threads(self._count)

    def __exit__(self, *exc_info: object) -> None:
        if self._before is None:
            return
        global _threads
        _threads, environ, drjit_count, oiio_count = self._before
        self._before = None
        for name, value in environ.items():
            if value is None:
                os.environ.pop(name, None)
            else:
                os.environ[name] = value
        if "drjit" in sys.modules:
            sys.modules["drjit"].set_thread_count(drjit_count or os.cpu_count() or 1)
        if oiio_count is not None:
            import OpenImageIO as oiio

            oiio.attribute("threads", oiio_count)


def _oiio_threads() -> int | None:
    """OpenImageIO's ``threads`` attribute, or ``None`` when OpenImageIO is not installed."""
    try:
        import OpenImageIO as oiio
    except ImportError:
        return None
    return oiio.get_int_attribute("threads")


def _llvm_major(path: str) -> int | None:
    """LLVM major version encoded in a library file name (``libLLVM-19.so``, ``libLLVM.so.19.1``)."""
    name = os.path.basename(path)
    match = re.search(r"libLLVM[-.]?(\d+)", name) or re.search(r"\.so\.(\d+)", name)
    if match:
        return int(match.group(1))
    match = re.search(r"llvm-(\d+)", path)
    return int(match.group(1)) if match else None


def find_libllvm(min_major: int = MIN_LLVM_MAJOR) -> tuple[str, int] | None:
    """Newest shared libLLVM with major version >= ``min_major``, as ``(path, major)``.

    A ``DRJIT_LIBLLVM_PATH`` already set by the user wins when the file exists.
    """
    preset = os.environ.get("DRJIT_LIBLLVM_PATH")
    if preset and os.path.exists(preset):
        major = _llvm_major(preset)
        return preset, major if major is not None else min_major
    found: list[tuple[int, str]] = []
    for pattern in _SEARCH_GLOBS:
        for path in glob.glob(pattern):
            major = _llvm_major(path)
            if major is not None and major >= min_major and os.path.isfile(path):
                found.append((major, path))
    if not found:
        return None
    major, path = max(found, key=lambda item: (item[0], -len(item[1])))
    return path, major


#: Exit status of the probe when Dr.Jit itself cannot load: a verdict on the system, not on the
#: libLLVM, so it is not cached (installing the library must take effect at once).
NO_DRJIT_STATUS = 3
#: What the probe runs after :func:`first_import_error`'s definition (see :func:`_probe_code`): a
#: kernel using the min/max that LLVM < 16 cannot select (``fminimum``).
_PROBE_BODY = """
import sys
try:
    import drjit as dr
except Exception as exc:  # Dr.Jit hides the ImportError of a missing .so behind a NameError
    print("Dr.Jit cannot load:", first_import_error(exc), file=sys.stderr)
    raise SystemExit(NO_DRJIT_STATUS)
if not dr.has_backend(dr.JitBackend.LLVM):
    raise SystemExit("Dr.Jit could not initialise its LLVM back-end with this library")
from drjit.llvm import Float
x = dr.minimum(Float([1.0, 2.0]), Float([2.0, 1.0])) + dr.maximum(Float([1.0, 2.0]), Float(0.5))
dr.eval(x)
if [float(v) for v in x] != [2.0, 3.0]:
    raise SystemExit(f"wrong result {list(x)}")
print("ok")
""".replace("NO_DRJIT_STATUS", str(NO_DRJIT_STATUS))
#: Seconds a probe may take (compiling one kernel takes well under one).
PROBE_TIMEOUT = 60.0
_probed: dict[tuple, tuple[bool, str]] = {}


def probe_cache_path() -> Path:
    """Where probe verdicts are kept: ``$PAVONINE_CACHE_DIR`` or ``$XDG_CACHE_HOME/pavonine``
    (``~/.cache/pavonine``), file ``libllvm-probe.json``."""
    folder = os.environ.get("PAVONINE_CACHE_DIR") or os.path.join(
        os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache"),
        "pavonine",
    )
    return Path(folder) / "libllvm-probe.json"


def _probe_key(path: str) -> tuple:
    from importlib.metadata import PackageNotFoundError, version

    info = os.stat(path)
    try:
        drjit = version("drjit")
    except PackageNotFoundError:
        drjit = "none"
    return (os.path.realpath(path), info.st_size, info.st_mtime_ns, drjit)


def _read_cache() -> dict:
    try:
        data = json.loads(probe_cache_path().read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return {}
    return data if isinstance(data, dict) else {}


def _write_cache(key: str, verdict: tuple[bool, str]) -> None:
    """Record ``verdict`` (best effort: an unwritable cache only costs a probe next time)."""
    path = probe_cache_path()
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        data = _read_cache()
        data[key] = list(verdict)
        fd, tmp = tempfile.mkstemp(prefix=".libllvm-probe.", dir=path.parent)
        with os.fdopen(fd, "w", encoding="utf-8") as handle:
            json.dump(data, handle, indent=1)
        os.replace(tmp, path)
    except OSError:
        return


def _probe_code() -> str:
    """The probe's program: this module's :func:`first_import_error` (one implementation; the
    probe runs in a bare interpreter that need not import Pavonine), then :data:`_PROBE_BODY`."""
    import inspect

    return inspect.getsource(first_import_error) + _PROBE_BODY


def _run_probe(path: str) -> tuple[bool, str]:
    """The verdict of one probe subprocess on the libLLVM at ``path``; raises
    :class:`RendererUnavailable` when the subprocess could not even import Dr.Jit."""
    env = {**os.environ, "DRJIT_LIBLLVM_PATH": path}
    try:
        done = subprocess.run(
            [sys.executable, "-c", _probe_code()],
            env=env,
            capture_output=True,
            text=True,
            timeout=PROBE_TIMEOUT,
            check=False,
        )
    except subprocess.TimeoutExpired:
        return False, f"a test kernel did not finish within {PROBE_TIMEOUT:g} s"
    except OSError as exc:
        return False, f"cannot start the probe ({exc.strerror or exc})"
    if done.returncode == 0 and done.stdout.strip().endswith("ok"):
        return True, "ok"
    if done.returncode == NO_DRJIT_STATUS and "Dr.Jit cannot load" in done.stderr:
        raise RendererUnavailable(done.stderr.strip().splitlines()[-1])
    lines = [line.strip() for line in (done.stderr + done.stdout).splitlines() if line.strip()]
    detail = next((line for line in lines if "LLVM ERROR" in line or "Unable to load" in line), "")
    detail = detail or (lines[-1] if lines else "")
    status = (
        f"killed by signal {-done.returncode}"
        if done.returncode < 0
        else f"exit status {done.returncode}"
    )
    return False, f"a test kernel failed ({status}{': ' + detail[:200] if detail else ''})"


def probe_libllvm(path: str) -> tuple[bool, str]:
    """Whether Dr.Jit can compile and run a kernel with the libLLVM at ``path``, and why not.

    Runs in a subprocess, because an unusable library aborts the process that loads it. The
    verdict is cached in memory and in :func:`probe_cache_path` per (path, size, mtime, Dr.Jit
    version): a replaced library is probed again. When Dr.Jit itself cannot load, the verdict is
    about the system, not the library: :class:`RendererUnavailable` is raised, and nothing is
    cached or memoised.
    """
    try:
        key = _probe_key(path)
    except OSError as exc:
        return False, f"cannot read it ({exc.strerror or exc})"
    if key in _probed:
        return _probed[key]
    text_key = json.dumps(key)
    cached = _read_cache().get(text_key)
    if (
        isinstance(cached, list)
        and len(cached) == 2
        and isinstance(cached[0], bool)
        and isinstance(cached[1], str)
    ):
        verdict = (cached[0], cached[1])
    else:
        verdict = _run_probe(path)  # RendererUnavailable: about the system, not this library
        _write_cache(text_key, verdict)
    _probed[key] = verdict
    return verdict


def usable_libllvm(min_major: int = MIN_LLVM_MAJOR) -> tuple[tuple[str, int] | None, str]:
    """:func:`find_libllvm`'s library if it passes :func:`probe_libllvm`, and why not otherwise.

    A ``DRJIT_LIBLLVM_PATH`` the user set to an unusable library (missing, older than
    ``min_major`` by its name, or failing the probe) gives ``None``: Pavonine does not silently
    use another one. Raises :class:`RendererUnavailable` when Dr.Jit itself cannot load.
    """
    preset = os.environ.get("DRJIT_LIBLLVM_PATH")
    if preset and not os.path.isfile(preset):
        return None, f"DRJIT_LIBLLVM_PATH={preset} is not a file"
    lib = find_libllvm(min_major)
    if lib is None:
        return None, f"no shared libLLVM >= {min_major} found"
    path, major = lib
    if _llvm_major(path) is not None and major < min_major:
        return None, f"{path} is LLVM {major}; Dr.Jit needs LLVM >= {min_major}"
    ok, reason = probe_libllvm(path)
    if not ok:
        return None, f"{path} is not usable: {reason}"
    return lib, "ok"


def select_variant(preferred: str | None = None) -> Backend:
    """Set the Mitsuba variant once per process and return what was chosen.

    ``preferred`` (or ``PAVONINE_VARIANT``) forces a variant; a forced ``llvm_*`` variant without
    a usable LLVM still falls back to the scalar variant of the same colour mode, with a warning.
    Raises :class:`RendererUnavailable` when Dr.Jit cannot load at all (no variant can run).
    """
    global _selected, _unavailable
    wanted = preferred or os.environ.get("PAVONINE_VARIANT") or FAST_VARIANT
    if _selected is not None and (_selected.variant == wanted or preferred is None):
        return _selected

    if _unavailable is not None:  # once per process: the system does not change under it
        raise RendererUnavailable(_unavailable)
    for module in ("drjit", "mitsuba"):  # not installed (no [render] extra): as importing says
        if importlib.util.find_spec(module) is None:
            raise ModuleNotFoundError(f"No module named {module!r}", name=module)
    try:
        lib, why = usable_libllvm() if wanted.startswith("llvm_") else (find_libllvm(), "")
    except RendererUnavailable as exc:
        _unavailable = str(exc)
        raise
    if wanted.startswith("llvm_") and lib is None:
        fallback = (
            "scalar_" + wanted.split("_", 2)[-1] if wanted.count("_") >= 2 else FALLBACK_VARIANT
        )
        warnings.warn(
            f"pavonine: {why} (install Debian's libllvm19 or set DRJIT_LIBLLVM_PATH to a "
            f"libLLVM >= {MIN_LLVM_MAJOR}); falling back to the slow '{fallback}' Mitsuba variant",
            BackendWarning,
            stacklevel=2,
        )
        wanted, reason = fallback, "no usable libLLVM"
    else:
        reason = "requested" if preferred or os.environ.get("PAVONINE_VARIANT") else "default"
    if lib is not None:
        os.environ["DRJIT_LIBLLVM_PATH"] = lib[0]

    try:
        import drjit as dr
        import mitsuba as mi
    except Exception as exc:  # a missing system library: ImportError, or a NameError hiding it
        _unavailable = f"Dr.Jit cannot load: {first_import_error(exc)}"
        raise RendererUnavailable(_unavailable) from None

    mi.set_variant(wanted)
    if _threads is not None:
        dr.set_thread_count(_threads)
    _selected = Backend(
        variant=wanted,
        libllvm=lib[0] if lib and wanted.startswith("llvm_") else None,
        llvm_major=lib[1] if lib and wanted.startswith("llvm_") else None,
        reason=reason,
    )
    return _selected


def first_import_error(error: BaseException) -> str:
    """The first ImportError in ``error``'s chain (Dr.Jit hides it behind a NameError), one line."""
    seen: BaseException | None = error
    while seen is not None and not isinstance(seen, ImportError):
        seen = seen.__context__
    return " ".join(str(seen or error).split())


#: System library a wheel loads → the Debian package that has it (named in errors).
DEBIAN_PACKAGE_OF_LIBRARY = {
    "libGL.so.1": "libgl1",
    "libgomp.so.1": "libgomp1",
    "libatomic.so.1": "libatomic1",
    "libOpenGL.so.0": "libopengl0",
}


def debian_hint(message: str) -> str:
    """`` (Debian: apt-get install PACKAGE)`` for the system library ``message`` names, or ``""``."""
    package = next((p for lib, p in DEBIAN_PACKAGE_OF_LIBRARY.items() if lib in message), None)
    return f" (Debian: apt-get install {package})" if package else ""
