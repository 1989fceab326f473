"""Figures of the optics model, laid out like the paper's (Figures 5, 7, 10, Table 1)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from pavonine.materials import optics, rod
from pavonine.materials.parameters import CLASS_NAMES, FeatherParameters

FIGURE5_OBSERVE = (15, 25, 35, 45, 55, 65, 75, 85)


def _save(fig, path: Path) -> None:
    fig.savefig(path, dpi=120, bbox_inches="tight")
    plt.close(fig)


def figure5(
    path: Path,
    params: FeatherParameters,
    title: str,
    incidence_deg: float = 0.0,
    observe_deg: Sequence[float] = FIGURE5_OBSERVE,
    **kwargs,
) -> list[optics.SpectrumSummary]:
    """Stacked reflectance spectra per observation angle (top = first angle), swatches at right."""
    spectra = optics.reflectance_spectra(params, incidence_deg, observe_deg, **kwargs)
    summaries = optics.summarise(params, incidence_deg, observe_deg, **kwargs)
    w = optics.PLOT_WAVELENGTHS_NM
    offset = max(float(spectra.max()), 1e-6) * 0.6
    fig, (ax, sw) = plt.subplots(1, 2, figsize=(7, 6), gridspec_kw={"width_ratios": [6, 1]})
    n = len(spectra)
    for i, (spectrum, s) in enumerate(zip(spectra, summaries, strict=True)):
        base = (n - 1 - i) * offset
        ax.plot(w, spectrum + base, color=s.srgb, lw=1.8)
        ax.axhline(base, color="0.85", lw=0.6, zorder=0)
        ax.text(w[-1] + 5, base + 0.05 * offset, f"{s.observe_deg:g}°", va="bottom", fontsize=8)
        sw.add_patch(plt.Rectangle((0, base), 1, offset * 0.9, color=s.srgb))
    ax.set_xlabel("wavelength (nm)")
    ax.set_ylabel("reflectance factor πf (offset per angle)")
    ax.set_title(f"{title}: incidence {incidence_deg:g}°")
    ax.set_xlim(w[0], w[-1] + 30)
    sw.set_xlim(0, 1)
    sw.set_ylim(ax.get_ylim())
    sw.axis("off")
    sw.set_title("colour", fontsize=9)
    _save(fig, path)
    return summaries


def figure7(path: Path, counts: Sequence[int] = (1, 2, 5, 10, 20)) -> None:
    """Eq. 3: rod rows at normal incidence (a = 70 nm, L = 140 nm, λ = 600 nm, n = 2.0), normalised at 0°."""
    theta = np.linspace(-math.pi / 2, math.pi / 2, 2001)
    single = rod.unpolarised_intensity(2 * math.pi * 70.0 / 600.0, 2.0, math.pi - np.abs(theta))
    fig = plt.figure(figsize=(6, 4))
    ax = fig.add_subplot(projection="polar")
    for n in counts:
        curve = optics.rod_row_intensity(single, n, 140.0, 0.0, np.sin(theta), 600.0)
        ax.plot(theta, curve / curve[len(curve) // 2], label=f"N = {n}")
    ax.set_thetamin(-90)
    ax.set_thetamax(90)
    ax.set_theta_zero_location("N")
    ax.set_title("Figure 7 (Eq. 3): rod rows, normalised at 0°", fontsize=10)
    ax.legend(loc="center left", bbox_to_anchor=(1.08, 0.5), fontsize=8)
    _save(fig, path)


def figure10(path: Path, incidences: Sequence[float] = (0, 15, 30, 45, 60)) -> None:
    """Eq. 6: density of crescent normal tilts for several incidence angles (θ0 = 15°)."""
    tilt = np.linspace(-math.pi / 2, math.pi / 2, 1001)
    fig, ax = plt.subplots(figsize=(6, 4))
    for inc in incidences:
        density = optics.crescent_density(tilt, math.radians(inc))
        ax.plot(np.degrees(tilt), density * math.pi / 180.0, label=f"θin = {inc}°")
    ax.set_xlim(-60, 60)
    ax.set_xlabel("normal tilt θ across the barbule (degrees)")
    ax.set_ylabel("density (per degree)")
    ax.set_title("Figure 10 (Eq. 6): crescent normal density, θ0 = 15°", fontsize=10)
    ax.legend(fontsize=8)
    _save(fig, path)


def table1_swatches(
    path: Path, params: FeatherParameters, observe_deg: Sequence[float] = (10, 30, 50, 70)
) -> np.ndarray:
    """Each class's colour (incidence 0°) at a few angles, in the planes along and across the
    barbule (Eq. 7's two axes), both gradation ends."""
    rows = []
    labels = []
    for cls in range(len(params.classes)):
        for end, t in (("black", 0.0), ("white", 1.0)):
            row = []
            for azimuth in (0.0, 90.0):
                s = optics.summarise(
                    params, 0.0, observe_deg, ocellar_class=cls, gradation=t, azimuth_deg=azimuth
                )
                row += [x.srgb for x in s]
            rows.append(row)
            name = CLASS_NAMES[cls] if cls < len(CLASS_NAMES) else str(cls)
            labels.append(f"class {cls} ({name}) · {end} end")
    grid = np.array(rows)
    fig, ax = plt.subplots(figsize=(2.0 * len(observe_deg) + 3, 0.42 * len(rows) + 1))
    ax.imshow(grid, aspect="auto", interpolation="nearest")
    ticks = [f"along {o}°" for o in observe_deg] + [f"across {o}°" for o in observe_deg]
    ax.set_xticks(range(len(ticks)), ticks, fontsize=8, rotation=30)
    ax.axvline(len(observe_deg) - 0.5, color="white", lw=3)
    ax.set_yticks(range(len(rows)), labels, fontsize=8)
    ax.set_xlabel("plane of observation and angle (incidence 0°)")
    ax.set_title(f"Ocellar classes: structural colour ({params.interference} mode)", fontsize=10)
    _save(fig, path)
    return grid


#: The stacks the physical mode is pinned on (issue 9): name -> (interval d, radius a in nm, N).
REFERENCE_STACKS = {
    "yellow (d 190, a 70, N 4)": (190.0, 70.0, 4),
    "blue (d 150, a 65, N 10)": (150.0, 65.0, 10),
    "class 5 black end (d 110, a 60, N 16)": (110.0, 60.0, 16),
}
#: Index sets: label -> (rod index or None = melanin, medium index or None = keratin).
INDEX_SETS = {
    "paper indices: rods n = 2.0 in air": (2.0, 1.0),
    "melanin in keratin (dispersive, absorbing)": (None, None),
}


def physical_comparison(path: Path, grcwa_points: bool = True) -> str | None:
    """Paper mode, physical mode and the rigorous RCWA of the rod lattice at normal incidence, for
    the yellow, blue and class-5 stacks with both index sets. With ``grcwa_points`` a few
    wavelengths are also solved by the independent ``grcwa`` package (markers); returns a note
    when grcwa is not installed (the figure is still drawn, without those markers)."""
    from pavonine.materials import dispersion, rcwa
    from pavonine.materials.lattice import RodLattice

    lam = np.arange(340.0, 861.0, 5.0)
    note = None
    fig, axes = plt.subplots(2, 3, figsize=(13, 7.5), sharex=True)
    for row, (index_label, (n_rod, n_med)) in enumerate(INDEX_SETS.items()):
        rod_index = dispersion.MELANIN.index(lam) if n_rod is None else n_rod
        medium = dispersion.KERATIN.index(lam).real if n_med is None else n_med
        for col, (name, (d, a, n)) in enumerate(REFERENCE_STACKS.items()):
            ax = axes[row, col]
            lattice = RodLattice(d, a, n)
            exact = rcwa.lattice_reflectance(
                lattice, lam, n_rod=rod_index, n_matrix=medium, harmonics=7, per_diameter=12
            )
            kwargs = dict(n_rod=n_rod, n_medium=n_med)
            paper = optics.stack_reflectance(lam, d, a, n, mode="paper", **kwargs)
            physical = optics.stack_reflectance(lam, d, a, n, mode="physical", **kwargs)
            ax.plot(lam, paper, color="0.55", ls="--", lw=1.4, label="paper mode (Eq. 2–4)")
            ax.plot(lam, physical, color="tab:blue", lw=2.0, label="physical mode (EMT TMM)")
            ax.plot(lam, exact, color="black", lw=1.0, label="RCWA of the rod lattice")
            if grcwa_points and note is None:
                peak = float(lam[np.argmax(exact)])
                picks = [w for w in (peak - 80.0, peak, peak + 80.0) if 345.0 <= w <= 855.0]
                try:
                    values = [
                        rcwa.grcwa_reflectance(
                            lattice,
                            w,
                            n_rod=complex(dispersion.MELANIN.index(w)) if n_rod is None else n_rod,
                            n_matrix=float(dispersion.KERATIN.real(w)) if n_med is None else n_med,
                            harmonics=15,
                            per_diameter=8,
                            grid=256,
                        )
                        for w in picks
                    ]
                    ax.plot(picks, values, "o", mfc="none", color="tab:red", label="grcwa check")
                except ImportError:
                    note = "grcwa is not installed: the independent grcwa check points are omitted"
            ax.set_title(name, fontsize=9)
            ax.set_ylim(0, max(1.05 * max(paper.max(), physical.max(), exact.max()), 0.02))
            if col == 0:
                ax.set_ylabel(f"{index_label}\nreflectance (normal incidence)", fontsize=8)
            if row == 1:
                ax.set_xlabel("wavelength (nm)")
    handles, labels = axes[0, 0].get_legend_handles_labels()
    fig.suptitle(
        "Rod stacks: paper mode vs physical mode vs rigorous coupled-wave analysis", fontsize=11
    )
    fig.tight_layout(rect=(0, 0.05, 1, 1))
    fig.legend(handles, labels, loc="lower center", ncol=4, fontsize=8, frameon=False)
    if note:
        fig.text(0.5, 0.035, note, ha="center", fontsize=8, color="tab:red")
    _save(fig, path)
    return note
