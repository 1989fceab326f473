"""Shared pytest fixtures, and skips for tests whose system libraries are missing."""

import importlib.abc
import importlib.util
import os
import re
import signal
import subprocess
import sys

import pytest

# Ctrl-C tests send SIGINT to child processes. A suite started in the background by a
# non-interactive shell (a CI runner's `cmd &`) inherits SIGINT ignored, and an ignored signal
# stays ignored across exec, so the children would never see it. A handled one is reset to the
# default on exec: handle it here, as an interactive session does.
if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
    signal.signal(signal.SIGINT, signal.default_int_handler)


# ------------------------------------------------------------------ raw warnings (issue 27)
#: What a warning looks like when it reaches stderr without the command's ``warning: …`` line:
#: Python's ``file.py:70: StageWarning: …`` (warnings.formatwarning), and NumPy's floating-point
#: messages (``overflow encountered in cast``), however they got there.
RAW_WARNING = re.compile(
    r"^.*:\d+: \w*Warning: .*$|^.*\b(?:overflow|invalid value|divide by zero|underflow) "
    r"encountered in \w+.*$",
    re.MULTILINE,
)
#: Raw warnings seen in CLI runs during the current test (checked by ``_no_raw_warnings``).
RAW_WARNINGS_SEEN: list[str] = []


def raw_warnings(stderr: str | bytes | None) -> list[str]:
    """The lines of ``stderr`` that are a raw Python or NumPy warning."""
    if isinstance(stderr, bytes):
        stderr = stderr.decode("utf-8", "replace")
    return RAW_WARNING.findall(stderr or "")


def _is_cli(args) -> bool:
    """Whether a subprocess's command runs ``pavonine`` (the script or ``-m pavonine…cli``)."""
    words = [args] if isinstance(args, (str, bytes, os.PathLike)) else list(args)
    words = [os.fsdecode(w) if isinstance(w, (bytes, os.PathLike)) else str(w) for w in words]
    return any(os.path.basename(w) == "pavonine" or w.startswith("pavonine.apps.cli")
               or " pavonine " in f" {w} " for w in words)  # fmt: skip


_communicate = subprocess.Popen.communicate


def _checked_communicate(self, *args, **kwargs):
    stdout, stderr = _communicate(self, *args, **kwargs)
    if _is_cli(self.args):
        RAW_WARNINGS_SEEN.extend(f"{self.args}: {line}" for line in raw_warnings(stderr))
    return stdout, stderr


subprocess.Popen.communicate = _checked_communicate


def _check_cli_runner() -> None:
    from click.testing import CliRunner

    invoke = CliRunner.invoke

    def checked_invoke(self, cli, args=None, *more, **kwargs):
        result = invoke(self, cli, args, *more, **kwargs)
        RAW_WARNINGS_SEEN.extend(f"{args}: {line}" for line in raw_warnings(result.stderr))
        return result

    CliRunner.invoke = checked_invoke


_check_cli_runner()


@pytest.fixture(autouse=True)
def _no_raw_warnings():
    """Session-wide: no CLI run of any test (a subprocess running ``pavonine``, or click's
    runner in process) may print a raw Python or NumPy warning on stderr; every warning goes
    through the command's ``warning: …`` line."""
    RAW_WARNINGS_SEEN.clear()
    yield
    if RAW_WARNINGS_SEEN:
        seen = "\n".join(RAW_WARNINGS_SEEN[:5])
        RAW_WARNINGS_SEEN.clear()
        pytest.fail(f"raw warnings reached stderr in CLI runs:\n{seen}", pytrace=False)


def _drjit_load_error() -> str | None:
    """Why Dr.Jit (so Mitsuba) cannot load here, or None. Checked in a child process: importing
    Dr.Jit here, before ``pavonine.base.backend`` has pointed it at a libLLVM, would be too early."""
    if importlib.util.find_spec("drjit") is None:
        return None  # not installed: tests use pytest.importorskip("mitsuba")
    probe = "import drjit"
    result = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True)
    if result.returncode == 0:
        return None
    lines = [line for line in result.stderr.splitlines() if "Error" in line]
    return lines[0].strip() if lines else result.stderr.strip()[-200:]


