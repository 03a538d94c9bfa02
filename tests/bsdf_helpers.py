"""Shared pieces of the BSDF tests: constant hit parameters, sphere sampling, furnace integrals."""

import numpy as np


class ConstantHits:
    """HitParameters for N hits whose parameters are constants (RGB rays)."""

    def __init__(self, n: int):
        self.n = n

    def colour(self, value):
        return np.tile(np.asarray(value, np.float32).reshape(1, 3), (self.n, 1))

    def scalar(self, value):
        return np.full(self.n, value, np.float32)


def uniform_sphere(rng: np.random.Generator, n: int) -> np.ndarray:
    v = rng.normal(size=(n, 3))
    return (v / np.linalg.norm(v, axis=1, keepdims=True)).astype(np.float32)


def direction(theta_deg: float, phi_deg: float = 0.0, n: int = 1) -> np.ndarray:
    t, p = np.radians(theta_deg), np.radians(phi_deg)
    return np.tile(np.float32([[np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)]]), (n, 1))


def albedo_by_sampling(bsdf, wo: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Directional albedo (C,) from the BSDF's own samples: mean of value |cos| / pdf (specular included)."""
    n = len(wo)
    s = bsdf.sample(wo, rng.random((n, 2)).astype(np.float32), rng.random(n).astype(np.float32))
    w = np.where(s.valid, np.abs(s.wi[:, 2]) / np.where(s.valid, s.pdf, 1.0), 0.0)
    return (s.value * w[:, None]).mean(axis=0)


def albedo_by_integration(bsdf, wo: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Directional albedo (C,) of the non-specular lobes by uniform sphere sampling (pdf 1 / 4 pi)."""
    wi = uniform_sphere(rng, len(wo))
    return (bsdf.evaluate(wo, wi) * (np.abs(wi[:, 2]) * 4 * np.pi)[:, None]).mean(axis=0)


def pdf_integral(bsdf, wo: np.ndarray, rng: np.random.Generator) -> float:
    wi = uniform_sphere(rng, len(wo))
    return float((bsdf.pdf(wo, wi) * 4 * np.pi).mean())


class SpectralHits:
    """HitParameters for N spectral rays at ``wavelength_nm`` (N,): colours become (N, 1) spectra."""

    def __init__(self, wavelength_nm: np.ndarray):
        from realistic.core.spectrum import rgb_basis

        self.n, self.basis = len(wavelength_nm), rgb_basis(wavelength_nm)

    def colour(self, value):
        from realistic.core.spectrum import spectral_value

        rgb = np.tile(np.asarray(value, np.float32).reshape(1, 3), (self.n, 1))
        return spectral_value(rgb, self.basis)[:, None]

    def scalar(self, value):
        return np.full(self.n, value, np.float32)
