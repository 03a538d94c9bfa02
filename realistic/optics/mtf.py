"""MTF: the contrast a lens keeps at each spatial frequency, by diffraction (FFT) or from its traced spot.

The FFT model (the default) is the modulus of the OTF of each wavelength's pupil function
(``realistic.optics.wavefront`` and ``realistic.optics.diffraction``), all wavelengths referred to
one point on the film (the weighted mean of their rays' landing centroids, so lateral colour counts)
and their OTFs averaged with the wavelengths' weights (relative powers; equal by default) before the
modulus. Each wavelength's OTF is read at its own cell shift for a frequency nu, nu lambda L / dh
(``realistic.optics.diffraction``), so the curves add on one frequency axis. The plot adds the
diffraction-limited MTF of the paraxial f-number, averaged over the same wavelengths and weights.

The geometric model:

The line spread function is the spot projected on one film axis; its Fourier transform at
frequency nu (line pairs per mm) over N equally weighted ray landings u_k is
(1/N) sum_k exp(-2 pi i nu u_k), and the MTF is its modulus. No histogram is built, so nothing
depends on a bin size. Fields lie along +y: the *tangential* MTF projects on y (lines
perpendicular to the field's radius), the *sagittal* on x. Several wavelengths enter with equal
weight (weights are the FFT model's). Diffraction is not included.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from realistic.core import validation
from realistic.errors import UserError
from realistic.optics.diffraction import diffraction_limited_mtf, fft_otf, otf_along, pupil_function
from realistic.optics.lens import LensSystem
from realistic.optics.paraxial import paraxial_data
from realistic.optics.spot import Spot, film_distance_for, focus_label, spots_at, trace_fields
from realistic.optics.wavefront import wavefront

#: ``--model`` of ``lens mtf`` and ``lens psf``: diffraction of the pupil function, or traced rays only.
MODELS = ("fft", "geometric")

#: Frequencies evaluated at once (bounds the (rays x frequencies) phase array).
_CHUNK = 64


def spot_mtf(spot: Spot, frequencies_lp_mm: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(sagittal, tangential) MTF of a spot, wavelengths weighted equally."""
    sagittal = np.zeros(len(frequencies_lp_mm), dtype=np.complex128)
    tangential = np.zeros(len(frequencies_lp_mm), dtype=np.complex128)
    used = [p for p in spot.points if len(p)]
    centre = spot.centroid_mm
    for points in used:
        sagittal += _complex_mean(points[:, 0] - centre[0], frequencies_lp_mm)
        tangential += _complex_mean(points[:, 1] - centre[1], frequencies_lp_mm)
    return np.abs(sagittal) / len(used), np.abs(tangential) / len(used)


def _complex_mean(u: np.ndarray, frequencies_lp_mm: np.ndarray) -> np.ndarray:
    """mean exp(-2 pi i nu u) per frequency (complex: wavelengths add before the modulus)."""
    out = np.empty(len(frequencies_lp_mm), dtype=np.complex128)
    for start in range(0, len(frequencies_lp_mm), _CHUNK):
        phase = 2 * np.pi * np.outer(frequencies_lp_mm[start:start + _CHUNK], u)
        out[start:start + _CHUNK] = np.cos(phase).mean(axis=1) - 1j * np.sin(phase).mean(axis=1)
    return out


@dataclass(frozen=True)
class MtfReport:
    """Sagittal and tangential MTF per field on one film plane (``diffraction_limit``: the FFT model's
    aberration-free curve, None for the geometric model)."""

    lens_name: str
    focus: str
    film_distance_mm: float
    frequencies_lp_mm: np.ndarray
    fields_deg: tuple[float, ...]
    sagittal: tuple[np.ndarray, ...]
    tangential: tuple[np.ndarray, ...]
    model: str = "geometric"
    diffraction_limit: np.ndarray | None = None
    undersampled: tuple[float, ...] = ()  # FFT model: per field, the worst ``Wavefront.undersampled_fraction``

    def as_dict(self) -> dict[str, object]:
        limit = None if self.diffraction_limit is None else self.diffraction_limit.tolist()
        return {"lens": self.lens_name, "model": self.model, "focus": self.focus,
                "film_distance_mm": self.film_distance_mm, "frequencies_lp_mm": self.frequencies_lp_mm.tolist(),
                "diffraction_limit": limit,
                "fields": [{"field_deg": f, "sagittal": s.tolist(), "tangential": t.tolist()}
                           for f, s, t in zip(self.fields_deg, self.sagittal, self.tangential)]}


