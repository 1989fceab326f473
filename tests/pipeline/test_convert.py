"""``pavonine convert``: a real, valid, movable USD component asset — and clean failures."""

from __future__ import annotations

import json
import re
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

pytest.importorskip("xatlas", reason="needs the [convert] extra", exc_type=ImportError)
pytestmark = pytest.mark.convert

from pavonine.apps.cli import cli
from pavonine.base.map_files import read_map, sample_bilinear, write_map
from pavonine.base.map_filters import prefilter
from pavonine.pipeline.convert.atlas import st_overlap_fraction
from pavonine.pipeline.convert.surface import FeatherFrame
from pavonine.pipeline.convert.topology import edge_report
from pavonine.pipeline.convert.vane import triangle_areas
from pavonine.pipeline.maps.paint import MAP_NAMES, generate_maps, write_maps
from pavonine.schemas.plugin import PLUGIN_DIR

LOD = {"high": 12_000, "medium": 4_000, "low": 1_000}
GEOMETRY = "[geometry]\nlength_cm = 20\nrachis_length = 0.74\ndisplacement_cm = 0.05\n"
BAKE = "[bake]\nresolution = 128\n"  # small textures: these tests are about geometry


def recipe_text(name: str, map_dir: str = "m", ext: str = "png", extra: str = "") -> str:
    maps = "\n".join(f'{m} = "{map_dir}/{m}.{ext}"' for m in MAP_NAMES)
    lod = "\n".join(f"{k} = {v}" for k, v in LOD.items())
    return (
        f'name = "{name}"\n{extra}[maps]\n{maps}\n[material]\npreset = "freyer2020"\n'
        f"{BAKE}{GEOMETRY}[geometry.lod]\n{lod}\n"
    )


def run(*args: str):
    result = CliRunner().invoke(cli, list(args))
    return result


@pytest.fixture(scope="module")
def workdir(tmp_path_factory) -> Path:
    work = tmp_path_factory.mktemp("convert")
    write_maps(generate_maps("eye", 256, seed=4), work / "m")
    (work / "eye.toml").write_text(recipe_text("eye_feather"))
    return work


@pytest.fixture(scope="module")
def asset(workdir) -> Path:
    result = run("convert", str(workdir / "eye.toml"), "-o", str(workdir / "out"))
    assert result.exit_code == 0, result.output
    root = workdir / "out" / "eye_feather" / "eye_feather.usd"
    assert root.is_file()
    return root


def open_lod(root: Path, lod: str):
    from pxr import Usd

    import pavonine  # noqa: F401  (registers the schema)

    stage = Usd.Stage.Open(str(root))
    stage.SetEditTarget(stage.GetSessionLayer())  # the asset's files stay as converted
    stage.GetDefaultPrim().GetVariantSet("lod").SetVariantSelection(lod)
    return stage


def mesh_arrays(stage, name: str) -> dict[str, np.ndarray]:
    from pxr import UsdGeom

    prim = stage.GetPrimAtPath(f"/eye_feather/Geom/{name}")
    mesh = UsdGeom.Mesh(prim)
    pv = UsdGeom.PrimvarsAPI(prim)
    counts = np.asarray(mesh.GetFaceVertexCountsAttr().Get())
    assert np.all(counts == 3)
    st = pv.GetPrimvar("st")
    return {
        "points": np.asarray(mesh.GetPointsAttr().Get(), dtype=np.float64),
        "faces": np.asarray(mesh.GetFaceVertexIndicesAttr().Get()).reshape(-1, 3),
        "normals": np.asarray(mesh.GetNormalsAttr().Get(), dtype=np.float64),
        "st": np.asarray(st.ComputeFlattened(), dtype=np.float64),
        "st_interp": st.GetInterpolation(),
        "uv": np.asarray(pv.GetPrimvar("pavonine_featherUV").Get(), dtype=np.float64),
        "uv_interp": pv.GetPrimvar("pavonine_featherUV").GetInterpolation(),
        "tangent": np.asarray(pv.GetPrimvar("pavonine_barbTangent").Get(), dtype=np.float64),
    }


