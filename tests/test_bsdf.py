"""BSDF conventions: the shading frame is orthonormal, and the Lambertian lobe conserves energy."""

import numpy as np

from realistic.renderer.bsdf import Lambertian, ShadingFrame


def _unit(rng: np.random.Generator, n: int) -> np.ndarray:
    v = rng.normal(size=(n, 3)).astype(np.float32)
    return v / np.linalg.norm(v, axis=1)[:, None]


def test_shading_frame_is_orthonormal_and_inverts():
    rng = np.random.default_rng(3)
    normal = np.vstack([_unit(rng, 2000), [[0, 0, -1], [0, 0, 1], [1, 0, 0]]]).astype(np.float32)
    frame = ShadingFrame(normal)
    basis = np.stack([frame.s, frame.t, frame.n], axis=1)
    gram = np.einsum("nij,nkj->nik", basis, basis)
    assert np.abs(gram - np.eye(3)).max() < 1e-5
    assert np.abs(frame.to_local(normal) - [0, 0, 1]).max() < 1e-5
    w = _unit(rng, len(normal))
    assert np.abs(frame.to_world(frame.to_local(w)) - w).max() < 1e-5


def test_lambertian_sampling_estimates_its_albedo_and_pdf_matches_cosine():
    rng = np.random.default_rng(4)
    n = 200_000
    albedo = np.tile(np.float32([[0.2, 0.5, 0.9]]), (n, 1))
    bsdf = Lambertian(albedo)
    wo = np.tile(np.float32([[0.3, 0.0, np.sqrt(1 - 0.09)]]), (n, 1))
    s = bsdf.sample(wo, rng.random((n, 2)), rng.random(n))
    assert s.valid.all()
    assert np.allclose(s.pdf, s.wi[:, 2] / np.pi, rtol=1e-5)
    throughput = s.value * (s.wi[:, 2] / s.pdf)[:, None]
    assert np.allclose(throughput, albedo, rtol=1e-4)  # f cos / pdf is the albedo, sample by sample
    # Independent check by uniform hemisphere integration: integral of f cos = albedo.
    z = rng.random(n)
    phi = 2 * np.pi * rng.random(n)
    r = np.sqrt(1 - z * z)
    wi = np.column_stack([r * np.cos(phi), r * np.sin(phi), z]).astype(np.float32)
    estimate = (bsdf.evaluate(wo, wi) * (z * 2 * np.pi)[:, None]).mean(axis=0)
    assert np.allclose(estimate, [0.2, 0.5, 0.9], rtol=0.01)
