"""pbrt-v4's named metals: their tables' colours, their RGB, and their import without a warning.

Normal-incidence reflectance of a conductor of complex index n + ik in air:
R = ((n - 1)^2 + k^2) / ((n + 1)^2 + k^2). Known colours: gold reflects red more than green more
than blue; silver and aluminium are near-neutral and reflect above 85 % across the visible; copper
is reddish; MgO and TiO2 are transparent dielectrics (k ~ 0) of index about 1.74 and 2.8-3.2 (TiO2
rises toward the blue).
"""

import numpy as np
import pytest

from realistic.core.cie_data import CIE_X, CIE_Y, CIE_Z, NAMED_ILLUMINANTS
from realistic.core.pbrt_spectra import PBRT4_RGB_FROM_XYZ
from realistic.renderer.bsdf import fresnel
from realistic.renderer.path import PathIntegrator
from realistic.scene.intersect import Intersector
from realistic.scene.materials import Conductor
from realistic.scene.metals import TABLE_COSINES, TABLES, named_metal, reflectance_table
from realistic.scene.pbrt.importer import import_pbrt, import_world

BLUE, GREEN, RED = 450.0, 550.0, 650.0


def _reflectance(n, k):
    n, k = np.asarray(n, float), np.asarray(k, float)
    return ((n - 1) ** 2 + k ** 2) / ((n + 1) ** 2 + k ** 2)


def _table_reflectance(name: str, nm: float) -> float:
    wavelengths, n, k = (np.asarray(a, float) for a in TABLES[name])
    return float(_reflectance(np.interp(nm, wavelengths, n), np.interp(nm, wavelengths, k)))


def _rgb_reflectance(name: str) -> np.ndarray:
    eta, k = named_metal(name)
    return _reflectance(eta, k)


@pytest.mark.parametrize("name", ["Au", "Cu"])
def test_gold_and_copper_reflect_red_most_and_blue_least(name):
    assert _table_reflectance(name, RED) > _table_reflectance(name, GREEN) > _table_reflectance(name, BLUE)
    r, g, b = _rgb_reflectance(name)
    assert r > g > b


@pytest.mark.parametrize("name", ["Ag", "Al"])
def test_silver_and_aluminium_are_bright_and_nearly_neutral(name):
    table = [_table_reflectance(name, nm) for nm in (BLUE, GREEN, RED)]
    rgb = _rgb_reflectance(name)
    for values in (table, rgb):
        assert min(values) > 0.85 and max(values) - min(values) < 0.06


@pytest.mark.parametrize("name,index,spread", [("MgO", 1.74, 0.03), ("TiO2", 3.0, 0.25)])
def test_oxides_are_transparent_dielectrics(name, index, spread):
    eta, k = named_metal(name)
    assert np.allclose(eta, index, atol=spread) and np.all((np.asarray(k) >= 0) & (np.asarray(k) < 0.01))


@pytest.mark.parametrize("name", sorted(TABLES))
def test_each_named_metal_imports_without_a_warning(tmp_path, name):
    path = tmp_path / "scene.pbrt"
    path.write_text(f'Camera "perspective"\nWorldBegin\nMaterial "conductor" "spectrum eta" "metal-{name}-eta" '
                    f'"spectrum k" "metal-{name}-k"\nShape "sphere"\nWorldEnd\n')
    scene, parsed, _ = import_world(path, dialect="v4")
    material = scene.instances[-1].material
    assert not parsed.warnings and isinstance(material, Conductor)
    assert (material.eta, material.k) == named_metal(name)


def test_untabulated_brass_warns_with_file_and_line(tmp_path):
    path = tmp_path / "scene.pbrt"
    path.write_text('Camera "perspective"\nWorldBegin\nMaterial "conductor" "spectrum eta" "metal-CuZn-eta"\n'
                    'Shape "sphere"\nWorldEnd\n')
    _, parsed, _ = import_world(path, dialect="v4")
    assert any(w.endswith('scene.pbrt:3: unsupported: named spectrum "metal-CuZn-eta" (copper\'s used)')
               for w in parsed.warnings)


# pbrt-v4's spectral Fresnel of the named metals (issue 34), checked against integrations done here:
# the CIE 1931 tables and D65 (data), and sRGB's matrix built from its primaries and D65's white.
SRGB_PRIMARIES_XY = ((0.64, 0.33), (0.30, 0.60), (0.15, 0.06))


def _srgb_from_xyz(white_xyz: np.ndarray) -> np.ndarray:
    """The XYZ -> linear RGB matrix of sRGB's primaries whose (1, 1, 1) is ``white_xyz``."""
    primaries = np.array([[x / y, 1.0, (1 - x - y) / y] for x, y in SRGB_PRIMARIES_XY]).T
    return np.linalg.inv(primaries * np.linalg.solve(primaries, white_xyz))


def _film_rgb_of_reflectance(nm: np.ndarray, reflectance: np.ndarray) -> np.ndarray:
    """RGB of a reflectance at ``nm`` (1 nm steps, 360-830) lit by D65 and seen through x, y, z bar."""
    d65_start, d65 = NAMED_ILLUMINANTS["stdillum-D65"]
    illuminant = np.interp(nm, d65_start + 5.0 * np.arange(len(d65)), d65)
    cmf = np.column_stack([CIE_X, CIE_Y, CIE_Z])
    white = illuminant @ cmf
    return _srgb_from_xyz(white / white[1]) @ ((reflectance * illuminant) @ cmf / white[1])


