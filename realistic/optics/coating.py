"""Fresnel transmission of a lens surface, bare or with a single-layer quarter-wave coating.

A ray crossing a refracting surface loses the light the interface reflects. For unpolarised light
the transmitted fraction is the average of the s and p polarisations, (Ts + Tp) / 2, from the
Fresnel equations (Born and Wolf, Principles of Optics, 1.5.2). A coating is one thin film of
magnesium fluoride, of index ``mgf2_index`` (its ordinary index: M. J. Dodge, "Refractive properties
of magnesium fluoride", Applied Optics 23, 1980-1985 (1984), Sellmeier fit for 0.2-7 um; a coating
film is polycrystalline, its index near the ordinary one) and quarter-wave optical thickness at
``DESIGN_WAVELENGTH_NM`` (d = lambda0 / (4 n(lambda0)), ``MGF2_INDEX`` = n(lambda0)) between the two
media; its reflection is the Airy sum of the beams reflected inside the film
(Born and Wolf 1.6.4), for s and p apart:

    r = (r01 + r12 e^(2 i delta)) / (1 + r01 r12 e^(2 i delta)),  t = t01 t12 e^(i delta) / (same),
    delta = 2 pi n1 d cos(theta1) / lambda,

with r_ij, t_ij the single interfaces' amplitude coefficients. Every medium is lossless, so
R + T = 1; both are computed here from their own amplitudes (the tests check the sum).

A lens's coating is one of ``COATINGS`` per surface: ``ideal`` transmits everything (the renderer
before coatings), ``none`` is bare glass, ``mgf2`` puts the layer on a surface between glass and air.
A cemented surface (glass on both sides) is never coated, so it is bare under ``none`` and ``mgf2``.
``interface_models`` turns a lens's choice into one of ``IDEAL``, ``BARE`` or ``LAYER`` per surface,
the one decision the float64 tracer and the OpenCL kernel (``kernels/lens.cl``) both follow.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from realistic.optics.dispersion import GlassFormula

#: The coating choices, per surface or for the whole lens.
COATINGS = ("ideal", "none", "mgf2")
#: What a surface does to a ray's weight: nothing, bare Fresnel, Fresnel through the layer.
IDEAL, BARE, LAYER = 0, 1, 2
#: Magnesium fluoride's ordinary index: Dodge (1984), n^2 - 1 = sum B_i lambda^2 / (lambda^2 - C_i) (um).
MGF2 = GlassFormula("MgF2 (ordinary ray)", "Dodge 1984", "sellmeier",
                    (0.48755108, 0.39875031, 2.3120353, 0.04338408 ** 2, 0.09461442 ** 2, 23.793604 ** 2))
#: The wavelength at which the layer is a quarter wave thick.
DESIGN_WAVELENGTH_NM = 550.0


def mgf2_index(wavelength_nm: float | np.ndarray) -> np.ndarray:
    """The layer's index at ``wavelength_nm`` (``MGF2``)."""
    return MGF2.index(np.asarray(wavelength_nm, dtype=np.float64) * 1e-3)


#: The layer's index at its design wavelength, which sets its thickness lambda0 / (4 n).
MGF2_INDEX = float(mgf2_index(DESIGN_WAVELENGTH_NM))


def interface_models(coatings: Sequence[str], index_behind: np.ndarray, index_in_front: np.ndarray) -> np.ndarray:
    """Per surface, ``IDEAL``, ``BARE`` or ``LAYER`` (int array): the surface's coating name and
    the media's d-line indices on its two sides. Media of equal index form no interface (IDEAL); a
    layer goes only where one side is air (index 1)."""
    behind, front = np.asarray(index_behind, float), np.asarray(index_in_front, float)
    names = np.asarray(coatings)
    model = np.where(names == "ideal", IDEAL, np.where(names == "none", BARE, LAYER))
    model = np.where((model == LAYER) & (behind != 1.0) & (front != 1.0), BARE, model)
    return np.where(behind == front, IDEAL, model)