FRESH = textwrap.dedent(
    """
    import json, sys
    from pxr import Usd, UsdGeom, UsdShade, Kind
    stage = Usd.Stage.Open(sys.argv[1])
    root = stage.GetDefaultPrim()
    models = [p.GetPath().pathString for p in stage.Traverse()
              if Usd.ModelAPI(p).GetKind() == Kind.Tokens.component]
    vset = root.GetVariantSet("lod")
    out = {"models": models, "lods": vset.GetVariantNames(), "selected": vset.GetVariantSelection(),
           "meters": UsdGeom.GetStageMetersPerUnit(stage), "up": UsdGeom.GetStageUpAxis(stage),
           "info": {k: str(v) for k, v in root.GetAssetInfo().items()},
           "xformable": bool(UsdGeom.Xformable(root)), "meshes": {}}
    for lod in vset.GetVariantNames():
        vset.SetVariantSelection(lod)
        for prim in stage.Traverse():
            if prim.IsA(UsdGeom.Mesh) and prim.GetParent().GetName() == "Geom":
                material, _ = UsdShade.MaterialBindingAPI(prim).ComputeBoundMaterial()
                out["meshes"][lod + ":" + prim.GetName()] = {
                    "faces": len(UsdGeom.Mesh(prim).GetFaceVertexCountsAttr().Get()),
                    "material": material.GetPath().pathString if material else None,
                    "schemas": list(material.GetPrim().GetPrimTypeInfo().GetAppliedAPISchemas())
                    if material else [],
                    "extent": bool(UsdGeom.Mesh(prim).GetExtentAttr().Get()),
                }
    print(json.dumps(out))
    """
)


def test_fresh_process_sees_one_component_with_three_lods(asset):
    env = {"PXR_PLUGINPATH_NAME": str(PLUGIN_DIR)}
    proc = subprocess.run(
        [sys.executable, "-c", FRESH, str(asset)], env=env, capture_output=True, text=True
    )
    assert proc.returncode == 0, proc.stderr
    info = json.loads(proc.stdout)
    assert info["models"] == ["/eye_feather"]
    assert sorted(info["lods"]) == ["high", "low", "medium"] and info["selected"] == "high"
    assert info["meters"] == pytest.approx(0.01) and info["up"] == "Y" and info["xformable"]
    assert info["info"]["name"] == "eye_feather" and "version" in info["info"]
    assert "identifier" in info["info"]
    for lod, target in LOD.items():
        vane, rachis = info["meshes"][f"{lod}:Vane"], info["meshes"][f"{lod}:Rachis"]
        assert vane["material"] == "/eye_feather/Materials/Feather"
        assert "PavonineFeatherAPI" in vane["schemas"]
        assert rachis["material"] == "/eye_feather/Materials/Rachis"
        assert vane["extent"] and rachis["extent"]
        assert 0.8 * target <= vane["faces"] + rachis["faces"] <= 1.25 * target
    assert info["meshes"]["high:Vane"]["faces"] > info["meshes"]["medium:Vane"]["faces"]
    assert info["meshes"]["medium:Vane"]["faces"] > info["meshes"]["low:Vane"]["faces"]


@pytest.mark.parametrize("lod", list(LOD))
def test_lod_meshes_are_manifold_with_a_valid_atlas(asset, lod):
    stage = open_lod(asset, lod)
    for name in ("Vane", "Rachis"):
        m = mesh_arrays(stage, name)
        assert m["st_interp"] == "faceVarying" and m["uv_interp"] == "vertex"
        assert edge_report(m["faces"], len(m["points"])) == {
            "non_manifold_edges": 0,
            "misoriented_edges": 0,
            "non_manifold_vertices": 0,
        }
        size = np.ptp(m["points"], axis=0).max()
        assert triangle_areas(m["points"], m["faces"]).min() > 1e-9 * size**2
        assert np.all((m["st"] >= 0) & (m["st"] <= 1))
        assert np.all((m["uv"] >= 0) & (m["uv"] <= 1))
        assert len(m["uv"]) == len(m["points"]) == len(m["tangent"]) == len(m["normals"])
        assert np.allclose(np.linalg.norm(m["normals"], axis=1), 1, atol=1e-4)
        assert np.allclose(np.sum(m["tangent"] * m["normals"], axis=1), 0, atol=1e-3)
    both = np.concatenate([mesh_arrays(stage, n)["st"] for n in ("Vane", "Rachis")])
    assert st_overlap_fraction(both, 1024) == 0.0


