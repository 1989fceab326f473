"""``pavonine convert``: recipes in, feather component assets out (one, or many in parallel).

One recipe runs the stages

    maps → mesh (silhouette-cut vane, rachis) → atlas (xatlas, coarse) →
    refine+displace (high LOD) → lods (medium, low: refine + quadric decimation) →
    barbs (every barb as a ribbon, ``[geometry.barbs]``) →
    bake (textures over the atlas, the barbs' colours, MaterialX document) → write

and its asset appears atomically. Many recipes run in worker processes (``jobs``); one
failing recipe does not stop the others and the summary names each failure.
"""

from __future__ import annotations

import multiprocessing
import os
import signal
import time
import traceback
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from pavonine.base.commit import recover
from pavonine.base.errors import InputError
from pavonine.base.faults import checkpoint
from pavonine.base.limits import MAX_MAP_ASPECT, MIN_MAP_SIDE, name_too_long
from pavonine.base.map_files import DataMap, check_aspects, read_data_map
from pavonine.materials.parameters import ParameterError
from pavonine.pipeline.convert.asset import (
    LODS,
    check_outdir,
    in_threads,
    map_paths,
    staging_folder,
    write_asset,
)
from pavonine.pipeline.convert.barb_curves import build_barbs
from pavonine.pipeline.convert.barb_layer import barb_colors
from pavonine.pipeline.convert.barb_polylines import BarbCurves
from pavonine.pipeline.convert.mesh import RACHIS_SHARE, MeshData, build_base, build_lod
from pavonine.pipeline.convert.rachis import RachisSpec
from pavonine.pipeline.convert.recipe import Recipe, asset_seed, parameter_key, parse_recipe
from pavonine.pipeline.convert.surface import FeatherFrame
from pavonine.pipeline.maps.paint import MAP_NAMES
from pavonine.pipeline.shading.looks import Looks

STAGES = ("maps", "mesh", "atlas", "refine+displace", "lods", "barbs", "bake", "write")


@dataclass
class ConvertResult:
    """Outcome of one recipe: the root layer, triangles per LOD and seconds per stage."""

    recipe: str
    name: str = ""
    root: Path | None = None
    triangles: dict[str, int] = field(default_factory=dict)
    barbs: int = 0  # barbs in the ``geometry = barbs`` variant (0: none written)
    seconds: dict[str, float] = field(default_factory=dict)
    error: str | None = None
    bad_input: bool = False
    meshes: dict[str, list[MeshData]] | None = None  # only with ``keep_meshes``
    barb_curves: BarbCurves | None = None  # only with ``keep_meshes``

    @property
    def ok(self) -> bool:
        return self.error is None


class _Timer:
    def __init__(self, sink: dict[str, float], report: Callable[[str], None] | None):
        self.sink = sink
        self.report = report

    def stage(self, name: str):
        timer = self

        class _Stage:
            def __enter__(self):
                if timer.report:
                    timer.report(name)
                self.start = time.perf_counter()

            def __exit__(self, *exc):
                timer.sink[name] = timer.sink.get(name, 0.0) + time.perf_counter() - self.start

        return _Stage()


def load_maps(recipe: Recipe) -> dict[str, DataMap]:
    """Read the six maps and check them together (equal aspect; a visible silhouette)."""
    from pavonine.base.groups import settle

    settle([recipe.maps[name] for name in MAP_NAMES])  # crashed writers' commits, once, first
    read = in_threads(lambda name: read_data_map(recipe.maps[name], f"maps.{name}"), MAP_NAMES)
    maps = dict(zip(MAP_NAMES, read, strict=True))
    check_maps(recipe, {name: data.values for name, data in maps.items()})
    return maps


def check_maps(recipe: Recipe, maps: dict[str, np.ndarray]) -> None:
    """Raise :class:`InputError` naming the file and field for maps that cannot make a feather."""
    ref_h, ref_w = maps["alpha"].shape
    ref_aspect = ref_w / ref_h
    where = f"{recipe.maps['alpha']}: maps.alpha"
    if min(ref_h, ref_w) < MIN_MAP_SIDE:
        raise InputError(
            where, f"{ref_w}x{ref_h} pixels; each side must be at least {MIN_MAP_SIDE} pixels"
        )
    if not 1.0 / MAX_MAP_ASPECT <= ref_aspect <= MAX_MAP_ASPECT:
        raise InputError(
            where,
            f"{ref_w}x{ref_h} pixels: width:height must lie in [1:{MAX_MAP_ASPECT:g}, "
            f"{MAX_MAP_ASPECT:g}:1] (the maps span the feather's length and width)",
        )
    check_aspects(
        {name: maps[name] for name in MAP_NAMES},
        {name: f"{recipe.maps[name]}: maps.{name}" for name in MAP_NAMES},
    )
    threshold = recipe.geometry.alpha_threshold
    if float(maps["alpha"].max()) <= threshold:
        raise InputError(
            f"{recipe.maps['alpha']}: maps.alpha",
            f"fully transparent (no pixel above the cut threshold {threshold})",
        )