def _cos_in(n_from: np.ndarray, n_to: np.ndarray, cos_from: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Cosine of the refracted angle in medium ``n_to`` by Snell's law (0 past the critical angle),
    and where the light is past it."""
    radicand = 1.0 - (n_from / n_to) ** 2 * (1.0 - cos_from * cos_from)
    return np.sqrt(np.maximum(radicand, 0.0)), radicand < 0


def _interface(n_i: np.ndarray, n_j: np.ndarray, c_i: np.ndarray, c_j: np.ndarray
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Amplitude coefficients (r_s, r_p, t_s, t_p) of light going from medium i into medium j
    (electric field amplitudes; r_p with the sign that makes r_p = -r_s at normal incidence)."""
    rs = (n_i * c_i - n_j * c_j) / (n_i * c_i + n_j * c_j)
    rp = (n_j * c_i - n_i * c_j) / (n_j * c_i + n_i * c_j)
    ts = 2.0 * n_i * c_i / (n_i * c_i + n_j * c_j)
    tp = 2.0 * n_i * c_i / (n_j * c_i + n_i * c_j)
    return rs, rp, ts, tp


def reflect_transmit(model: int, n_from: float | np.ndarray, n_to: float | np.ndarray,
                     cos_from: float | np.ndarray, wavelength_nm: float | np.ndarray
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(Rs, Rp, Ts, Tp) of light from medium ``n_from`` into ``n_to`` at incidence cosine
    ``cos_from`` (>= 0), through a surface of ``model``, in float64. Past the critical angle R = 1, T = 0."""
    n0, n2, c0, lam = np.broadcast_arrays(*(np.asarray(v, np.float64) for v in
                                            (n_from, n_to, cos_from, wavelength_nm)))
    if model == IDEAL:
        return np.zeros_like(c0), np.zeros_like(c0), np.ones_like(c0), np.ones_like(c0)
    c2, tir = _cos_in(n0, n2, c0)
    if model == BARE:
        rs, rp, ts, tp = _interface(n0, n2, c0, c2)
        amplitudes = [(rs, ts), (rp, tp)]
    else:
        n1 = mgf2_index(lam)
        # complex inside the layer past its critical angle: the film is then crossed by an evanescent
        # wave (frustrated total reflection), which the same sum describes
        c1 = np.sqrt((1.0 - (n0 / n1) ** 2 * (1.0 - c0 * c0)).astype(np.complex128))
        delta = 2.0 * np.pi * n1 * (DESIGN_WAVELENGTH_NM / (4.0 * MGF2_INDEX)) * c1 / lam
        phase = np.exp(2j * delta)
        r01s, r01p, t01s, t01p = _interface(n0, n1, c0, c1)
        r12s, r12p, t12s, t12p = _interface(n1, n2, c1, c2)
        amplitudes = [((r01 + r12 * phase) / (1.0 + r01 * r12 * phase),
                       t01 * t12 * np.exp(1j * delta) / (1.0 + r01 * r12 * phase))
                      for r01, r12, t01, t12 in ((r01s, r12s, t01s, t12s), (r01p, r12p, t01p, t12p))]
    flux = n2 * c2 / (n0 * c0)  # the transmitted beam's cross-section and speed relative to the incident's
    (rs, ts), (rp, tp) = amplitudes
    r = [np.where(tir, 1.0, np.abs(v) ** 2) for v in (rs, rp)]
    t = [np.where(tir, 0.0, flux * np.abs(v) ** 2) for v in (ts, tp)]
    return r[0], r[1], t[0], t[1]


def transmittance(model: int, n_from: float | np.ndarray, n_to: float | np.ndarray,
                  cos_from: float | np.ndarray, wavelength_nm: float | np.ndarray) -> np.ndarray:
    """Unpolarised transmittance (Ts + Tp) / 2 of a surface of ``model`` (``reflect_transmit``)."""
    _, _, ts, tp = reflect_transmit(model, n_from, n_to, cos_from, wavelength_nm)
    return 0.5 * (ts + tp)


def reflectance(model: int, n_from: float | np.ndarray, n_to: float | np.ndarray,
                cos_from: float | np.ndarray, wavelength_nm: float | np.ndarray) -> np.ndarray:
    """Unpolarised reflectance (Rs + Rp) / 2 of a surface of ``model`` (``reflect_transmit``)."""
    rs, rp, _, _ = reflect_transmit(model, n_from, n_to, cos_from, wavelength_nm)
    return 0.5 * (rs + rp)
