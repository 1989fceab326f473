"""``pavonine spectra``, ``figures`` and ``doctor`` from the command line."""

import json

import pytest
from click.testing import CliRunner

from pavonine.apps.cli import cli


@pytest.fixture
def runner():
    return CliRunner()


def test_spectra_writes_plot_csv_and_table(runner, tmp_path):
    result = runner.invoke(cli, ["spectra", "--preset", "yellow", "-o", str(tmp_path)])
    assert result.exit_code == 0, result.output
    png, csv = tmp_path / "spectra_yellow.png", tmp_path / "spectra_yellow.csv"
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    rows = csv.read_text().splitlines()
    assert rows[0].startswith("wavelength_nm,observe_15deg") and len(rows) == 1 + 401
    assert "peak (nm)" in result.output


def test_spectra_json_summary(runner, tmp_path):
    result = runner.invoke(
        cli,
        ["spectra", "--preset", "blue", "--observe", "10,40", "--json", "-", "-o", str(tmp_path)],
    )
    assert result.exit_code == 0, result.output
    report = json.loads(result.stdout)
    assert report["label"] == "blue" and report["incidence_deg"] == 0.0
    assert report["files"]["png"] == str(tmp_path / "spectra_blue.png")
    summary = report["spectra"]
    assert [s["observe_deg"] for s in summary] == [10.0, 40.0]
    assert set(summary[0]) == {"observe_deg", "peak_nm", "peak_reflectance", "fwhm_nm", "srgb"}
    assert summary[0]["peak_nm"] > summary[1]["peak_nm"]
    assert 480 < summary[0]["peak_nm"] < 530


def test_spectra_explicit_structure_and_class(runner, tmp_path):
    explicit = runner.invoke(
        cli,
        [
            "spectra",
            "--interval",
            "190",
            "--radius",
            "70",
            "--layers",
            "4",
            "--observe",
            "0",
            "--json",
            "-",
            "-o",
            str(tmp_path),
        ],
    )
    assert explicit.exit_code == 0, explicit.output
    assert abs(json.loads(explicit.stdout)["spectra"][0]["peak_nm"] - 600) < 15
    by_class = runner.invoke(
        cli, ["spectra", "--class", "3", "--gradation", "1", "--json", "-", "-o", str(tmp_path)]
    )
    assert by_class.exit_code == 0, by_class.output