def build_meshes(
    recipe: Recipe,
    maps: dict[str, np.ndarray],
    timer: _Timer,
) -> tuple[dict[str, list[MeshData]], BarbCurves | None]:
    """The three LODs of a recipe's feather and, when the recipe enables them, its barbs
    (stages mesh, atlas, refine+displace, lods, barbs)."""
    opts = recipe.geometry
    height, width = maps["alpha"].shape
    frame = FeatherFrame(opts.length_cm, width / height, opts.bend_cm, opts.cup_cm)
    rachis = RachisSpec(
        opts.calamus_cm, opts.rachis_length, opts.rachis_radius_cm, opts.rachis_tip_radius_cm
    )
    with timer.stage("mesh"):
        try:
            geo, atlas_seconds = build_base(
                maps["alpha"],
                maps["displacement"],
                frame,
                rachis,
                opts.displacement_cm,
                opts.alpha_threshold,
                base_triangles_for(opts.base_triangles, opts.lod.high),
                rachis_triangles=round(RACHIS_SHARE * opts.lod.low),
                low_triangles=opts.lod.low,
            )
        except ValueError as exc:
            raise InputError(f"{recipe.maps['alpha']}: maps.alpha", str(exc)) from None
    # build_base times xatlas itself; book it under "atlas", not "mesh".
    timer.sink["mesh"] -= atlas_seconds
    timer.sink["atlas"] = timer.sink.get("atlas", 0.0) + atlas_seconds
    lods: dict[str, list[MeshData]] = {}
    with timer.stage("refine+displace"):
        lods["high"] = build_lod(geo, opts.lod.high, decimate=False)
    with timer.stage("lods"):
        lods["medium"] = build_lod(geo, opts.lod.medium, decimate=True)
        lods["low"] = build_lod(geo, opts.lod.low, decimate=True)
    if not opts.barbs.enabled:
        return lods, None
    with timer.stage("barbs"):
        barbs = build_barbs(
            maps,
            geo.barb_field,
            frame,
            rachis,
            opts.barbs,
            opts.displacement_cm,
            opts.form,
            asset_seed(recipe.name) if opts.form.seed is None else opts.form.seed,
        )
    return lods, barbs


def base_triangles_for(preferred: int, high: int) -> int:
    """Coarse-mesh size so that regular refinement lands on the high target: ``high / n²``
    with ``n`` the whole number of splits nearest to ``√(high / preferred)``."""
    vane_high = (1.0 - RACHIS_SHARE) * high
    n = max(1, round((vane_high / preferred) ** 0.5))
    return max(200, round(vane_high / n**2))


def convert_recipe(
    recipe_path: str | os.PathLike,
    outdir: str | os.PathLike,
    *,
    force: bool = False,
    report: Callable[[str], None] | None = None,
    keep_meshes: bool = False,
) -> ConvertResult:
    """Convert one recipe into ``outdir/<name>/``. Raises :class:`InputError` for bad input.

    ``keep_meshes`` returns the LOD meshes in the result (for benchmarks and tests).
    """
    result = ConvertResult(str(recipe_path))
    timer = _Timer(result.seconds, report)
    recipe = parse_recipe(recipe_path)
    result.name = recipe.name
    checkpoint("convert.recipe", recipe.name)
    outdir = Path(outdir)
    too_long = name_too_long(recipe.name, outdir)
    if too_long:
        raise InputError(f"{recipe.path}: name", too_long)
    target = outdir / recipe.name
    if target.exists() and not force:
        raise InputError(str(target), "asset exists; pass --force to replace it")
    check_outdir(outdir)
    with timer.stage("maps"):
        maps = load_maps(recipe)
    values = {name: data.values for name, data in maps.items()}
    lods, barbs = build_meshes(recipe, values, timer)
    with staging_folder(outdir, recipe.name, force) as folder:
        try:
            with timer.stage("bake"):
                vane = next(mesh for mesh in lods["high"] if mesh.name == "Vane")
                looks = Looks.bake(
                    folder,
                    recipe.name,
                    vane,
                    values,
                    map_paths(maps),
                    recipe.material,
                    recipe.bake.resolution,
                )
                if barbs is not None:
                    barbs.display_color = barb_colors(barbs, values, recipe.material)
            with timer.stage("write"):
                write_asset(
                    folder, recipe.name, recipe.version, recipe.material, maps, lods, looks, barbs
                )
        except ParameterError as exc:
            raise InputError(f"{recipe.path}: {parameter_key(exc.field)}", exc.reason) from None
    result.root = target / f"{recipe.name}.usd"
    result.triangles = {lod: sum(m.triangle_count for m in lods[lod]) for lod in LODS}
    result.barbs = 0 if barbs is None else barbs.barb_count
    if keep_meshes:
        result.meshes = lods
        result.barb_curves = barbs
    return result


