"""``pavonine compare TEST REF``: do two renders agree, allowing for Monte Carlo noise?"""

from __future__ import annotations

from pathlib import Path

import click

from pavonine.apps.cli.options import (
    display_options,
    display_overrides,
    emit_json,
    json_option,
    output_option,
    say,
    stdout_console,
)
from pavonine.apps.cli.values import FiniteFloat, max_pixels_option
from pavonine.apps.compare.methods import (
    FLIP_THRESHOLD,
    METHODS,
    PASS_RATIO,
    SIGNIFICANCE,
    CompareOptions,
    ComparisonResult,
    check_same_shape,
    match_display_range,
    quantization_variance,
    read_image,
    read_variance,
)
from pavonine.base.errors import InputError, one_line_errors

EXIT_AGREE, EXIT_DIFFER = 0, 1

_RESULT = {
    "type": "object",
    "required": ["passed", "heatmap"],
    "properties": {
        "passed": {"type": "boolean"},
        "heatmap": {"type": "string", "description": "heat-map PNG written"},
    },
    "additionalProperties": True,
    "description": "the method's statistics (docs/compare.md) besides passed and heatmap",
}
JSON_SCHEMA = {
    "type": "object",
    "required": ["test", "reference", "passed", "methods"],
    "properties": {
        "test": {"type": "string"},
        "reference": {"type": "string"},
        "passed": {"type": "boolean", "description": "every method agrees (exit 0)"},
        "methods": {
            "type": "object",
            "description": "method name (stat, flip) → its result",
            "additionalProperties": _RESULT,
        },
        "report": {"type": ["string", "null"], "description": "HTML report, if written"},
    },
}


def print_results(results: list[ComparisonResult], title: str) -> None:
    """Print each method's verdict and numbers as a small table."""
    from rich.table import Table

    console = stdout_console()
    for result in results:
        verdict = "[green]agree[/]" if result.passed else "[bold red]DIFFER[/]"
        table = Table(title=f"{title} — {result.method}: {verdict}", title_justify="left")
        table.add_column("statistic")
        table.add_column("value", justify="right")
        for key, value in result.numbers.items():
            table.add_row(key, str(value))
        console.print(table)


