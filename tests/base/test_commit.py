"""Crash safety (issue 14, "Data loss" and "Outside the output"): the real CLI killed with SIGKILL
at every named commit step (``PAVONINE_FAULT``, :mod:`pavonine.base.faults`) leaves every
output either the complete old version or the complete new one, never a mix or nothing, and
writes nothing outside its output folder. Harness: ``tests/fault_harness.py``."""

from __future__ import annotations

import json
import shutil
import threading
import time
from pathlib import Path

import numpy as np
import pytest
from fault_harness import hidden_entries, pavonine, snapshot, version_of

from pavonine.base.commit import recover

pytestmark = pytest.mark.faults

REPO = Path(__file__).parents[2]
QUAD = REPO / "tests" / "data" / "render" / "bare_quad.usda"
MAPS = ("alpha", "ocellar", "gradation", "angle", "displacement", "melanin")


def recipe(name: str, maps: Path, version: str, high: int) -> str:
    """A small, fast feather recipe (64-pixel maps, a few thousand triangles)."""
    lines = "\n".join(f'{m} = "{maps}/{m}.png"' for m in MAPS)
    return (
        f'name = "{name}"\nversion = "{version}"\n[maps]\n{lines}\n'
        '[material]\npreset = "freyer2020"\n[bake]\nresolution = 32\n'
        f"[geometry]\nlength_cm = 20\n[geometry.lod]\nhigh = {high}\nmedium = 800\nlow = 300\n"
    )


@pytest.fixture(scope="module")
def feathers(tmp_path_factory) -> dict:
    """Recipes of an old (1.0) and a new (2.0) version of one feather, and what each converts
    to on its own (the versions a reader may see)."""
    pytest.importorskip("xatlas", reason="needs the [convert] extra", exc_type=ImportError)
    from pavonine.pipeline.maps.paint import generate_maps, write_maps

    work = tmp_path_factory.mktemp("feathers")
    write_maps(generate_maps("eye", 64, seed=4), work / "maps")
    recipes = {}
    for label, version, high in (("old", "1.0", 2000), ("new", "2.0", 1500)):
        recipes[label] = work / f"{label}.toml"
        recipes[label].write_text(recipe("tiny", work / "maps", version, high))
    versions = {}
    for label, path in recipes.items():
        run = pavonine("convert", path, "-o", work / label, "-q")
        assert run.returncode == 0, run.stderr
        versions[label] = snapshot(work / label / "tiny")
    assert versions["old"] != versions["new"]
    return {"work": work, "recipes": recipes, "versions": versions}


def old_asset(feathers: dict, tmp_path: Path) -> Path:
    """A copy of the old asset in a fresh OUTDIR."""
    outdir = tmp_path / "out"
    shutil.copytree(feathers["work"] / "old", outdir)
    return outdir


@pytest.mark.convert
@pytest.mark.parametrize("step", ["staging.written", "folder.exchanged"])
def test_convert_force_crash_leaves_the_old_or_the_new_asset_never_nothing(
    feathers, tmp_path, step
):
    outdir = old_asset(feathers, tmp_path)
    run = pavonine("convert", feathers["recipes"]["new"], "-o", outdir, "--force", fault=step)
    assert run.killed, run.stderr
    expected = {"staging.written": "old", "folder.exchanged": "new"}[step]
    assert version_of(snapshot(outdir / "tiny"), feathers["versions"]) == expected
    assert [p.name for p in outdir.iterdir() if not p.name.startswith(".")] == ["tiny"]
    recover(outdir)  # what the next run does first (a real next run: the missing-OUTDIR test)
    assert hidden_entries(outdir) == []
    assert version_of(snapshot(outdir / "tiny"), feathers["versions"]) == expected


