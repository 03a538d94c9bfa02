"""pbrt-v2's measured BRDFs: the MERL half-angle table and the irregular isotropic samples, checked
against pbrt-v2's formulas written out independently here, and the readers' error handling."""

import numpy as np
import pytest
from hypothesis import example, given
from hypothesis import strategies as st

from bsdf_helpers import direction, uniform_sphere
from conftest import shared_file
from realistic.errors import UserError
from realistic.renderer.bsdf.measured import MeasuredBRDF, halfangle_lookup, irregular_lookup
from realistic.scene.measured import brdf_remap, load_measured, read_halfangle, read_irregular

SHAPE = (90, 90, 180)
COUNT = 90 * 90 * 180


@pytest.fixture(scope="module")
def index_table(tmp_path_factory):
    """A MERL file whose raw value at flat index i is i in every channel (and -1 at index 7)."""
    path = tmp_path_factory.mktemp("merl") / "index.binary"
    raw = np.tile(np.arange(COUNT, dtype="<f8"), 3)
    raw[7] = raw[COUNT + 7] = raw[2 * COUNT + 7] = -1.0
    path.write_bytes(np.array(SHAPE, "<i4").tobytes() + raw.tobytes())
    return read_halfangle(path)


def _rusinkiewicz_index(wo: np.ndarray, wi: np.ndarray) -> np.ndarray:
    """MERL flat index by rotating wi into the half vector's frame with rotation matrices
    (Rusinkiewicz 1998: rotate by -phi_h about z, then -theta_h about y)."""
    out = []
    for o, i in zip(wo.astype(np.float64), wi.astype(np.float64)):
        h = o + i
        if h[2] < 0:
            h, i = -h, -i
        h /= np.linalg.norm(h)
        theta_h, phi_h = np.arccos(np.clip(h[2], -1, 1)), np.arctan2(h[1], h[0])
        rz = np.array([[np.cos(-phi_h), -np.sin(-phi_h), 0], [np.sin(-phi_h), np.cos(-phi_h), 0], [0, 0, 1]])
        ry = np.array([[np.cos(-theta_h), 0, np.sin(-theta_h)], [0, 1, 0], [-np.sin(-theta_h), 0, np.cos(-theta_h)]])
        d = ry @ rz @ i
        theta_d = np.arccos(np.clip(d[2], -1, 1))
        phi_d = np.arctan2(d[1], d[0]) % (2 * np.pi)
        phi_d = phi_d - np.pi if phi_d > np.pi else phi_d
        ih = min(int(np.sqrt(theta_h / (np.pi / 2)) * 90), 89)
        idd = min(int(theta_d / (np.pi / 2) * 90), 89)
        ip = min(int(phi_d / np.pi * 180), 179)
        out.append(ip + 180 * (idd + 90 * ih))
    return np.array(out)


def test_merl_scales_channels_clamps_negatives_and_indexes_as_pbrt_v2(index_table):
    rgb = index_table.rgb.reshape(-1, 3)
    assert np.allclose(rgb[1000], 1000 * np.array([1.0, 1.15, 1.66]) / 1500, rtol=1e-6)
    assert np.all(rgb[7] == 0.0)
    # hand-picked: both along the normal -> all angles 0; both at 40.5 degrees, phi 0 -> theta_h 40.5,
    # index floor(sqrt(40.5 / 90) * 90) = 60; wi at 31.5 degrees and wo its mirror image about the
    # normal, phi_i 45.5 -> theta_h 0, theta_d 31.5 (index 31), phi_d 45.5 (index 45)
    wo = np.vstack([direction(0.0), direction(40.5), direction(31.5, 225.5)])
    wi = np.vstack([direction(0.0), direction(40.5), direction(31.5, 45.5)])
    index = np.rint(halfangle_lookup(index_table, wo, wi)[:, 0] * 1500).astype(int)
    assert list(index) == [0, 180 * 90 * 60, 45 + 180 * 31]
    rng = np.random.default_rng(3)
    wo, wi = uniform_sphere(rng, 3000), uniform_sphere(rng, 3000)
    wi[:, 2] = np.abs(wi[:, 2]) * np.sign(wo[:, 2])
    got = np.rint(halfangle_lookup(index_table, wo, wi)[:, 0] * 1500).astype(int)
    expected = _rusinkiewicz_index(wo, wi)
    expected = np.where(expected == 7, 0, expected)
    assert np.mean(got == expected) > 0.998  # ties at bin edges aside (float32 directions)


