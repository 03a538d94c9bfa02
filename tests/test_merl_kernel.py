"""The MERL lobe of kernels/bsdf.cl (a measured material whose file is a MERL half-angle table)
against the numpy ``MeasuredBRDF`` (the reference, ``halfangle_lookup``): the bin it reads at random
pairs, at pairs straddling every bin edge of theta_h, theta_d and phi_d and near theta_h = 90
degrees; its pdf and cosine samples; spectral rays; the lookup's reciprocity; the table placed once
per file; and the fused bounce (kernels/bounce.cl) per hit and over whole paths. The tables are
written here (``_write_merl``); a MERL file under ../shared is read too where there is one."""

from pathlib import Path

import numpy as np
import pytest

from bsdf_helpers import ConstantHits, SpectralHits, uniform_sphere
from conftest import SHARED
from realistic.renderer.bsdf import bsdf_for
from realistic.scene.materials import Measured, Mix, Plastic
from realistic.scene.measured import MERL_SHAPE, load_measured
from test_bounce_kernel import _pair, _paths_agree, _scene, _shades_as_numpy

pytest.importorskip("realistic.camera.opencl_host")
pytestmark = pytest.mark.usefixtures("opencl_platform")

from realistic.device.opencl import Device  # noqa: E402
from realistic.renderer.bsdf_kernel import BSDF_PARAMS, KIND, TABLE_ALIGN, BsdfKernel, parameters  # noqa: E402

COUNT = int(np.prod(MERL_SHAPE))
N_H, N_D, N_PHI = MERL_SHAPE


def _write_merl(path: Path, raw: np.ndarray) -> Measured:
    """A MERL file at ``path`` of ``raw`` (3 * COUNT values: all red, then green, then blue)."""
    path.write_bytes(np.array(MERL_SHAPE, "<i4").tobytes() + np.asarray(raw, "<f8").tobytes())
    return Measured(str(path))


@pytest.fixture(scope="module")
def index_merl(tmp_path_factory: pytest.TempPathFactory) -> Measured:
    """A MERL file whose raw value at flat index i is i in every channel: a hit's red f times 1500
    is the index of the bin it read."""
    return _write_merl(tmp_path_factory.mktemp("merl") / "index.binary", np.tile(np.arange(COUNT, dtype=float), 3))


@pytest.fixture(scope="module")
def random_merl(tmp_path_factory: pytest.TempPathFactory) -> Measured:
    """A MERL file of random bins, red up to 0.2, green 0.23, blue 0.33 after the channel scales."""
    raw = np.random.default_rng(21).random(3 * COUNT) * 300.0
    return _write_merl(tmp_path_factory.mktemp("merl") / "random.binary", raw)


@pytest.fixture(scope="module")
def kernel() -> BsdfKernel:
    return BsdfKernel(Device.for_spec())


def _bins(red_f: np.ndarray) -> np.ndarray:
    """The flat bin index an index table's red f (N,) holds (``index_merl``)."""
    return np.rint(red_f.astype(np.float64) * 1500.0).astype(np.int64)


def _pairs(theta_h: np.ndarray, phi_h: np.ndarray, theta_d: np.ndarray, phi_d: np.ndarray
           ) -> tuple[np.ndarray, np.ndarray]:
    """float32 (wo, wi) with the given half and difference angles (radians): wd rotated by theta_h
    about y and phi_h about z (Rusinkiewicz 1998) is wi, and wo is wi mirrored about the half vector."""
    wh = np.column_stack([np.sin(theta_h) * np.cos(phi_h), np.sin(theta_h) * np.sin(phi_h), np.cos(theta_h)])
    d = np.column_stack([np.sin(theta_d) * np.cos(phi_d), np.sin(theta_d) * np.sin(phi_d), np.cos(theta_d)])
    x = d[:, 0] * np.cos(theta_h) + d[:, 2] * np.sin(theta_h)  # about y by theta_h
    z = -d[:, 0] * np.sin(theta_h) + d[:, 2] * np.cos(theta_h)
    wi = np.column_stack([x * np.cos(phi_h) - d[:, 1] * np.sin(phi_h), x * np.sin(phi_h) + d[:, 1] * np.cos(phi_h), z])
    wo = 2 * np.sum(wi * wh, axis=1)[:, None] * wh - wi
    return wo.astype(np.float32), wi.astype(np.float32)


