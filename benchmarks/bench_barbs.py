"""Barbs against the sheet, the sheet as yardstick, in the same run.

1. **Convert** the shipped eye recipe twice, alternately, best of ``--repeat``: as shipped (with
   its barbs) and with ``[geometry.barbs] enabled = false`` (the sheet only); prints both
   totals, the barbs' own stages and the ratio (target <= 2x).
2. **Render the hero view** (``assets/scenes/eye_feather_sun.usda``, the README's) with the
   feather's ``geometry`` variant ``sheet`` and ``barbs``, each in a fresh process (its own peak
   resident set): a warm-up pass, then the timed render; prints seconds, peak RSS and the
   ratios (targets <= 2x each).
3. ``--train``: the shipped train and the same train with its front row of eye feathers as
   barbs (``rows.5.geometry = "barbs"``, the innermost eye row), at ``--train-resolution`` (1024x768) and ``--spp``;
   prints the peak RSS of each and their ratio (target <= 1.5x).
4. ``--cycles`` (on whenever ``--bpy-python`` or ``$PAVONINE_BPY_PYTHON`` is given): Pavonine
   against Blender Cycles on the shipped ``assets/scenes/peacock_train.usda``, at
   ``--train-resolution`` and ``--spp`` (equal samples per pixel), ``--rounds`` alternating rounds
   of each, every render a fresh process measured from start to exit (scene load included on
   both sides): prints CPU seconds, peak RSS, each image's noise and the ratios Pavonine / Cycles
   (targets <= 1x). What each side renders: train_vs_cycles.py.

Usage: python benchmarks/bench_barbs.py [--resolution 512x768] [--spp 64] [--repeat 2] [--train]
       [--cycles [--bpy-python PY] [--rounds 2]] [--skip-convert] [--skip-hero]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).parents[1]
RECIPE = REPO / "assets" / "recipes" / "eye_feather.toml"
HERO = REPO / "assets" / "scenes" / "eye_feather_sun.usda"
TRAIN_SCENE = REPO / "assets" / "scenes" / "peacock_train.usda"
TRAIN_RECIPE = REPO / "assets" / "recipes" / "peacock_train.toml"
FRONT_ROW = "count = 28\nradius_cm = 32.4\n"
sys.path.insert(0, str(Path(__file__).parent))


def _recipes(folder: Path) -> dict[str, Path]:
    """The eye recipe as shipped and without barbs, its map paths made absolute."""
    text = RECIPE.read_text().replace('"maps/', f'"{RECIPE.parent / "maps"}/')
    out = {"barbs": folder / "eye_barbs.toml", "sheet": folder / "eye_sheet.toml"}
    out["barbs"].write_text(text)
    out["sheet"].write_text(text + "\n[geometry.barbs]\nenabled = false\n")
    return out


def convert(folder: Path, repeat: int) -> dict[str, dict]:
    """Best total convert seconds of each recipe, alternating."""
    from pavonine.pipeline.convert.batch import convert_recipe

    best: dict[str, dict] = {}
    recipes = _recipes(folder)
    for _ in range(repeat):
        for name, recipe in recipes.items():
            start = time.perf_counter()
            result = convert_recipe(recipe, folder / name, force=True)
            seconds = time.perf_counter() - start
            if name not in best or seconds < best[name]["seconds"]:
                best[name] = {"seconds": seconds, "stages": result.seconds, "barbs": result.barbs}
    return best


def in_child(function, *args):
    """``function(*args)`` in a fresh (spawned) Python process, so this one stays small.

    A child's ``ru_maxrss`` is never below the peak of the process it was started from: Linux
    keeps the high-water mark across ``fork`` and ``execve`` (getrusage(2)), and Python starts
    children with ``vfork``. Converting in this process (990 MiB peak, 2026-12-08) made every
    render measured after it report 990 MiB; the converts run in a child of their own instead.
    """
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    spawn = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(max_workers=1, mp_context=spawn) as pool:
        return pool.submit(function, *args).result()


def _scene(folder: Path, geometry: str) -> Path:
    """The hero scene with the feather's geometry variant selected (references made absolute)."""
    asset = REPO / "assets" / "feathers" / "eye_feather" / "eye_feather.usd"
    text = HERO.read_text().replace("@../feathers/eye_feather/eye_feather.usd@", f"@{asset}@")
    selection = f'@{asset}@\n        variants = {{ string geometry = "{geometry}" }}'
    path = folder / f"hero_{geometry}.usda"
    path.write_text(text.replace(f"@{asset}@", selection, 1))
    return path


def _train_scene(folder: Path, barbs: bool) -> Path:
    """The shipped train recipe assembled into ``folder`` (front row as barbs if ``barbs``)."""
    from click.testing import CliRunner

    from pavonine.apps.cli import cli

    text = TRAIN_RECIPE.read_text().replace('"../feathers/', f'"{REPO / "assets" / "feathers"}/')
    if barbs:
        text = text.replace(FRONT_ROW, FRONT_ROW + 'geometry = "barbs"\n')
    name = "train_barbs" if barbs else "train_sheet"
    (folder / f"{name}.toml").write_text(text)
    out = folder / name
    result = CliRunner().invoke(
        cli, ["assemble", "train", str(folder / f"{name}.toml"), "-o", str(out)]
    )
    if result.exit_code != 0:
        raise SystemExit(result.output)
    assembly = out / "peacock_train" / "peacock_train.usda"
    scene = folder / f"{name}.usda"
    scene.write_text(
        (REPO / "assets" / "scenes" / "peacock_train.usda")
        .read_text()
        .replace("@../assemblies/peacock_train/peacock_train.usda@", f"@{assembly}@")
    )
    return scene