@click.command("compare")
@click.argument("test", type=click.Path(path_type=Path))
@click.argument("ref", type=click.Path(path_type=Path))
@click.option(
    "--method",
    type=click.Choice([*METHODS, "all"]),
    default="stat",
    show_default=True,
    help="stat: noise-aware Z-test; flip: NVIDIA FLIP on display-referred images; all: both.",
)
@click.option(
    "--ref-variance",
    type=click.Path(path_type=Path),
    help="EXR: per-pixel variance of REF's estimate (a baseline folder as REF supplies it).",
)
@click.option(
    "--test-variance",
    type=click.Path(path_type=Path),
    help="EXR: per-pixel variance of TEST's estimate (default: REF's, scaled by --ref-spp/--test-spp).",
)
@click.option("--ref-spp", type=click.IntRange(min=1), help="Samples per pixel of REF.")
@click.option(
    "--test-spp",
    type=click.IntRange(min=1),
    help="Samples per pixel of TEST: without --test-variance, TEST's variance is REF's x "
    "ref-spp/test-spp (a baseline folder supplies both, its check spp for TEST).",
)
@output_option(
    folder=True,
    help="Folder for the heat-maps <TEST stem>.<method>-diff.png [default: beside TEST].",
)
@json_option(JSON_SCHEMA)
@click.option(
    "--report",
    type=click.Path(file_okay=False, path_type=Path),
    help="Also write a static HTML report into this folder.",
)
@click.option(
    "--significance",
    type=FiniteFloat(),
    default=SIGNIFICANCE,
    show_default=True,
    help="stat: family-wise false-alarm probability (Šidák-corrected per test).",
)
@click.option(
    "--pass-ratio",
    type=FiniteFloat(),
    default=PASS_RATIO,
    show_default=True,
    help="stat: share of tests per block size that must pass.",
)
@click.option(
    "--flip-threshold",
    type=FiniteFloat(),
    help=f"Mean FLIP above which images differ [default: a baseline folder's calibrated "
    f"threshold, else {FLIP_THRESHOLD}].",
)
@display_options
@max_pixels_option
@one_line_errors
def compare(
    test: Path,
    ref: Path,
    method: str,
    ref_variance: Path | None,
    test_variance: Path | None,
    ref_spp: int | None,
    test_spp: int | None,
    output: Path | None,
    json_target: str | None,
    report: Path | None,
    significance: float,
    pass_ratio: float,
    flip_threshold: float | None,
    display,
) -> None:
    """Compare TEST with REF (EXR or PNG; REF may be a baseline folder).

    A PNG is decoded with the display transform it records (written by pavonine), else with
    the current one; --ocio-config/--display/--view/--exposure given here override what a PNG
    records. Exit 0 when they agree, 1 when they differ, 2 on bad input. Writes a heat-map PNG
    per method.
    """
    from pavonine.apps.compare.methods import compare_arrays
    from pavonine.render.imageio import write_display_png

    if not 0 < significance < 1:
        raise InputError("--significance", f"must be in (0, 1), got {significance}")
    if not 0 < pass_ratio <= 1:
        raise InputError("--pass-ratio", f"must be in (0, 1], got {pass_ratio}")
    if flip_threshold is not None and flip_threshold <= 0:
        raise InputError("--flip-threshold", f"must be positive, got {flip_threshold}")
    overrides = display_overrides()

    if ref.is_dir():
        from pavonine.apps.compare.baselines import load_baseline, options_for

        baseline = load_baseline(ref)
        ref_image = baseline.mean
        ref_var = baseline.variance
        if ref_variance is not None:
            ref_var = read_variance(ref_variance, ref_image.size)
        ref_spp = ref_spp or baseline.settings.spp
        test_spp = test_spp or baseline.check_settings.spp
        flip_threshold = flip_threshold or options_for(baseline).flip_threshold
    else:
        ref_image = read_image(ref, overrides)
        ref_var = read_variance(ref_variance, ref_image.size) if ref_variance else None
    test_image = read_image(test, overrides)
    check_same_shape(test_image, ref_image)
    test_image, ref_image = match_display_range(test_image, ref_image)
    test_var = read_variance(test_variance, test_image.size) if test_variance else None

    options = CompareOptions(
        significance, pass_ratio, flip_threshold=flip_threshold or FLIP_THRESHOLD
    )
    noise = "estimated from the images"
    if ref_var is not None:
        noise = "given"
        if test_var is None:  # variance of a mean ∝ 1/spp
            ratio = ref_spp / test_spp if ref_spp and test_spp else 1.0
            test_var = ref_var * ratio
            noise = f"TEST variance assumed = REF variance x {ratio:g}"
        # 8-bit PNGs carry rounding error on top of Monte Carlo noise
        test_var = test_var + quantization_variance(test_image)
        ref_var = ref_var + quantization_variance(ref_image)
    methods = list(METHODS) if method == "all" else [method]
    results = [
        compare_arrays(
            test_image.rgb,
            ref_image.rgb,
            m,
            test_variance=test_var,
            ref_variance=ref_var,
            options=options,
        )
        for m in methods
    ]
    for result in results:
        if result.method == "stat":
            result.numbers["variance"] = noise
    out_dir = output if output is not None else test.parent
    for result in results:
        heatmap = out_dir / f"{test.stem}.{result.method}-diff.png"
        write_display_png(heatmap, result.heatmap)
        result.numbers["heatmap"] = str(heatmap)
    print_results(results, f"{test} vs {ref}")
    page = None
    if report is not None:
        from pavonine.apps.compare.report import SceneEntry, write_report

        entry = SceneEntry(test.stem, test_image.rgb, ref_image.rgb, results)
        entry.metadata = {"test": str(test), "reference": str(ref)}
        page = write_report(report, [entry], title=f"pavonine compare: {test.name}")
        say(f"report: {page}")
    passed = all(r.passed for r in results)
    emit_json(
        json_target,
        {
            "test": str(test),
            "reference": str(ref),
            "passed": passed,
            "methods": {r.method: {"passed": r.passed, **r.numbers} for r in results},
            "report": None if page is None else str(page),
        },
    )
    raise SystemExit(EXIT_AGREE if passed else EXIT_DIFFER)
