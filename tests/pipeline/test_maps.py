"""Procedural maps (paper §3.3): encodings, look, file format, the ``pavonine maps`` command."""

from __future__ import annotations

import itertools
import re
import shlex
from pathlib import Path

import numpy as np
import OpenImageIO as oiio
import pytest
from click.testing import CliRunner

from pavonine.apps.cli import cli
from pavonine.base.map_files import read_map, sample_bilinear, write_map
from pavonine.pipeline.maps.paint import (
    KINDS,
    MAP_NAMES,
    MEASURED_GRADATION,
    angle_degrees,
    angle_grey,
    generate_maps,
    ocellar_class,
    ocellar_grey,
)

SIZE = 160


@pytest.fixture(scope="module")
def eye() -> dict[str, np.ndarray]:
    return generate_maps("eye", SIZE, seed=3)


def _at(values: np.ndarray, u: float, v: float) -> float:
    return float(sample_bilinear(values, np.array([[u, v]]))[0])


@pytest.mark.parametrize("kind", sorted(KINDS))
def test_every_kind_gives_six_maps_of_its_aspect_in_unit_range(kind):
    maps = generate_maps(kind, SIZE, seed=0)
    assert tuple(maps) == MAP_NAMES
    expected = (SIZE, round(SIZE * KINDS[kind].aspect))
    for name, values in maps.items():
        assert values.shape == expected, name
        assert values.dtype == np.float32
        assert np.all((values >= 0) & (values <= 1)), name
    alpha = maps["alpha"]
    assert alpha[0, 0] == 0 and alpha[-1, -1] == 0  # corners are outside the feather
    assert alpha[SIZE // 2, expected[1] // 2] > 0.5  # the middle is inside
    assert maps["displacement"][0, 0] == 0 and maps["displacement"][-1, -1] == 0


def test_maps_are_deterministic_per_seed():
    a = generate_maps("blue", 64, seed=5)
    b = generate_maps("blue", 64, seed=5)
    c = generate_maps("blue", 64, seed=6)
    assert all(np.array_equal(a[n], b[n]) for n in MAP_NAMES)
    assert not np.array_equal(a["displacement"], c["displacement"])


def test_ocellar_grey_levels_round_trip_for_six_and_one_class():
    k = np.arange(6)
    assert np.allclose(ocellar_grey(k), 1 - k / 5)
    assert np.array_equal(ocellar_class(ocellar_grey(k)), k)
    # Quantisation: the nearest level wins.
    assert ocellar_class(np.array([1 - 2 / 5 + 0.09]))[0] == 2
    assert np.all(ocellar_class(np.array([0.0, 0.3, 1.0]), classes=1) == 0)


def test_angle_encoding_is_an_axis_mod_180():
    assert np.allclose(angle_grey(np.array([0.0, 35.0, -35.0, 180.0])), [0, 35 / 180, 145 / 180, 0])
    assert np.allclose(angle_degrees(angle_grey(np.array([30.0, 40.0]))), [30, 40], atol=1e-4)


def test_eye_has_its_ocellus_rings_in_order(eye):
    klass = ocellar_class(eye["ocellar"])
    inside = eye["alpha"] > 0.5
    assert set(np.unique(klass[inside])) == set(range(6))
    # From the heart (the rachis' apex at v = 0.74) outward along the feather's axis.
    centre = ocellar_class(np.array([_at(eye["ocellar"], 0.5, 0.745)]))[0]
    assert centre == 5
    path = [
        ocellar_class(np.array([_at(eye["ocellar"], u, 0.75)]))[0]
        for u in np.linspace(0.5, 0.78, 40)
    ]
    # Classes never increase walking outward: 5 (heart) → 4 → 3 → 2 → 1.
    assert all(b <= a for a, b in itertools.pairwise(path))
    assert path[0] == 5 and path[-1] <= 2
    # The lower vane is the white class.
    assert ocellar_class(np.array([_at(eye["ocellar"], 0.5, 0.2)]))[0] == 0


def test_eye_melanin_fades_at_the_edge_and_gradation_rises_to_the_apex(eye):
    melanin, alpha = eye["melanin"], eye["alpha"]
    assert _at(melanin, 0.5, 0.64) > 0.95  # full structural colour in the eye's rings
    # The heart keeps the full structural share too: its black-violet is its own dark band, and a
    # lower share mixes in the lighter melanin brown (docs/model.md, the heart's lightness).
    assert _at(melanin, 0.5, 0.74) > 0.95
    # The eye's fringe keeps most of the vane's share out to its tips (bronze-green, issue 33);
    # the lower vane's loose barbs fade to melanin brown at the edge.
    for v, low, high in ((0.74, 0.45, 1.0), (0.2, 0.0, 0.3)):
        row = int(SIZE * (1 - v))
        edge_cols = np.nonzero(alpha[row] > 0.5)[0]
        for col in (edge_cols[0], edge_cols[-1]):
            assert low <= melanin[row, col] <= high, (v, col, melanin[row, col])
    g = eye["gradation"]
    assert _at(g, 0.5, 0.95) > _at(g, 0.5, 0.7) > _at(g, 0.5, 0.35)


@pytest.mark.parametrize("kind", sorted(KINDS))
def test_gradation_stays_near_the_measured_structure(kind):
    """The literature preset puts each region's measured structure at t = ½ (docs/model.md,
    "Gradation in freyer2020"): the maps drift around it from base to apex, and the eye's rings
    sit within 0.2 of it, so the ocellus keeps its measured colours."""
    maps = generate_maps(kind, 256, seed=1)
    g, inside = maps["gradation"], maps["alpha"] > 0.5
    assert abs(np.median(g[inside]) - MEASURED_GRADATION) < 0.1
    assert 0.05 < np.ptp(np.percentile(g[inside], [5, 95])) < 0.6  # a drift, not a constant
    if kind == "eye":
        rings = inside & (ocellar_class(maps["ocellar"]) >= 2)
        assert np.all(np.abs(g[rings] - MEASURED_GRADATION) < 0.2)


def test_eye_barbs_are_radial_around_the_eye():
    """The streaks of the displacement map run radially around the eye: along a circle round
    the eye centre the height oscillates (one crest per barb), along a ray it barely does."""
    d = generate_maps("eye", 1024, seed=3)["displacement"]
    aspect = d.shape[1] / d.shape[0]
    t = np.linspace(0, 2 * np.pi, 720, endpoint=False)
    r = 0.16
    circle = np.column_stack([0.5 + r * np.sin(t) / aspect, 0.74 + r * np.cos(t)])
    ring = sample_bilinear(d, circle)
    ray = np.column_stack([np.full(200, 0.5 + 0.05 / aspect), 0.74 + np.linspace(0.1, 0.2, 200)])
    along = sample_bilinear(d, ray)
    assert np.std(np.diff(ring)) > 3 * np.std(np.diff(along))


def test_png_round_trip_is_16_bit_raw_and_exr_is_tagged(tmp_path):
    values = np.linspace(0, 1, 40 * 24, dtype=np.float32).reshape(40, 24)
    write_map(tmp_path / "m.png", values)
    spec = oiio.ImageInput.open(str(tmp_path / "m.png")).spec()
    assert (spec.width, spec.height, spec.nchannels, spec.format) == (24, 40, 1, oiio.UINT16)
    assert spec.get_string_attribute("Software") == "pavonine"
    data = (tmp_path / "m.png").read_bytes()
    assert b"sRGB" not in data and b"gAMA" not in data  # not tagged as colour
    back = read_map(tmp_path / "m.png", "maps.test")
    assert np.max(np.abs(back - values)) <= 0.5 / 65535 + 1e-7
    write_map(tmp_path / "m.exr", values)
    spec = oiio.ImageInput.open(str(tmp_path / "m.exr")).spec()
    assert spec.get_string_attribute("oiio:ColorSpace").lower() in ("raw", "data")
    assert np.max(np.abs(read_map(tmp_path / "m.exr", "maps.test") - values)) < 1e-3


@pytest.mark.parametrize("basetype, levels", [(oiio.UINT8, 256), (oiio.UINT16, 65536)])
def test_every_integer_grey_level_reads_as_openimageio_converts_it(tmp_path, basetype, levels):
    """read_map decodes one grey channel as stored and scales it itself: for every level the
    value is OpenImageIO's own conversion to float, bit for bit."""
    stored = np.arange(levels, dtype=np.uint8 if levels == 256 else np.uint16).reshape(-1, 256)
    path = tmp_path / "levels.png"
    spec = oiio.ImageSpec(stored.shape[1], stored.shape[0], 1, basetype)
    out = oiio.ImageOutput.create(str(path))
    assert out.open(str(path), spec) and out.write_image(stored[..., None]) and out.close()
    image = oiio.ImageInput.open(str(path))
    library = image.read_image(0, 0, 0, 1, oiio.FLOAT)[..., 0]
    image.close()
    assert np.array_equal(read_map(path, "maps.test"), library)


def test_fast_png_holds_the_same_pixels(tmp_path):
    """write_map(fast=True), the asset's copies of the maps: other bytes, the same pixels."""
    rng = np.random.default_rng(3)
    values = np.cumsum(rng.normal(0, 0.01, (64, 48)), axis=1).clip(0, 1).astype(np.float32)
    write_map(tmp_path / "default.png", values)
    write_map(tmp_path / "fast.png", values, fast=True)
    assert (tmp_path / "default.png").read_bytes() != (tmp_path / "fast.png").read_bytes()
    assert np.array_equal(
        read_map(tmp_path / "default.png", "a"), read_map(tmp_path / "fast.png", "b")
    )


def test_sample_bilinear_puts_v0_at_the_bottom_row():
    image = np.zeros((4, 2), np.float32)
    image[-1, :] = 1.0  # bottom row
    assert _at(image, 0.5, 0.01) == pytest.approx(1.0)
    assert _at(image, 0.5, 0.99) == pytest.approx(0.0)


def test_maps_command_writes_six_maps_and_a_contact_sheet(tmp_path):
    out = tmp_path / "m"
    result = CliRunner().invoke(cli, ["maps", "eye", "-o", str(out), "--size", "64", "--seed", "2"])
    assert result.exit_code == 0, result.output
    for name in MAP_NAMES:
        assert read_map(out / f"{name}.png", name).shape == (64, 32)
    sheet = oiio.ImageInput.open(str(out / "contact_sheet.png")).spec()
    assert sheet.width > sheet.height > 100


def test_maps_command_rejects_unknown_kind(tmp_path):
    result = CliRunner().invoke(cli, ["maps", "ostrich", "-o", str(tmp_path / "m")])
    assert result.exit_code == 2
    assert not (tmp_path / "m").exists()


ROOT = Path(__file__).resolve().parents[2]


def _documented_maps_commands() -> list[tuple[str, str]]:
    """(file, command) for every ``pavonine maps KIND ...`` command in the recipes' comments,
    the README and docs/*.md (up to a backtick, a ``#`` comment or a table bar)."""
    files = [*sorted((ROOT / "assets" / "recipes").glob("*.toml")), ROOT / "README.md"]
    files += sorted((ROOT / "docs").glob("*.md"))
    found = []
    for path in files:
        for match in re.finditer(r"pavonine maps ([^`#|\n]*)", path.read_text()):
            command = match.group(1).strip()
            if command.split(" ")[0] in KINDS:
                found.append((str(path.relative_to(ROOT)), command))
    return found


@pytest.mark.parametrize(("source", "command"), _documented_maps_commands())
def test_documented_maps_commands_run(source, command, tmp_path, monkeypatch):
    """Each documented command, at 16 pixels into a scratch folder, exits 0."""
    monkeypatch.chdir(tmp_path)
    result = CliRunner().invoke(cli, ["maps", *shlex.split(command), "--size", "16", "-q"])
    assert result.exit_code == 0, f"{source}: pavonine maps {command}: {result.output}"