def _jittered(wo: np.ndarray, wi: np.ndarray, copies: int, rng: np.random.Generator
              ) -> tuple[np.ndarray, np.ndarray]:
    """Each pair, then ``copies`` - 1 copies of it with each component moved by up to two float32
    steps at random: pairs on both sides of a bin edge that lies within rounding of the pair."""
    out = []
    for w in (wo, wi):
        moved = np.repeat(w, copies, axis=0)
        for _ in range(2):
            step = np.nextafter(moved, np.where(rng.random(moved.shape) < 0.5, -np.inf, np.inf).astype(np.float32))
            moved = np.where(rng.random(moved.shape) < 0.5, step, moved)
        moved[::copies] = w
        out.append(moved)
    return out[0], out[1]


def _edge_pairs() -> dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """Per axis: pairs whose angle on that axis is at each of its bin edges (theta_h at
    (k / 90)^2 90 degrees, theta_d at k degrees, phi_d at k degrees), the other angles where both
    directions stay above the surface, and k (per pair)."""
    deg = np.pi / 180
    k_h = np.arange(1, N_H)
    k_d = np.arange(1, N_D)
    k_phi = np.arange(1, N_PHI)
    theta_h_edge = (k_h / N_H) ** 2 * (np.pi / 2)
    # theta_d small where theta_h is near 90 degrees, so that both directions stay above the surface
    theta_d_h = np.minimum(5 * deg, 0.5 * (np.pi / 2 - theta_h_edge))
    cases = {"theta_h": (theta_h_edge, 0.3 + k_h * 0.05, theta_d_h, 0.7 + k_h * 0.11, k_h),
             "theta_d": (np.full(len(k_d), 0.2 * deg), 1.1 + k_d * 0.07, k_d * deg, 0.4 + k_d * 0.03, k_d),
             "phi_d": (np.full(len(k_phi), 20 * deg), 2.0 + k_phi * 0.013, np.full(len(k_phi), 30 * deg),
                       k_phi * deg, k_phi)}
    return {axis: (*_pairs(theta_h, phi_h, theta_d, phi_d), k)
            for axis, (theta_h, phi_h, theta_d, phi_d, k) in cases.items()}


