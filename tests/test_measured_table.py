"""The irregular measured BRDF's table (``renderer/bsdf/measured.py``): pbrt-v2's kd-tree average
tabulated over BRDFRemap's unit cube and interpolated trilinearly, checked against pbrt-v2's
formula written out in ``test_measured`` (nodes), against the trilinear interpolant written out here
(lookups), within a bound derived from the cell size (random directions), in a furnace-style
albedo integral, and through the verified disk cache."""

import itertools
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from bsdf_helpers import uniform_sphere
from conftest import shared_file
from realistic.core.disk_cache import load_arrays, store_arrays
from realistic.renderer.bsdf import measured
from realistic.renderer.bsdf.measured import (
    FIRST_RADIUS2,
    LAST_LEVEL,
    TABLE_NODES,
    MeasuredBRDF,
    build_irregular_table,
    irregular_lookup,
    irregular_table,
    table_lookup,
    table_nodes,
)
from realistic.scene.measured import IrregularSamples, brdf_remap, load_measured, read_irregular
from test_measured import _pbrt_irregular

#: A pixel of the seed scene (pbrt-v2 dof-dragons.pbrt) averages 16 spp x 128 light samples.
PIXEL_SAMPLES = 16 * 128


@pytest.fixture(scope="module")
def blue():
    samples = load_measured(str(shared_file("scenes/pbrt/brdfs/acryl_blue.brdf")))
    return samples, irregular_table(samples)


