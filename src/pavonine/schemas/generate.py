"""Generate ``generatedSchema.usda`` and ``plugInfo.json`` from ``schema.usda``.

Runs usd-core's own ``pxr/Usd/usdGenSchema.py`` (codeless: ``skipCodeGeneration``) on a copy of
``schema.usda`` whose numeric fallbacks are replaced by the values of
``pavonine.materials.parameters`` (one source of truth), fills the ``@PLUG_INFO_…@``
placeholders, and writes the Python plugin that carries Pavonine's validators into its own folder
(``validators/plugInfo.json``): the schema's folder declares only the schema, so a process without
Pavonine's Python package can use it (see ``plugin.py``).

    python -m pavonine.schemas.generate            # rewrite the generated files
    python -m pavonine.schemas.generate --check    # exit 1 if they are stale
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

from pavonine.schemas.plugin import VALIDATOR_PLUGIN_NAME

SCHEMA_DIR = Path(__file__).resolve().parent
SOURCE = SCHEMA_DIR / "schema.usda"
GENERATED = ("generatedSchema.usda", "plugInfo.json", "validators/plugInfo.json")

#: Python plugin (imported by USD's plugin system) that registers Pavonine's validators.
VALIDATOR_PLUGIN = VALIDATOR_PLUGIN_NAME

#: Validator name (without the plugin prefix) -> (doc, schema types). Keyword: PavonineValidators.
VALIDATORS: dict[str, tuple[str, list[str]]] = {
    "FeatherApiOnMaterial": (
        "PavonineFeatherAPI is applied only to Material prims.",
        ["PavonineFeatherAPI"],
    ),
    "FeatherParameters": (
        "Per-class arrays agree in length and hold physical values (positive, rods not "
        "overlapping: pi*a <= 2*d, and in the physical mode the rod lattice fits, e.g. "
        "d >= sqrt(3)*a for staggered touching rods; layer counts >= 1, angles in range, known "
        "interference mode and rod lattice, dispersive indices >= 1).",
        ["PavonineFeatherAPI"],
    ),
    "FeatherMaps": (
        "Map assets exist, load with OpenImageIO, are single-channel or convertible, have sane "
        "sizes and are read as raw data.",
        ["PavonineFeatherAPI"],
    ),
    "FeatherDerivedShaders": (
        "The MaterialX and UsdPreviewSurface shaders bound beside the schema agree with the schema "
        "attributes they are derived from; baked textures were made from the current attributes.",
        ["PavonineFeatherAPI"],
    ),
}


def fallback_values() -> dict[str, object]:
    """Schema property name -> fallback value (as a Python/Gf value) from ``parameters.py``."""
    from pxr import Gf

    from pavonine.materials.parameters import FeatherParameters, preset

    params = preset("paper-table1")
    arrays = params.class_arrays()
    out: dict[str, object] = {}
    for axis in ("long", "short"):
        out[f"pavonine:{axis}:layerInterval"] = [
            Gf.Vec2f(*row) for row in arrays[f"{axis}_interval"].tolist()
        ]
        out[f"pavonine:{axis}:rodRadius"] = [
            Gf.Vec2f(*row) for row in arrays[f"{axis}_radius"].tolist()
        ]
        out[f"pavonine:{axis}:layerCount"] = [
            Gf.Vec2i(*(int(v) for v in row)) for row in arrays[f"{axis}_count"].tolist()
        ]
    for name in (
        "pavonine:long:rodSpacing",
        "pavonine:long:airChannelDiameter",
        "pavonine:short:rodSpacing",
        "pavonine:short:airChannelDiameter",
        "pavonine:cortexThickness",
    ):
        out[name] = []  # empty: 0 for every class (touching rods, no channels, no cortex)
    defaults = FeatherParameters(classes=params.classes)
    out["pavonine:melaninIndex"] = defaults.melanin_index
    out["pavonine:mediumIndex"] = defaults.medium_index
    out["pavonine:crescentSigma"] = defaults.crescent_sigma_deg
    out["pavonine:blockSigma"] = defaults.block_sigma_deg
    out["pavonine:rodLength"] = defaults.rod_length_um
    out["pavonine:glitter"] = defaults.glitter
    out["pavonine:glitterSeed"] = defaults.glitter_seed
    out["pavonine:blockLength"] = defaults.block_length_um
    out["pavonine:barbuleWidth"] = defaults.barbule_width_um
    out["pavonine:interference"] = defaults.interference
    out["pavonine:melaninColor"] = Gf.Vec3f(*defaults.melanin_color)
    out["pavonine:rodLattice"] = defaults.lattice
    out["pavonine:melaninDispersion"] = Gf.Vec2f(
        defaults.melanin.cauchy_a, defaults.melanin.cauchy_b
    )
    out["pavonine:melaninAbsorption"] = Gf.Vec2f(
        defaults.melanin.extinction, defaults.melanin.extinction_scale
    )
    out["pavonine:keratinDispersion"] = Gf.Vec2f(
        defaults.keratin.cauchy_a, defaults.keratin.cauchy_b
    )
    return out


def source_mismatches(source: Path = SOURCE) -> list[str]:
    """Properties whose fallback written in ``schema.usda`` differs from ``parameters.py``."""
    from pxr import Sdf

    layer = Sdf.Layer.FindOrOpen(str(source))
    spec = layer.GetPrimAtPath("/PavonineFeatherAPI")
    problems = []
    for name, value in fallback_values().items():
        written = spec.attributes[name].default if name in spec.attributes else None
        if written is None or list(_flat(written)) != list(_flat(value)):
            problems.append(f"{name}: schema.usda has {written}, parameters.py has {value}")
    return problems


def _flat(value) -> list:
    """Scalars, Gf vectors and arrays of them as a flat list of float32-compatible numbers."""
    if isinstance(value, str):
        return [value]
    try:
        items = list(value)
    except TypeError:
        return [float(value)]
    flat: list = []
    for item in items:
        flat.extend(_flat(item))
    return flat


def _effective_source(directory: Path) -> Path:
    """``schema.usda`` with its fallbacks replaced by ``parameters.py``, written to ``directory``."""
    from pxr import Sdf

    layer = Sdf.Layer.OpenAsAnonymous(str(SOURCE))
    spec = layer.GetPrimAtPath("/PavonineFeatherAPI")
    for name, value in fallback_values().items():
        spec.attributes[name].default = value
    path = directory / "schema.usda"
    layer.Export(str(path))
    return path


def _usd_gen_schema() -> Path:
    import pxr.Usd

    return Path(pxr.Usd.__file__).resolve().parent / "usdGenSchema.py"


def _plug_info(raw: str) -> str:
    """Fill usdGenSchema's placeholders (paths relative to ``plugInfo.json``)."""
    text = (
        raw.replace("@PLUG_INFO_LIBRARY_PATH@", "")
        .replace("@PLUG_INFO_RESOURCE_PATH@", ".")
        .replace("@PLUG_INFO_ROOT@", ".")
    )
    start = "\n".join(line for line in text.splitlines() if not line.lstrip().startswith("#"))
    return json.dumps(json.loads(start), indent=4, sort_keys=True) + "\n"