def fft_field_mtf(lens: LensSystem, field_deg: float, wavelengths_nm: list[float], film_distance_mm: float,
                  frequencies_lp_mm: np.ndarray, samples_across: int, weights: list[float] | None = None
                  ) -> tuple[np.ndarray, np.ndarray, float]:
    """(sagittal, tangential, worst ``Wavefront.undersampled_fraction``) of the FFT MTF of one field at
    infinity, wavelengths with relative powers ``weights`` (None: equal)."""
    weights = validation.spectral_weights(weights, len(wavelengths_nm))
    fronts = [wavefront(lens, field_deg, w, film_distance_mm, samples_across) for w in wavelengths_nm]
    reference = np.average([f.reference_mm for f in fronts], axis=0, weights=weights)
    if len(fronts) > 1:
        fronts = [wavefront(lens, field_deg, w, film_distance_mm, samples_across, reference_mm=tuple(reference))
                  for w in wavelengths_nm]
    sagittal = np.zeros(len(frequencies_lp_mm), dtype=np.complex128)
    tangential = np.zeros(len(frequencies_lp_mm), dtype=np.complex128)
    for front, weight in zip(fronts, weights):
        otf = fft_otf(pupil_function(front.opd_waves))
        shifts = frequencies_lp_mm * front.wavelength_nm * 1e-6 / front.spacing_mm
        sagittal += weight * otf_along(otf, 1, shifts * front.scale_mm[0])  # columns run along x
        tangential += weight * otf_along(otf, 0, shifts * front.scale_mm[1])
    worst = max(front.undersampled_fraction for front in fronts)
    return np.abs(sagittal), np.abs(tangential), worst


def lens_mtf(lens: LensSystem, fields_deg: list[float], wavelengths_nm: list[float], max_frequency_lp_mm: float,
             focus: str | float = "paraxial", samples_across: int = 128, frequency_count: int = 101,
             model: str = "fft", weights: list[float] | None = None) -> MtfReport:
    """MTF (``model`` fft or geometric) from 0 to ``max_frequency_lp_mm`` of objects at infinity at
    ``fields_deg``; ``weights``: the FFT model's relative power per wavelength (None: equal)."""
    max_frequency_lp_mm = validation.positive_length(max_frequency_lp_mm, "maximum frequency (lp/mm)")
    if model not in MODELS:
        raise UserError(f"MTF model must be one of {', '.join(MODELS)}, got {model!r}")
    if model == "geometric" and weights is not None:
        raise UserError("wavelength weights apply to the FFT model (the geometric MTF weights every ray equally)")
    weights = validation.spectral_weights(weights, len(wavelengths_nm))
    nu = np.linspace(0.0, max_frequency_lp_mm, frequency_count)
    if model == "geometric" or focus == "best":
        traced = trace_fields(lens, fields_deg, wavelengths_nm, samples_across)
    film = film_distance_for(lens, traced if focus == "best" else [], focus)
    if model == "geometric":
        spots = spots_at(traced, fields_deg, wavelengths_nm, film)
        curves = [spot_mtf(s, nu) for s in spots]
        return MtfReport(lens.name, focus_label(focus), film, nu, tuple(fields_deg), tuple(c[0] for c in curves),
                         tuple(c[1] for c in curves))
    fft = [fft_field_mtf(lens, f, wavelengths_nm, film, nu, samples_across, weights) for f in fields_deg]
    f_number = paraxial_data(lens).f_number
    limit = np.average([diffraction_limited_mtf(nu * w * 1e-6 * f_number) for w in wavelengths_nm], axis=0,
                       weights=weights)
    return MtfReport(lens.name, focus_label(focus), film, nu, tuple(fields_deg), tuple(c[0] for c in fft),
                     tuple(c[1] for c in fft), model, limit, tuple(c[2] for c in fft))