@pytest.mark.convert
@pytest.mark.parametrize("step", ["staging.written", "folder.exchanged"])
def test_bake_crash_leaves_the_old_or_the_new_asset(feathers, rebaked, tmp_path, step):
    outdir = old_asset(feathers, tmp_path)
    versions = {"old": feathers["versions"]["old"], "new": rebaked}
    killed = pavonine("bake", outdir / "tiny", "--resolution", "16", fault=step)
    assert killed.killed
    expected = {"staging.written": "old", "folder.exchanged": "new"}[step]
    assert version_of(snapshot(outdir / "tiny"), versions) == expected
    recover(outdir)
    assert hidden_entries(outdir) == []


@pytest.fixture(scope="module")
def rebaked(feathers, tmp_path_factory) -> dict[str, str]:
    """The old asset re-baked at 16 texels, by a run that was not interrupted."""
    scratch = tmp_path_factory.mktemp("rebaked")
    shutil.copytree(feathers["work"] / "old" / "tiny", scratch / "tiny")
    assert pavonine("bake", scratch / "tiny", "--resolution", "16", "-q").returncode == 0
    files = snapshot(scratch / "tiny")
    assert files != feathers["versions"]["old"]
    return files


@pytest.mark.parametrize("step", ["staging.written", "folder.exchanged"])
def test_assemble_force_crash_leaves_the_old_or_the_new_assembly(tmp_path, step):
    shipped = (REPO / "assets" / "recipes" / "peacock_train.toml").read_text()
    text = shipped.replace('"../feathers/', f'"{REPO / "assets" / "feathers"}/')
    recipes = {}
    for label, seed in (("old", "7"), ("new", "8")):
        recipes[label] = tmp_path / f"{label}.toml"
        recipes[label].write_text(text.replace("\nseed = 7\n", f"\nseed = {seed}\n"))
    versions = {}
    for label in ("new", "old"):  # the old one stays in place
        run = pavonine("assemble", "train", recipes[label], "-o", tmp_path / "out", "--force")
        assert run.returncode == 0, run.stderr
        versions[label] = snapshot(tmp_path / "out" / "peacock_train")
    assert versions["old"] != versions["new"]
    killed = pavonine("assemble", "train", recipes["new"], "-o", tmp_path / "out", "--force",
                      fault=step)  # fmt: skip
    assert killed.killed
    expected = {"staging.written": "old", "folder.exchanged": "new"}[step]
    assert version_of(snapshot(tmp_path / "out" / "peacock_train"), versions) == expected
    recover(tmp_path / "out")
    assert hidden_entries(tmp_path / "out") == []


@pytest.mark.convert
def test_readers_polling_the_asset_during_convert_force_never_see_it_missing(feathers, tmp_path):
    outdir = old_asset(feathers, tmp_path)
    root = outdir / "tiny" / "tiny.usd"
    contents = {feathers["versions"][v]["tiny.usd"] for v in ("old", "new")}
    seen: dict[str, int] = {"polls": 0, "missing": 0, "other": 0}
    stop = threading.Event()

    def poll() -> None:
        import hashlib

        while not stop.is_set():
            seen["polls"] += 1
            try:
                digest = hashlib.sha256(root.read_bytes()).hexdigest()
            except FileNotFoundError:
                seen["missing"] += 1
                continue
            seen["other"] += digest not in contents
            time.sleep(0.0002)  # leave the converter a core; a swap is one step either way

    reader = threading.Thread(target=poll)
    reader.start()
    try:
        run = pavonine("convert", feathers["recipes"]["new"], "-o", outdir, "--force", "-q")
    finally:
        stop.set()
        reader.join()
    assert run.returncode == 0, run.stderr
    assert seen["polls"] > 100 and seen["missing"] == 0 and seen["other"] == 0, seen
    assert version_of(snapshot(outdir / "tiny"), feathers["versions"]) == "new"


