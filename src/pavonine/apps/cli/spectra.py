"""``pavonine spectra``: reflectance spectra, peaks and colours of a feather material."""

from __future__ import annotations

import csv
import functools
import math
import sys
from contextlib import ExitStack
from pathlib import Path

import click

from pavonine.apps.cli.options import (
    display_options,
    emit_json,
    json_option,
    json_to_stdout,
    output_option,
    say,
)
from pavonine.apps.cli.values import FiniteFloat
from pavonine.base.errors import InputError, one_line_errors

DEFAULT_OUTPUT = Path("out/spectra")

JSON_SCHEMA = {
    "type": "object",
    "required": ["label", "incidence_deg", "spectra", "files"],
    "properties": {
        "label": {
            "type": "string",
            "description": "preset (and class) or d…_a…_n… of the material",
        },
        "incidence_deg": {"type": "number", "description": "incidence angle, degrees"},
        "spectra": {
            "type": "array",
            "description": "one entry per observation angle",
            "items": {
                "type": "object",
                "required": ["observe_deg", "peak_nm", "fwhm_nm", "srgb"],
                "properties": {
                    "observe_deg": {"type": "number", "description": "observation angle, degrees"},
                    "peak_nm": {"type": "number", "description": "peak wavelength, nm"},
                    "fwhm_nm": {
                        "type": ["number", "null"],
                        "description": "full width at half maximum, nm (null: band not closed)",
                    },
                    "srgb": {
                        "type": "array",
                        "items": {"type": "number"},
                        "minItems": 3,
                        "maxItems": 3,
                        "description": "display-referred swatch colour (0-1) through the display "
                        "transform",
                    },
                },
            },
        },
        "files": {
            "type": "object",
            "description": "what was written (empty under --json - without -o)",
            "properties": {"png": {"type": "string"}, "csv": {"type": "string"}},
        },
    },
}


