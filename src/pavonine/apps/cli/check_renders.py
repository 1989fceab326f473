"""``pavonine check-renders``: render every shipped scene and compare it with its baseline."""

from __future__ import annotations

import time
from pathlib import Path

import click

from pavonine.apps.cli.baseline import store_options
from pavonine.apps.cli.limits import limit_options
from pavonine.apps.cli.options import (
    display_options,
    emit_json,
    json_option,
    junit_option,
    progress_bar,
    requires,
    say,
    threads_option,
    warnings_to_log,
)
from pavonine.apps.cli.values import SEED
from pavonine.apps.compare.baselines import (
    BASELINES_DIR,
    SceneCheck,
    baseline_for,
    check_stage,
    resolve_stage,
    scene_name,
    shipped_scenes,
)
from pavonine.apps.compare.methods import METHODS
from pavonine.base.errors import InputError, one_line_errors
from pavonine.render.limits import DEFAULT_LIMITS, RenderLimits

JSON_SCHEMA = {
    "type": "object",
    "required": ["passed", "scenes"],
    "properties": {
        "passed": {"type": "boolean", "description": "every scene matches (exit 0)"},
        "report": {"type": ["string", "null"], "description": "HTML report, if written"},
        "scenes": {
            "type": "object",
            "description": "scene name → its check",
            "additionalProperties": {
                "type": "object",
                "required": ["passed", "check", "seconds", "methods", "notes"],
                "properties": {
                    "passed": {"type": "boolean"},
                    "check": {
                        "type": "object",
                        "description": "resolution, spp and seed of the check render",
                    },
                    "seconds": {"type": "number", "description": "render and comparison time"},
                    "methods": {
                        "type": "object",
                        "description": "method (stat, flip) → passed and its statistics",
                        "additionalProperties": {
                            "type": "object",
                            "required": ["passed"],
                            "properties": {"passed": {"type": "boolean"}},
                        },
                    },
                    "notes": {"type": "array", "items": {"type": "string"}},
                },
            },
        },
    },
}


def run_checks(
    stages: list[Path],
    *,
    baselines_dir: Path = BASELINES_DIR,
    methods: tuple[str, ...] = METHODS,
    seed: int | None = None,
    limits: RenderLimits = DEFAULT_LIMITS,
) -> list[tuple[SceneCheck, float]]:
    """Render and compare each stage with its baseline (progress on stderr); checks and seconds.

    Every baseline's check settings are held against ``limits`` before the first render.
    """
    from rich.progress import BarColumn, TextColumn, TimeElapsedColumn

    baselines = [baseline_for(stage, baselines_dir) for stage in stages]
    for baseline in baselines:
        baseline.check_limits(limits)
    checks: list[tuple[SceneCheck, float]] = []
    columns = (TextColumn("{task.description}"), BarColumn(), TimeElapsedColumn())
    with progress_bar(*columns) as progress:
        task = progress.add_task("render checks", total=len(stages))
        for stage, baseline in zip(stages, baselines, strict=True):
            progress.update(task, description=f"rendering {scene_name(stage)}")
            start = time.perf_counter()
            check = check_stage(stage, baseline, seed=seed, methods=methods, limits=limits)
            checks.append((check, time.perf_counter() - start))
            progress.advance(task)
            detail = ", ".join(
                f"{r.method} {'pass' if r.passed else 'FAIL'}" for r in check.results
            )
            say(f"{check.scene}: {'pass' if check.passed else 'FAIL'} ({detail})")
            for note in check.notes:
                say(f"  note: {note}")
    return checks