def test_merl_lookup_is_reciprocal_up_to_bin_edges(index_table):
    rng = np.random.default_rng(4)
    wo, wi = uniform_sphere(rng, 3000), uniform_sphere(rng, 3000)
    wi[:, 2] = np.abs(wi[:, 2]) * np.sign(wo[:, 2])
    assert np.mean(np.all(halfangle_lookup(index_table, wo, wi) == halfangle_lookup(index_table, wi, wo),
                          axis=1)) > 0.99


def _pbrt_irregular(points: np.ndarray, rgb: np.ndarray, m: np.ndarray) -> np.ndarray:
    """pbrt-v2 IrregIsotropicBRDF::f written out: grow the squared radius from 0.001 by doubling
    until more than 2 samples lie strictly inside or it passes 1.5; average with exp(-100 d^2)."""
    d2 = ((points - m) ** 2).sum(axis=1)
    radius2 = 0.001
    while True:
        inside = d2 < radius2
        if inside.sum() > 2 or radius2 > 1.5:
            w = np.exp(-100 * d2[inside])
            return np.maximum((w[:, None] * rgb[inside]).sum(axis=0), 0) / w.sum() if w.sum() else np.zeros(3)
        radius2 *= 2


def test_irregular_file_layout_and_lookup_against_pbrt_v2():
    path = shared_file("scenes/pbrt/brdfs/acryl_blue.brdf")
    data = read_irregular(path)
    numbers = [float(t) for line in path.read_text().splitlines() for t in line.split("#")[0].split()]
    assert int(numbers[0]) == 31 and len(data.points) == (len(numbers) - 32) // 35
    ti, pi, to, po = numbers[32:36]  # the first record: theta_i, phi_i, theta_o, phi_o
    assert (ti, pi, to, po) == (0.872665, 0.0, 0.573513, 0.0)
    assert np.allclose(data.points[0], [np.sin(ti) * np.sin(to), 0.0, np.cos(ti) * np.cos(to)])
    assert data.rgb[:, 2].mean() > data.rgb[:, 0].mean()  # blue acrylic
    rng = np.random.default_rng(5)
    wo, wi = uniform_sphere(rng, 300), uniform_sphere(rng, 300)
    wo[:, 2], wi[:, 2] = np.abs(wo[:, 2]), np.abs(wi[:, 2])
    queries = np.vstack([brdf_remap(wo, wi), data.points[:20]])
    expected = np.array([_pbrt_irregular(data.points, data.rgb, m) for m in queries])
    assert np.allclose(irregular_lookup(data, queries), expected, rtol=1e-9, atol=1e-12)


def test_irregular_lookup_with_clusters_beyond_the_neighbour_count_and_with_two_samples(tmp_path):
    """200 samples at one point (more than the 32 neighbours fetched first) and a file of two
    samples (pbrt stops at radius^2 2.048 with whatever it found)."""
    rng = np.random.default_rng(6)
    rows = [f"0.5 0.0 0.5 0.0 {v:.6f}" for v in rng.random(200)] + ["1.2 0.0 0.3 2.0 0.9"]
    path = tmp_path / "cluster.brdf"
    path.write_text("1 550\n" + "\n".join(rows) + "\n")
    data = read_irregular(path)
    queries = np.vstack([data.points[:1] + 0.01, data.points[-1:], [[0.5, 0.5, 0.5]]])
    expected = np.array([_pbrt_irregular(data.points, data.rgb, m) for m in queries])
    assert np.allclose(irregular_lookup(data, queries), expected, rtol=1e-9)
    two = tmp_path / "two.brdf"
    two.write_text("# flat\n2 400 700\n0.1 0 0.2 0 0.3 0.3\n0.9 0 1.0 3.0 0.6 0.6\n")
    data = read_irregular(two)
    # flat spectra as pbrt-v2's FromSampled makes them: unadapted sRGB of E, (1.205, 0.948, 0.909) (issue 34)
    assert np.allclose(data.rgb, np.outer([0.3, 0.6], [1.205, 0.948, 0.909]), rtol=1e-3)
    q = np.array([[0.0, 0.0, 1.0]])
    assert np.allclose(irregular_lookup(data, q), _pbrt_irregular(data.points, data.rgb, q[0]))