def _angles(text: str) -> list[float]:
    try:
        values = [float(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise InputError(
            "--observe", f"expected degrees separated by commas, got {text!r}"
        ) from None
    if not values:
        raise InputError("--observe", "needs at least one angle")
    if not all(math.isfinite(v) for v in values):
        raise InputError("--observe", f"angles must be finite numbers, got {text!r}")
    return values


def resolve_parameters(preset_name, ocellar_class, interval, radius, layers, interference):
    """The material and class selected by the command-line options."""
    from pavonine.materials.parameters import MAX_LAYER_COUNT, preset, uniform_parameters

    explicit = [v is not None for v in (interval, radius, layers)]
    if any(explicit):
        if not all(explicit):
            raise InputError("--interval/--radius/--layers", "give all three together")
        for name, value in (("--interval", interval), ("--radius", radius), ("--layers", layers)):
            if math.isnan(value):
                raise InputError(name, "is NaN")
        for name, value in (("--interval", interval), ("--radius", radius)):
            if value <= 0:
                raise InputError(name, f"must be positive, got {value:g} nm")
            if value < 1.0:
                raise InputError(
                    name,
                    f"is in nanometres; {value:g} nm is below 1 nm (did you mean {value * 1000:g}?)",
                )
        if layers != int(layers) or layers < 1:
            raise InputError("--layers", f"must be a whole number of layers >= 1, got {layers:g}")
        if layers > MAX_LAYER_COUNT:
            raise InputError("--layers", f"must be at most {MAX_LAYER_COUNT}, got {layers:g}")
        params = uniform_parameters(interval / 1000.0, radius / 1000.0, layers)
        label = f"d{interval:g}_a{radius:g}_n{layers:g}"
    else:
        params = preset(preset_name)
        label = preset_name
    if interference:
        params = params.with_(interference=interference)
    params.validate()
    for k, _axis, message in params.geometry_warnings():
        if k == (ocellar_class or 0):  # only the plotted class's geometry concerns this plot
            click.echo(f"warning: {message}", err=True)
    if ocellar_class is not None:
        params.stacks(ocellar_class, 0.0)
        label += f"_class{ocellar_class}"
    return params, label


#: The option behind each argument of the optics functions that a ParameterError names.
OPTION_OF_FIELD = {
    "ocellar_class": "--class",
    "preset": "--preset",
    "gradation": "--gradation",
    "incidence": "--incidence",
    "observe": "--observe",
    "azimuth": "--azimuth",
    "structural_share": "--structural-share",
    "barbule_tilt": "--barbule-tilt",
    "barbule_twist": "--barbule-twist",
    "interference": "--interference",
}


def _errors_name_options(command):
    """``command`` with the model's :class:`ParameterError` (naming a function argument, such as
    ``ocellar_class``) turned into an :class:`InputError` naming the option the user typed."""

    @functools.wraps(command)
    def wrapper(*args, **kwargs):
        from pavonine.materials.parameters import ParameterError

        try:
            return command(*args, **kwargs)
        except ParameterError as exc:
            raise InputError(OPTION_OF_FIELD.get(exc.field, exc.field), exc.reason) from None

    return wrapper


@click.command()
@click.option(
    "--preset",
    "preset_name",
    default="paper-table1",
    show_default=True,
    help="paper-table1, freyer2020, yellow or blue.",
)
@click.option(
    "--class",
    "ocellar_class",
    type=int,
    default=None,
    help="Ocellar class of the preset (0 = white … 5 = black).",
)
@click.option(
    "--gradation",
    type=FiniteFloat(),
    default=None,
    help="0 = black end, 1 = white end [default: where the preset holds its measured structure: "
    "0.5 for freyer2020, 0 otherwise].",
)
@click.option(
    "--interval",
    type=FiniteFloat(),
    default=None,
    help="Layer interval d in nm (with --radius, --layers).",
)
@click.option("--radius", type=FiniteFloat(), default=None, help="Rod radius a in nm.")
@click.option("--layers", type=FiniteFloat(), default=None, help="Number of layers N_d.")
@click.option(
    "--interference",
    type=click.Choice(["paper", "intensity", "physical"]),
    default=None,
    help="Eq. 3/4 as printed (|Σ|/N), intensity (|Σ|²/N²), or physical (exact transfer matrix "
    "of the rod lattice, real melanin and keratin). Default: the preset's.",
)
@click.option(
    "--incidence",
    type=FiniteFloat(),
    default=0.0,
    show_default=True,
    help="Incidence angle (degrees from the vane normal).",
)
@click.option(
    "--observe",
    default="15,25,35,45,55,65,75,85",
    show_default=True,
    help="Observation angles, degrees, comma-separated (specular side).",
)
@click.option(
    "--azimuth",
    type=FiniteFloat(),
    default=90.0,
    show_default=True,
    help="Plane of incidence, degrees from the barbule's long axis (90 = across).",
)
@click.option(
    "--structural-share",
    type=FiniteFloat(),
    default=1.0,
    show_default=True,
    help="Melanin map value.",
)
@click.option(
    "--barbule-tilt",
    type=FiniteFloat(),
    default=0.0,
    show_default=True,
    help="Barbule long axis inclined out of the vane by this many degrees (macro-geometry).",
)
@click.option(
    "--barbule-twist",
    type=FiniteFloat(),
    default=0.0,
    show_default=True,
    help="Barbule turned about its long axis by this many degrees (macro-geometry).",
)
@output_option(
    folder=True,
    help=f"Folder for the PNG and CSV [default: {DEFAULT_OUTPUT}; none under --json - without -o].",
)
@json_option(JSON_SCHEMA)
@display_options
@one_line_errors
@_errors_name_options
def spectra(
    preset_name,
    ocellar_class,
    gradation,
    interval,
    radius,
    layers,
    interference,
    incidence,
    observe,
    azimuth,
    structural_share,
    barbule_tilt,
    barbule_twist,
    output,
    json_target,
    display,
):
    """Reflectance spectra (380–780 nm) per observation angle: PNG (paper Fig. 5 layout), CSV, table.

    Colours are display-referred through the display transform (--ocio-config, --view, …).
    """
    from pavonine.materials import optics

    params, label = resolve_parameters(
        preset_name, ocellar_class, interval, radius, layers, interference
    )
    observe_deg = _angles(observe)
    if gradation is None:
        from pavonine.materials.parameters import preset_gradation

        gradation = preset_gradation(preset_name) if interval is None else 0.0
    kwargs = dict(
        ocellar_class=ocellar_class or 0,
        gradation=gradation,
        azimuth_deg=azimuth,
        structural_share=structural_share,
        barbule_tilt_deg=barbule_tilt,
        barbule_twist_deg=barbule_twist,
    )
    if output is None and json_to_stdout():  # a report on stdout only: write no files
        summaries = optics.summarise(params, incidence, observe_deg, **kwargs)
        files = {}
    else:
        summaries, files = _write_files(
            output or DEFAULT_OUTPUT, params, label, incidence, observe_deg, kwargs
        )
    emit_json(
        json_target,
        {
            "label": label,
            "incidence_deg": incidence,
            "spectra": [s.as_json() for s in summaries],
            "files": files,
        },
    )
    _print_table(label, incidence, summaries, sys.stdout.isatty())
    if files:
        say(f"wrote {files['png']} and {files['csv']}")


def _write_files(output: Path, params, label, incidence, observe_deg, kwargs):
    """The PNG (Fig. 5 layout) and CSV, renamed into place together; their summaries and paths."""
    from pavonine.base.commit import commit_files, recover, temporary_file
    from pavonine.materials import optics, plots

    curves = optics.reflectance_spectra(params, incidence, observe_deg, **kwargs)
    png = output / f"spectra_{label}.png"
    csv_path = output / f"spectra_{label}.csv"
    with ExitStack() as outputs:  # both complete, then renamed as one journalled group
        tmp_png = outputs.enter_context(temporary_file(png))
        tmp_csv = outputs.enter_context(temporary_file(csv_path))
        summaries = plots.figure5(tmp_png, params, label, incidence, observe_deg, **kwargs)
        with open(tmp_csv, "w", newline="") as fh:
            writer = csv.writer(fh)
            writer.writerow(["wavelength_nm", *[f"observe_{o:g}deg" for o in observe_deg]])
            for i, lam in enumerate(optics.PLOT_WAVELENGTHS_NM):
                writer.writerow([f"{lam:g}", *[f"{c[i]:.6g}" for c in curves]])
        recover(output)
        commit_files([(tmp_csv, csv_path), (tmp_png, png)])
    return summaries, {"png": str(png), "csv": str(csv_path)}


def _print_table(label, incidence, summaries, colour: bool) -> None:
    from rich.console import Console
    from rich.table import Table

    table = Table(title=f"{label}, incidence {incidence:g}°")
    for column in ("observe", "peak (nm)", "peak πf", "FWHM (nm)", "sRGB", "colour"):
        table.add_column(column, justify="right")
    for s in summaries:
        r, g, b = (round(255 * c) for c in s.srgb)
        width = "—" if s.fwhm_nm is None else f"{s.fwhm_nm:.1f}"
        table.add_row(
            f"{s.observe_deg:g}°",
            f"{s.peak_nm:.1f}",
            f"{s.peak_value:.3f}",
            width,
            f"#{r:02x}{g:02x}{b:02x}",
            f"[on #{r:02x}{g:02x}{b:02x}]      [/]",
        )
    Console(force_terminal=colour, width=100, quiet=json_to_stdout()).print(table)