class _Unloadable(importlib.abc.MetaPathFinder):
    """Turns ``import mitsuba``/``import drjit`` into ModuleNotFoundError with the reason, so
    ``pytest.importorskip("mitsuba")`` skips instead of crashing collection."""

    def __init__(self, reason: str):
        self.reason = reason

    def find_spec(self, name, path=None, target=None):
        if name.split(".")[0] in ("drjit", "mitsuba"):
            raise ModuleNotFoundError(self.reason, name=name)
        return None


DRJIT_ERROR = _drjit_load_error()
if DRJIT_ERROR is not None:
    DRJIT_REASON = (
        f"Dr.Jit cannot load ({DRJIT_ERROR}; Debian: apt-get install libatomic1; "
        ".ci/setup does it as root)"
    )
    sys.meta_path.insert(0, _Unloadable(DRJIT_REASON))


@pytest.fixture
def restore_variant():
    """Give the test the current Mitsuba variant and select it again afterwards (tests that switch
    to the scalar fallback must not leave the rest of the session in it)."""
    from pavonine.base.backend import select_variant

    previous = select_variant().variant
    yield previous
    select_variant(previous)


@pytest.fixture
def scalar_centre(restore_variant):
    """Render a stage in the scalar fallback variant (8×8, 2 spp); return its centre's mean colour."""
    import warnings

    from pavonine.render.api import render_stage
    from pavonine.render.diagnostics import StageWarning

    def render(stage_path):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", StageWarning)
            result = render_stage(
                stage_path, spp=2, resolution=(8, 8), variant="scalar_spectral", progress=False
            )
        assert result.metadata["variant"] == "scalar_spectral"
        return result.rgb[2:6, 2:6].reshape(-1, 3).mean(axis=0)

    return render


def missing_system_tools() -> dict[str, str]:
    """Marker → why its tests cannot run here (a system library is missing)."""
    from pavonine.base.backend import MIN_LLVM_MAJOR, find_libllvm

    missing = {}
    if DRJIT_ERROR is not None:
        missing["render"] = missing["llvm"] = missing["mitsuba"] = DRJIT_REASON
    elif os.environ.get("PAVONINE_VARIANT", "").startswith("scalar") or find_libllvm() is None:
        missing["render"] = missing["llvm"] = (
            f"needs a shared libLLVM >= {MIN_LLVM_MAJOR} for Mitsuba's llvm variants, the scalar "
            "fallback is too slow for the suite (Debian: apt-get install libllvm19; .ci/setup "
            "does it as root)"
        )
    try:
        import pymeshlab

        from pavonine.pipeline.convert.meshing import check_filters

        check_filters(pymeshlab)
    except ImportError as exc:  # convert tests run with the NumPy fallback; these need pymeshlab
        missing["pymeshlab"] = (
            f"pymeshlab cannot load ({' '.join(str(exc).split())}; Debian: apt-get install "
            "libgl1 libopengl0 libgomp1; .ci/setup does it as root)"
        )
    return missing


# ------------------------------------------------------------------ the checkout stays as it is
#: The repository (the checkout the tests run from).
REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
#: Shipped files no test may change: an edit left in memory on a shipped layer (a variant chosen
#: on the stage's root layer) reaches every later stage of the process that references it, and a
#: later ``stage.Save()`` writes it into the checkout, where the wheel and subprocesses see it.
SHIPPED = ("assets", "src")


def _dirty_checkout_layers() -> list[str]:
    """File-backed USD layers of this process, inside :data:`SHIPPED`, with unsaved edits."""
    if "pxr" not in sys.modules:
        return []
    from pxr import Sdf

    roots = tuple(os.path.join(REPO, room) + os.sep for room in SHIPPED)
    return sorted(
        layer.realPath
        for layer in Sdf.Layer.GetLoadedLayers()
        if layer.dirty and not layer.anonymous and layer.realPath.startswith(roots)
    )


@pytest.fixture(autouse=True)
def _shipped_layers_stay_clean():
    """No test leaves an edit in memory on a shipped layer (edit a copy, or the session layer)."""
    yield
    dirty = _dirty_checkout_layers()
    if dirty:
        from pxr import Sdf

        for path in dirty:  # the next test starts from the files as shipped
            Sdf.Layer.Find(path).Reload(force=True)
        pytest.fail(f"a shipped layer was edited in memory: {', '.join(dirty)}", pytrace=False)