def test_vertex_heights_follow_the_displacement_map(asset, workdir):
    stage = open_lod(asset, "high")
    m = mesh_arrays(stage, "Vane")
    displacement = read_map(workdir / "m" / "displacement.png", "displacement")
    frame = FeatherFrame(20.0, displacement.shape[1] / displacement.shape[0], 1.5, 0.4)
    uv = m["uv"]
    height = np.sum((m["points"] - frame.position(uv)) * frame.normal(uv), axis=1)
    spacing = np.sqrt(np.mean(triangle_areas(uv * [frame.aspect, 1], m["faces"])) * 2)
    expected = 0.05 * sample_bilinear(prefilter(displacement, spacing), uv)
    assert np.corrcoef(height, expected)[0, 1] > 0.999
    assert np.max(np.abs(height - expected)) < 1e-3 * 0.05 + 1e-5
    assert np.ptp(height) > 0.2 * 0.05  # the streaks are real relief


def test_vane_follows_the_silhouette(asset, workdir):
    m = mesh_arrays(open_lod(asset, "high"), "Vane")
    alpha = read_map(workdir / "m" / "alpha.png", "alpha")
    inside = sample_bilinear(prefilter(alpha, 1 / 60), m["uv"])
    assert np.mean(inside > 0.15) > 0.95  # the vane is cut at alpha 0.25 (box-filtered)
    assert np.mean(inside > 0.9) > 0.5
    # and covers the whole feather, base to apex
    assert m["uv"][:, 1].min() < 0.05 and m["uv"][:, 1].max() > 0.95


def test_pavonine_validate_and_usd_validation_pass_clean(asset):
    result = run("validate", str(asset))
    assert result.exit_code == 0, result.output
    assert result.output.strip() == "1 file, no findings"
    from pxr import Usd, UsdValidation

    stage = Usd.Stage.Open(str(asset))
    registry = UsdValidation.ValidationRegistry()
    validators = [
        v for v in registry.GetOrLoadAllValidators() if not v.GetMetadata().name.startswith("pav")
    ]
    errors = UsdValidation.ValidationContext(validators).Validate(stage)
    messages = [e.GetMessage() for e in errors if not e.HasNoError()]
    # usd-core ships no usdMtlx, so Sdr knows no MaterialX node definition (docs/schema.md).
    lookup = re.compile(
        r"shaderId 'ND_\w+' specified on shader prim <[^>]+> not found in sdrRegistry"
    )
    assert [m for m in messages if not lookup.fullmatch(m.strip().rstrip("."))] == []


def test_asset_is_movable(asset, tmp_path):
    from pxr import Usd, UsdShade

    from pavonine.schemas.authoring import resolve_maps

    moved = tmp_path / "elsewhere" / "eye_feather"
    shutil.copytree(asset.parent, moved)
    stage = Usd.Stage.Open(str(moved / "eye_feather.usd"))
    vane = stage.GetPrimAtPath("/eye_feather/Geom/Vane")
    assert vane.IsValid()
    material, _ = UsdShade.MaterialBindingAPI(vane).ComputeBoundMaterial()
    maps = resolve_maps(material)
    assert set(maps) == set(MAP_NAMES)
    for path in maps.values():
        assert path is not None and Path(path).is_file()
        assert Path(path).is_relative_to(moved)
    text = (moved / "eye_feather.usd").read_text() + (
        moved / "eye_feather_material.usda"
    ).read_text()
    assert str(asset.parent) not in text


@pytest.mark.render
def test_moved_asset_renders(asset, tmp_path):
    moved = tmp_path / "eye_feather"
    shutil.copytree(asset.parent, moved)
    out = tmp_path / "r.exr"
    result = run(
        "render",
        str(moved / "eye_feather.usd"),
        "-o",
        str(out),
        "--spp",
        "2",
        "--resolution",
        "24x32",
        "-q",
    )
    assert result.exit_code == 0, result.output
    from pavonine.render.imageio import read_exr  # a render, not a map: HDR, beyond 1

    image, _ = read_exr(out)
    assert image.max() > 0


# ------------------------------------------------------------------ maps made by someone else


def _foreign_maps(folder: Path, size: tuple[int, int], fmt: str, bits: int) -> None:
    """Smooth grey maps of any resolution/format: an ellipse, two classes, a ramp, a wave."""
    import OpenImageIO as oiio

    h, w = size
    v, u = np.mgrid[0:h, 0:w]
    u = (u + 0.5) / w
    v = 1 - (v + 0.5) / h
    ellipse = ((u - 0.5) / 0.45) ** 2 + ((v - 0.5) / 0.45) ** 2 < 1
    maps = {
        "alpha": ellipse.astype(np.float32),
        "ocellar": np.where(v > 0.5, 0.0, 1.0),
        "gradation": v,
        "angle": np.full_like(u, 35 / 180),
        "displacement": 0.5 + 0.5 * np.sin(2 * np.pi * 3 * v),
        "melanin": np.ones_like(u),
    }
    folder.mkdir(parents=True, exist_ok=True)
    for name, values in maps.items():
        path = folder / f"{name}.{fmt}"
        if bits == 8:
            spec = oiio.ImageSpec(w, h, 1, oiio.UINT8)
            out = oiio.ImageOutput.create(str(path))
            out.open(str(path), spec)
            out.write_image(np.round(values * 255).astype(np.uint8)[..., None].copy())
            out.close()
        else:
            write_map(path, values)


