"""Hostile input for the fuzzing tests: hypothesis generators, odd files and the clean-failure
property, in one place so that a reviewer can extend them.

To fuzz something new, add its values here: a number to :data:`HOSTILE_NUMBERS`, a string to
:data:`HOSTILE_STRINGS`, a recipe key to :data:`RECIPE_KEYS` / :data:`TRAIN_KEYS`, an odd file to
:func:`odd_files`, or a command-line option to :data:`CLI_OPTIONS` (values that must be refused
before any work) or :data:`CLI_ANY` (any value, cheap commands). ``tests/apps/test_fuzz_inputs.py``
draws from them; ``tests/base/test_limits.py`` holds the named cases of issue 14.

The property every run must meet (:func:`assert_clean`): exit 0, or exit 1/2 with exactly one
``error: <file or field>: <message>`` line on stderr (``warning:`` lines allowed), never a
traceback, never a hang (:func:`time_limit`), and no partial output (:func:`assert_nothing_left`).
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import signal
import struct
import zlib
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from hypothesis import strategies as st

# ----------------------------------------------------------------------------------- values
#: Numbers that break naive checks: NaN/inf, signed zero, int32/int64/uint32 edges, beyond float.
HOSTILE_NUMBERS: list[Any] = [
    math.nan,
    math.inf,
    -math.inf,
    -0.0,
    0,
    -1,
    1e-320,
    1e308,
    -1e308,
    1e39,  # finite as a double, beyond float32 (USD's float): a cast would overflow to inf
    2**31 - 1,
    2**31,
    2**32,
    2**63 - 1,
    -(2**63),
    0.5,
    1,
    3,
    1000,
]
#: Strings that break naive checks: names with newlines, paths, shell and TOML metacharacters.
HOSTILE_STRINGS: list[str] = [
    "",
    "eye\n",
    "eye feather",
    "../../etc/passwd",
    "/dev/zero",
    "x" * 300,
    "$(touch pwned)",
    "'; rm -rf ~; '",
    "ocellus\u2019s",
    "nan",
    "inf",
    "\t",
    "0",
    "paper-table1",
    "freyer2020",
    "physical",
]

hostile_scalars = st.one_of(
    st.sampled_from(HOSTILE_NUMBERS),
    st.sampled_from(HOSTILE_STRINGS),
    st.booleans(),
    st.integers(min_value=-(2**63), max_value=2**63 - 1),
    st.floats(allow_nan=True, allow_infinity=True),
    st.text(alphabet=st.characters(exclude_categories=("Cs",)), max_size=12),
)
#: Any TOML value: scalars, arrays (possibly nested and mixed) and inline tables.
hostile_values = st.recursive(
    hostile_scalars,
    lambda inner: st.one_of(
        st.lists(inner, max_size=4),
        st.dictionaries(st.sampled_from(["long", "short", "0", "x", "count"]), inner, max_size=3),
    ),
    max_leaves=8,
)


# ------------------------------------------------------------------------------ TOML writer
def toml_value(value: Any) -> str:
    """``value`` as TOML (strings, numbers incl. nan/inf, booleans, arrays, inline tables)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if math.isnan(value):
            return "nan"
        if math.isinf(value):
            return "inf" if value > 0 else "-inf"
        return repr(value)
    if isinstance(value, str):
        return json.dumps(value, ensure_ascii=False).replace("\x7f", "\\u007f")
    if isinstance(value, list):
        return "[" + ", ".join(toml_value(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{json.dumps(k)} = {toml_value(v)}" for k, v in value.items()) + "}"
    raise TypeError(f"no TOML for {value!r}")


def to_toml(table: dict[str, Any]) -> str:
    """A document with one ``key = value`` line per top-level key (tables inline)."""
    return "".join(f"{json.dumps(k)} = {toml_value(v)}\n" for k, v in table.items())


def set_dotted(table: dict, dotted: str, value: Any) -> None:
    """``table[a][b][c] = value`` for ``"a.b.c"``, creating (or replacing) tables on the way."""
    *parents, last = dotted.split(".")
    for key in parents:
        if not isinstance(table.get(key), dict):
            table[key] = {}
        table = table[key]
    table[last] = value


def delete_dotted(table: dict, dotted: str) -> None:
    *parents, last = dotted.split(".")
    for key in parents:
        table = table.get(key)
        if not isinstance(table, dict):
            return
    table.pop(last, None)


# ---------------------------------------------------------------------------------- recipes
MAP_NAMES = ("alpha", "ocellar", "gradation", "angle", "displacement", "melanin")
#: Every key a feather recipe knows (docs/pipeline.md), plus a few it must refuse.
RECIPE_KEYS = [
    "name",
    "version",
    *(f"maps.{m}" for m in MAP_NAMES),
    "maps.extra",
    "material.preset",
    "material.melanin_index",
    "material.medium_index",
    "material.crescent_sigma_deg",
    "material.block_sigma_deg",
    "material.rod_length_um",
    "material.interference",
    "material.lattice",
    "material.melanin_color",
    "material.melanin_dispersion",
    "material.keratin_dispersion",
    "material.class",
    "material.class.0",
    "material.class.0.region",
    "material.class.0.cortex",
    "material.class.0.long.interval",
    "material.class.0.long.radius",
    "material.class.0.long.count",
    "material.class.0.short.spacing",
    "material.class.5.long.count",
    "material.class.99.long.count",
    "material.glitter",
    "material.glitter_seed",
    "material.block_length_um",
    "material.barbule_width_um",
    "geometry",
    "geometry.length_cm",
    "geometry.rachis_length",
    "geometry.calamus_cm",
    "geometry.rachis_radius_cm",
    "geometry.rachis_tip_radius_cm",
    "geometry.bend_cm",
    "geometry.cup_cm",
    "geometry.displacement_cm",
    "geometry.alpha_threshold",
    "geometry.base_triangles",
    "geometry.lod",
    "geometry.lod.high",
    "geometry.lod.medium",
    "geometry.lod.low",
    "geometry.barbs",
    "geometry.barbs.enabled",
    "geometry.barbs.spacing_cm",
    "geometry.barbs.tip_barbs",
    "geometry.barbs.segment_cm",
    "geometry.barbs.width_share",
    "geometry.form",
    "geometry.form.enabled",
    "geometry.form.camber",
    "geometry.form.bow",
    "geometry.form.bow_out",
    "geometry.form.droop_deg",
    "geometry.form.root_jitter",
    "geometry.form.length_jitter",
    "geometry.form.clump",
    "geometry.form.clump_size",
    "geometry.form.fan_lift",
    "geometry.form.seed",
    "bake.resolution",
    "unknown",
]
#: Every key a train recipe knows, plus a few it must refuse.
TRAIN_KEYS = [
    "name",
    "version",
    "seed",
    "lod",
    "components",
    "components.eye",
    "components.eye\n",
    "rows",
    "rows.0",
    "rows.0.component",
    "rows.0.count",
    "rows.0.radius_cm",
    "rows.0.length",
    "rows.0.span_deg",
    "rows.0.dish_deg",
    "rows.0.depth_cm",
    "rows.0.edge",
    "rows.0.edge_count",
    "rows.0.stagger",
    "rows.0.geometry",
    "rows.0.bend",
    "rows.0.edge_bend",
    "rows.0.edge_droop_deg",
    "jitter",
    "jitter.length",
    "jitter.twist_deg",
    "variation.gradation_offset",
    "variation.structural_scale",
    "unknown",
]
#: Keys of a train recipe's ``[rattle]`` table (``pipeline/assemble/rattle.py``) and its own.
RATTLE_KEYS = [
    "rattle",
    "rattle.frequency_hz",
    "rattle.eyespot_mm",
    "rattle.barb_mm",
    "rattle.phase_spread",
    "rattle.phases",
    "rattle.fps",
    "rattle.duration_s",
    "rattle.start_frame",
    "rattle.samples_per_frame",
    "rattle.unknown",
]


def small_feather_recipe(maps_dir: Path) -> dict[str, Any]:
    """A valid recipe whose conversion is quick (tiny maps, the smallest LODs and bake)."""
    return {
        "name": "fuzz_feather",
        "maps": {m: str(maps_dir / f"{m}.png") for m in MAP_NAMES},
        "material": {"preset": "paper-table1"},
        "geometry": {"base_triangles": 200, "lod": {"high": 400, "medium": 200, "low": 100}},
        "bake": {"resolution": 16},
    }


def small_train_recipe(component: Path) -> dict[str, Any]:
    """A valid train recipe with one row of one component."""
    return {
        "name": "fuzz_train",
        "components": {"eye": str(component)},
        "rows": [{"component": "eye", "count": 3, "radius_cm": 10}],
    }


def small_rattle_recipe(component: Path) -> dict[str, Any]:
    """A valid train recipe with a ``[rattle]`` of every key (a 2-frame shot)."""
    return {
        **small_train_recipe(component),
        "rattle": {
            "frequency_hz": 25.6,
            "eyespot_mm": 1.7,
            "barb_mm": 9.6,
            "phase_spread": 1.0,
            "phases": 2,
            "fps": 24,
            "duration_s": 0.08,
            "start_frame": 1,
            "samples_per_frame": 8,
        },
    }


def _rows_as_list(table: dict) -> dict:
    """``rows.0.x`` is written into a dict keyed "0"; TOML wants ``[[rows]]`` (a list)."""
    rows = table.get("rows")
    if isinstance(rows, dict):
        table["rows"] = [rows[k] for k in sorted(rows)] if all(k == "0" for k in rows) else rows
    return table


@st.composite
def mutated(draw, base: dict[str, Any], keys: list[str]) -> dict[str, Any]:
    """``base`` with one to three keys set to hostile values or deleted."""
    table = json.loads(json.dumps(base))
    if isinstance(table.get("rows"), list):
        table["rows"] = {str(i): row for i, row in enumerate(table["rows"])}
    for _ in range(draw(st.integers(1, 3))):
        key = draw(st.sampled_from(keys))
        if draw(st.integers(0, 5)) == 0:
            delete_dotted(table, key)
        else:
            set_dotted(table, key, draw(hostile_values))
    return _rows_as_list(table)


#: Whole files that are not recipes: binary noise, other encodings, deep nesting, huge tables.
odd_recipe_texts = st.one_of(
    st.binary(max_size=200),
    st.text(max_size=100).map(lambda t: t.encode("utf-16")),
    st.integers(1, 3000).map(lambda n: ("a = " + "[" * n + "]" * n + "\n").encode()),
    st.integers(1, 3000).map(lambda n: ("a = " + "{b = " * n + "1" + "}" * n + "\n").encode()),
    st.text(max_size=200).map(lambda t: t.encode("utf-8", "surrogatepass")),
)


# ------------------------------------------------------------------------------------- maps
@dataclass(frozen=True)
class MapSpec:
    """An image file to write: size, channels, pixel type, format, and how many NaN pixels."""

    width: int
    height: int
    channels: int
    dtype: str  # uint8, uint16, half, float
    suffix: str  # .png, .exr, .tif
    nans: int = 0

    def write(self, path: Path) -> Path:
        import OpenImageIO as oiio

        suffix = self.suffix
        dtype = self.dtype
        if suffix == ".png" and dtype in ("half", "float"):
            dtype = "uint16"
        if suffix == ".exr" and dtype in ("uint8", "uint16"):
            dtype = "half"
        channels = min(self.channels, 4) if suffix == ".png" else self.channels
        path = path.with_suffix(suffix)
        pixels = np.full((self.height, self.width, channels), 0.75, dtype=np.float32)
        if self.nans and dtype in ("half", "float"):
            pixels.reshape(-1)[: self.nans] = np.nan
        out = oiio.ImageOutput.create(str(path))
        assert out is not None and out.open(
            str(path), oiio.ImageSpec(self.width, self.height, channels, dtype)
        ), oiio.geterror()
        out.write_image(pixels)
        out.close()
        return path


map_specs = st.builds(
    MapSpec,
    width=st.sampled_from([1, 2, 7, 8, 16, 33, 64]),
    height=st.sampled_from([1, 2, 8, 16, 32, 64]),
    channels=st.sampled_from([1, 2, 3, 4, 5]),
    dtype=st.sampled_from(["uint8", "uint16", "half", "float"]),
    suffix=st.sampled_from([".png", ".exr", ".tif"]),
    nans=st.sampled_from([0, 0, 1, 50]),
)


def _png_chunk(kind: bytes, data: bytes) -> bytes:
    return (
        struct.pack(">I", len(data))
        + kind
        + data
        + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)
    )