def _checkout_digest() -> dict[str, str]:
    """sha256 of every file under :data:`SHIPPED` but caches (``__pycache__``, ``*.egg-info``)."""
    import hashlib

    digest = {}
    for room in SHIPPED:
        for folder, dirs, files in os.walk(os.path.join(REPO, room)):
            dirs[:] = [d for d in dirs if d != "__pycache__" and not d.endswith(".egg-info")]
            for name in files:
                path = os.path.join(folder, name)
                with open(path, "rb") as handle:
                    digest[path] = hashlib.sha256(handle.read()).hexdigest()
    return digest


def pytest_sessionstart(session):
    """Take the checkout's digest once, on the controller (not on each xdist worker)."""
    if not hasattr(session.config, "workerinput"):
        session.config._checkout_digest = _checkout_digest()


def pytest_sessionfinish(session, exitstatus):
    """Fail the run when a test changed, added or removed a shipped file."""
    before = getattr(session.config, "_checkout_digest", None)
    if before is None:
        return
    after = _checkout_digest()
    changed = sorted(p for p in before.keys() | after.keys() if before.get(p) != after.get(p))
    if changed:
        shown = ", ".join(os.path.relpath(p, REPO) for p in changed[:10])
        sys.stderr.write(f"\nerror: the tests changed shipped files: {shown}\n")
        session.exitstatus = pytest.ExitCode.TESTS_FAILED


def pytest_collection_modifyitems(config, items):
    """Tests marked ``render``, ``llvm``, ``mitsuba`` or ``pymeshlab`` skip, saying what to install,
    when the system library they need is missing."""
    missing = missing_system_tools()
    for item in items:
        for marker, reason in missing.items():
            if marker in item.keywords:
                item.add_marker(pytest.mark.skip(reason=reason))


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item, call):
    """When Dr.Jit cannot load, a test that imports Mitsuba anyway is skipped with the reason,
    not failed (the import raised ModuleNotFoundError through ``_Unloadable``, or
    ``select_variant`` raised :class:`~pavonine.base.backend.RendererUnavailable`)."""
    from pavonine.base.backend import RendererUnavailable

    outcome = yield
    report = outcome.get_result()
    error = call.excinfo.value if call.excinfo is not None else None
    unloadable = isinstance(error, RendererUnavailable) or (
        isinstance(error, ModuleNotFoundError)
        and (error.name or "").split(".")[0] in ("drjit", "mitsuba")
    )
    if DRJIT_ERROR is not None and unloadable:
        report.outcome = "skipped"
        report.longrepr = (str(item.path), item.location[1] or 0, f"Skipped: {DRJIT_REASON}")


@pytest.fixture(scope="session")
def eye_asset(tmp_path_factory):
    """A converted eye feather shared by the portable-asset tests (256-px maps, 12k/4k/1k
    triangles, 256² baked textures; the shipped feathers' freyer2020 preset). Tests that change it work on a copy."""
    return convert_eye(tmp_path_factory.mktemp("eye_asset"), "eye_feather")


def convert_eye(
    work, name: str, geometry: str = "", lods: str = "12000, 4000, 1000", bake: int = 256
):
    """The eye feather converted from 256-px painted maps (seed 4) into ``work/out/<name>``
    (``geometry``: extra ``[geometry]`` lines; ``lods``: high, medium, low); its root folder.
    Skips when the converter's system tools are missing."""
    reason = missing_system_tools().get("convert")
    if reason:
        pytest.skip(reason)
    from pavonine.pipeline.convert.batch import convert_recipe
    from pavonine.pipeline.maps.paint import MAP_NAMES, generate_maps, write_maps

    if not (work / "m").is_dir():
        write_maps(generate_maps("eye", 256, seed=4), work / "m")
    maps = "\n".join(f'{map_name} = "m/{map_name}.png"' for map_name in MAP_NAMES)
    high, medium, low = (int(n) for n in lods.split(","))
    (work / f"{name}.toml").write_text(
        f'name = "{name}"\n[maps]\n{maps}\n[material]\npreset = "freyer2020"\n'
        f"[geometry]\nlength_cm = 20\nrachis_length = 0.74\n{geometry}"
        f"[geometry.lod]\nhigh = {high}\nmedium = {medium}\nlow = {low}\n"
        f"[bake]\nresolution = {bake}\n"
    )
    return convert_recipe(work / f"{name}.toml", work / "out").root
