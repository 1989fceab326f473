"""Approved baseline renders: ``assets/baselines/<scene>/`` holds ``mean.exr`` (scene-linear),
``variance.exr`` (per-pixel variance of that estimate), ``preview.png`` and ``baseline.json`` (how
it was made and how CI re-renders it). Only :func:`update_baseline` writes them, and only when asked
(``pavonine baseline update``); checks never touch them.
"""

from __future__ import annotations

import datetime as _dt
import hashlib
import json
import os
import platform
from dataclasses import dataclass, field, replace
from importlib import metadata
from pathlib import Path
from typing import Any

import numpy as np

from pavonine.apps.compare.methods import (
    CompareOptions,
    ComparisonResult,
    LoadedImage,
    compare_arrays,
    read_image,
    read_variance,
)
from pavonine.apps.compare.record import (
    FORMAT_VERSION,
    CheckSettings,
    read_record,
    recorded_settings,
)
from pavonine.base.commit import staged_folder
from pavonine.base.errors import InputError
from pavonine.base.groups import GROUP_ATTRIBUTE, content_group_id, group_marks, read_mark
from pavonine.base.shipped import baselines_dir, display_path, scenes_dir
from pavonine.render.limits import DEFAULT_LIMITS, RenderLimits

#: The shipped scenes and baselines (a checkout's ``assets/``, or an installed wheel's data).
SCENES_DIR = scenes_dir()
BASELINES_DIR = baselines_dir()

MEAN_FILE = "mean.exr"
VARIANCE_FILE = "variance.exr"
INFO_FILE = "baseline.json"
PREVIEW_FILE = "preview.png"

_VERSIONED = ("pavonine", "mitsuba", "drjit", "usd-core", "numpy", "opencolorio", "OpenImageIO")


#: Seed-to-seed renders made at update time to measure the check's noise.
CALIBRATION_SEEDS = 2
#: Per-scene FLIP threshold = this × the worst seed-to-seed mean FLIP at check settings.
FLIP_NOISE_FACTOR = 2.0
#: ... but never below this (a noise-free scene would otherwise fail on rounding).
FLIP_MIN_THRESHOLD = 0.01

#: Longer image side of CI renders (pixels); the shorter follows the stage's aspect ratio.
CI_LONG_SIDE = 192
#: The baseline itself: 4x the check's samples, so its noise adds only 1/4 to the check's variance.
BASELINE_SETTINGS = CheckSettings(None, 512, 0)
#: What ``check-renders`` renders: same size, another seed (a check must not replay the baseline).
CHECK_SETTINGS = CheckSettings(None, 128, 1)


@dataclass
class Baseline:
    """A loaded baseline: scene-linear mean, per-pixel variance of that estimate, and its record
    (``info``, with the fields comparisons use checked: ``settings``, ``check_settings`` and
    ``flip_threshold``)."""

    scene: str
    directory: Path
    mean: LoadedImage
    variance: np.ndarray
    info: dict[str, Any]
    #: How the baseline was rendered (``baseline`` in ``baseline.json``).
    settings: CheckSettings
    #: Settings for re-rendering this scene in CI (``check``, recorded at update time).
    check_settings: CheckSettings
    #: Calibrated mean-FLIP threshold of this scene.
    flip_threshold: float

    def check_limits(self, limits: RenderLimits = DEFAULT_LIMITS) -> CheckSettings:
        """The check settings, refused (naming ``baseline.json``'s field) beyond ``limits``."""
        settings = self.check_settings
        where = f"{self.directory / INFO_FILE}: check"
        limits.check_spp(settings.spp, f"{where}.spp")
        if settings.resolution is not None:
            limits.check_resolution(settings.resolution, f"{where}.resolution")
        return settings

    @property
    def recorded_sha256(self) -> str | None:
        """:func:`stage_sha256` of the stage when the baseline was made."""
        return self.info.get("stage_sha256")


def scene_name(stage: str | Path) -> str:
    """A scene's name: its stage file's stem (``eye_feather_sun``)."""
    return Path(stage).stem


def is_scene(path: Path) -> bool:
    """A stage meant to be rendered: its root layer names its render settings.

    ``renderSettingsPrimPath`` layer metadata; assets referenced by scenes (a feather component
    beside them) do not have it.
    """
    from pxr import Sdf, Tf

    try:
        layer = Sdf.Layer.FindOrOpen(str(path))
    except Tf.ErrorException:
        return True  # broken layers count as scenes, so that checking them reports the error
    return layer is None or bool(layer.pseudoRoot.GetInfo("renderSettingsPrimPath"))