def _gold_on_the_cie_grid() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    nm = np.arange(360.0, 831.0)
    wavelengths, n, k = (np.asarray(a, float) for a in TABLES["Au"])
    return nm, np.interp(nm, wavelengths, n), np.interp(nm, wavelengths, k)


def test_gold_at_normal_incidence_is_the_film_integral_of_its_spectral_reflectance():
    nm, n, k = _gold_on_the_cie_grid()
    expected = _film_rgb_of_reflectance(nm, _reflectance(n, k))
    assert reflectance_table("Au", "Au")[-1] == pytest.approx(expected, rel=1e-4)
    assert _film_rgb_of_reflectance(nm, np.ones_like(nm)) == pytest.approx(np.ones(3), abs=1e-9)


def test_the_table_between_samples_is_the_integral_of_fresnel_there():
    """Off normal incidence: pbrt-v4's FrComplex as s and p reflectances of the complex index, per wavelength."""
    nm, n, k = _gold_on_the_cie_grid()
    index = n + 1j * k
    for cos in (0.03, 0.4111, 0.77):
        cos_t = np.sqrt(1 - (1 - cos ** 2) / index ** 2)
        s = np.abs((cos - index * cos_t) / (cos + index * cos_t)) ** 2
        p = np.abs((index * cos - cos_t) / (index * cos + cos_t)) ** 2
        table = fresnel.tabulated(np.array([cos]), reflectance_table("Au", "Au"))[0]
        assert table == pytest.approx(_film_rgb_of_reflectance(nm, (s + p) / 2), abs=5e-5)


def _albedo(reflectance: np.ndarray) -> np.ndarray:
    """Hemispherical albedo of a smooth mirror of reflectance (T, 3) at ``TABLE_COSINES``: int F 2 cos dcos."""
    c = TABLE_COSINES
    return np.sum((reflectance[1:] * c[1:, None] + reflectance[:-1] * c[:-1, None]) * np.diff(c)[:, None], axis=0)


def test_rgb_converted_gold_differs_from_spectral_gold_as_the_issue_measured():
    """Issue 34: RGB-converted gold renders its red about 3.6 % low and its green about 3 % high."""
    eta, k = (np.tile(v, (len(TABLE_COSINES), 1)) for v in named_metal("Au"))
    rgb_converted = _albedo(fresnel.conductor(TABLE_COSINES, eta, k))
    ratio = rgb_converted / _albedo(reflectance_table("Au", "Au")) - 1
    assert -0.045 < ratio[0] < -0.03 and 0.025 < ratio[1] < 0.04


@pytest.mark.parametrize("name", sorted(TABLES))
def test_spectral_reflectance_is_bounded_at_every_angle(name):
    """F(lambda) in [0, 1] keeps the luminance in [0, 1] and reaches 1 at grazing; a colour outside
    sRGB's gamut (gold: red 1.022 at normal incidence) may leave [0, 1] in one channel, a few % at most."""
    table = reflectance_table(name, name).astype(np.float64)
    luminance = table @ (np.linalg.inv(PBRT4_RGB_FROM_XYZ)[1])
    assert np.all((luminance >= 0) & (luminance <= 1 + 1e-6))
    assert np.all((table > -0.01) & (table < 1.03)) and table[0] == pytest.approx(np.ones(3), abs=1e-5)


def test_pbrt_v4_named_metals_are_spectral_and_other_indices_stay_rgb(tmp_path):
    def imported(material: str, dialect: str = "v4") -> Conductor:
        path = tmp_path / "scene.pbrt"
        path.write_text(f'Camera "perspective"\nWorldBegin\nMaterial "conductor" {material}\nShape "sphere"\n')
        return import_world(path, dialect=dialect)[0].instances[-1].material

    gold = '"spectrum eta" "metal-Au-eta" "spectrum k" "metal-Au-k"'
    assert imported(gold).spectra == ("Au", "Au")
    assert imported('"spectrum eta" "metal-Ag-eta"').spectra == ("Ag", "Cu")  # pbrt-v4's default k: copper's
    assert imported("").spectra == ("Cu", "Cu")
    assert imported('"rgb eta" [0.2 0.4 1.4] "spectrum k" "metal-Au-k"').spectra is None
    assert imported(gold, dialect="v3").spectra is None


def test_a_pbrt_v4_gold_sphere_renders_with_the_spectral_reflectance(tmp_path):
    """A smooth gold sphere in a white furnace, seen head on, reflects the table's value at cos 1."""
    path = tmp_path / "gold.pbrt"
    path.write_text('LookAt 0 0 5  0 0 0  0 1 0\nCamera "perspective"\nWorldBegin\n'
                    'LightSource "infinite" "rgb L" [1 1 1]\n'
                    'Material "conductor" "spectrum eta" "metal-Au-eta" "spectrum k" "metal-Au-k" "float roughness" 0\n'
                    'Shape "sphere"\n')
    scene = import_pbrt(path).scene
    n = 64
    origin = np.tile([0.0, 0.0, 5.0], (n, 1)).astype(np.float32)
    direction = np.tile([0.0, 0.0, -1.0], (n, 1)) + np.random.default_rng(0).uniform(-0.002, 0.002, (n, 3))
    direction = (direction / np.linalg.norm(direction, axis=1, keepdims=True)).astype(np.float32)
    integrator = PathIntegrator(scene, Intersector(scene), 1, 0, 0.0, 2, "path")
    radiance, _ = integrator.radiance(origin, direction, np.arange(n), np.zeros(n, int), None, None)
    assert radiance.mean(axis=0) == pytest.approx(reflectance_table("Au", "Au")[-1], rel=2e-3)