@pytest.mark.convert
def test_convert_into_a_missing_outdir_stages_inside_it_never_outside(feathers, tmp_path):
    parent = tmp_path / "new"
    outdir = parent / "deeper" / "out"
    run = pavonine("convert", feathers["recipes"]["new"], "-o", outdir, fault="staging.written")
    assert run.killed
    # The staging folder is inside OUTDIR (created first), nowhere else.
    assert sorted(p.name for p in tmp_path.iterdir()) == ["new"]
    assert [p.name for p in (parent / "deeper").iterdir()] == ["out"]
    assert [n for n in hidden_entries(outdir) if ".pavonine-staging-" in n]
    assert not (outdir / "tiny").exists()
    again = pavonine("convert", feathers["recipes"]["new"], "-o", outdir, "-q")
    assert again.returncode == 0, again.stderr
    assert hidden_entries(outdir) == [] and [p.name for p in outdir.iterdir()] == ["tiny"]


@pytest.mark.convert
def test_killed_convert_jobs_2_worker_loses_only_its_own_recipe(feathers, tmp_path):
    """Killed with its asset complete in staging: the batch goes on, the staging goes."""
    other = tmp_path / "other.toml"
    other.write_text(feathers["recipes"]["new"].read_text().replace('"tiny"', '"other"'))
    outdir = tmp_path / "out"
    run = pavonine(
        "convert", feathers["recipes"]["new"], other, "-o", outdir, "--jobs", "2",
        fault="staging.written@other",
    )  # fmt: skip
    assert run.returncode == 1, run.stderr
    assert "BrokenProcessPool" not in run.stderr and "Traceback" not in run.stderr
    failed = [line for line in run.stderr.splitlines() if line.startswith("FAILED")]
    assert failed == [
        f"FAILED  {other}: worker process was killed (SIGKILL); nothing was written for this recipe"
    ]
    assert version_of(snapshot(outdir / "tiny"), feathers["versions"]) == "new"
    assert sorted(p.name for p in outdir.iterdir()) == ["tiny"]  # no staging left


@pytest.mark.convert
def test_commit_fallback_without_rename_exchange_crashed_midway_is_completed_by_recovery(
    feathers, tmp_path
):
    """Where the file system refuses RENAME_EXCHANGE the asset is replaced file by file: killed
    half-way, the folder is still there (whole files, a mix of versions) and the next run
    completes it."""
    import subprocess
    import sys

    outdir = old_asset(feathers, tmp_path)
    staging = outdir / ".tiny.pavonine-staging-999999999-x"  # its owner: no such process
    shutil.copytree(feathers["work"] / "new" / "tiny", staging)
    script = (
        "import sys; from pathlib import Path; from pavonine.base import commit; "
        "commit.exchange_supported = False; "
        "commit.commit_folder(Path(sys.argv[1]), Path(sys.argv[2]), replace=True)"
    )
    killed = subprocess.run(
        [sys.executable, "-c", script, str(staging), str(outdir / "tiny")],
        env={**__import__("os").environ, "PAVONINE_FAULT": "folder.moving"},
    )
    assert killed.returncode == -9
    state = snapshot(outdir / "tiny")
    assert state and all(
        digest in (feathers["versions"]["old"].get(k), feathers["versions"]["new"].get(k))
        for k, digest in state.items()
    )  # every file whole, old or new
    assert recover(outdir)
    assert version_of(snapshot(outdir / "tiny"), feathers["versions"]) == "new"
    assert hidden_entries(outdir) == []


def test_commit_fallback_replaces_the_folder_and_leaves_nothing_hidden(tmp_path, monkeypatch):
    from pavonine.base import commit

    monkeypatch.setattr(commit, "exchange_supported", False)
    target = tmp_path / "asset"
    (target / "sub").mkdir(parents=True)
    (target / "a.usd").write_text("old a")
    (target / "gone.usd").write_text("old only")
    (target / "sub" / "b.dat").write_text("old b")
    with commit.staged_folder(target, replace=True) as staging:
        (staging / "a.usd").write_text("new a")
        (staging / "sub").mkdir()
        (staging / "sub" / "b.dat").write_text("new b")
    assert snapshot(target) == snapshot(
        _tree(tmp_path / "ref", {"a.usd": "new a", "sub/b.dat": "new b"})
    )
    assert hidden_entries(tmp_path) == []


