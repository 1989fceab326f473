"""``pavonine baseline``: list the approved renders CI compares with, and re-render them on purpose."""

from __future__ import annotations

import shlex
import sys
from pathlib import Path

import click

from pavonine.apps.cli.limits import limit_options
from pavonine.apps.cli.options import (
    emit_json,
    json_option,
    progress_bar,
    requires,
    say,
    stdout_console,
    threads_option,
)
from pavonine.apps.cli.values import SEED
from pavonine.apps.compare.baselines import (
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
from pavonine.base.errors import InputError, one_line_errors
from pavonine.base.shipped import is_packaged
from pavonine.render.limits import RenderLimits

LIST_SCHEMA = {
    "type": "object",
    "required": ["scenes_dir", "baselines_dir", "baselines"],
    "properties": {
        "scenes_dir": {"type": "string"},
        "baselines_dir": {"type": "string"},
        "baselines": {
            "type": "array",
            "items": {
                "type": "object",
                "required": ["scene", "stage", "baseline"],
                "properties": {
                    "scene": {"type": "string"},
                    "stage": {"type": "string", "description": "the scene's stage file"},
                    "baseline": {
                        "type": ["string", "null"],
                        "description": "its baseline folder (null: missing, exit 1)",
                    },
                    "spp": {"type": ["integer", "null"], "description": "baseline samples/pixel"},
                    "check_spp": {"type": "integer", "description": "CI samples per pixel"},
                    "resolution": {"type": "array", "items": {"type": "integer"}},
                    "created": {"type": ["string", "null"]},
                    "inputs_changed": {
                        "type": "boolean",
                        "description": "the stage or a file it uses changed since the baseline",
                    },
                },
            },
        },
    },
}
UPDATE_SCHEMA = {
    "type": "object",
    "required": ["updated"],
    "properties": {
        "updated": {
            "type": "array",
            "items": {"type": "string"},
            "description": "baseline folders written",
        }
    },
}


def store_options(command):
    """``--scenes-dir`` and ``--baselines-dir``: where shipped scenes and their baselines live."""
    directory = click.Path(file_okay=False, path_type=Path)
    command = click.option(
        "--baselines-dir",
        type=directory,
        default=BASELINES_DIR,
        help="Baseline folders [default: the shipped ones].",
    )(command)
    return click.option(
        "--scenes-dir",
        type=directory,
        default=SCENES_DIR,
        help="Scenes [default: the shipped ones].",
    )(command)


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
@click.option("--seed", type=SEED, default=BASELINE_SETTINGS.seed, show_default=True)
@click.option(
    "--check-spp",
    type=int,
    default=CHECK_SETTINGS.spp,
    show_default=True,
    help="Samples per pixel CI renders with.",
)
@click.option(
    "--check-seed",
    type=SEED,
    default=CHECK_SETTINGS.seed,
    show_default=True,
    help="Seed CI renders with (must differ from --seed).",
)
@store_options
@limit_options
@threads_option
@json_option(UPDATE_SCHEMA)
@requires("mitsuba", "drjit", "flip_evaluator")
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
    json_target: str | None,
    limits: RenderLimits,
) -> None:
    """Re-render the baselines of SCENES (names like eye_feather_sun, or stage paths)."""
    from click.core import ParameterSource

    from pavonine.render.settings import parse_resolution

    ctx = click.get_current_context()
    if is_packaged() and ctx.get_parameter_source("baselines_dir") == ParameterSource.DEFAULT:
        raise InputError(
            "--baselines-dir",
            f"the shipped baselines ({baselines_dir}) belong to the installed package; "
            "re-approve them in a source checkout, or name another folder",
        )

    if not scenes and not all_scenes:
        raise InputError("baseline update", "name at least one SCENE, or pass --all")
    for option, value in (("--spp", spp), ("--check-spp", check_spp)):
        if value <= 0:
            raise InputError(option, f"samples per pixel must be positive, got {value}")
    if seed == check_seed:
        raise InputError("--check-seed", "must differ from --seed (a check must not replay it)")
    size = None if resolution == "auto" else parse_resolution(resolution)
    limits.check_spp(spp, "--spp")
    limits.check_spp(check_spp, "--check-spp")
    if size is not None:
        limits.check_resolution(size, "--resolution")
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
    updated = []
    with progress_bar() as progress:
        task = progress.add_task("baselines", total=len(stages))
        for stage in stages:
            progress.update(task, description=f"rendering {scene_name(stage)}")
            made = update_baseline(
                stage,
                baselines_dir=baselines_dir,
                settings=CheckSettings(size, spp, seed),
                check=CheckSettings(size, check_spp, check_seed),
                command=command,
                limits=limits,
            )
            progress.advance(task)
            updated.append(str(made.directory))
            say(f"updated {made.directory}")
    emit_json(json_target, {"updated": updated})


@baseline.command("list")
@store_options
@json_option(LIST_SCHEMA)
@one_line_errors
def list_baselines(scenes_dir: Path, baselines_dir: Path, json_target: str | None) -> None:
    """Show each shipped scene and the baseline it is checked against.

    Exit 0 when every scene has a baseline, 1 when one is missing, 2 when there is no scene or
    no baseline at all.
    """
    from rich.table import Table

    from pavonine.apps.compare.baselines import stage_sha256

    stages = shipped_scenes(scenes_dir)
    if not stages:
        raise InputError(str(scenes_dir), "no scenes (*.usda naming their render settings) found")
    rows = []
    for stage in stages:
        directory = baselines_dir / scene_name(stage)
        row = {"scene": scene_name(stage), "stage": relative_to_repo(stage), "baseline": None}
        if (directory / MEAN_FILE).is_file():
            made = load_baseline(directory)
            row.update(
                baseline=relative_to_repo(directory),
                spp=made.settings.spp,
                check_spp=made.check_settings.spp,
                resolution=list(made.mean.size),
                created=made.info.get("created"),
                inputs_changed=made.recorded_sha256 not in (None, stage_sha256(stage)),
            )
        rows.append(row)
    if all(row["baseline"] is None for row in rows):
        raise InputError(str(baselines_dir), f"no baselines for the {len(rows)} scene(s) found")

    table = Table(title=f"baselines in {relative_to_repo(baselines_dir)}")
    table.add_column("scene", no_wrap=True)
    for column in ("spp", "check spp", "size", "made", "inputs since"):
        table.add_column(column)
    for row in rows:
        if row["baseline"] is None:
            table.add_row(row["scene"], "[red]missing[/]", "", "", "", "")
            continue
        table.add_row(
            row["scene"],
            str(row["spp"] if row["spp"] is not None else "?"),
            str(row["check_spp"]),
            "x".join(map(str, row["resolution"])),
            str(row["created"] or "?")[:10],
            "[yellow]changed[/]" if row["inputs_changed"] else "unchanged",
        )
    stdout_console().print(table)
    emit_json(
        json_target,
        {
            "scenes_dir": str(scenes_dir),
            "baselines_dir": str(baselines_dir),
            "baselines": rows,
        },
    )
    if any(row["baseline"] is None for row in rows):
        sys.exit(1)
