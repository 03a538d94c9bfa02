"""Plots that judge a lens (matplotlib): spot diagrams and MTF curves.

Drawing only; the numbers come from ``realistic.optics.spot`` and ``realistic.optics.mtf``.
"""

from __future__ import annotations

from pathlib import Path

from realistic.core.atomic_files import save_figure
from realistic.optics.mtf import MtfReport
from realistic.optics.spot import SpotReport

#: Colour per wavelength band (blue F, green d, red C and anything else by order).
WAVELENGTH_COLOURS = ("tab:blue", "tab:green", "tab:red", "tab:purple", "tab:orange")


def _use_agg() -> None:
    """Draw to files only (no display): select the Agg backend before pyplot is imported."""
    import matplotlib

    matplotlib.use("Agg")


def plot_spots(report: SpotReport, out: Path) -> None:
    """One panel per field: ray landings (micrometres from the centroid), coloured by wavelength."""
    _use_agg()
    import matplotlib.pyplot as plt

    count = len(report.spots)
    fig, axes = plt.subplots(1, count, figsize=(3.2 * count, 3.6), squeeze=False)
    extent = max(s.geometric_radius_mm for s in report.spots) * 1000 * 1.1 or 1.0
    for ax, spot in zip(axes[0], report.spots):
        centre = spot.centroid_mm
        order = sorted(range(len(spot.wavelengths_nm)), key=lambda i: spot.wavelengths_nm[i])
        for rank, i in enumerate(order):
            pts = (spot.points[i] - centre) * 1000
            ax.scatter(pts[:, 0], pts[:, 1], s=1, color=WAVELENGTH_COLOURS[rank % len(WAVELENGTH_COLOURS)],
                       label=f"{spot.wavelengths_nm[i]:.1f} nm")
        ax.set_xlim(-extent, extent)
        ax.set_ylim(-extent, extent)
        ax.set_aspect("equal")
        ax.set_title(f"{spot.field_deg:g} deg\nRMS {spot.rms_radius_mm * 1000:.2f} um, "
                     f"geo {spot.geometric_radius_mm * 1000:.2f} um", fontsize=8)
        ax.set_xlabel("x (um)")
    axes[0][0].set_ylabel("y (um)")
    axes[0][0].legend(fontsize=6, markerscale=6)
    fig.suptitle(f"{report.lens_name}: spots at {report.focus} focus "
                 f"(film {report.film_distance_mm:.4f} mm behind the rear vertex)", fontsize=9)
    fig.tight_layout()
    save_figure(fig, out, 120)
    plt.close(fig)


def plot_mtf(report: MtfReport, out: Path) -> None:
    """Sagittal (dashed) and tangential (solid) MTF per field, with the diffraction limit (black,
    dotted) on the same axes for the FFT model."""
    _use_agg()
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4.5))
    for k, field in enumerate(report.fields_deg):
        colour = f"C{k % 10}"
        ax.plot(report.frequencies_lp_mm, report.tangential[k], color=colour, label=f"{field:g} deg T")
        ax.plot(report.frequencies_lp_mm, report.sagittal[k], color=colour, linestyle="--", label=f"{field:g} deg S")
    if report.diffraction_limit is not None:
        ax.plot(report.frequencies_lp_mm, report.diffraction_limit, color="black", linestyle=":",
                label="diffraction limit")
    ax.set_xlabel("spatial frequency (lp/mm)")
    ax.set_ylabel("MTF")
    ax.set_ylim(0, 1.02)
    ax.set_xlim(0, report.frequencies_lp_mm[-1])
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)
    ax.set_title(f"{report.lens_name}: {report.model} MTF at {report.focus} focus", fontsize=9)
    fig.tight_layout()
    save_figure(fig, out, 120)
    plt.close(fig)
