"""``pavonine check-renders``: render every shipped scene and compare it with its baseline."""

from __future__ import annotations

import json
from pathlib import Path

import click

from pavonine.pipeline.cli.baseline import store_options
from pavonine.pipeline.compare.baselines import (
    BASELINES_DIR,
    SceneCheck,
    baseline_for,
    check_stage,
    resolve_stage,
    scene_name,
    shipped_scenes,
)
from pavonine.pipeline.compare.methods import METHODS
from pavonine.pipeline.errors import InputError, atomic_path, one_line_errors


def run_checks(
    stages: list[Path],
    *,
    baselines_dir: Path = BASELINES_DIR,
    methods: tuple[str, ...] = METHODS,
    seed: int | None = None,
) -> list[SceneCheck]:
    """Render and compare each stage with its baseline, showing a progress bar."""
    from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

    baselines = [baseline_for(stage, baselines_dir) for stage in stages]
    checks: list[SceneCheck] = []
    columns = (TextColumn("{task.description}"), BarColumn(), TimeElapsedColumn())
    with Progress(*columns, transient=True) as progress:
        task = progress.add_task("render checks", total=len(stages))
        for stage, baseline in zip(stages, baselines, strict=True):
            progress.update(task, description=f"rendering {scene_name(stage)}")
            check = check_stage(stage, baseline, seed=seed, methods=methods)
            checks.append(check)
            progress.advance(task)
            verdict = "[green]pass[/]" if check.passed else "[bold red]FAIL[/]"
            detail = ", ".join(
                f"{r.method} {'pass' if r.passed else 'FAIL'}" for r in check.results
            )
            progress.console.print(f"{check.scene}: {verdict} ({detail})")
            for note in check.notes:
                progress.console.print(f"  [yellow]note:[/] {note}")
    return checks


def report_entries(checks: list[SceneCheck]):
    """Report rows for :func:`pavonine.pipeline.compare.report.write_report`."""
    from pavonine.pipeline.compare.report import SceneEntry

    entries = []
    for check in checks:
        info = check.baseline.info
        settings = check.settings
        metadata = {
            "baseline": str(check.baseline.directory),
            "baseline spp / seed": (
                f"{info.get('baseline', {}).get('spp', '?')} / "
                f"{info.get('baseline', {}).get('seed', '?')}"
            ),
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
@click.option("--seed", type=int, help="Override the check seed recorded with each baseline.")
@click.option(
    "--json",
    "json_path",
    type=click.Path(dir_okay=False, path_type=Path),
    help="Write the numbers.",
)
@store_options
@one_line_errors
def check_renders(
    scenes: tuple[str, ...],
    report: Path | None,
    method: str,
    seed: int | None,
    json_path: Path | None,
    scenes_dir: Path,
    baselines_dir: Path,
) -> None:
    """Render SCENES (default: every shipped scene) and compare each with its baseline.

    Exit 0 when all agree, 1 when any differs, 2 on bad input (e.g. a scene without a baseline).
    """
    stages = [resolve_stage(s, scenes_dir) for s in scenes] or shipped_scenes(scenes_dir)
    if not stages:
        raise InputError(str(scenes_dir), "no shipped scenes (*.usda) to check")
    methods = METHODS if method == "all" else (method,)
    checks = run_checks(stages, baselines_dir=baselines_dir, methods=methods, seed=seed)
    if report is not None:
        from pavonine.pipeline.compare.report import write_report

        page = write_report(report, report_entries(checks))
        click.echo(f"report: {page}")
    if json_path is not None:
        payload = {
            c.scene: {
                "passed": c.passed,
                "check": c.settings.to_json(),
                **{r.method: {"passed": r.passed, **r.numbers} for r in c.results},
            }
            for c in checks
        }
        with atomic_path(json_path) as tmp:
            tmp.write_text(json.dumps(payload, indent=2) + "\n", encoding="utf-8")
    failed = [c.scene for c in checks if not c.passed]
    if failed:
        click.echo(
            f"{len(failed)} of {len(checks)} scene(s) differ from baseline: {', '.join(failed)}"
        )
        raise SystemExit(1)
    click.echo(f"{len(checks)} scene(s) match their baselines")