def shipped_scenes(scenes_dir: str | Path = SCENES_DIR) -> list[Path]:
    """Every shipped scene (``assets/scenes/*.usda`` naming its render settings), by name."""
    return sorted(p for p in Path(scenes_dir).glob("*.usda") if is_scene(p))


def resolve_stage(scene: str, scenes_dir: str | Path = SCENES_DIR) -> Path:
    """A scene given by name (``eye_feather_sun``) or path, as an existing stage file."""
    candidate = Path(scene)
    if candidate.suffix in (".usda", ".usd", ".usdc") and candidate.is_file():
        return candidate
    stage = Path(scenes_dir) / f"{scene}.usda"
    if stage.is_file():
        return stage
    if not Path(scenes_dir).is_dir():
        raise InputError(f"--scenes-dir {scenes_dir}", "no such folder")
    known = ", ".join(scene_name(p) for p in shipped_scenes(scenes_dir)) or "none"
    raise InputError(scene, f"no such scene (shipped scenes: {known})")


def ci_resolution(stage: str | Path, long_side: int = CI_LONG_SIDE) -> tuple[int, int]:
    """The stage's render resolution (``UsdRender.Settings``) scaled to ``long_side`` pixels."""
    from pavonine.render.delegate import open_stage
    from pavonine.render.diagnostics import Diagnostics
    from pavonine.render.settings import DEFAULT_RESOLUTION, read_render_settings

    diag = Diagnostics()
    width, height = read_render_settings(open_stage(stage, diag), diag).resolution or (
        DEFAULT_RESOLUTION
    )
    scale = long_side / max(width, height)
    return max(1, round(width * scale)), max(1, round(height * scale))


def file_sha256(path: str | Path) -> str:
    """Hex SHA-256 of a file's bytes."""
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def stage_sha256(stage: str | Path) -> str:
    """Hex SHA-256 of everything a stage is made of: its layers and assets (maps), by content.

    Dependencies come from ``UsdUtils.ComputeAllDependencies``; their digests are sorted so the
    result does not depend on where the repository is checked out.
    """
    from pxr import Tf, UsdUtils

    files = [str(stage)]
    try:
        layers, assets, _unresolved = UsdUtils.ComputeAllDependencies(str(stage))
        files += [layer.realPath for layer in layers if layer.realPath] + list(assets)
    except Tf.ErrorException:
        pass  # a broken stage: the root file alone, and rendering will name the error
    digests = sorted({file_sha256(f) for f in files if os.path.isfile(f)})
    return hashlib.sha256("\n".join(digests).encode()).hexdigest()


def load_baseline(directory: str | Path) -> Baseline:
    """Read ``mean.exr``, ``variance.exr`` and ``baseline.json`` from a baseline folder."""
    directory = Path(directory)
    if not (directory / MEAN_FILE).is_file():
        raise InputError(
            str(directory),
            f"no baseline here (missing {MEAN_FILE}); run 'pavonine baseline update "
            f"{directory.name}'",
        )
    mean = read_image(directory / MEAN_FILE)
    if not np.all(np.isfinite(mean.rgb)):
        raise InputError(str(directory / MEAN_FILE), "baseline has NaN or infinite pixels")
    variance = read_variance(directory / VARIANCE_FILE, mean.size)
    info_path = directory / INFO_FILE
    info = read_record(info_path, directory.name)
    mark = read_mark(directory / MEAN_FILE)
    if "group" in info and mark is not None and info["group"] != mark.id:
        raise InputError(
            str(info_path),
            f"is from another write than {MEAN_FILE} (pavonine:group {str(info['group'])[:8]} vs "
            f"{mark.id[:8]}): the baseline is a mix of two versions; run 'pavonine baseline "
            f"update {directory.name}' again",
        )
    settings, check, threshold = recorded_settings(info, info_path, mean)
    return Baseline(directory.name, directory, mean, variance, info, settings, check, threshold)


def baseline_for(scene: str, baselines_dir: str | Path = BASELINES_DIR) -> Baseline:
    """The stored baseline of ``scene`` (a name or a stage path)."""
    return load_baseline(Path(baselines_dir) / scene_name(scene))


def package_versions() -> dict[str, str]:
    """Versions of everything that shapes a render, for the baseline record."""
    versions = {"python": platform.python_version()}
    for dist in _VERSIONED:
        try:
            versions[dist] = metadata.version(dist)
        except metadata.PackageNotFoundError:
            versions[dist] = "not installed"
    return versions


