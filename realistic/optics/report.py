"""What ``realistic lens info`` reports: one dictionary, printed as text or JSON."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from realistic.optics.asphere import COEFFICIENT_POWERS
from realistic.optics.dispersion import D_LINE_NM
from realistic.optics.lens import LensSystem
from realistic.optics.paraxial import film_distance_for_focus, focus_distance_for_film, nearest_focus_mm, paraxial_data
from realistic.optics.sampling import exit_pupil_table, pass_fractions
from realistic.optics.tracer import trace_from_film

#: The coatings ``lens info`` gives the T-stop for (``ideal``'s is the f-number).
T_STOP_COATINGS = ("none", "mgf2")


def on_axis_transmittance(lens: LensSystem, wavelength_nm: float = D_LINE_NM) -> float:
    """Fraction of the light the lens's surfaces (``LensSystem.coating``) transmit along the axis, where
    every surface is met at normal incidence."""
    film_distance = film_distance_for_focus(lens, math.inf, wavelength_nm)
    traced = trace_from_film(lens, film_distance, np.zeros((1, 3)), np.array([[0.0, 0.0, 1.0]]), wavelength_nm)
    return float(traced.transmittance[0])


def t_stop(lens: LensSystem, wavelength_nm: float = D_LINE_NM) -> float:
    """The T-stop: the f-number of a lossless lens as bright on axis, N / sqrt(transmittance)."""
    return paraxial_data(lens, wavelength_nm).f_number / math.sqrt(on_axis_transmittance(lens, wavelength_nm))


def lens_summary(lens: LensSystem, wavelength_nm: float = D_LINE_NM, film_distance_mm: float | None = None,
                 sampling_film_diagonal_mm: float | None = None) -> dict[str, object]:
    """Surfaces, paraxial data, focusing and (optionally) sampler pass fractions of ``lens``: a JSON document."""
    summary: dict[str, object] = {"name": lens.name, "source": lens.source}
    if lens.convention_note:
        summary["convention_note"] = lens.convention_note
    summary.update(paraxial_data(lens, wavelength_nm).as_dict())
    infinity_mm = film_distance_for_focus(lens, math.inf, wavelength_nm)
    summary["film_distance_infinity_mm"] = infinity_mm
    summary["nearest_focus_from_film_mm"] = nearest_focus_mm(lens, wavelength_nm)
    summary["has_dispersion"] = lens.has_dispersion
    summary["t_stop"] = {name: t_stop(lens.with_coating(name), wavelength_nm) for name in T_STOP_COATINGS}
    summary["transmittance_on_axis"] = {name: on_axis_transmittance(lens.with_coating(name), wavelength_nm)
                                        for name in T_STOP_COATINGS}
    if film_distance_mm is not None:
        summary["film_distance_mm"] = film_distance_mm
        summary["focus_distance_from_film_mm"] = focus_distance_for_film(lens, film_distance_mm, wavelength_nm)
    surfaces: list[dict[str, object]] = [
        {"radius_mm": float(r), "thickness_mm": float(t), "index_d": float(n), "abbe_v": float(v),
         "aperture_mm": float(a), "stop": i == lens.stop}
        for i, (r, t, n, v, a) in enumerate(zip(lens.radius_mm, lens.thickness_mm, lens.index_d,
                                                lens.abbe_v, lens.aperture_mm))
    ]
    for i, glass in enumerate(lens.glass):
        if glass is not None:
            surfaces[i]["glass"] = glass.label
    for i in map(int, lens.aspheric.nonzero()[0]):
        surfaces[i]["conic"] = float(lens.conic[i])
        surfaces[i]["aspheric_coefficients"] = {
            f"A{p}": float(a) for p, a in zip(COEFFICIENT_POWERS, lens.aspheric_coefficients[i]) if a != 0}
    for i in map(int, lens.paraxial.nonzero()[0]):
        surfaces[i]["focal_length_mm"] = [1 / p if p else None for p in map(float, lens.paraxial_power_per_mm[i])]
    summary["surfaces"] = surfaces
    if sampling_film_diagonal_mm:
        distance = film_distance_mm if film_distance_mm is not None else infinity_mm
        table = exit_pupil_table(lens, distance, sampling_film_diagonal_mm)
        half = sampling_film_diagonal_mm / 2
        summary["pass_fraction"] = {
            "film_diagonal_mm": sampling_film_diagonal_mm,
            "at": {f"{frac:g}": pass_fractions(lens, distance, table, frac * half) for frac in (0.0, 0.5, 0.999)},
        }
    return summary


def format_summary(summary: dict[str, Any]) -> str:
    """Human-readable text for ``lens info``, from ``lens_summary``'s document."""
    lines = [f"lens {summary['name']}  ({summary['source']})"]
    if "convention_note" in summary:
        lines.append(f"note: {summary['convention_note']}")
    lines.append("")
    lines.append("  #      radius   thickness     n_d      V_d   aperture  glass")
    for i, s in enumerate(summary["surfaces"]):
        radius = "stop" if s["stop"] and s["radius_mm"] == 0 else f"{s['radius_mm']:.4f}" + "*" * s["stop"]
        abbe = f"{s['abbe_v']:.1f}" if s["abbe_v"] else "-"
        focal = s.get("focal_length_mm")
        kind = s.get("glass", "") if focal is None else "paraxial f " + " x ".join(
            "inf" if f is None else f"{f:.6g}" for f in (focal[:1] if focal[0] == focal[1] else focal)) + " mm"
        lines.append(f"{i:3d} {radius:>11} {s['thickness_mm']:11.4f} {s['index_d']:7.4f} {abbe:>8} "
                     f"{s['aperture_mm']:10.3f}  {kind}".rstrip())
    if any(s["stop"] and s["radius_mm"] != 0 for s in summary["surfaces"]):
        lines.append("  * the aperture stop, on a curved surface")
    aspheres = [(i, s) for i, s in enumerate(summary["surfaces"]) if "conic" in s]
    if aspheres:
        lines.append("")
        lines.append("even aspheres: sag = c r^2 / (1 + sqrt(1 - (1 + k) c^2 r^2)) + sum A_p r^p (mm)")
        for i, s in aspheres:
            terms = "  ".join(f"{name} {value:.6e}" for name, value in s["aspheric_coefficients"].items())
            lines.append(f"{i:3d}  conic k {s['conic']:.6g}" + (f"  {terms}" if terms else ""))
    rows = [
        ("wavelength", summary["wavelength_nm"], "nm"),
        ("effective focal length", summary["efl_mm"], "mm"),
        ("back focal distance (last vertex -> F')", summary["bfl_mm"], "mm"),
        ("front focal distance (front vertex -> F)", summary["ffd_mm"], "mm"),
        ("front principal plane (from front vertex)", summary["front_principal_plane_mm"], "mm"),
        ("rear principal plane (from last vertex)", summary["rear_principal_plane_mm"], "mm"),
        ("entrance pupil (from front vertex)", summary["entrance_pupil_mm"], "mm"),
        ("entrance pupil diameter", summary["entrance_pupil_diameter_mm"], "mm"),
        ("exit pupil (from last vertex)", summary["exit_pupil_mm"], "mm"),
        ("exit pupil diameter", summary["exit_pupil_diameter_mm"], "mm"),
        ("f-number", summary["f_number"], ""),
        *((f"T-stop, {'uncoated' if name == 'none' else 'MgF2-coated'} "
           f"(transmits {summary['transmittance_on_axis'][name]:.1%} on axis)", value, "")
          for name, value in summary["t_stop"].items()),
        ("track length", summary["track_length_mm"], "mm"),
        ("film distance for infinity", summary["film_distance_infinity_mm"], "mm"),
        ("nearest focus (from film)", summary["nearest_focus_from_film_mm"], "mm"),
    ]
    if "film_distance_mm" in summary:
        rows.append((f"in focus at film distance {summary['film_distance_mm']:g} mm",
                     summary["focus_distance_from_film_mm"], "mm from film"))
    lines.append("")
    lines.append("paraxial data (positions signed + toward the film):")
    width = max(len(r[0]) for r in rows)
    lines += [f"  {label:<{width}}  {value:12.4f} {unit}" for label, value, unit in rows]
    if "pass_fraction" in summary:
        pf = summary["pass_fraction"]
        lines.append("")
        lines.append(f"fraction of sampled rays that pass (film diagonal {pf['film_diagonal_mm']:g} mm):")
        lines.append("  film radius / half diagonal   rear element   exit pupil")
        for at, fr in pf["at"].items():
            lines.append(f"  {float(at):27.3f}   {fr['rear']:12.3f}   {fr['pupil']:10.3f}")
    return "\n".join(lines)