def _pairs(rng: np.random.Generator, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Random float32 pairs on one side (both up or both down)."""
    wo, wi = uniform_sphere(rng, n), uniform_sphere(rng, n)
    wi[:, 2] = np.abs(wi[:, 2]) * np.sign(wo[:, 2])
    return wo, wi


def _gathered(points: np.ndarray, m: np.ndarray) -> np.ndarray:
    """Which samples pbrt-v2 averages at ``m``: those strictly inside the first radius^2 0.001 * 2^L
    holding more than two (L at most ``LAST_LEVEL``)."""
    d2 = ((points - m) ** 2).sum(axis=1)
    radius2 = FIRST_RADIUS2
    for _ in range(LAST_LEVEL):
        if np.count_nonzero(d2 < radius2) > 2:
            break
        radius2 *= 2
    return d2 < radius2


def test_the_table_holds_pbrt_v2s_average_at_its_nodes(blue):
    samples, table = blue
    assert table.shape == (TABLE_NODES,) * 3 + (3,) and table.dtype == np.float32
    nodes = table_nodes(TABLE_NODES)
    rng = np.random.default_rng(7)
    picked = np.vstack([nodes[rng.choice(len(nodes), 300, replace=False)], [[0, 0, 0]],
                        [[TABLE_NODES - 1, TABLE_NODES - 1, 0]], [[0, TABLE_NODES - 1, TABLE_NODES - 1]]])
    expected = np.array([_pbrt_irregular(samples.points, samples.rgb, ijk / (TABLE_NODES - 1.0)) for ijk in picked])
    got = table[picked[:, 0], picked[:, 1], picked[:, 2]]
    assert np.allclose(got, expected, rtol=1e-6, atol=1e-7 * samples.rgb.max())
    # the nodes a lookup never reads (m_x + m_z = cos(theta_i - theta_o) <= 1) are not computed
    i, _, k = np.meshgrid(*(np.arange(TABLE_NODES),) * 3, indexing="ij")
    assert len(nodes) == np.count_nonzero(i + k <= TABLE_NODES + 1) and np.all(table[i + k > TABLE_NODES + 1] == 0)


def test_a_lookup_is_the_trilinear_interpolant_of_its_cells_nodes(blue):
    samples, table = blue
    rng = np.random.default_rng(8)
    wo, wi = _pairs(rng, 4000)
    wo[:3] = [[0, 0, 1], [0, 0, -1], [0.6, 0.0, 0.8]]  # along the normal (phi 0, as pbrt's atan2(0, 0))
    wi[:3] = [[0.0, 0.6, 0.8], [0.0, 0.6, -0.8], [0.0, 0.0, 1.0]]
    m = brdf_remap(wo, wi)
    g = np.clip(m * (TABLE_NODES - 1), 0, TABLE_NODES - 1)
    i = np.minimum(g.astype(int), TABLE_NODES - 2)
    f = g - i
    expected = np.zeros((len(m), 3))
    for corner in itertools.product((0, 1), repeat=3):
        w = np.prod(np.where(np.array(corner) == 1, f, 1 - f), axis=1)
        expected += w[:, None] * table[i[:, 0] + corner[0], i[:, 1] + corner[1], i[:, 2] + corner[2]]
    got = table_lookup(table, wo, wi)
    assert np.allclose(got, expected, rtol=1e-5, atol=1e-6 * samples.rgb.max())
    assert np.all(table_lookup(table, wo, -wi) == 0)  # opposite sides: no reflection
    assert np.all(table_lookup(table, wo * [1, 1, 0], wi) == 0)  # grazing: cos theta 0
    brdf = MeasuredBRDF(samples, np.tile(np.eye(3, dtype=np.float32), (len(wo), 1, 1)))
    assert np.allclose(brdf.evaluate(wo, wi), got, rtol=1e-6, atol=1e-6)
    assert np.allclose(table_lookup(table, wi, wo), got, rtol=1e-5, atol=1e-6 * samples.rgb.max())  # reciprocal


def test_the_table_is_within_its_cells_gathered_samples_of_pbrt_v2s_value(blue):
    """The derived tolerance: pbrt-v2's value at m is a weighted mean of the samples it gathers there,
    and the table's a weighted mean of its value at the eight nodes of m's cell (within a cell
    diagonal, sqrt(3) / (n - 1), of m), each a weighted mean of the samples gathered at that node
    (clamped at 0). So both lie between the least and greatest value U gathered at m or at those
    nodes, and differ by at most the spread of U: a bound that shrinks with the cell where the data
    vary smoothly, and holds at the samples' discontinuous radii too."""
    samples, table = blue
    rng = np.random.default_rng(9)
    wo, wi = _pairs(rng, 400)
    m = brdf_remap(wo, wi)
    reference = irregular_lookup(samples, m)
    got = table_lookup(table, wo, wi)
    step = 1.0 / (TABLE_NODES - 1)
    cell = np.minimum((m / step).astype(int), TABLE_NODES - 2)
    eps = 1e-6 * samples.rgb.max()
    spreads = []
    for q in range(len(m)):
        gathered = _gathered(samples.points, m[q])
        for corner in itertools.product((0, 1), repeat=3):
            gathered |= _gathered(samples.points, (cell[q] + corner) * step)
        values = np.maximum(samples.rgb[gathered], 0)
        low, high = values.min(axis=0), values.max(axis=0)
        assert np.all(got[q] >= low - eps) and np.all(got[q] <= high + eps), q
        assert np.all(np.abs(got[q] - reference[q]) <= high - low + eps), q
        spreads.append(high - low)
    # the bound is no formality: where the data are flat it is small beside the values themselves
    assert np.median(np.array(spreads) / np.maximum(reference, 1e-3)) < 1.0


def test_furnace_albedo_from_the_table_is_pbrt_v2s_within_a_pixels_noise(blue):
    """Directional albedo rho(wo) = integral f cos over the hemisphere, by the same 64 x 64 stratified
    cosine-weighted directions from the table and from the kd-tree reference: they differ by less
    than the standard error of rho estimated from a seed-scene pixel's samples (PIXEL_SAMPLES
    cosine-sampled directions, each pi f), taken from the reference's own spread. The albedo is
    positive and the table's values never exceed the greatest sample."""
    samples, table = blue
    side = 64
    u = (np.stack(np.meshgrid(np.arange(side), np.arange(side), indexing="ij"), -1).reshape(-1, 2) + 0.5) / side
    r, phi = np.sqrt(u[:, 0]), 2 * np.pi * u[:, 1]
    wi = np.column_stack([r * np.cos(phi), r * np.sin(phi), np.sqrt(1 - r * r)])
    for theta_o in (5.0, 30.0, 55.0, 80.0):
        t = np.radians(theta_o)
        wo = np.tile([np.sin(t), 0.0, np.cos(t)], (len(wi), 1))
        reference = np.pi * irregular_lookup(samples, brdf_remap(wo, wi))
        from_table = np.pi * table_lookup(table, wo, wi)
        standard_error = reference.std(axis=0) / np.sqrt(PIXEL_SAMPLES)
        assert np.all(reference.mean(axis=0) > 0)
        assert np.all(np.abs(from_table.mean(axis=0) - reference.mean(axis=0)) < standard_error), theta_o
    assert table.max() <= samples.rgb.max()


NODES = 6  # a coarse grid keeps the cache tests' builds quick
TWO = "2 400 700\n0.1 0 0.2 0 0.3 0.3\n0.9 0 1.0 3.0 0.6 0.6\n0.5 1 0.4 2 0.2 0.5\n"
#: Another file's samples: their table is a plausible one (every value within the bounds) but not TWO's.
OTHER = "2 400 700\n0.2 0 0.1 0.5 0.2 0.3\n0.7 0 0.9 0.4 0.4 0.1\n0.4 1 0.6 0.1 0.3 0.2\n"


def _irregular(tmp_path: Path, name: str, text: str) -> IrregularSamples:
    path = tmp_path / name
    path.write_text(text)
    return read_irregular(path)


@pytest.fixture
def coarse_cache(tmp_path, monkeypatch):
    """A disk cache of the test's own, ``NODES`` per table axis, and the tables' memory emptied
    before and after."""
    monkeypatch.setenv("REALISTIC_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.setattr(measured, "TABLE_NODES", NODES)
    measured._irregular_table.cache_clear()
    yield
    measured._irregular_table.cache_clear()


def _from_cache(samples: IrregularSamples, entry: dict[str, np.ndarray]) -> np.ndarray:
    """The table ``irregular_table`` gives with ``entry`` stored under the samples' key."""
    store_arrays(measured._table_key(samples, NODES), entry)
    measured._irregular_table.cache_clear()
    return irregular_table(samples)


def test_the_table_goes_through_the_verified_disk_cache(tmp_path, coarse_cache):
    """A built table is stored and a stored one used; one that cannot be this file's table (a
    value above the greatest sample, another shape or type, another file's, scaled) is rebuilt."""
    samples = _irregular(tmp_path, "two.brdf", TWO)
    built = irregular_table(samples)
    assert built.shape == (NODES,) * 3 + (3,) and np.array_equal(built, build_irregular_table(samples, NODES))
    key = measured._table_key(samples, NODES)
    assert np.array_equal(load_arrays(key)["table"], built)
    other = build_irregular_table(_irregular(tmp_path, "other.brdf", OTHER), NODES)
    assert np.all(other <= samples.rgb.max(axis=0)) and not np.array_equal(other, built)  # within the bounds
    assert np.array_equal(_from_cache(samples, {"table": built}), built)
    for stored in (built * 0.5, built * 0 + 2 * samples.rgb.max(), built[:-1], built.astype(np.float64), other):
        assert np.array_equal(_from_cache(samples, {"table": stored}), built)


TABLE_SHAPE = (NODES,) * 3 + (3,)
SPECIAL = st.sampled_from([np.nan, np.inf, -np.inf, -1.0, -1e-30, 1e30, 3.1, np.finfo(np.float32).max])
ENTRY_ARRAYS = st.sampled_from([np.float32, np.float64, np.float16, np.int32, np.uint8, np.bool_]).flatmap(
    lambda dtype: hnp.arrays(dtype, st.sampled_from([TABLE_SHAPE, TABLE_SHAPE[:-1], (NODES - 1, NODES, NODES, 3),
                                                     (NODES**3 * 3,), ()])
                             | hnp.array_shapes(min_dims=0, max_dims=4, max_side=7)))


@given(data=st.data())
def test_any_cache_entry_is_this_files_table_or_rebuilt(tmp_path, coarse_cache, data):
    """Entries of random contents (any arrays, names, dtypes, shapes; the table with NaN, inf,
    negative, huge values, or another file's table, scaled or not) are never used: the table is
    the one built from the samples, bit for bit."""
    samples = _irregular(tmp_path, "two.brdf", TWO)
    built = build_irregular_table(samples, NODES)
    kind = data.draw(st.sampled_from(["arrays", "special", "other", "scaled"]), label="kind")
    if kind == "arrays":
        entry = data.draw(st.dictionaries(st.sampled_from(["table", "tables", "x"]), ENTRY_ARRAYS, max_size=2))
    elif kind == "special":
        table = built.copy()
        flat = table.reshape(-1)
        for _ in range(data.draw(st.integers(1, 3), label="values")):
            flat[data.draw(st.integers(0, flat.size - 1), label="position")] = data.draw(SPECIAL, label="value")
        entry = {"table": table}
    else:
        table = build_irregular_table(_irregular(tmp_path, "other.brdf", OTHER), NODES) if kind == "other" else built
        scale = data.draw(st.floats(0.0, 1.0, exclude_max=kind == "scaled"), label="scale")
        entry = {"table": (table * np.float32(scale)).astype(np.float32)}
    assert np.array_equal(_from_cache(samples, entry), built)