@dataclass
class SceneRender:
    """A render for comparison: scene-linear RGB, variance of the estimate, renderer metadata."""

    rgb: np.ndarray
    variance: np.ndarray
    metadata: dict[str, Any]


def render_scene(
    stage: str | Path,
    settings: CheckSettings,
    *,
    progress: bool = False,
    limits: RenderLimits = DEFAULT_LIMITS,
) -> SceneRender:
    """Render ``stage`` with :func:`pavonine.render.api.render_stage`, with per-pixel variance."""
    from pavonine.render.api import render_stage

    result = render_stage(
        str(stage),
        spp=settings.spp,
        resolution=settings.resolution,
        seed=settings.seed,
        moments=True,
        progress=progress,
        limits=limits,
    )
    rgb = np.asarray(result.rgb, dtype=np.float32)
    variance = np.maximum(np.asarray(result.variance, dtype=np.float32), 0.0)
    if (rgb.shape[1], rgb.shape[0]) != settings.resolution:
        raise InputError(
            str(stage),
            f"render is {rgb.shape[1]}x{rgb.shape[0]}, expected "
            f"{settings.resolution[0]}x{settings.resolution[1]}",
        )
    return SceneRender(rgb, variance, dict(result.metadata))


def update_baseline(
    stage: str | Path,
    *,
    baselines_dir: str | Path = BASELINES_DIR,
    settings: CheckSettings = BASELINE_SETTINGS,
    check: CheckSettings = CHECK_SETTINGS,
    command: str = "",
    progress: bool = False,
    limits: RenderLimits = DEFAULT_LIMITS,
) -> Baseline:
    """Render ``stage`` at ``settings`` and replace its baseline folder atomically."""
    stage = Path(stage)
    name = scene_name(stage)
    size = settings.resolution or ci_resolution(stage)
    settings = replace(settings, resolution=size)
    check = replace(check, resolution=size)
    if check.seed == settings.seed:
        raise InputError(
            "check seed", "must differ from the baseline seed (a check must not replay it)"
        )
    limits.check_resolution(size, "--resolution")
    limits.check_spp(settings.spp, "--spp")
    limits.check_spp(check.spp, "--check-spp")
    render = render_scene(stage, settings, progress=progress, limits=limits)
    if not np.all(np.isfinite(render.rgb)):
        raise InputError(str(stage), "render has NaN or infinite pixels; refusing to store it")
    calibration = calibrate(stage, render, check, progress=progress, limits=limits)
    target = Path(baselines_dir) / name
    info = {
        "format": FORMAT_VERSION,
        "scene": name,
        "stage": relative_to_repo(stage),
        "stage_sha256": stage_sha256(stage),
        "baseline": settings.to_json(),
        "check": check.to_json(),
        "variance": "per-pixel variance of the mean estimate (scene-linear units squared)",
        "created": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
        "command": command,
        "calibration": calibration,
        "flip_threshold": calibration["flip_threshold"],
        "versions": package_versions(),
        "renderer": _jsonable({k: v for k, v in render.metadata.items() if k != "stage"}),
    }
    from pavonine.materials.display import REFERENCE_DISPLAY
    from pavonine.render.imageio import write_exr, write_png

    # Built inside the baselines folder, then exchanged with the old baseline in one atomic
    # step (pavonine.base.commit): a reader sees the old baseline or the new one, whole.
    # Its files are also marked as one group (pavonine.base.groups): where the file system
    # cannot exchange folders the commit is file by file, and load_baseline refuses a mix. The
    # id is a hash of the pixels: the same render gives the same files.
    group_id = content_group_id((render.rgb, render.variance))
    info["group"] = group_id
    with staged_folder(target, replace=True, subject=name) as staging:
        files = [staging / f for f in (MEAN_FILE, VARIANCE_FILE, PREVIEW_FILE)]
        marks = {f.name: mark for f, mark in group_marks(group_id, files).items()}
        write_exr(
            staging / MEAN_FILE,
            render.rgb,
            {"scene": name, **settings.to_json(), "group": marks[MEAN_FILE]},
        )
        write_exr(
            staging / VARIANCE_FILE,
            render.variance,
            {
                "scene": name,
                "quantity": "variance of the mean (scene-linear units squared)",
                "group": marks[VARIANCE_FILE],
            },
        )
        write_png(
            staging / PREVIEW_FILE,
            render.rgb,
            REFERENCE_DISPLAY,
            attributes={GROUP_ATTRIBUTE: marks[PREVIEW_FILE]},
        )
        (staging / INFO_FILE).write_text(json.dumps(info, indent=2) + "\n", encoding="utf-8")
        for written in staging.iterdir():
            written.chmod(0o644)
        staging.chmod(0o755)
    return load_baseline(target)