def png_declaring(path: Path, width: int, height: int, rows: int = 1) -> Path:
    """A grey 8-bit PNG whose header declares ``width × height`` but which holds ``rows`` rows."""
    header = struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0)
    row = b"\x00" + b"\x80" * min(width, 64)
    path.write_bytes(
        b"\x89PNG\r\n\x1a\n"
        + _png_chunk(b"IHDR", header)
        + _png_chunk(b"IDAT", zlib.compress(row * rows))
        + _png_chunk(b"IEND", b"")
    )
    return path


def real_png(path: Path, width: int, height: int) -> Path:
    """A real, complete grey 8-bit PNG of ``width × height`` (streamed: a 30000x30000 image is
    about 0.9 MB on disk and a second to write, but 900 MB of pixels once decoded)."""
    packer = zlib.compressobj(1)
    block = (b"\x00" + b"\x80" * width) * 64
    parts = [packer.compress(block) for _ in range(height // 64)]
    parts.append(packer.compress((b"\x00" + b"\x80" * width) * (height % 64)))
    parts.append(packer.flush())
    header = struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0)
    path.write_bytes(
        b"\x89PNG\r\n\x1a\n"
        + _png_chunk(b"IHDR", header)
        + _png_chunk(b"IDAT", b"".join(parts))
        + _png_chunk(b"IEND", b"")
    )
    return path


# ------------------------------------------------------------------------------- odd files
def odd_files(folder: Path) -> dict[str, Path]:
    """Paths that are not regular readable files: missing, a folder, a FIFO, ``/dev/zero``, a
    symlink loop, a dangling link, an empty file, text, and a PNG declaring 30000x30000."""
    folder.mkdir(parents=True, exist_ok=True)
    files = {
        "missing": folder / "missing.png",
        "folder": folder / "folder.png",
        "fifo": folder / "fifo.png",
        "dev_zero": Path("/dev/zero"),
        "loop": folder / "loop.png",
        "dangling": folder / "dangling.png",
        "empty": folder / "empty.png",
        "text": folder / "text.png",
        "huge_header": folder / "huge_header.png",
    }
    files["folder"].mkdir(exist_ok=True)
    if not files["fifo"].exists():
        os.mkfifo(files["fifo"])
    if not files["loop"].is_symlink():
        (folder / "loop2.png").symlink_to(files["loop"])
        files["loop"].symlink_to(folder / "loop2.png")
    if not files["dangling"].is_symlink():
        files["dangling"].symlink_to(folder / "nowhere.png")
    files["empty"].write_bytes(b"")
    files["text"].write_text("not an image\n")
    png_declaring(files["huge_header"], 30000, 30000)
    return files


# ---------------------------------------------------------------------- command-line options
#: Option values that must be refused before a command does any work (so fuzzing the expensive
#: commands never starts a render or a conversion): option → values.
CLI_OPTIONS: dict[str, list[str]] = {
    "--seed": ["-1", str(2**32), str(2**70), "nan", "1.5", "", "0x10"],
    "--resolution": ["100000x100000", "0x0", "-5x5", "nanxnan", "1e3x1e3", "x", "", "64x0"],
    "--spp": ["0", "-1", "nan", "1e3", ""],
    "--size": ["0", "-8", "nan", str(2**70), ""],
    "--time": ["nan", "inf", "-inf", "x"],
    "--exposure": ["nan", "inf", "1e308", "x"],
    "--max-pixels": ["0", "-1", "nan", "x"],
    "--threads": ["0", "-1", "nan"],
    "--jobs": ["0", "-1", "65", "nan", str(2**70)],
}
#: Values of the cheap commands' numeric options, valid or not: any outcome must be clean.
CLI_ANY: dict[str, list[str]] = {
    "--gradation": ["0", "1", "0.5", "-1", "2", "nan", "inf", "1e308"],
    "--incidence": ["0", "45", "89.9", "90", "-90", "1e308", "nan"],
    "--azimuth": ["0", "90", "360", "-1e9", "nan"],
    "--structural-share": ["0", "1", "-1", "2", "nan", "inf"],
    "--observe": ["15", "0,90", "nan", "inf", "1e308", "x", "", "15,,25", "-90"],
    "--class": ["0", "5", "6", "-1", str(2**70), "x"],
    "--significance": ["0", "1", "0.5", "nan", "-1", "1e-300"],
    "--pass-ratio": ["0", "1", "0.5", "nan", "2"],
    "--flip-threshold": ["0", "-1", "nan", "inf", "0.1", "1e-300"],
    "--ref-spp": ["0", "1", "-1", str(2**70)],
    "--test-spp": ["0", "1", "-1", str(2**70)],
}


# -------------------------------------------------------------------------------- property
class Hang(Exception):
    """A run exceeded its time limit."""


@contextlib.contextmanager
def time_limit(seconds: float) -> Iterator[None]:
    """Raise :class:`Hang` in the main thread after ``seconds`` (SIGALRM)."""

    def fire(signum, frame):
        raise Hang(f"did not finish within {seconds:g} s")

    previous = signal.signal(signal.SIGALRM, fire)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)


