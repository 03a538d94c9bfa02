"""Drawings of a lens (matplotlib): the cross-section with ray fans, and the field curves.

Drawing only; the numbers come from ``realistic.optics.field_curves`` and the tracer.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from realistic.core.atomic_files import save_figure
from realistic.core.film_geometry import FULL_FRAME_DIAGONAL_MM
from realistic.optics.asphere import sag_mm
from realistic.optics.field_curves import FieldPoint, meridional_fan
from realistic.optics.lens import LensSystem
from realistic.optics.sampling import exit_pupil_table

FAN_COLOURS = ("tab:blue", "tab:green", "tab:red")


def surface_profile(lens: LensSystem, film_distance_mm: float, i: int, rho: np.ndarray) -> np.ndarray:
    """z of surface i at heights rho (lens frame): the vertex less the sag, which for an even
    asphere is its own (conic and polynomial, ``realistic.optics.asphere``), not the base sphere's."""
    z = lens.vertex_z_mm(film_distance_mm)[i]
    r = lens.radius_mm[i]
    flat = r == 0 or not np.isfinite(r)
    if lens.aspheric[i]:
        return z - sag_mm(rho * rho, 0.0 if flat else 1.0 / r, lens.conic[i], lens.aspheric_coefficients[i])
    if flat:
        return np.full_like(rho, z)
    return z - r + np.sign(r) * np.sqrt(r * r - rho * rho)


def plot_cross_section(lens: LensSystem, film_distance_mm: float, out: Path,
                       film_diagonal_mm: float = FULL_FRAME_DIAGONAL_MM) -> None:
    """The elements (a paraxial surface as a double arrow), the stop, the film and meridional ray fans
    from three film heights."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(10, 5))
    for i in range(lens.surface_count):
        half = lens.aperture_mm[i] / 2
        if i == lens.stop:
            z = lens.vertex_z_mm(film_distance_mm)[i]
            top = lens.aperture_mm.max() / 2 * 1.05
            ax.plot([z, z], [half, top], "k", lw=2)
            ax.plot([z, z], [-half, -top], "k", lw=2)
            if lens.stop_is_flat_in_air:
                continue
        if lens.paraxial[i]:  # an ideal thin lens, as optics programs draw one: arrows out, or in if diverging
            z = lens.vertex_z_mm(film_distance_mm)[i]
            style = "<->" if lens.paraxial_power_per_mm[i].sum() > 0 else "]-["
            ax.annotate("", xy=(z, half), xytext=(z, -half), arrowprops={"arrowstyle": style, "lw": 1})
            continue
        rho = np.linspace(-half, half, 101)
        ax.plot(surface_profile(lens, film_distance_mm, i, rho), rho, "k", lw=1)
        if lens.index_d[i] > 1 and i + 1 < lens.surface_count:  # glass behind: close the element's rim
            edge = min(half, lens.aperture_mm[i + 1] / 2)
            for sign in (-1, 1):
                za = surface_profile(lens, film_distance_mm, i, np.array([sign * edge]))[0]
                zb = surface_profile(lens, film_distance_mm, i + 1, np.array([sign * edge]))[0]
                ax.plot([za, zb], [sign * edge, sign * edge], "k", lw=1)
    table = exit_pupil_table(lens, film_distance_mm, film_diagonal_mm)
    lit = np.flatnonzero(table.area_mm2() > 0)
    reach = (lit[-1] + 1) * table.film_radius_mm / len(table.bounds) if len(lit) else 0.0
    for colour, fraction in zip(FAN_COLOURS, (0.0, 0.5, 0.9)):
        for line in meridional_fan(lens, film_distance_mm, fraction * reach, table):
            ax.plot(line[:, 2], line[:, 0], color=colour, lw=0.6)
    # The axial range of the film, the vertices and the fans (0.6 track beyond the front), plus 5 %:
    # an asphere's polynomial may run far off near a rim no ray reaches (phone-us10101561's
    # surface 8 reaches 71 mm at its stated clear aperture), which would otherwise shrink the lens.
    vertex_z = lens.vertex_z_mm(film_distance_mm)
    near, far = min(0.0, vertex_z.min()), vertex_z.max() + 0.6 * lens.track_length_mm
    # As optics programs draw a lens: the scene on the left, the film on the right, the axis horizontal
    # (the lens frame's +z points to the scene, so its axis runs right to left).
    ax.set_xlim(far + 0.05 * (far - near), near - 0.05 * (far - near))
    ax.axvline(0.0, color="grey", lw=2)
    ax.axhline(0.0, color="grey", lw=0.5, ls="--")
    ax.set_aspect("equal")
    ax.set_xlabel("z (mm, film at 0 on the right, scene to the left)")
    ax.set_ylabel("height (mm)")
    ax.set_title(f"{lens.name}: film distance {film_distance_mm:.3f} mm; fans from 0, 50 and 90 % of the "
                 f"image circle ({reach:.1f} mm)")
    fig.tight_layout()
    save_figure(fig, out, 150)
    plt.close(fig)


def plot_field_curves(name: str, rows: list[FieldPoint], out: Path) -> None:
    """Relative illumination, vignetting and distortion against film radius."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    radius = [r["film_radius_mm"] for r in rows]
    fig, (left, right) = plt.subplots(1, 2, figsize=(11, 4.5))
    left.plot(radius, [r["relative_illumination"] for r in rows], label="relative illumination")
    left.plot(radius, [r["vignetting"] for r in rows], "--", label="vignetting (open pupil area)")
    left.set_xlabel("film radius (mm)")
    left.set_ylim(0, 1.05)
    left.legend()
    distorted = [(r["film_radius_mm"], r["distortion_percent"]) for r in rows if r["distortion_percent"] is not None]
    right.plot(*zip(*distorted) if distorted else ([], []))
    right.set_xlabel("film radius (mm)")
    right.set_ylabel("distortion (%)")
    right.axhline(0, color="grey", lw=0.5)
    fig.suptitle(f"{name}: field curves")
    fig.tight_layout()
    save_figure(fig, out, 120)
    plt.close(fig)
