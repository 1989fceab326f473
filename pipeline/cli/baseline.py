"""``pavonine baseline``: list the approved renders CI compares with, and re-render them on purpose."""

from __future__ import annotations

import shlex
from pathlib import Path

import click

from pavonine.pipeline.compare.baselines import (
    BASELINE_SETTINGS,
    BASELINES_DIR,
    CHECK_SETTINGS,
    CI_LONG_SIDE,
    MEAN_FILE,
    SCENES_DIR,
    CheckSettings,
    load_baseline,
    relative_to_repo,
    resolve_stage,
    scene_name,
    shipped_scenes,
    update_baseline,
)
from pavonine.pipeline.errors import InputError, one_line_errors


def store_options(command):
    """``--scenes-dir`` and ``--baselines-dir``: where shipped scenes and their baselines live."""
    directory = click.Path(file_okay=False, path_type=Path)
    command = click.option(
        "--baselines-dir", type=directory, default=BASELINES_DIR, help="Baseline folders."
    )(command)
    return click.option("--scenes-dir", type=directory, default=SCENES_DIR, help="Scenes.")(command)


@click.group("baseline")
def baseline() -> None:
    """Approved baseline renders under assets/baselines/ (only 'update' changes them)."""


@baseline.command("update")
@click.argument("scenes", nargs=-1)
@click.option("--all", "all_scenes", is_flag=True, help="Every shipped scene (assets/scenes).")
@click.option(
    "--resolution",
    default="auto",
    show_default=True,
    help=f"WIDTHxHEIGHT of baseline and check renders; auto: the stage's aspect, "
    f"longer side {CI_LONG_SIDE}.",
)
@click.option("--spp", type=int, default=BASELINE_SETTINGS.spp, show_default=True)
@click.option("--seed", type=int, default=BASELINE_SETTINGS.seed, show_default=True)
@click.option(
    "--check-spp",
    type=int,
    default=CHECK_SETTINGS.spp,
    show_default=True,
    help="Samples per pixel CI renders with.",
)
@click.option(
    "--check-seed",
    type=int,
    default=CHECK_SETTINGS.seed,
    show_default=True,
    help="Seed CI renders with (must differ from --seed).",
)
@store_options
@one_line_errors
def update(
    scenes: tuple[str, ...],
    all_scenes: bool,
    resolution: str,
    spp: int,
    seed: int,
    check_spp: int,
    check_seed: int,
    scenes_dir: Path,
    baselines_dir: Path,
) -> None:
    """Re-render the baselines of SCENES (names like eye_feather_sun, or stage paths)."""
    from rich.progress import Progress

    from pavonine.render.settings import parse_resolution

    if not scenes and not all_scenes:
        raise InputError("baseline update", "name at least one SCENE, or pass --all")
    if spp <= 0 or check_spp <= 0:
        raise InputError("--spp/--check-spp", "samples per pixel must be positive")
    if seed == check_seed:
        raise InputError("--check-seed", "must differ from --seed (a check must not replay it)")
    size = None if resolution == "auto" else parse_resolution(resolution)
    stages = [resolve_stage(s, scenes_dir) for s in scenes]
    if all_scenes:
        stages += [p for p in shipped_scenes(scenes_dir) if p not in stages]
    if not stages:
        raise InputError(str(scenes_dir), "no shipped scenes (*.usda) found")
    command = shlex.join(
        [
            *("pavonine", "baseline", "update"),
            *(scene_name(p) for p in stages),
            *("--resolution", resolution, "--spp", str(spp), "--seed", str(seed)),
            *("--check-spp", str(check_spp), "--check-seed", str(check_seed)),
        ]
    )
    with Progress(transient=True) as progress:
        task = progress.add_task("baselines", total=len(stages))
        for stage in stages:
            progress.update(task, description=f"rendering {scene_name(stage)}")
            made = update_baseline(
                stage,
                baselines_dir=baselines_dir,
                settings=CheckSettings(size, spp, seed),
                check=CheckSettings(size, check_spp, check_seed),
                command=command,
            )
            progress.advance(task)
            progress.console.print(f"updated {made.directory}")


@baseline.command("list")
@store_options
@one_line_errors
def list_baselines(scenes_dir: Path, baselines_dir: Path) -> None:
    """Show each shipped scene and the baseline it is checked against."""
    from rich.console import Console
    from rich.table import Table

    from pavonine.pipeline.compare.baselines import stage_sha256

    table = Table(title=f"baselines in {relative_to_repo(baselines_dir)}")
    table.add_column("scene", no_wrap=True)
    for column in ("spp", "check spp", "size", "made", "inputs since"):
        table.add_column(column)
    for stage in shipped_scenes(scenes_dir):
        directory = baselines_dir / scene_name(stage)
        if not (directory / MEAN_FILE).is_file():
            table.add_row(scene_name(stage), "[red]missing[/]", "", "", "", "")
            continue
        made = load_baseline(directory)
        info = made.info
        changed = info.get("stage_sha256") not in (None, stage_sha256(stage))
        table.add_row(
            scene_name(stage),
            str(info.get("baseline", {}).get("spp", "?")),
            str(made.check_settings.spp),
            "x".join(map(str, made.mean.size)),
            str(info.get("created", "?"))[:10],
            "[yellow]changed[/]" if changed else "unchanged",
        )
    Console().print(table)