def test_measured_bsdf_turns_rgb_into_the_rays_channels(index_table):
    wo, wi = direction(20.0, 0.0, 2), direction(50.0, 90.0, 2)
    rgb = halfangle_lookup(index_table, wo, wi)
    basis = np.float32([[[0.2, 0.5, 0.3]], [[0.0, 0.1, 0.9]]])  # (N, C = 1, 3): spectral rays
    value = MeasuredBRDF(index_table, basis).evaluate(wo, wi)
    assert value.shape == (2, 1) and np.allclose(value[:, 0], (basis[:, 0] * rgb).sum(axis=1), rtol=1e-5)
    assert np.all(MeasuredBRDF(index_table, basis).evaluate(wo, -wi) == 0)  # opposite sides: no reflection


def test_load_measured_is_cached_per_path():
    path = str(shared_file("scenes/pbrt/brdfs/garnet_red.brdf"))
    assert load_measured(path) is load_measured(path)


_TEXT = st.text(alphabet="0123456789 .-+e#\nx\t", max_size=300)


@given(_TEXT)
@example("1e310")  # an infinite wavelength count
@example("nan 1 2 3 4 5")
def test_irregular_reader_succeeds_or_fails_with_one_line(tmp_path_factory, text):
    path = tmp_path_factory.mktemp("fuzz") / "f.brdf"
    path.write_text(text)
    try:
        data = read_irregular(path)
    except UserError as err:
        assert "\n" not in str(err) and str(path) in str(err)
    else:
        assert np.all(np.isfinite(data.points)) and data.rgb.shape == data.points.shape


@given(st.binary(max_size=64), st.sampled_from([None, (90, 90, 180), (180, 90, 90), (1, 2, 3), (-90, -90, 180)]))
def test_merl_reader_succeeds_or_fails_with_one_line(tmp_path_factory, payload, dims):
    path = tmp_path_factory.mktemp("fuzz") / "f.binary"
    path.write_bytes((np.array(dims, "<i4").tobytes() if dims else b"") + payload)
    with pytest.raises(UserError) as err:
        read_halfangle(path)
    assert "\n" not in str(err.value) and str(path) in str(err.value)


@pytest.mark.parametrize("name", ["acryl_blue", "garnet_red"])
def test_measured_brdfs_are_reciprocal_and_reflect_less_than_they_receive(name):
    from bsdf_helpers import albedo_by_integration, albedo_by_sampling

    data = load_measured(str(shared_file(f"scenes/pbrt/brdfs/{name}.brdf")))
    rng = np.random.default_rng(8)
    n = 40_000
    bsdf = MeasuredBRDF(data, np.tile(np.eye(3, dtype=np.float32), (n, 1, 1)))
    a, b = uniform_sphere(rng, n), uniform_sphere(rng, n)
    b[:, 2] = np.abs(b[:, 2]) * np.sign(a[:, 2])
    assert np.allclose(bsdf.evaluate(a, b), bsdf.evaluate(b, a), rtol=1e-6, atol=1e-9)
    for theta in (10.0, 60.0):
        wo = direction(theta, 0.0, n)
        by_integration = albedo_by_integration(bsdf, wo, rng)
        assert np.all(by_integration < 1.0) and by_integration.max() > 0.01
        assert np.allclose(albedo_by_sampling(bsdf, wo, rng), by_integration, rtol=0.05, atol=0.003)