def _tree(folder: Path, files: dict[str, str]) -> Path:
    for relative, text in files.items():
        (folder / relative).parent.mkdir(parents=True, exist_ok=True)
        (folder / relative).write_text(text)
    return folder


def test_rename_exchange_swaps_two_folders_in_one_step(tmp_path):
    from pavonine.base.commit import exchange

    a, b = _tree(tmp_path / "a", {"x": "A"}), _tree(tmp_path / "b", {"x": "B"})
    if not exchange(a, b):
        pytest.skip("this file system has no RENAME_EXCHANGE (the fallback is tested above)")
    assert (a / "x").read_text() == "B" and (b / "x").read_text() == "A"


@pytest.mark.mitsuba
@pytest.mark.render
@pytest.mark.parametrize("step", ["staging.written", "folder.exchanged"])
def test_baseline_update_crash_leaves_the_old_or_the_new_baseline(tmp_path, step):
    bdir = tmp_path / "baselines"
    args = ("baseline", "update", QUAD, "--resolution", "12x12", "--check-spp", "64",
            "--baselines-dir", bdir, "--scenes-dir", tmp_path, "-q")  # fmt: skip
    versions = {}
    for label, spp in (("new", "256"), ("old", "192")):  # the old one stays in place
        run = pavonine(*args, "--spp", spp)
        assert run.returncode == 0, run.stderr
        versions[label] = _baseline_files(bdir / "bare_quad")
    killed = pavonine(*args, "--spp", "256", fault=step)
    assert killed.killed
    expected = {"staging.written": "old", "folder.exchanged": "new"}[step]
    assert version_of(_baseline_files(bdir / "bare_quad"), versions) == expected
    assert [p.name for p in bdir.iterdir() if not p.name.startswith(".")] == ["bare_quad"]
    recover(bdir)
    assert hidden_entries(bdir) == []


def _baseline_files(folder: Path) -> dict[str, str]:
    """The baseline's images by content (EXRs by their pixels: OpenImageIO stamps the time in
    the header), and its record without the time it was made."""
    import hashlib

    from pavonine.render.imageio import read_exr

    files = snapshot(folder)
    for name in [k for k in files if k.endswith(".exr")]:
        files[name] = hashlib.sha256(read_exr(folder / name)[0].tobytes()).hexdigest()
    record = json.loads((folder / "baseline.json").read_text())
    files["baseline.json"] = json.dumps(record["baseline"])
    return files