@dataclass
class Outcome:
    """What a command did: exit status, stdout, stderr, and the exception if it escaped."""

    code: int
    stdout: str
    stderr: str
    exception: BaseException | None = None


def run_cli(args: list[str], seconds: float = 60.0) -> Outcome:
    """Run ``pavonine ARGS`` in this process (click's runner) within ``seconds``."""
    from click.testing import CliRunner

    from pavonine.apps.cli import cli

    with time_limit(seconds):
        result = CliRunner().invoke(cli, [str(a) for a in args])
    exception = result.exception
    if isinstance(exception, SystemExit):
        exception = None
    return Outcome(result.exit_code, result.stdout, result.stderr, exception)


def assert_clean(outcome: Outcome, args: Any = None, codes: tuple[int, ...] = (0, 1, 2)) -> None:
    """Exit 0; or exit 1 (a documented outcome such as "images differ", at most one error line);
    or exit 2 with exactly one ``error: WHERE: MESSAGE`` line on stderr (other lines only
    ``warning:``/``info:``); never a traceback."""
    context = f"{args}: exit {outcome.code}\nstderr: {outcome.stderr}"
    assert outcome.exception is None, f"{context}\nescaped: {outcome.exception!r}"
    assert "Traceback" not in outcome.stderr, context
    assert outcome.code in codes, context
    if outcome.code == 0:
        return
    lines = [line for line in outcome.stderr.splitlines() if line.strip()]
    errors = [line for line in lines if line.startswith("error: ")]
    if outcome.code == 1 and not errors:  # a documented outcome: images differ, findings
        return
    assert len(errors) == 1, context
    assert errors[0].count(": ") >= 2, context
    others = [line for line in lines if line not in errors]
    assert all(line.startswith(("warning:", "info:", "aborted")) for line in others), context


def assert_nothing_left(folder: Path, before: set[Path] | None = None) -> None:
    """No file under ``folder`` beyond ``before``: a failed command left no partial output."""
    if not folder.exists():
        return
    now = {p for p in folder.rglob("*")}
    left = now - (before or set())
    assert not left, f"left behind: {sorted(str(p) for p in left)[:5]}"