def render(scene: Path, resolution: str, spp: int) -> dict:
    """One render in a child process (bench_train.py's ``--one``: warm-up, timed render, RSS)."""
    done = subprocess.run(
        [sys.executable, str(Path(__file__).with_name("bench_train.py")), "--one", str(scene),
         "--resolution", resolution, "--spp", str(spp)],
        capture_output=True, text=True, check=True,
    )  # fmt: skip
    return json.loads(done.stdout.strip().splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--resolution", default="512x768", help="of the hero view")
    parser.add_argument("--spp", type=int, default=64)
    parser.add_argument("--repeat", type=int, default=2, help="converts of each, best taken")
    parser.add_argument("--train", action="store_true", help="also the train's peak memory")
    parser.add_argument("--train-resolution", default="1024x768")
    parser.add_argument("--skip-convert", action="store_true")
    parser.add_argument("--skip-hero", action="store_true", help="no hero renders (part 2)")
    parser.add_argument("--cycles", action="store_true", help="also the train against Cycles")
    parser.add_argument("--bpy-python", help="python of the venv with bpy [$PAVONINE_BPY_PYTHON]")
    parser.add_argument("--cycles-spp", type=int, help="Cycles' samples per pixel [--spp]")
    parser.add_argument("--rounds", type=int, default=2, help="alternating rounds of each (>= 2)")
    parser.add_argument("--cycles-out", default=str(Path(tempfile.gettempdir()) / "bench_cycles"))
    args = parser.parse_args()
    if args.rounds < 2:
        parser.error("--rounds must be >= 2 (the noise of each side needs two images)")
    with tempfile.TemporaryDirectory(prefix="bench-barbs-") as tmp:
        folder = Path(tmp)
        if not args.skip_convert:
            found = in_child(convert, folder, args.repeat)
            sheet, barbs = found["sheet"], found["barbs"]
            own = barbs["stages"].get("barbs", 0.0)
            print(
                f"convert eye, sheet only: {sheet['seconds']:6.1f} s; with {barbs['barbs']} barbs: "
                f"{barbs['seconds']:6.1f} s (barbs stage {own:.1f} s, bake {barbs['stages']['bake']:.1f}"
                f" s vs {sheet['stages']['bake']:.1f} s)"
            )
            print(
                f"convert barbs / sheet: {barbs['seconds'] / sheet['seconds']:.2f}x (target <= 2x)"
            )
        if not args.skip_hero:
            hero_views(folder, args)
        if args.train:
            train_memory(folder, args)
        if args.cycles or args.bpy_python or os.environ.get("PAVONINE_BPY_PYTHON"):
            against_cycles(args)


def hero_views(folder: Path, args: argparse.Namespace) -> None:
    """Part 2: the hero view with the sheet and with the barbs, each in a fresh process."""
    hero = {g: render(_scene(folder, g), args.resolution, args.spp) for g in ("sheet", "barbs")}
    for name, r in hero.items():
        print(
            f"hero {name:<6} {args.resolution} @ {args.spp} spp: {r['seconds']:6.1f} s "
            f"({r['cpu_seconds']:.1f} s CPU, load {r['load']:.1f}), peak RSS {r['peak_mib']:.0f} MiB"
        )
    s, b = hero["sheet"], hero["barbs"]
    print(
        f"hero barbs / sheet: time {b['seconds'] / s['seconds']:.2f}x, "
        f"peak memory {b['peak_mib'] / s['peak_mib']:.2f}x (targets <= 2x)"
    )


def train_memory(folder: Path, args: argparse.Namespace) -> None:
    """Part 3: the train's peak memory with its front row as sheets and as barbs."""
    trains = {
        k: render(_train_scene(folder, k == "barbs"), args.train_resolution, args.spp)
        for k in ("sheet", "barbs")
    }
    for name, r in trains.items():
        print(
            f"train, front row {name:<6} {args.train_resolution} @ {args.spp} spp: "
            f"{r['seconds']:6.1f} s, peak RSS {r['peak_mib']:.0f} MiB"
        )
    ratio = trains["barbs"]["peak_mib"] / trains["sheet"]["peak_mib"]
    print(f"train barbs front row / sheet: peak memory {ratio:.2f}x (target <= 1.5x)")


def against_cycles(args: argparse.Namespace) -> None:
    """Part 4: the shipped train, Pavonine against Blender Cycles, alternating rounds."""
    from blender_barbs import _bpy_python
    from train_vs_cycles import compare

    width, height = (int(v) for v in args.train_resolution.split("x"))
    print(f"train {TRAIN_SCENE.name}, Pavonine vs Cycles, {args.rounds} alternating rounds:")
    compare(TRAIN_SCENE, (width, height), args.spp, args.rounds, _bpy_python(args.bpy_python),
            Path(args.cycles_out), args.cycles_spp)  # fmt: skip


if __name__ == "__main__":
    main()
