"""Short writes and over-long names (issue 27): a file a library reported written but cut short
is a write error, checked from the file's own structure after the write; a copy's full disk
names the output, not the package's source file; a name the file system cannot hold is refused
when the recipe is read, and a clean-up never trips over the path that is the problem."""

from __future__ import annotations

import errno
import os
import shutil
from pathlib import Path

import numpy as np
import pytest

from pavonine.base.errors import InputError, write_error
from pavonine.base.truncation import (
    cut_short,
    refuse_size_other_than,
    save_whole,
    text_layer_cut_short,
)

FULL = os.strerror(errno.ENOSPC)


def _cuts(path: Path) -> list[int]:
    size = path.stat().st_size
    return [size - 1, size // 2, 40]


@pytest.mark.parametrize("suffix", [".png", ".exr"])
def test_a_map_cut_short_anywhere_is_found_and_the_whole_one_passes(tmp_path, suffix):
    from pavonine.base.map_files import write_map

    whole = tmp_path / f"map{suffix}"
    write_map(whole, np.random.default_rng(1).random((300, 200), dtype=np.float32))
    assert cut_short(whole) is None
    data = whole.read_bytes()
    for cut in _cuts(whole):
        short = tmp_path / f"short{suffix}"
        short.write_bytes(data[:cut])
        reason = cut_short(short)
        assert reason is not None and f"{cut:,} bytes" in reason, (cut, reason)


def test_a_render_exr_and_png_cut_short_are_found(tmp_path):
    from pavonine.render.imageio import write_exr, write_png

    rgb = np.random.default_rng(2).random((40, 60, 3), dtype=np.float32)
    write_exr(tmp_path / "r.exr", rgb, {})
    write_png(tmp_path / "r.png", rgb)
    for name in ("r.exr", "r.png"):
        whole = tmp_path / name
        assert cut_short(whole) is None
        for cut in _cuts(whole):
            (tmp_path / f"c{name}").write_bytes(whole.read_bytes()[:cut])
            assert cut_short(tmp_path / f"c{name}") is not None, (name, cut)


def test_a_png_with_an_unwritten_tail_or_an_empty_file_is_found(tmp_path):
    png = tmp_path / "a.png"
    png.write_bytes(b"")
    assert cut_short(png) == "the file is empty"
    png.write_bytes(b"\0" * 100)  # a hole: the start of the file never reached the disk
    assert "does not begin" in cut_short(png)


def test_a_crate_layer_cut_short_is_found_and_a_text_layer_by_its_export(tmp_path):
    from pxr import Usd, UsdGeom

    for suffix in (".usdc", ".usda"):
        path = tmp_path / f"x{suffix}"
        stage = Usd.Stage.CreateNew(str(path))
        UsdGeom.Mesh.Define(stage, "/M").CreatePointsAttr([(1, 2, 3)] * 500)
        layer = stage.GetRootLayer()
        save_whole(layer, path)  # whole: no error
        assert text_layer_cut_short(layer, path) is None
        data = path.read_bytes()
        for cut in (len(data) - 1, len(data) // 2):
            path.write_bytes(data[:cut])
            reason = text_layer_cut_short(layer, path)
            assert reason is not None and f"{cut:,} bytes" in reason, (suffix, cut)
        assert (cut_short(path) is None) == (suffix == ".usda")  # text: checked by its export


def test_a_document_of_another_size_than_written_is_a_write_error_naming_the_output(tmp_path):
    written = tmp_path / ".x.pavonine-tmp-1-abc.mtlx"
    written.write_bytes(b"<?xml" + b" " * 4091)
    with pytest.raises(InputError) as caught:
        refuse_size_other_than(written, 10_744, tmp_path / "x.mtlx")
    assert caught.value.where == str(tmp_path / "x.mtlx")
    assert "4,096 bytes, its structure needs 10,744" in caught.value.message


def test_a_full_disk_while_copying_names_the_output_not_the_source(tmp_path):
    """``shutil.copyfile`` reports ENOSPC with the *source* as ``filename`` (and the output as
    ``filename2``): the package's ``materials/pavonine_feather.mtlx`` used to be named."""
    source = "/site-packages/pavonine/materials/pavonine_feather.mtlx"
    staging = tmp_path / ".tiny.pavonine-staging-1-x"
    tmp = staging / ".pavonine_feather.pavonine-tmp-1-y.mtlx"
    copy = OSError(errno.ENOSPC, FULL, source, None, str(tmp))
    mapped = write_error(copy, tmp_path / "tiny", staging)
    assert mapped.where == str(tmp_path / "tiny") and mapped.message == f"cannot write: {FULL}"
    tree = shutil.Error([(source, str(staging / "a.mtlx"), f"[Errno 28] {FULL}: {source!r}")])
    mapped = write_error(tree, tmp_path / "tiny", staging)
    assert mapped.where == str(tmp_path / "tiny" / "a.mtlx"), mapped
    unreadable = OSError(errno.EIO, "Input/output error", source, None, str(tmp))  # a read error
    assert write_error(unreadable, tmp_path / "tiny", staging) is None


def test_a_full_disk_while_copying_is_one_line_naming_the_output_at_the_command_line(capsys):
    from pavonine.base.errors import one_line_errors

    @one_line_errors
    def command() -> None:
        raise OSError(errno.ENOSPC, FULL, "/pkg/source.mtlx", None, "out/tiny/x.mtlx")

    with pytest.raises(SystemExit):
        command()
    assert capsys.readouterr().err == f"error: out/tiny/x.mtlx: {FULL}\n"


def test_a_staged_folder_whose_name_is_too_long_leaves_no_folder(tmp_path):
    """The clean-up's own existence check raised 'File name too long' and left ``out/``."""
    from pavonine.base.commit import staged_folder

    with pytest.raises(InputError, match="File name too long"):
        with staged_folder(tmp_path / "out" / ("a" * 300), replace=False):
            pass
    assert list(tmp_path.iterdir()) == []


def _recipe(tmp_path: Path, name: str) -> Path:
    maps = "\n".join(f'{m} = "m/{m}.png"' for m in ("alpha", "ocellar", "gradation", "angle",
                                                    "displacement", "melanin"))  # fmt: skip
    path = tmp_path / "r.toml"
    path.write_text(f'name = "{name}"\n[maps]\n{maps}\n[material]\npreset = "freyer2020"\n')
    return path


def test_a_name_longer_than_the_file_system_allows_is_refused_when_the_recipe_is_read(tmp_path):
    from pavonine.base.limits import NAME_OVERHEAD
    from pavonine.pipeline.convert.recipe import parse_recipe

    name_max = os.pathconf(tmp_path, "PC_NAME_MAX")
    longest = name_max - NAME_OVERHEAD
    with pytest.raises(InputError) as caught:
        parse_recipe(_recipe(tmp_path, "a" * 300))
    assert caught.value.where == f"{tmp_path / 'r.toml'}: name"
    assert f"allows {name_max} (NAME_MAX" in caught.value.message
    assert f"at most {longest} characters" in caught.value.message
    with pytest.raises(InputError, match=f"at most {longest} "):
        parse_recipe(_recipe(tmp_path, "a" * (longest + 1)))
    assert parse_recipe(_recipe(tmp_path, "a" * longest)).name == "a" * longest


def test_a_name_making_the_deepest_path_longer_than_path_max_is_refused_with_the_limit(tmp_path):
    from pavonine.base.limits import name_too_long

    path_max = os.pathconf(tmp_path, "PC_PATH_MAX")
    deep = tmp_path / "/".join(["d" * 200] * ((path_max - 400) // 201))
    reason = name_too_long("a" * 200, deep)
    assert reason is not None and f"PATH_MAX of {path_max}" in reason, reason
    assert name_too_long("a" * 20, tmp_path) is None


@pytest.mark.convert
def test_convert_with_a_300_character_name_leaves_no_output_folder(tmp_path):
    from fault_harness import one_line_error, pavonine

    run = pavonine("convert", _recipe(tmp_path, "a" * 300), "-o", tmp_path / "out")
    one_line_error(run, f"{tmp_path / 'r.toml'}: name", "NAME_MAX")
    assert not (tmp_path / "out").exists()
