"""pbrt-v4's named metals: their tables' colours, their RGB, and their import without a warning.

Normal-incidence reflectance of a conductor of complex index n + ik in air:
R = ((n - 1)^2 + k^2) / ((n + 1)^2 + k^2). Known colours: gold reflects red more than green more
than blue; silver and aluminium are near-neutral and reflect above 85 % across the visible; copper
is reddish; MgO and TiO2 are transparent dielectrics (k ~ 0) of index about 1.74 and 2.8-3.2 (TiO2
rises toward the blue).
"""

import numpy as np
import pytest

from realistic.scene.materials import Conductor
from realistic.scene.metals import TABLES, named_metal
from realistic.scene.pbrt.importer import import_world

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