def calibrate(
    stage: Path,
    baseline: SceneRender,
    check: CheckSettings,
    *,
    seeds: int = CALIBRATION_SEEDS,
    progress: bool = False,
    limits: RenderLimits = DEFAULT_LIMITS,
) -> dict[str, Any]:
    """Measure seed-to-seed noise: render ``check`` with other seeds and compare with the baseline.

    Every such render must pass ``stat`` (else the check would be flaky: raise the sample counts);
    the FLIP threshold becomes ``FLIP_NOISE_FACTOR`` times the worst seed-to-seed mean FLIP.
    """
    record: dict[str, Any] = {"seeds": [], "stat_max_z_ratio": [], "flip_mean": []}
    for k in range(1, seeds + 1):
        settings = CheckSettings(check.resolution, check.spp, check.seed + k)
        render = render_scene(stage, settings, progress=progress, limits=limits)
        stat, flip = (
            compare_arrays(
                render.rgb, baseline.rgb, method,
                test_variance=render.variance, ref_variance=baseline.variance,
            )
            for method in ("stat", "flip")
        )  # fmt: skip
        if not stat.passed:
            raise InputError(
                str(stage),
                f"seed {settings.seed} at {check.spp} spp fails 'stat' against the new baseline "
                f"({stat.numbers}); the check would be flaky: raise --check-spp or --spp",
            )
        record["seeds"].append(settings.seed)
        record["stat_max_z_ratio"].append(stat.numbers["max_z_ratio"])
        record["flip_mean"].append(flip.numbers["mean_flip"])
    worst = max(record["flip_mean"], default=0.0)
    record["flip_threshold"] = round(max(FLIP_NOISE_FACTOR * worst, FLIP_MIN_THRESHOLD), 4)
    return record


@dataclass
class SceneCheck:
    """One scene re-rendered and compared with its baseline."""

    scene: str
    render: SceneRender
    baseline: Baseline
    results: list[ComparisonResult]
    settings: CheckSettings
    notes: list[str] = field(default_factory=list)

    @property
    def passed(self) -> bool:
        return all(r.passed for r in self.results)


def check_stage(
    stage: str | Path,
    baseline: Baseline,
    *,
    seed: int | None = None,
    methods: tuple[str, ...] = ("stat", "flip"),
    options: CompareOptions | None = None,
    progress: bool = False,
    limits: RenderLimits = DEFAULT_LIMITS,
) -> SceneCheck:
    """Render ``stage`` with the baseline's check settings (another seed) and compare."""
    settings = baseline.check_limits(limits)
    if seed is not None:
        settings = CheckSettings(settings.resolution, settings.spp, seed)
    if settings.resolution != baseline.mean.size:
        raise InputError(
            str(baseline.directory / INFO_FILE),
            f"check resolution {settings.resolution} differs from the baseline's {baseline.mean.size}",
        )
    options = options or options_for(baseline)
    render = render_scene(stage, settings, progress=progress, limits=limits)
    results = [
        compare_arrays(
            render.rgb,
            baseline.mean.rgb,
            method,
            test_variance=render.variance,
            ref_variance=baseline.variance,
            options=options,
        )
        for method in methods
    ]
    notes = []
    recorded = baseline.recorded_sha256
    if recorded and Path(stage).is_file() and stage_sha256(stage) != recorded:
        notes.append(
            f"{relative_to_repo(Path(stage))} or a layer or map it uses changed since the baseline "
            "was made; if the change is "
            f"intended, run 'pavonine baseline update {baseline.scene}'"
        )
    return SceneCheck(baseline.scene, render, baseline, results, settings, notes)


def options_for(baseline: Baseline) -> CompareOptions:
    """Comparison options with the baseline's calibrated FLIP threshold."""
    return CompareOptions(flip_threshold=baseline.flip_threshold)


def relative_to_repo(path: str | Path) -> str:
    """``path`` relative to the repository when inside it (for records and messages)."""
    return display_path(path)


def _jsonable(value: Any) -> Any:
    """Renderer metadata reduced to JSON types (unknown objects become strings)."""
    if isinstance(value, dict):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_jsonable(v) for v in value]
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist() if value.size <= 16 else f"array{value.shape}"
    if value is None or isinstance(value, bool | int | float | str):
        return value
    return str(value)