def test_foreign_8bit_png_and_exr_maps_of_equal_aspect_convert(tmp_path):
    _foreign_maps(tmp_path / "a", (200, 100), "png", 8)
    _foreign_maps(tmp_path / "b", (120, 60), "exr", 16)
    # Mix them: the recipe may point at maps of different sizes and formats.
    text = recipe_text("mixed", "a").replace('"a/displacement.png"', '"b/displacement.exr"')
    text = text.replace('"a/gradation.png"', '"b/gradation.exr"')
    (tmp_path / "mixed.toml").write_text(text)
    result = run("convert", str(tmp_path / "mixed.toml"), "-o", str(tmp_path / "out"))
    assert result.exit_code == 0, result.output
    root = tmp_path / "out" / "mixed" / "mixed.usd"
    assert run("validate", str(root)).exit_code == 0
    from pxr import Usd, UsdGeom

    stage = Usd.Stage.Open(str(root))
    prim = stage.GetPrimAtPath("/mixed/Geom/Vane")
    uv = np.asarray(UsdGeom.PrimvarsAPI(prim).GetPrimvar("pavonine_featherUV").Get())
    points = np.asarray(UsdGeom.Mesh(prim).GetPointsAttr().Get(), dtype=np.float64)
    frame = FeatherFrame(20.0, 0.5, 1.5, 0.4)
    height = np.sum((points - frame.position(uv)) * frame.normal(uv), axis=1)
    wave = 0.05 * (0.5 + 0.5 * np.sin(2 * np.pi * 3 * uv[:, 1]))
    assert np.max(np.abs(height - wave)) < 0.05 * 0.04  # smooth map: the mesh follows it


# ------------------------------------------------------------------ bad input


def _bad_case(workdir: Path, tmp_path: Path, case: str) -> tuple[Path, str, str]:
    """A recipe for ``case`` and the file and field its error must name."""
    folder = tmp_path / "m"
    shutil.copytree(workdir / "m", folder)
    recipe = tmp_path / "bad.toml"
    recipe.write_text(recipe_text("bad_feather"))
    if case == "aspect":
        write_map(folder / "ocellar.png", np.ones((64, 64), np.float32))
        return recipe, str(folder / "ocellar.png"), "maps.ocellar"
    if case == "unreadable":
        (folder / "angle.png").write_bytes(b"not an image at all")
        return recipe, str(folder / "angle.png"), "maps.angle"
    if case == "transparent":
        write_map(folder / "alpha.png", np.zeros((256, 128), np.float32))
        return recipe, str(folder / "alpha.png"), "maps.alpha"
    if case == "missing":
        (folder / "melanin.png").unlink()
        return recipe, str(folder / "melanin.png"), "maps.melanin"
    if case in ("below-range", "above-range"):  # float maps are not clipped into [0, 1]
        key, value = ("melanin", -3.0) if case == "below-range" else ("gradation", 7.0)
        _float_exr(folder / f"{key}.exr", np.full((256, 128), value, np.float32))
        recipe.write_text(recipe_text("bad_feather").replace(f"m/{key}.png", f"m/{key}.exr"))
        return recipe, str(folder / f"{key}.exr"), f"maps.{key}: values outside [0, 1]"
    recipe.write_text(recipe_text("bad_feather") + "[render]\nspp = 3\n")
    return recipe, str(recipe), "render"


def _float_exr(path: Path, values: np.ndarray) -> None:
    """A single-channel float EXR as someone else writes it (``write_map`` would clip)."""
    import OpenImageIO as oiio

    out = oiio.ImageOutput.create(str(path))
    out.open(str(path), oiio.ImageSpec(values.shape[1], values.shape[0], 1, "float"))
    out.write_image(values[..., None].copy())
    out.close()


