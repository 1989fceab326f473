"""``pavonine doctor``: what Pavonine found on this machine."""

from __future__ import annotations

import importlib.metadata
import json
import sys
import warnings

import click

from pavonine import __version__

PACKAGES = (
    ("usd-core", "usd-core"),
    ("Mitsuba", "mitsuba"),
    ("Dr.Jit", "drjit"),
    ("OpenImageIO", "OpenImageIO"),
    ("OpenColorIO", "opencolorio"),
    ("MaterialX", "MaterialX"),
    ("xatlas", "xatlas"),
    ("pymeshlab", "pymeshlab"),
    ("NumPy", "numpy"),
)


def _version(distribution: str) -> str | None:
    try:
        return importlib.metadata.version(distribution)
    except importlib.metadata.PackageNotFoundError:
        return None


def collect(variant: str | None = None) -> dict:
    """Versions of the stack, the Mitsuba variant chosen and the libLLVM it uses."""
    from pavonine.backend import select_variant

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        backend = select_variant(variant)
    return {
        "pavonine": __version__,
        "python": sys.version.split()[0],
        "packages": {label: _version(dist) for label, dist in PACKAGES},
        "variant": backend.variant,
        "variant_reason": backend.reason,
        "libllvm": backend.libllvm,
        "llvm_major": backend.llvm_major,
        "warnings": [str(w.message) for w in caught],
    }


@click.command()
@click.option("--json", "as_json", is_flag=True, help="Print machine-readable JSON.")
@click.option("--variant", default=None, help="Try this Mitsuba variant instead of the default.")
def doctor(as_json: bool, variant: str | None) -> None:
    """Print the versions of the stack, the Mitsuba variant and the libLLVM found."""
    info = collect(variant)
    if as_json:
        click.echo(json.dumps(info, indent=2))
        return
    click.echo(f"pavonine {info['pavonine']} (Python {info['python']})")
    for label, version in info["packages"].items():
        click.echo(f"  {label:<12} {version or 'MISSING'}")
    llvm = f"{info['libllvm']} (LLVM {info['llvm_major']})" if info["libllvm"] else "none"
    click.echo(f"  {'variant':<12} {info['variant']} ({info['variant_reason']})")
    click.echo(f"  {'libLLVM':<12} {llvm}")
    for message in info["warnings"]:
        click.echo(f"warning: {message}", err=True)
    if any(v is None for v in info["packages"].values()):
        raise SystemExit(1)