def test_spectra_json_to_stdout_alone_writes_no_files(runner, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    result = runner.invoke(cli, ["spectra", "--preset", "yellow", "--json", "-"])
    assert result.exit_code == 0, result.output
    report = json.loads(result.stdout)  # stdout is the JSON report and nothing else
    assert report["files"] == {} and len(report["spectra"]) == 8
    assert not list(tmp_path.iterdir())


@pytest.mark.parametrize(
    ("args", "needle"),
    [
        (["--interval", "150", "--radius", "-65", "--layers", "10"], "--radius: must be positive"),
        (["--interval", "100", "--radius", "70", "--layers", "4"], "rods overlap"),
        (["--interval", "150", "--radius", "65", "--layers", "0"], "--layers: must be a whole"),
        (["--interval", "150", "--radius", "65", "--layers", "2.5"], "--layers: must be a whole"),
        (
            ["--interval", "nan", "--radius", "65", "--layers", "4"],
            "--interval: must be a finite number",
        ),
        (["--observe", "95"], "--observe: must lie inside"),
        (["--incidence", "nan"], "--incidence: must be a finite number"),
        (["--class", "9"], "--class: unknown class 9"),
        (["--preset", "green"], "--preset: unknown preset"),
        (["--azimuth", "nan"], "azimuth"),
        (["--gradation", "nan"], "gradation"),
        (["--gradation", "2"], "--gradation: must lie in [0, 1]"),
        (["--structural-share", "3"], "--structural-share: must lie in [0, 1]"),
        (["--interval", "0.19", "--radius", "0.07", "--layers", "4"], "nanometres"),
    ],
)
def test_spectra_bad_input_is_one_line_exit_2_and_writes_nothing(runner, tmp_path, args, needle):
    out = tmp_path / "out"
    result = runner.invoke(cli, ["spectra", *args, "-o", str(out)])
    assert result.exit_code == 2
    lines = [line for line in result.output.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith("error:") and needle in lines[0]
    assert not out.exists() or not any(out.iterdir())


def test_figures(runner, tmp_path):
    result = runner.invoke(cli, ["figures", "-o", str(tmp_path)])
    assert result.exit_code == 0, result.output
    names = sorted(p.name for p in tmp_path.iterdir())
    assert names == [
        "fig10_crescent.png",
        "fig5_blue.png",
        "fig5_yellow.png",
        "fig7_rod_rows.png",
        "physical_vs_rcwa.png",
        "table1_swatches.png",
    ]


def test_physical_comparison_degrades_without_grcwa(tmp_path, monkeypatch):
    """Without grcwa (dev extra) the figure is still drawn, without its check points, and says so."""
    import sys

    import numpy as np

    from pavonine.materials import plots, rcwa

    monkeypatch.setitem(sys.modules, "grcwa", None)  # import grcwa -> ImportError
    monkeypatch.setattr(rcwa, "lattice_reflectance", lambda _lattice, lam, **_: np.zeros_like(lam))
    note = plots.physical_comparison(tmp_path / "cmp.png")
    assert note and "grcwa is not installed" in note
    assert (tmp_path / "cmp.png").read_bytes()[:4] == b"\x89PNG"


@pytest.mark.mitsuba
def test_doctor_reports_variant_and_versions(runner):
    result = runner.invoke(cli, ["doctor", "--json", "-"])
    assert result.exit_code == 0, result.output
    info = json.loads(result.stdout)
    assert info["variant"].endswith("spectral")
    assert info["packages"]["usd-core"] and info["packages"]["Mitsuba"]
    assert info["extras"] == {"convert": True, "render": True, "farm": True}
    if info["variant"].startswith("llvm"):
        assert info["llvm_major"] >= 16


def test_spectra_json_file_is_written_with_the_plot(runner, tmp_path):
    target = tmp_path / "summary.json"
    result = runner.invoke(
        cli, ["spectra", "--preset", "yellow", "--json", str(target), "-o", str(tmp_path)]
    )
    assert result.exit_code == 0, result.output
    spectra = json.loads(target.read_text())["spectra"]
    assert [s["observe_deg"] for s in spectra][:2] == [15.0, 25.0]
    assert "peak (nm)" in result.stdout  # a JSON file leaves the table on stdout


@pytest.mark.parametrize("command", ["spectra", "figures", "maps"])
def test_output_below_a_file_is_one_line_exit_2(runner, tmp_path, command):
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    args = {
        "spectra": ["spectra", "--preset", "blue", "-o", str(blocker / "out")],
        "figures": ["figures", "-o", str(blocker / "out")],
        "maps": ["maps", "blue", "-o", str(blocker / "out"), "--size", "32"],
    }[command]
    result = runner.invoke(cli, args)
    assert result.exit_code == 2, result.output
    lines = [line for line in result.output.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith("error:") and str(blocker) in lines[0]


def test_maps_rejects_a_negative_seed(runner, tmp_path):
    result = runner.invoke(cli, ["maps", "eye", "-o", str(tmp_path / "m"), "--seed", "-1"])
    assert result.exit_code == 2 and "--seed" in result.output
    assert not (tmp_path / "m").exists()


def test_figures_in_the_physical_mode(runner, tmp_path, monkeypatch):
    """``--interference physical`` draws Figure 5 and the class swatches in the physical mode
    (the freyer2020 classes); the RCWA figure is stubbed here (it has its own tests)."""
    from pavonine.materials import plots

    seen = []
    original = plots.table1_swatches

    def spy(path, params):
        seen.append(params.interference)
        return original(path, params)

    monkeypatch.setattr(plots, "table1_swatches", spy)
    # a whole one-pixel PNG: every image written is checked whole after the write
    monkeypatch.setattr(
        plots, "physical_comparison", lambda path: plots.plt.imsave(path, [[0.0]], cmap="gray")
    )
    result = runner.invoke(cli, ["figures", "-o", str(tmp_path), "--interference", "physical"])
    assert result.exit_code == 0, result.output
    assert seen == ["physical"]
    assert (tmp_path / "fig5_blue.png").stat().st_size > 1000


def test_spectra_default_gradation_is_where_the_preset_was_measured(runner):
    """freyer2020 holds its measured structure at gradation ½ (its ends are scaled by ∓3 %)."""

    def peaks(*extra):
        args = ["spectra", "--preset", "freyer2020", "--class", "2", "--observe", "15", "--json"]
        result = runner.invoke(cli, [*args, "-", *extra])
        assert result.exit_code == 0, result.output
        return [s["peak_nm"] for s in json.loads(result.stdout)["spectra"]]

    default = peaks()
    assert default == peaks("--gradation", "0.5")
    assert default != peaks("--gradation", "0")