@pytest.mark.parametrize(
    "case",
    ["aspect", "unreadable", "transparent", "missing", "unknown-key", "below-range", "above-range"],
)
def test_bad_input_fails_on_one_line_and_writes_nothing(workdir, tmp_path, case):
    recipe, file, field = _bad_case(workdir, tmp_path, case)
    out = tmp_path / "out"
    result = run("convert", str(recipe), "-o", str(out))
    assert result.exit_code == 2
    # exactly one line: no blank line left behind by a progress bar (stderr is no terminal here)
    assert result.stderr.startswith("error: ") and result.stderr.count("\n") == 1
    line = result.stderr.strip()
    assert file in line and field in line
    assert "Traceback" not in result.output
    assert not out.exists()


def test_existing_asset_is_replaced_only_with_force(workdir, tmp_path):
    recipe = tmp_path / "eye.toml"
    recipe.write_text(recipe_text("eye_feather", str(workdir / "m")))
    out = tmp_path / "out"
    assert run("convert", str(recipe), "-o", str(out)).exit_code == 0
    marker = out / "eye_feather" / "stale.txt"
    marker.write_text("old")
    again = run("convert", str(recipe), "-o", str(out))
    assert again.exit_code == 2 and "--force" in again.stderr and marker.exists()
    forced = run("convert", str(recipe), "-o", str(out), "--force")
    assert forced.exit_code == 0, forced.output
    assert not marker.exists() and (out / "eye_feather" / "eye_feather.usd").is_file()
    assert sorted(p.name for p in out.iterdir()) == ["eye_feather"]  # no temp folders left


def test_batch_in_parallel_keeps_going_and_names_the_failure(workdir, tmp_path):
    good = []
    for name in ("one", "two"):
        path = tmp_path / f"{name}.toml"
        path.write_text(recipe_text(name, str(workdir / "m")))
        good.append(path)
    bad = tmp_path / "broken.toml"
    bad.write_text(recipe_text("broken", str(workdir / "m")).replace("freyer2020", "ostrich"))
    out = tmp_path / "out"
    result = run("convert", str(good[0]), str(bad), str(good[1]), "-o", str(out), "--jobs", "2")
    assert result.exit_code == 2
    assert (out / "one" / "one.usd").is_file() and (out / "two" / "two.usd").is_file()
    assert not (out / "broken").exists()
    assert f"FAILED  {bad}" in result.stderr and "material.preset" in result.stderr
    assert "2 converted, 1 failed" in result.stderr


def test_fractional_layer_count_fails_before_meshing_naming_the_recipe_key(workdir, tmp_path):
    recipe = tmp_path / "frac.toml"
    extra = "[material.class.0.long]\ncount = 4.5\n"
    recipe.write_text(
        recipe_text("frac", str(workdir / "m")).replace("[geometry]\n", extra + "[geometry]\n")
    )
    out = tmp_path / "out"
    result = run("convert", str(recipe), "-o", str(out))
    assert result.exit_code == 2
    assert (
        result.stderr
        == f"error: {recipe}: material.class.0.long.count: a layer count must be a whole number, got 4.5\n"
    )
    assert not out.exists()


def test_failed_write_leaves_no_output_folder(workdir, tmp_path, monkeypatch):
    from pavonine.base.errors import InputError
    from pavonine.pipeline.convert import batch as convert

    def fail(folder, *args):
        (folder / "partial.usda").write_text("#usda 1.0\n")
        raise InputError(str(folder), "disk on fire")

    monkeypatch.setattr(convert, "write_asset", fail)
    recipe = tmp_path / "eye.toml"
    recipe.write_text(recipe_text("eye_feather", str(workdir / "m")))
    out = tmp_path / "deep" / "out"
    with pytest.raises(InputError, match="disk on fire"):
        convert.convert_recipe(recipe, out)
    assert not (tmp_path / "deep").exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["eye.toml"]  # no staging folder left


def test_output_below_a_file_is_bad_input_on_one_line(workdir, tmp_path):
    recipe = tmp_path / "eye.toml"
    recipe.write_text(recipe_text("eye_feather", str(workdir / "m")))
    blocker = tmp_path / "somefile"
    blocker.write_text("not a folder")
    result = run("convert", str(recipe), "-o", str(blocker / "sub"))
    assert result.exit_code == 2, result.output
    assert (
        result.stderr.startswith(f"error: {blocker / 'sub'}: ") and result.stderr.count("\n") == 1
    )
    assert "internal error" not in result.stderr and blocker.read_text() == "not a folder"