def _f(kernel: BsdfKernel, material: Measured, wo: np.ndarray, wi: np.ndarray, channels: int = 3,
       hits: ConstantHits | SpectralHits | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The kernel's f (N, channels) and pdf (N,) of ``material`` at the pairs."""
    n = len(wo)
    rows = kernel.rows(material, hits or ConstantHits(n), n)
    assert rows is not None and np.all(rows[:, BSDF_PARAMS.offset("kind")] == KIND["merl"])
    zeros = np.zeros((n, 2), np.float32)
    f, pdf, _ = kernel(rows, wo, wi[None], zeros, zeros[:, 0], channels)
    return f[0], pdf[0]


def test_kernel_reads_the_bin_numpy_reads_at_random_pairs(kernel, index_merl):
    """At pairs of random directions (both on one side, on either side, and on opposite sides) the
    kernel's f is the numpy BSDF's bit for bit (the same bin, the same channel scales), and its pdf
    the cosine's."""
    rng = np.random.default_rng(1)
    n = 100_000
    wo, wi = uniform_sphere(rng, n), uniform_sphere(rng, n)
    wi[: n // 2, 2] = np.abs(wi[: n // 2, 2]) * np.sign(wo[: n // 2, 2])
    f, pdf = _f(kernel, index_merl, wo, wi)
    bsdf = bsdf_for(index_merl, ConstantHits(n))
    expected = bsdf.evaluate(wo, wi)
    assert np.array_equal(f, expected)
    assert len(np.unique(_bins(f[: n // 2, 0]))) > 20_000  # many bins read
    assert np.all(f[wo[:, 2] * wi[:, 2] <= 0] == 0)
    assert np.allclose(pdf, bsdf.pdf(wo, wi), rtol=1e-6, atol=0)


@pytest.mark.parametrize("axis", ["theta_h", "theta_d", "phi_d"])
def test_kernel_reads_numpys_bin_on_both_sides_of_every_bin_edge(kernel, index_merl, axis):
    """Pairs within float32 rounding of each bin edge of ``axis`` (eight copies of each, moved by a
    float32 step or two): the numpy reference reads the bins on both sides of most edges, and the
    kernel reads the same bin as numpy at every pair."""
    wo, wi, k = _edge_pairs()[axis]
    copies = 8
    wo, wi = _jittered(wo, wi, copies, np.random.default_rng(2))
    assert np.all(wo[:, 2] > 0) and np.all(wi[:, 2] > 0)
    f, _ = _f(kernel, index_merl, wo, wi)
    expected = bsdf_for(index_merl, ConstantHits(len(wo))).evaluate(wo, wi)
    index = _bins(expected[:, 0])
    picked = {"theta_h": index // (N_D * N_PHI), "theta_d": index // N_PHI % N_D, "phi_d": index % N_PHI}[axis]
    sides = picked.reshape(-1, copies)
    edge = k[:, None]
    assert np.all((sides == edge) | (sides == edge - 1))
    assert np.mean(np.any(sides == edge, axis=1) & np.any(sides == edge - 1, axis=1)) > 0.5
    assert np.array_equal(_bins(f[:, 0]), index)
    assert np.array_equal(f, expected)


def test_kernel_reads_numpys_bin_near_theta_h_of_90_degrees(kernel, index_merl):
    """Grazing pairs whose half vector lies within 0.1 to 1e-5 degrees of the surface (theta_h's
    last bin, and the clamp of sqrt(theta_h / 90 degrees) 90 at 90), theta_d up to what keeps both
    directions above the surface: numpy's bin, theta_h's last."""
    deg = np.pi / 180
    below = np.repeat(np.array([0.1, 0.01, 1e-3, 1e-4, 1e-5]) * deg, 40)
    rng = np.random.default_rng(3)
    theta_d = below * rng.uniform(0.0, 0.9, len(below))
    wo, wi = _pairs(np.pi / 2 - below, rng.uniform(0, 2 * np.pi, len(below)), theta_d,
                    rng.uniform(0, 2 * np.pi, len(below)))
    above = (wo[:, 2] > 0) & (wi[:, 2] > 0)
    assert above.mean() > 0.9
    f, _ = _f(kernel, index_merl, wo, wi)
    expected = bsdf_for(index_merl, ConstantHits(len(wo))).evaluate(wo, wi)
    assert np.array_equal(f, expected)
    assert np.all(_bins(expected[above, 0]) // (N_D * N_PHI) == N_H - 1)


def test_kernel_lookup_is_reciprocal(kernel, index_merl):
    """Swapping wo and wi leaves the half vector and theta_d as they are and turns phi_d by 180
    degrees, which the fold into [0, 180) undoes: the kernel's f(a, b) is f(b, a) (but where
    rounding puts the two on either side of a bin edge)."""
    rng = np.random.default_rng(4)
    n = 100_000
    a, b = uniform_sphere(rng, n), uniform_sphere(rng, n)
    b[:, 2] = np.abs(b[:, 2]) * np.sign(a[:, 2])
    fab, _ = _f(kernel, index_merl, a, b)
    fba, _ = _f(kernel, index_merl, b, a)
    assert np.mean(np.all(fab == fba, axis=1)) > 0.9999


def test_kernel_samples_as_the_numpy_bsdf(kernel, random_merl):
    """The kernel's BSDF sample with numpy's uniform numbers: numpy's cosine-weighted direction (to
    float32 rounding), its pdf, and the value numpy's f gives at the kernel's direction."""
    rng = np.random.default_rng(5)
    n = 50_000
    wo = uniform_sphere(rng, n)
    u, u_lobe = rng.random((n, 2)).astype(np.float32), rng.random(n).astype(np.float32)
    rows = kernel.rows(random_merl, ConstantHits(n), n)
    _, _, s = kernel(rows, wo, wo[None], u, u_lobe)
    bsdf = bsdf_for(random_merl, ConstantHits(n))
    ref = bsdf.sample(wo, u, u_lobe)
    assert not s.specular.any() and np.mean(s.valid != ref.valid) < 1e-3
    both = s.valid & ref.valid
    # as tests/test_bsdf_kernel.py: a float32 cosine sqrt(1 - x^2 - y^2) carries 2^-23 / (2 cos) or so
    cos = np.abs(ref.wi[both, 2].astype(np.float64))
    assert np.all(np.abs(s.wi[both] - ref.wi[both]) <= 2e-5 + 2.0 ** -22 / cos[:, None])
    assert np.all(np.abs(s.pdf[both] / ref.pdf[both] - 1) <= 2e-3 + 2.0 ** -23 / (2 * cos ** 2))
    assert np.array_equal(s.value[both], bsdf_for(random_merl, ConstantHits(int(both.sum()))).evaluate(wo[both],
                                                                                                     s.wi[both]))
    assert np.mean(np.all(s.value[both] == ref.value[both], axis=1)) > 0.999
    assert np.all(s.value[both] > 0)


def test_kernel_gives_spectral_rays_the_table_at_their_wavelength(kernel, random_merl):
    """Rays of one wavelength each: the rows hold the RGB-to-channel matrix (``rgb_channels``) and
    the kernel's one channel is numpy's (the table's RGB dotted with the ray's basis row)."""
    rng = np.random.default_rng(6)
    n = 50_000
    wo, wi = uniform_sphere(rng, n), uniform_sphere(rng, n)
    wi[:, 2] = np.abs(wi[:, 2]) * np.sign(wo[:, 2])
    hits = SpectralHits(rng.uniform(400, 700, n))
    f, _ = _f(kernel, random_merl, wo, wi, 1, hits)
    expected = bsdf_for(random_merl, hits).evaluate(wo, wi)
    assert f.shape == expected.shape == (n, 1)
    assert np.allclose(f, expected, rtol=1e-6, atol=1e-9) and np.abs(expected).max() > 0.05


def test_a_merl_table_is_placed_once_per_file(index_merl, random_merl):
    """The first row of a file puts its bins (float32, as read) in the kernel's tables; later rows of
    that file point at the same start; another file gets its own; without the kernel's tables a MERL
    material stays in numpy."""
    kernel = BsdfKernel(Device.for_spec())
    hits = ConstantHits(4)
    assert parameters(index_merl, hits, 4) is None
    first = kernel.rows(index_merl, hits, 4)
    size = len(kernel.tables._data)
    assert np.array_equal(kernel.rows(index_merl, ConstantHits(9), 9)[:1], first[:1])
    assert len(kernel.tables._data) == size
    other = kernel.rows(random_merl, hits, 4)
    assert len(kernel.tables._data) == size + -(-3 * COUNT // TABLE_ALIGN) * TABLE_ALIGN
    for rows, material in ((first, index_merl), (other, random_merl)):
        start = int(rows[0, BSDF_PARAMS.offset("extra")]) * TABLE_ALIGN
        placed = kernel.tables._data[start:start + 3 * COUNT]
        assert np.array_equal(placed, load_measured(material.path).rgb.ravel())


@pytest.mark.parametrize("depth", [0, 2])
@pytest.mark.parametrize("spectral", [False, True])
@pytest.mark.parametrize("mode, mis", [("path", True), ("direct", True), ("direct", False)])
def test_bounce_kernel_shades_merl_tables_as_the_numpy_reference(random_merl, depth, spectral, mode, mis):
    """The fused bounce per hit against ``PathIntegrator._shade`` (tests/test_bounce_kernel.py's
    comparison), a MERL material and a mix holding one, RGB and spectral rays, path tracing and
    pbrt's direct lighting (which scenes with MERL materials render with: ``make_integrator``)."""
    for seed, material in enumerate((random_merl, Mix(Plastic(), random_merl, 0.7))):
        _shades_as_numpy(material, depth, mode, mis, 140 + seed, spectral=spectral)


@pytest.mark.parametrize("spectral", [False, True])
@pytest.mark.parametrize("mode", ["path", "direct"])
def test_paths_over_a_merl_table_carry_the_numpy_radiance(random_merl, spectral, mode):
    """Whole paths (depth 5) over MERL objects through the fused bounce: the numpy backend's radiance."""
    scene = _scene(random_merl)
    _paths_agree(scene, *_pair(scene, mode), 150, spectral=spectral)


def test_a_shared_merl_file_reads_as_numpy(kernel):
    """A MERL table under ../shared (any ``*.binary``), where there is one: the kernel's f is numpy's."""
    files = sorted(SHARED.rglob("*.binary")) if SHARED.is_dir() else []
    if not files:
        pytest.skip(f"no MERL .binary file under {SHARED} (the synthetic tables above cover the lobe)")
    rng = np.random.default_rng(7)
    n = 50_000
    wo, wi = uniform_sphere(rng, n), uniform_sphere(rng, n)
    wi[:, 2] = np.abs(wi[:, 2]) * np.sign(wo[:, 2])
    for path in files[:2]:
        material = Measured(str(path))
        f, _ = _f(kernel, material, wo, wi)
        assert np.array_equal(f, bsdf_for(material, ConstantHits(n)).evaluate(wo, wi))