def report_entries(checks: list[SceneCheck]):
    """Report rows for :func:`pavonine.apps.compare.report.write_report`."""
    from pavonine.apps.compare.report import SceneEntry

    entries = []
    for check in checks:
        info = check.baseline.info
        made, settings = check.baseline.settings, check.settings
        metadata = {
            "baseline": str(check.baseline.directory),
            "baseline spp / seed": f"{made.spp} / {made.seed}",
            "check spp / seed": f"{settings.spp} / {settings.seed}",
            "baseline made": info.get("created", "?"),
            "baseline versions": ", ".join(
                f"{k} {v}" for k, v in sorted(info.get("versions", {}).items())
            ),
        }
        entries.append(
            SceneEntry(
                check.scene,
                check.render.rgb,
                check.baseline.mean.rgb,
                check.results,
                metadata=metadata,
                notes=list(check.notes),
            )
        )
    return entries


@click.command("check-renders")
@click.argument("scenes", nargs=-1)
@click.option(
    "--report",
    type=click.Path(file_okay=False, path_type=Path),
    help="Write a static HTML report (index.html and images) into this folder.",
)
@click.option(
    "--method",
    type=click.Choice([*METHODS, "all"]),
    default="all",
    show_default=True,
    help="Which comparisons must pass.",
)
@click.option("--seed", type=SEED, help="Override the check seed recorded with each baseline.")
@store_options
@limit_options
@json_option(JSON_SCHEMA)
@junit_option
@display_options
@threads_option
@requires("mitsuba", "drjit", "flip_evaluator")
@one_line_errors
def check_renders(
    scenes: tuple[str, ...],
    report: Path | None,
    method: str,
    seed: int | None,
    scenes_dir: Path,
    baselines_dir: Path,
    json_target: str | None,
    junit: Path | None,
    display,
    limits: RenderLimits,
) -> None:
    """Render SCENES (default: every shipped scene) and compare each with its baseline.

    Exit 0 when all agree, 1 when any differs, 2 on bad input (e.g. a scene without a baseline).
    The comparisons do not depend on the display options; the report's images do. --junit
    writes one test case per scene, failing when it differs.
    """
    from pavonine.base.backend import BackendWarning
    from pavonine.render.diagnostics import StageWarning

    stages = [resolve_stage(s, scenes_dir) for s in scenes] or shipped_scenes(scenes_dir)
    if not stages:
        raise InputError(str(scenes_dir), "no shipped scenes (*.usda) to check")
    methods = METHODS if method == "all" else (method,)
    with warnings_to_log(StageWarning, BackendWarning):
        timed = run_checks(
            stages, baselines_dir=baselines_dir, methods=methods, seed=seed, limits=limits
        )
    checks = [check for check, _ in timed]
    page = None
    if report is not None:
        from pavonine.apps.compare.report import write_report

        page = write_report(report, report_entries(checks))
        say(f"report: {page}")
    failed = [c.scene for c in checks if not c.passed]
    emit_json(
        json_target,
        {
            "passed": not failed,
            "report": None if page is None else str(page),
            "scenes": {
                c.scene: {
                    "passed": c.passed,
                    "check": c.settings.to_json(),
                    "seconds": round(seconds, 3),
                    "methods": {r.method: {"passed": r.passed, **r.numbers} for r in c.results},
                    "notes": list(c.notes),
                }
                for c, seconds in timed
            },
        },
    )
    if junit is not None:
        _write_junit(junit, timed)
    if failed:
        say(f"{len(failed)} of {len(checks)} scene(s) differ from baseline: {', '.join(failed)}")
        raise SystemExit(1)
    say(f"{len(checks)} scene(s) match their baselines")


def _write_junit(target: Path, timed: list[tuple[SceneCheck, float]]) -> None:
    """One test case per scene; each failing method is a failure with its statistics."""
    from pavonine.apps.cli.junit import Case, Problem, write_junit

    cases = []
    for check, seconds in timed:
        case = Case("pavonine.check-renders", check.scene, seconds, output="\n".join(check.notes))
        for result in check.results:
            if not result.passed:
                numbers = ", ".join(f"{k} {v}" for k, v in result.numbers.items())
                case.problems.append(
                    Problem(f"{result.method}: differs from the baseline", numbers)
                )
        cases.append(case)
    write_junit(target, "pavonine check-renders", cases)