def _convert_safely(
    recipe_path: str, outdir: str, force: bool, report: Callable[[str], None] | None = None
) -> ConvertResult:
    """Worker entry point: never raises; failures come back in the result."""
    try:
        return convert_recipe(recipe_path, outdir, force=force, report=report)
    except (InputError, ParameterError) as exc:
        return ConvertResult(recipe_path, error=str(exc), bad_input=True)
    except OSError as exc:  # unwritable output, a file where a folder should be, a full disk
        where = exc.filename if exc.filename is not None else outdir
        return ConvertResult(recipe_path, error=f"{where}: {exc.strerror or exc}", bad_input=True)
    except MemoryError:  # maps within the pixel budget can still be too much for this machine
        return ConvertResult(
            recipe_path,
            error=f"{recipe_path}: out of memory while converting (use smaller maps, or a lower "
            "pixel budget: --max-pixels, docs/reliability.md)",
            bad_input=True,
        )
    except Exception as exc:  # a bug: keep the batch going, report where it happened
        frame = traceback.extract_tb(exc.__traceback__)[-1]
        where = f"{Path(frame.filename).name}:{frame.lineno}"
        return ConvertResult(recipe_path, error=f"internal error ({where}): {exc!r}")


def check_unique_names(recipes: Sequence[str]) -> None:
    """Raise :class:`InputError` when two recipes name the same asset (they would race for one
    folder). Recipes that do not parse are left to fail on their own."""
    seen: dict[str, str] = {}
    for path in recipes:
        try:
            name = parse_recipe(path).name
        except (InputError, ParameterError):
            continue
        if name in seen:
            raise InputError(
                f"{path}: name",
                f"asset {name!r} is also made by {seen[name]}; "
                "give each recipe of a batch its own name",
            )
        seen[name] = path


def convert_many(
    recipes: Sequence[str],
    outdir: str | os.PathLike,
    *,
    jobs: int = 1,
    force: bool = False,
    on_done: Callable[[ConvertResult], None] | None = None,
    on_stage: Callable[[str, str], None] | None = None,
) -> list[ConvertResult]:
    """Convert every recipe; ``jobs > 1`` uses that many worker processes.

    Results come back in the order of ``recipes``; ``on_done`` is called as each finishes
    and ``on_stage(recipe, stage)`` (in-process runs only) as each stage starts. Two recipes
    naming the same asset raise :class:`InputError` before anything is converted.
    """
    check_unique_names(recipes)
    outdir = str(outdir)
    results: dict[int, ConvertResult] = {}
    if jobs <= 1 or len(recipes) <= 1:
        for i, path in enumerate(recipes):
            report = None
            if on_stage is not None:

                def report(stage: str, path: str = path) -> None:
                    on_stage(path, stage)

            results[i] = _convert_safely(path, outdir, force, report)
            if on_done:
                on_done(results[i])
    else:
        for i, result in _convert_in_processes(recipes, outdir, force, jobs):
            results[i] = result
            if on_done:
                on_done(result)
    return [results[i] for i in range(len(recipes))]


def _worker(recipe_path: str, outdir: str, force: bool, sender) -> None:
    """Worker process body: convert one recipe and send its result to the parent."""
    sender.send(_convert_safely(recipe_path, outdir, force))
    sender.close()


def _convert_in_processes(recipes: Sequence[str], outdir: str, force: bool, jobs: int):
    """Yield ``(index, result)`` as recipes finish, each in a process of its own, ``jobs`` at
    a time. A worker that dies (killed, out of memory) fails its own recipe only: the others
    go on, and what it staged is removed (:func:`pavonine.base.commit.recover`)."""
    from multiprocessing.connection import wait

    context = multiprocessing.get_context()
    pending = list(enumerate(recipes))
    running: dict[object, tuple[int, multiprocessing.Process]] = {}
    try:
        while pending or running:
            while pending and len(running) < jobs:
                i, path = pending.pop(0)
                receiver, sender = context.Pipe(duplex=False)
                process = context.Process(
                    target=_worker, args=(path, outdir, force, sender), daemon=True
                )
                process.start()
                sender.close()
                running[receiver] = (i, process)
            for receiver in wait(list(running)):
                i, process = running.pop(receiver)
                try:
                    result = receiver.recv()
                except EOFError:  # died before sending its result
                    process.join()
                    result = ConvertResult(recipes[i], error=_death(process.exitcode))
                    recover(outdir)
                receiver.close()
                process.join()
                yield i, result
    finally:
        for _, process in running.values():
            process.kill()
            process.join()
        if running:
            recover(outdir)


def _death(exitcode: int | None) -> str:
    """Why a worker ended without a result, in words."""
    if exitcode is not None and exitcode < 0:
        try:
            name = signal.Signals(-exitcode).name
        except ValueError:
            name = f"signal {-exitcode}"
        return f"worker process was killed ({name}); nothing was written for this recipe"
    return f"worker process exited with status {exitcode}; nothing was written for this recipe"