@pytest.mark.mitsuba
@pytest.mark.render
def test_render_exr_png_crash_leaves_each_file_whole_the_pair_detectable_and_recoverable(
    tmp_path,
):
    """``render -o X.exr --png``: both files are committed from one journalled step (EXR, then
    PNG). Killed once the journal is written but before the first rename, both files are the
    old pair; killed between the two renames, the EXR is new and the PNG old, their
    ``pavonine:render_id`` differ and the journal names the pending rename. Either way recovery
    (the next render into the folder) rolls the new pair forward."""
    from pavonine.render.imageio import read_exr

    out = tmp_path / "x.exr"
    args = ("render", QUAD, "-o", out, "--png", "--spp", "4", "--resolution", "16x16", "-q")

    def render_id(path: Path) -> str:
        return read_exr(path)[1]["pavonine:render_id"]

    assert pavonine(*args, "--seed", "1").returncode == 0
    old = {p: render_id(tmp_path / p) for p in ("x.exr", "x.png")}
    assert old["x.exr"] == old["x.png"]
    old_pixels = read_exr(out)[0]

    killed = pavonine(*args, "--seed", "2", fault="files.journal")
    assert killed.killed
    assert {p: render_id(tmp_path / p) for p in ("x.exr", "x.png")} == old
    # The journal on disk is the commit point: recovery rolls the whole pair forward.
    assert recover(tmp_path) == [f"completed {out}", f"completed {tmp_path / 'x.png'}"]
    new_id = render_id(out)
    assert render_id(tmp_path / "x.png") == new_id != old["x.exr"]
    assert hidden_entries(tmp_path) == []
    old = {"x.exr": new_id, "x.png": new_id}
    old_pixels = read_exr(out)[0]

    killed = pavonine(*args, "--seed", "3", fault="files.renaming")
    assert killed.killed
    assert render_id(out) != old["x.exr"] and render_id(tmp_path / "x.png") == old["x.png"]
    assert not np.array_equal(read_exr(out)[0], old_pixels)  # the new render, whole
    assert [n for n in hidden_entries(tmp_path) if ".pavonine-journal-" in n]
    assert recover(tmp_path) == [f"completed {tmp_path / 'x.png'}"]
    assert render_id(out) == render_id(tmp_path / "x.png") != old["x.png"]
    assert hidden_entries(tmp_path) == []


def map_versions(outdir: Path) -> tuple[tuple, dict[str, dict[str, str]]]:
    """``maps`` arguments writing into ``outdir`` and the two versions (seed 1 "old", in place;
    seed 2 "new"), by file content."""
    args = ("maps", "eye", "-o", outdir, "--size", "64", "--no-contact-sheet", "-q")
    versions = {}
    for label, seed in (("new", "2"), ("old", "1")):
        assert pavonine(*args, "--seed", seed).returncode == 0
        versions[label] = snapshot(outdir)
    return args, versions


@pytest.mark.parametrize("step", ["files.journal", "files.renaming"])
def test_maps_crash_leaves_whole_maps_and_recovery_completes_the_set(tmp_path, step):
    outdir = tmp_path / "maps"
    args, versions = map_versions(outdir)
    assert pavonine(*args, "--seed", "2", fault=step).killed
    state = snapshot(outdir)
    if step == "files.journal":
        assert version_of(state, versions) == "old"
    else:  # the first map renamed: each file whole, the set mixed until recovery
        assert set(state) == set(versions["old"])
        assert all(state[k] in (versions["old"][k], versions["new"][k]) for k in state)
    recover(outdir)  # the journal is the commit point: the new set, whole
    assert version_of(snapshot(outdir), versions) == "new"
    assert hidden_entries(outdir) == []
    assert sorted(p.name for p in tmp_path.iterdir()) == ["maps"]


@pytest.mark.parametrize("step", ["files.renaming", "folder.moving"])
def test_ctrl_c_in_the_middle_of_a_commit_rolls_it_forward(tmp_path, monkeypatch, step):
    """An interrupt between two renames of a group (or two moves of the fallback) finishes the
    commit before it propagates: never a mix left behind by a handled interruption."""
    from pavonine.base import commit

    def interrupt(reached: str, subject: str | None = None) -> None:
        if reached == step:
            raise KeyboardInterrupt

    monkeypatch.setattr(commit, "checkpoint", interrupt)
    monkeypatch.setattr(commit, "exchange_supported", False)
    old = _tree(tmp_path / "out", {"a.bin": "old", "a.dat": "old", "b.txt": "old"})
    with pytest.raises(KeyboardInterrupt):
        if step == "files.renaming":
            temporaries = _tree(tmp_path / "new", {"a.bin": "new", "a.dat": "new"})
            commit.commit_files([(temporaries / n, old / n) for n in ("a.bin", "a.dat")])
        else:
            with commit.staged_folder(old, replace=True) as staging:
                _tree(staging, {"a.bin": "new", "a.dat": "new", "b.txt": "new"})
    assert {p.name: p.read_text() for p in old.iterdir()} == {
        "a.bin": "new", "a.dat": "new", "b.txt": "new" if step == "folder.moving" else "old",
    }  # fmt: skip
    assert hidden_entries(tmp_path / "out") == [] and hidden_entries(tmp_path) == []


