"""``pavonine convert --scheduler``: feather recipes converted on a Dask cluster.

Each recipe is one task (:func:`pavonine.apps.farm.tasks.convert_task`): the worker checks
the recipe and its maps by content against the client's hashes, converts into its own temporary
folder and sends the asset's files back; the client writes each asset atomically (a hidden
staging folder renamed into place, as ``pavonine convert`` does), so workers need read access to
the inputs only. Results and failures are reported per recipe, as in a local batch.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from pathlib import Path

from pavonine.apps.farm.tasks import (
    ConvertedAsset,
    ConvertTask,
    convert_task,
    files_sha256,
    recipe_inputs,
)
from pavonine.base.errors import InputError
from pavonine.materials.parameters import ParameterError
from pavonine.pipeline.convert.asset import staging_folder
from pavonine.pipeline.convert.batch import ConvertResult, check_unique_names
from pavonine.pipeline.convert.recipe import parse_recipe


def write_converted(asset: ConvertedAsset, outdir: Path, force: bool) -> Path:
    """Write a worker's asset files into ``outdir/<name>/`` atomically; returns the root layer."""
    with staging_folder(outdir, asset.name, force) as folder:
        for relative, data in asset.files.items():
            target = folder / relative
            target.parent.mkdir(parents=True, exist_ok=True)
            target.write_bytes(data)
    return outdir / asset.name / f"{asset.name}.usd"


def convert_on_cluster(
    recipes: Sequence[str],
    outdir: str | os.PathLike,
    client,
    *,
    force: bool = False,
    on_done: Callable[[ConvertResult], None] | None = None,
) -> list[ConvertResult]:
    """Convert every recipe on ``client``'s cluster; results in the order of ``recipes``."""
    from distributed import as_completed

    from pavonine import __version__

    check_unique_names(recipes)
    outdir = Path(outdir)
    results: dict[int, ConvertResult] = {}
    futures = {}

    def finish(i: int, result: ConvertResult) -> None:
        results[i] = result
        if on_done:
            on_done(result)

    for i, path in enumerate(recipes):
        try:
            recipe = parse_recipe(path)
            if (outdir / recipe.name).exists() and not force:
                raise InputError(
                    str(outdir / recipe.name), "asset exists; pass --force to replace it"
                )
            for name, map_path in recipe.maps.items():
                if not map_path.is_file():
                    raise InputError(f"{map_path}: maps.{name}", "no such file")
            task = ConvertTask(str(recipe.path), files_sha256(recipe_inputs(path)), __version__)
        except (InputError, ParameterError) as exc:
            finish(i, ConvertResult(path, error=str(exc), bad_input=True))
            continue
        futures[client.submit(convert_task, task, pure=False)] = i
    for future in as_completed(list(futures)):
        i = futures[future]
        path = recipes[i]
        try:
            asset = future.result()
            root = write_converted(asset, outdir, force)
        except (InputError, ParameterError) as exc:
            finish(i, ConvertResult(path, error=str(exc), bad_input=True))
            continue
        except OSError as exc:
            where = exc.filename if exc.filename is not None else outdir
            finish(i, ConvertResult(path, error=f"{where}: {exc.strerror or exc}", bad_input=True))
            continue
        except Exception as exc:  # a worker lost too often, a crash in the converter
            finish(i, ConvertResult(path, error=f"farm: {type(exc).__name__}: {exc}"))
            continue
        finish(
            i,
            ConvertResult(
                path,
                asset.name,
                root,
                triangles=dict(asset.triangles),
                barbs=asset.barbs,
                seconds=dict(asset.seconds),
            ),
        )
        future.release()
    return [results[i] for i in range(len(recipes))]
