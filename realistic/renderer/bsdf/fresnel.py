"""Fresnel reflectance: dielectric (with total internal reflection), conductor, Schlick; and the
reflection and refraction of directions in the local frame (normal +z).

Formulas as pbrt-v3 ``src/core/reflection.cpp`` (``FrDielectric``, ``FrConductor``) and
``reflection.h`` (``Refract``); unpolarised light, the mean of the s and p reflectances.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike


def dielectric(cos_i: np.ndarray, eta: ArrayLike) -> np.ndarray:
    """Reflectance (N,) of a boundary between outside (index 1) and inside (index ``eta``) for
    light arriving at cosine ``cos_i`` with the normal (negative: from inside); 1 beyond the
    critical angle."""
    cos_i = np.clip(np.asarray(cos_i, np.float64), -1.0, 1.0)
    eta = np.broadcast_to(np.asarray(eta, np.float64), cos_i.shape)
    entering = cos_i > 0
    eta_i = np.where(entering, 1.0, eta)
    eta_t = np.where(entering, eta, 1.0)
    cos_i = np.abs(cos_i)
    sin_t = eta_i / eta_t * np.sqrt(np.maximum(0.0, 1.0 - cos_i * cos_i))
    cos_t = np.sqrt(np.maximum(0.0, 1.0 - sin_t * sin_t))
    with np.errstate(invalid="ignore", divide="ignore"):
        r_par = (eta_t * cos_i - eta_i * cos_t) / (eta_t * cos_i + eta_i * cos_t)
        r_perp = (eta_i * cos_i - eta_t * cos_t) / (eta_i * cos_i + eta_t * cos_t)
        r = 0.5 * (r_par * r_par + r_perp * r_perp)
    return np.where(sin_t >= 1.0, 1.0, np.nan_to_num(r, nan=1.0)).astype(np.float32)


def conductor(cos_i: np.ndarray, eta: np.ndarray, k: np.ndarray) -> np.ndarray:
    """Reflectance (N, C) of a conductor of complex index ``eta`` + i ``k`` (N, C) seen from a
    medium of index 1 at cosine ``cos_i`` (N,) (its absolute value is used)."""
    c = np.clip(np.abs(np.asarray(cos_i, np.float32)), 0.0, 1.0)[:, None]  # float32: ample for a reflectance
    eta, k = np.asarray(eta, np.float32), np.asarray(k, np.float32)
    cos2, sin2 = c * c, np.float32(1.0) - c * c
    eta2, k2 = eta * eta, k * k
    t0 = eta2 - k2 - sin2
    a2_plus_b2 = np.sqrt(t0 * t0 + np.float32(4.0) * eta2 * k2)
    t1 = a2_plus_b2 + cos2
    a = np.sqrt(np.maximum(np.float32(0.0), np.float32(0.5) * (a2_plus_b2 + t0)))
    t2 = np.float32(2.0) * c * a
    with np.errstate(invalid="ignore", divide="ignore"):
        r_s = (t1 - t2) / (t1 + t2)
        t3 = cos2 * a2_plus_b2 + sin2 * sin2
        t4 = t2 * sin2
        r_p = r_s * (t3 - t4) / (t3 + t4)
    return np.nan_to_num(np.float32(0.5) * (r_p + r_s), nan=1.0).astype(np.float32, copy=False)


def tabulated(cos_i: np.ndarray, table: np.ndarray) -> np.ndarray:
    """Reflectance (N, C) looked up at the absolute cosines ``cos_i`` (N,) in ``table`` (T, C), sampled at T
    cosines evenly spaced over [0, 1] and linear between them (a named metal's spectral Fresnel as RGB,
    ``realistic.scene.metals.reflectance_table``)."""
    last = len(table) - 1
    x = np.clip(np.abs(np.asarray(cos_i, np.float64)), 0.0, 1.0) * last
    i = np.minimum(x.astype(np.int64), last - 1)
    t = (x - i)[:, None]
    return ((1.0 - t) * table[i] + t * table[i + 1]).astype(np.float32)


def schlick(cos_i: np.ndarray, r0: np.ndarray) -> np.ndarray:
    """Schlick's approximation (N, C) with normal-incidence reflectance ``r0`` (N, C)."""
    m = (1.0 - np.clip(np.abs(cos_i), 0.0, 1.0)).astype(np.float32)[:, None]
    return (r0 + (m ** 5) * (1.0 - r0)).astype(np.float32)


def reflect_z(w: np.ndarray) -> np.ndarray:
    """Mirror directions (N, 3) about the local normal +z."""
    return (w * np.array([-1.0, -1.0, 1.0], np.float32)).astype(np.float32)


def refract_z(wo: np.ndarray, eta: np.ndarray | float) -> tuple[np.ndarray, np.ndarray]:
    """Refracted directions (N, 3) of ``wo`` through the local normal's plane into the other side,
    and whether each exists (False under total internal reflection). ``eta``: the inside index;
    ``wo`` with z > 0 is outside."""
    wo = np.asarray(wo, np.float64)
    eta = np.broadcast_to(np.asarray(eta, np.float64), (len(wo),))
    entering = wo[:, 2] > 0
    ratio = np.where(entering, 1.0 / eta, eta)  # eta_i / eta_t
    cos_i = np.abs(wo[:, 2])
    sin2_t = ratio * ratio * np.maximum(0.0, 1.0 - cos_i * cos_i)
    ok = sin2_t < 1.0
    cos_t = np.sqrt(np.maximum(0.0, 1.0 - sin2_t))
    wi = np.column_stack([-ratio * wo[:, 0], -ratio * wo[:, 1], np.where(entering, -cos_t, cos_t)])
    return wi.astype(np.float32), ok