# ------------------------------------------------------------------ groups: kills between renames
def _copy_without_hidden(folder: Path, to: Path) -> Path:
    """The files a backup or ``rsync --exclude '.*'`` of ``folder`` would take: no journal."""
    to.mkdir()
    for path in folder.iterdir():
        if not path.name.startswith("."):
            shutil.copy2(path, to / path.name)
    return to


@pytest.mark.mitsuba
@pytest.mark.render
@pytest.mark.parametrize("after", [1, 2])
def test_render_group_killed_between_any_two_renames_is_never_read_as_a_mix(tmp_path, after):
    """``render -o x.exr --png --variance`` commits three files (EXR, variance, PNG), killed
    after the first or the second rename. Each file stays whole. A Pavonine reader (``compare``)
    settles the group before reading: it completes the dead writer's commit (the journal is the
    commit point) and reads the new version. Where the journal is gone (a copy without hidden
    files, a read-only folder) the mix is refused in one line naming both files."""
    from pavonine.base.groups import read_mark

    out = tmp_path / "render" / "x.exr"
    files = [out, out.with_suffix(".variance.exr"), out.with_suffix(".png")]
    args = ("render", QUAD, "-o", out, "--png", "--variance", "--spp", "4",
            "--resolution", "16x16", "-q")  # fmt: skip
    assert pavonine(*args, "--seed", "1").returncode == 0
    old = read_mark(out).id
    assert [read_mark(f).id for f in files] == [old] * 3

    assert pavonine(*args, "--seed", "2", fault=f"files.renaming#{after}").killed
    ids = [read_mark(f).id for f in files]
    assert ids[after:] == [old] * (3 - after) and old not in ids[:after]  # renamed in order
    new = ids[0]

    copy = _copy_without_hidden(out.parent, tmp_path / "copy")
    refused = pavonine("compare", copy / "x.exr", copy / "x.exr")
    lines = refused.stderr.strip().splitlines()
    assert refused.returncode == 2 and len(lines) == 1, refused.stderr
    assert lines[0].startswith(f"error: {copy}/x.") and "mix of two versions" in lines[0], lines

    read = pavonine("compare", out, out, "-q")  # settles: completes the commit, then reads
    assert read.returncode == 0, read.stderr
    assert [read_mark(f).id for f in files] == [new] * 3
    assert hidden_entries(out.parent) == []


def test_maps_killed_between_any_two_renames_are_never_read_as_a_mixed_set(tmp_path):
    """``maps`` commits six maps by six renames; killed after each of the first five, every
    reader of a map (``read_data_map``: convert, bake, export) completes the set before it reads,
    and refuses a mixed set whose journal is gone, naming the map and the other file."""
    from pavonine.base.errors import InputError
    from pavonine.base.map_files import read_data_map

    outdir = tmp_path / "maps"
    args, versions = map_versions(outdir)
    renamed = sorted(versions["old"])  # the order of the renames
    for after in range(1, len(renamed)):
        assert pavonine(*args, "--seed", "2", fault=f"files.renaming#{after}").killed
        state = snapshot(outdir)
        assert [state[n] == versions["new"][n] for n in renamed] == [True] * after + [False] * (
            len(renamed) - after
        )
        copy = _copy_without_hidden(outdir, tmp_path / f"copy{after}")
        for name in (renamed[0], renamed[-1]):  # a new map and an old one
            with pytest.raises(InputError, match="mix of two versions") as caught:
                read_data_map(copy / name, "maps.x")
            assert str(caught.value).startswith(f"{copy / name}: maps.x: is from another write")
        read_data_map(outdir / renamed[-1], "maps.x")  # settles the set first
        assert version_of(snapshot(outdir), versions) == "new"
        assert hidden_entries(outdir) == []
        assert pavonine(*args, "--seed", "1").returncode == 0  # back to the old set