def test_os_errors_in_a_worker_are_one_line_bad_input(monkeypatch):
    import errno

    from pavonine.pipeline.convert import batch as convert

    def full_disk(*args, **kwargs):
        raise OSError(errno.ENOSPC, "No space left on device", "/assets/eye_feather")

    monkeypatch.setattr(convert, "convert_recipe", full_disk)
    result = convert._convert_safely("eye.toml", "/assets", force=False)
    assert result.bad_input
    assert result.error == "/assets/eye_feather: No space left on device"


def test_batch_with_one_name_twice_is_rejected_before_converting(workdir, tmp_path):
    first, second = tmp_path / "eye.toml", tmp_path / "eye2.toml"
    for path in (first, second):
        path.write_text(recipe_text("eye_feather", str(workdir / "m")))
    out = tmp_path / "race"
    result = run("convert", str(first), str(second), "-o", str(out), "--jobs", "2")
    assert result.exit_code == 2
    assert result.stderr.startswith("error: ") and result.stderr.count("\n") == 1
    assert str(first) in result.stderr and str(second) in result.stderr
    assert "eye_feather" in result.stderr and not out.exists()


def test_commit_refuses_to_replace_an_asset_without_force(tmp_path):
    from pavonine.base.errors import InputError
    from pavonine.pipeline.convert.asset import commit_asset

    target = tmp_path / "eye_feather"
    target.mkdir()
    (target / "eye_feather.usd").write_text("first")
    staging = tmp_path / ".eye_feather.tmp-1"
    staging.mkdir()
    (staging / "eye_feather.usd").write_text("second")
    # another writer committed between our existence check and our rename
    with pytest.raises(InputError, match="--force"):
        commit_asset(staging, target)
    assert (target / "eye_feather.usd").read_text() == "first"
    commit_asset(staging, target, force=True)
    assert (target / "eye_feather.usd").read_text() == "second" and not staging.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["eye_feather"]


def _channels(path: Path) -> int:
    import OpenImageIO as oiio

    image = oiio.ImageInput.open(str(path))
    try:
        return image.spec().nchannels
    finally:
        image.close()


def test_asset_maps_are_the_single_channel_values_the_geometry_used(tmp_path):
    """An RGB source map is stored as its luma (what the mesh was displaced by), not as RGB
    whose first channel (what the renderer reads) differs; float sources stay EXR."""
    import OpenImageIO as oiio
    from pxr import Usd

    import pavonine  # noqa: F401  (registers the schema)
    from pavonine.schemas.authoring import resolve_maps

    _foreign_maps(tmp_path / "m", (120, 60), "exr", 16)
    h, w = 120, 60
    u = np.tile((np.arange(w) + 0.5) / w, (h, 1)).astype(np.float32)
    rgb = np.stack([u, 1 - u, np.full_like(u, 0.5)], axis=-1)  # red and green disagree
    spec = oiio.ImageSpec(w, h, 3, oiio.UINT16)
    out = oiio.ImageOutput.create(str(tmp_path / "m" / "rgb.png"))
    out.open(str(tmp_path / "m" / "rgb.png"), spec)
    out.write_image(np.round(rgb * 65535).astype(np.uint16))
    out.close()
    text = recipe_text("rgb", "m", "exr").replace('"m/melanin.exr"', '"m/rgb.png"')
    (tmp_path / "rgb.toml").write_text(text)
    result = run("convert", str(tmp_path / "rgb.toml"), "-o", str(tmp_path / "out"))
    assert result.exit_code == 0, result.output
    root = tmp_path / "out" / "rgb" / "rgb.usd"
    stage = Usd.Stage.Open(str(root))
    paths = resolve_maps(stage.GetPrimAtPath("/rgb/Materials/Feather"))
    assert set(paths) == set(MAP_NAMES)
    for name, path in paths.items():
        path = Path(path)
        assert path.parent == root.parent / "maps" and path.stem == name
        assert path.suffix == (".png" if name == "melanin" else ".exr")
        assert _channels(path) == 1
    luma = rgb @ np.array([0.2126, 0.7152, 0.0722], dtype=np.float32)
    stored = read_map(Path(paths["melanin"]), "melanin")
    assert np.max(np.abs(stored - luma)) < 1e-4
    assert np.max(np.abs(stored - rgb[..., 0])) > 0.5  # the first channel would have been wrong
    stored_grey = read_map(Path(paths["gradation"]), "gradation")
    assert np.max(np.abs(stored_grey - read_map(tmp_path / "m" / "gradation.exr", "g"))) == 0
    assert run("validate", str(root)).exit_code == 0
