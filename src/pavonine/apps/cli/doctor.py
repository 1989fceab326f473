"""``pavonine doctor``: what Pavonine found on this machine."""

from __future__ import annotations

import importlib.metadata
import sys
import warnings

import click

from pavonine import __version__
from pavonine.apps.cli.options import (
    EXTRA_OF_MODULE,
    debian_hint,
    emit_json,
    importable,
    json_option,
    say,
)

#: (label, distribution, import name, extra or None for the base install)
PACKAGES = (
    ("usd-core", "usd-core", "pxr", None),
    ("NumPy", "numpy", "numpy", None),
    ("SciPy", "scipy", "scipy", None),
    ("OpenImageIO", "OpenImageIO", "OpenImageIO", None),
    ("Mitsuba", "mitsuba", "mitsuba", "render"),
    ("Dr.Jit", "drjit", "drjit", "render"),
    ("OpenColorIO", "opencolorio", "PyOpenColorIO", "render"),
    ("FLIP", "flip-evaluator", "flip_evaluator", "render"),
    ("MaterialX", "MaterialX", "MaterialX", "convert"),
    ("xatlas", "xatlas", "xatlas", "convert"),
    ("pymeshlab", "pymeshlab", "pymeshlab", "convert"),
    ("Dask", "dask", "dask", "farm"),
    ("distributed", "distributed", "distributed", "farm"),
)
EXTRAS = ("convert", "render", "farm")

JSON_SCHEMA = {
    "type": "object",
    "required": ["pavonine", "python", "packages", "extras", "variant", "libllvm", "warnings"],
    "properties": {
        "pavonine": {"type": "string"},
        "python": {"type": "string"},
        "packages": {
            "type": "object",
            "description": "package label → installed version (null: missing)",
            "additionalProperties": {"type": ["string", "null"]},
        },
        "extras": {
            "type": "object",
            "description": "optional extra (convert, render, farm) → fully installed",
            "additionalProperties": {"type": "boolean"},
        },
        "variant": {
            "type": ["string", "null"],
            "description": "Mitsuba variant (null: no [render], or it cannot load: variant_reason)",
        },
        "variant_reason": {"type": ["string", "null"]},
        "libllvm": {"type": ["string", "null"], "description": "libLLVM Dr.Jit uses"},
        "llvm_major": {"type": ["integer", "null"]},
        "ocio_config": {"type": "string", "description": "default OCIO config ($OCIO or pinned)"},
        "meshing": {
            "type": ["string", "null"],
            "description": "library convert meshes with: pymeshlab, or numpy when pymeshlab "
            "cannot load (meshing_reason says why); null: no [convert]",
        },
        "meshing_reason": {"type": ["string", "null"]},
        "warnings": {"type": "array", "items": {"type": "string"}},
    },
}


def _version(distribution: str) -> str | None:
    try:
        return importlib.metadata.version(distribution)
    except importlib.metadata.PackageNotFoundError:
        return None


def collect(variant: str | None = None) -> dict:
    """Versions of the stack, the extras installed, the Mitsuba variant and its libLLVM."""
    from pavonine.materials.display import default_config

    packages = {label: _version(dist) for label, dist, _, _ in PACKAGES}
    extras = {
        extra: all(importable(m) for m, e in EXTRA_OF_MODULE.items() if e == extra)
        for extra in EXTRAS
    }
    info = {
        "pavonine": __version__,
        "python": sys.version.split()[0],
        "packages": packages,
        "extras": extras,
        "variant": None,
        "variant_reason": "the [render] extra is not installed",
        "libllvm": None,
        "llvm_major": None,
        "ocio_config": default_config(),
        "meshing": None,
        "meshing_reason": None,
        "warnings": [],
    }
    if extras["convert"]:
        from pavonine.base.errors import InputError
        from pavonine.pipeline.convert.meshing import meshing_backend

        try:
            meshing = meshing_backend()
            info.update(meshing=meshing.name, meshing_reason=meshing.reason)
        except (ImportError, InputError) as exc:  # PAVONINE_MESHING: pymeshlab but it cannot
            info.update(meshing_reason=str(exc))  # load, or an unknown value
    if extras["render"]:
        from pavonine.base.backend import RendererUnavailable, select_variant

        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            try:
                backend = select_variant(variant)
            except RendererUnavailable as exc:  # installed, but a system library is missing
                reason = f"{exc}{debian_hint(str(exc))}"
                info.update(variant_reason=reason, warnings=[reason])
                return info
        info.update(
            variant=backend.variant,
            variant_reason=backend.reason,
            libllvm=backend.libllvm,
            llvm_major=backend.llvm_major,
            warnings=[str(w.message) for w in caught],
        )
    return info


@click.command()
@click.option("--variant", default=None, help="Try this Mitsuba variant instead of the default.")
@json_option(JSON_SCHEMA)
def doctor(variant: str | None, json_target: str | None) -> None:
    """Print the versions of the stack, the extras installed, the Mitsuba variant and libLLVM.

    Exit 1 when a package of the base install is missing.
    """
    info = collect(variant)
    emit_json(json_target, info)
    say(f"pavonine {info['pavonine']} (Python {info['python']})")
    for label, _, _, extra in PACKAGES:
        version = info["packages"][label] or "MISSING"
        say(f"  {label:<12} {version}{f'  [{extra}]' if extra else ''}")
    for extra, ok in info["extras"].items():
        hint = "" if ok else f" (pip install 'pavonine[{extra}]')"
        say(f"  {'[' + extra + ']':<12} {'installed' if ok else 'not installed'}{hint}")
    llvm = f"{info['libllvm']} (LLVM {info['llvm_major']})" if info["libllvm"] else "none"
    say(f"  {'variant':<12} {info['variant']} ({info['variant_reason']})")
    say(f"  {'libLLVM':<12} {llvm}")
    say(f"  {'OCIO config':<12} {info['ocio_config']}")
    if info["meshing"] or info["meshing_reason"]:
        reason = f" ({info['meshing_reason']})" if info["meshing_reason"] else ""
        say(f"  {'meshing':<12} {info['meshing']}{reason}")
    for message in info["warnings"]:
        click.echo(f"warning: {message}", err=True)
    if any(info["packages"][label] is None for label, _, _, extra in PACKAGES if extra is None):
        raise SystemExit(1)