def test_a_reader_waits_while_a_live_writer_is_between_two_renames(tmp_path):
    """A reader never reads a group while a live writer is half-way through renaming it: it
    waits for the commit (or, past its time limit, says who is writing), and once the writer
    is dead it completes the commit itself."""
    import os
    import subprocess

    from pavonine.base.errors import TEMPORARY_MARK, InputError
    from pavonine.base.groups import check_group, read_mark
    from pavonine.pipeline.maps.paint import generate_maps, write_maps

    folder, staging = tmp_path / "maps", tmp_path / "maps" / ".staging"
    maps = generate_maps("eye", 16, seed=1)
    write_maps(maps, folder, group_id="old")
    write_maps(maps, staging, group_id="new")
    names = sorted(p.name for p in staging.iterdir())
    os.replace(staging / names[0], folder / names[0])  # the writer's first rename
    writer = subprocess.Popen(["sleep", "60"])  # a live process owning the journal
    journal = folder / f".{names[0]}{TEMPORARY_MARK}journal-{writer.pid}-x.json"
    journal.write_text(json.dumps([[str(staging / n), str(folder / n)] for n in names]))
    try:
        with pytest.raises(InputError, match=f"being replaced by process {writer.pid}"):
            check_group(folder / names[0], timeout=0.2)

        def finish() -> None:
            time.sleep(0.3)
            for name in names[1:]:
                os.replace(staging / name, folder / name)
            journal.unlink()

        threading.Thread(target=finish).start()
        began = time.monotonic()
        assert check_group(folder / names[-1]).id == "new"
        assert time.monotonic() - began >= 0.25
        assert {read_mark(folder / n).id for n in names} == {"new"}

        write_maps(maps, staging, group_id="newer")  # the same again, and the writer dies
        os.replace(staging / names[0], folder / names[0])
        journal.write_text(json.dumps([[str(staging / n), str(folder / n)] for n in names]))
    finally:
        writer.kill()
        writer.wait()
    assert check_group(folder / names[-1]).id == "newer"  # completed by the reader
    assert {read_mark(folder / n).id for n in names} == {"newer"} and not journal.exists()


@pytest.mark.mitsuba
@pytest.mark.render
def test_a_baseline_mixed_from_two_updates_is_refused_by_its_readers(tmp_path):
    """Where folders cannot be exchanged a baseline is replaced file by file; its files carry
    one group mark (and ``baseline.json`` its id), so ``check-renders`` and ``baseline`` refuse
    a baseline mixed from two updates instead of comparing against it."""
    from pavonine.apps.compare.baselines import load_baseline
    from pavonine.base.errors import InputError

    bdir = tmp_path / "baselines"
    args = ("baseline", "update", QUAD, "--resolution", "12x12", "--check-spp", "64",
            "--baselines-dir", bdir, "--scenes-dir", tmp_path, "-q")  # fmt: skip
    folders = {}
    for label, spp in (("old", "192"), ("new", "256")):
        assert pavonine(*args, "--spp", spp).returncode == 0
        folders[label] = shutil.copytree(bdir / "bare_quad", tmp_path / label / "bare_quad")
    load_baseline(folders["old"])  # each whole version reads
    load_baseline(folders["new"])
    for mixed_in, named in (("mean.exr", "mean.exr"), ("baseline.json", "baseline.json")):
        mixed = shutil.copytree(folders["old"], tmp_path / f"mix-{named}" / "bare_quad")
        shutil.copy2(folders["new"] / mixed_in, mixed / mixed_in)
        with pytest.raises(InputError, match="mix of two versions") as caught:
            load_baseline(mixed)
        assert str(caught.value).startswith(f"{mixed / named}: "), caught.value