def _validator_plug_info() -> str:
    """``validators/plugInfo.json``: the Python plugin declaring Pavonine's validators."""
    info = {
        "Plugins": [
            {
                "Info": {
                    "Validators": {
                        name: {
                            "doc": doc,
                            "keywords": ["PavonineValidators"],
                            "schemaTypes": types,
                        }
                        for name, (doc, types) in VALIDATORS.items()
                    }
                },
                "LibraryPath": "",
                "Name": VALIDATOR_PLUGIN,
                "ResourcePath": ".",
                "Root": ".",
                "Type": "python",
            }
        ]
    }
    return json.dumps(info, indent=4, sort_keys=True) + "\n"


def generate(out_dir: Path) -> dict[str, str]:
    """Run usdGenSchema into a scratch directory; return ``{file name: text}`` of the results."""
    with tempfile.TemporaryDirectory(prefix="pavonine-schema-") as tmp:
        tmp_path = Path(tmp)
        src_dir = tmp_path / "src"
        gen_dir = tmp_path / "gen"
        src_dir.mkdir()
        source = _effective_source(src_dir)
        env = dict(os.environ)
        env.pop("PXR_PLUGINPATH_NAME", None)  # never let a previous build define the schema
        result = subprocess.run(
            [sys.executable, str(_usd_gen_schema()), "--quiet", str(source), str(gen_dir)],
            capture_output=True,
            text=True,
            env=env,
            check=False,
        )
        if result.returncode != 0:
            raise RuntimeError(f"usdGenSchema failed:\n{result.stdout}\n{result.stderr}")
        texts = {
            "generatedSchema.usda": (gen_dir / "generatedSchema.usda").read_text(),
            "plugInfo.json": _plug_info((gen_dir / "plugInfo.json").read_text()),
            "validators/plugInfo.json": _validator_plug_info(),
        }
    return texts


def stale_files(directory: Path = SCHEMA_DIR) -> list[str]:
    """Generated files in ``directory`` that differ from a fresh generation (or are missing)."""
    fresh = generate(directory)
    stale = []
    for name, text in fresh.items():
        path = directory / name
        if not path.exists() or path.read_text() != text:
            stale.append(name)
    return stale


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="exit 1 if generated files are stale")
    args = parser.parse_args(argv)
    mismatches = source_mismatches()
    for line in mismatches:
        print(f"schema.usda fallback differs from parameters.py: {line}", file=sys.stderr)
    if args.check:
        stale = stale_files()
        for name in stale:
            print(
                f"stale: schemas/{name} (run python -m pavonine.schemas.generate)", file=sys.stderr
            )
        return 1 if stale or mismatches else 0
    for name, text in generate(SCHEMA_DIR).items():
        (SCHEMA_DIR / name).parent.mkdir(parents=True, exist_ok=True)
        (SCHEMA_DIR / name).write_text(text)
        print(f"wrote schemas/{name}")
    return 1 if mismatches else 0


if __name__ == "__main__":
    raise SystemExit(main())
