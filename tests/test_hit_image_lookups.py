"""Image textures of the path integrator's per-hit parameters filtered on the device: the "opencl"
backend's ``image_lookup`` (``EwaKernel.lookup``, ``kernels/ewa.cl``) against the numpy reference
``textures.numpy_lookup`` under every filter and without a footprint, the fused bounce's per-hit
rows (``BounceKernel._hit_rows``) built from it against rows built from the reference, and whole
paths of the OpenCL path integrator that never call ``MipMap``'s numpy filters.

Tolerances: the kernels compute each filter in float64, as the reference does, and both round to
float32 at the end. Point and bilinear lookups (and every lookup without a footprint: level 0
bilinear) take the same float64 operations in the same order, so they are equal bit for bit
(``test_ewa_kernel``); trilinear takes its blend weight from the device library's log2 and EWA sums
its taps in the kernel's order, each a few float64 ulps from numpy's, so after rounding to float32 a
colour is within one float32 ulp (relative 6e-8) of the reference: ``rtol`` 1e-6 with ``atol`` 1e-7
for values near 0 (as ``test_ewa_kernel``). Rows derived from those colours (roughness to alpha,
Fresnel, ``Ks``) carry that through float32 arithmetic with a few more roundings: ``rtol`` 1e-5."""

from dataclasses import replace

import numpy as np
import pytest

from realistic.renderer.backends import backend_for
from realistic.renderer.path import PathIntegrator
from realistic.scene.intersect import Intersector
from realistic.scene.materials import Conductor, Mix, Plastic, ScaledTexture
from realistic.scene.mipmap import MipMap
from realistic.scene.model import ImageTexture, Material, Scene
from realistic.scene.textures import evaluate
from test_shading_reference import textured_scene

pytest.importorskip("realistic.camera.opencl_host")
pytestmark = pytest.mark.usefixtures("opencl_platform")

from realistic.renderer.bsdf_kernel import MAX_LOBES  # noqa: E402

FILTERS = ("ewa", "bilinear", "point", "trilinear")
#: An image and a roughness image of little symmetry (roughness in [0.02, 0.5]).
IMAGE = np.random.default_rng(21).random((32, 64, 3)).astype(np.float32)
ROUGH = (0.02 + 0.48 * np.random.default_rng(22).random((16, 32, 3))).astype(np.float32)
#: A pixel spread (radians) whose footprints reach coarser levels on the grazing floor.
SPREAD = 4e-3
#: ``MipMap``'s numpy filters: the OpenCL path integrator must call none of them.
NUMPY_FILTERS = ("ewa", "bilinear", "bilinear_at_width", "point", "trilinear")


def _assert_reference(got: np.ndarray, expected: np.ndarray, exact: bool) -> None:
    """``got`` is ``expected`` bit for bit where ``exact``, else within float32 rounding."""
    assert got.dtype == expected.dtype == np.float32 and got.shape == expected.shape
    if exact:
        assert np.array_equal(got, expected)
    else:
        np.testing.assert_allclose(got, expected, rtol=1e-6, atol=1e-7)


@pytest.mark.parametrize("texture_filter", FILTERS)
@pytest.mark.parametrize("wrap", ["repeat", "black", "clamp"])
@pytest.mark.parametrize("with_footprint", [True, False])
def test_device_lookups_are_the_numpy_references(texture_filter, wrap, with_footprint):
    """``textures.evaluate`` with the backend's ``image_lookup`` is the numpy reference's colours:
    every filter over footprints from under a texel to wider than the image (through the same st
    mapping: repeats, offset, a bottom-origin flip), and level 0 bilinear without one."""
    texture = ImageTexture(IMAGE, scale=(3.0, 2.0), offset=(0.25, 0.5), filter=texture_filter, wrap=wrap,
                           max_anisotropy=8.0)
    rng = np.random.default_rng(5)
    uv = rng.random((5000, 2)) * 1.4 - 0.2
    angle = rng.random(5000) * 2 * np.pi
    major = 10.0 ** rng.uniform(-4, 0, 5000)
    minor = major / (1 + 20 * rng.random(5000))
    footprint = (np.column_stack([np.cos(angle), np.sin(angle)]) * major[:, None],
                 np.column_stack([-np.sin(angle), np.cos(angle)]) * minor[:, None]) if with_footprint else None
    device = evaluate(texture, uv, footprint, backend_for("opencl").image_lookup)
    reference = evaluate(texture, uv, footprint)
    _assert_reference(device, reference, exact=texture_filter in ("point", "bilinear") or footprint is None)
    assert np.array_equal(evaluate(texture, uv, footprint, backend_for("numpy").image_lookup), reference)


def _materials(texture_filter: str) -> list:
    """Per-hit materials with image textures under ``texture_filter``: a plastic of image roughness,
    one of image ``Ks`` (scaled), a mix of a Lambertian and a conductor of image roughness (a textured
    second material) and a mix tree of more lobes than the fused bounce takes (``MAX_LOBES``) holding
    an image-textured plastic (``_shade``'s numpy bounce)."""
    rough = ImageTexture(ROUGH, scale=(3.0, 2.0), filter=texture_filter, max_anisotropy=4.0)
    image = ImageTexture(IMAGE, scale=(2.0, 3.0), v_origin="top", filter=texture_filter)
    conductor = Conductor(roughness_u=rough, roughness_v=replace(rough, scale=(2.0, 2.0)))
    inner = Mix(Material((0.5, 0.4, 0.3)), Plastic((0.5, 0.4, 0.3), ScaledTexture(image, (0.3, 0.3, 0.3)), rough), 0.5)
    return [Plastic((0.5, 0.3, 0.2), (0.4, 0.4, 0.4), rough),
            Plastic((0.5, 0.3, 0.2), ScaledTexture(image, (0.4, 0.4, 0.4)), 0.2),
            Mix(Material((0.7, 0.6, 0.5)), conductor, 0.7), _beyond_max_lobes(inner)]


def _beyond_max_lobes(inner: Mix) -> Mix:
    """``inner`` (two lobes) held by ``MAX_LOBES`` - 1 mixes, each with a Lambertian: ``MAX_LOBES`` + 1 lobes."""
    tree = inner
    for k in range(MAX_LOBES - 1):
        tree = Mix(Material((0.3, 0.5, 0.4 + 0.05 * k)), tree, 0.8)
    return tree


def _scene(texture_filter: str) -> Scene:
    """``textured_scene`` with its floor, sphere, cone and quad of ``_materials(texture_filter)``."""
    scene, _, _ = textured_scene()
    scene.instances[:4] = [replace(inst, material=m) for inst, m in zip(scene.instances, _materials(texture_filter))]
    return scene


def _rays(scene: Scene, n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Rays from around the eye toward the objects and the floor."""
    rng = np.random.default_rng(seed)
    origin = (np.array([0.0, 1.0, 4.0]) + rng.uniform(-0.5, 0.5, (n, 3))).astype(np.float32)
    direction = rng.uniform([-1.5, -0.2, -1.5], [1.5, 1.5, 1.5], (n, 3)) - origin
    return origin, (direction / np.linalg.norm(direction, axis=1, keepdims=True)).astype(np.float32)


def _pair(scene: Scene) -> tuple[PathIntegrator, PathIntegrator]:
    """The numpy and the OpenCL backend's path integrators over ``scene`` with a pixel spread."""
    return tuple(PathIntegrator(scene, Intersector(scene), 2, 7, SPREAD, 5, "path", backend=backend)
                 for backend in ("numpy", "opencl"))  # type: ignore[return-value]


@pytest.mark.parametrize("texture_filter", FILTERS)
@pytest.mark.parametrize("depth", [0, 2])
def test_per_hit_rows_from_device_lookups_are_the_references(texture_filter, depth):
    """The fused bounce's per-hit rows (``BSDF_PARAMS``, and the ``LOBE`` rows of the textured
    second material) at hits on image-textured roughness, ``Ks`` and a mix's second material, looked
    up through the OpenCL integrator's ``_hit_parameters`` (device filters over the pixel footprint
    at depth 0, level 0 deeper), are the rows the numpy integrator's lookups give: bit for bit where
    the colours are (point, bilinear, no footprint), else to float32 rounding; and the textured
    columns vary over the hits, so the comparison reads textures."""
    scene = _scene(texture_filter)
    numpy_one, device_one = _pair(scene)
    bounce = device_one._bounce
    assert bounce is not None and len(bounce._per_hit) == 3 and len(bounce._second_per_hit) == 1
    origin, direction = _rays(scene, 4000, 3)
    hits = Intersector(scene).closest(origin, direction)
    rows = np.flatnonzero((hits.geom >= 0) & (hits.geom < 3))
    assert len(rows) > 1000
    params, seconds = bounce._hit_rows(rows, hits, device_one._hit_parameters(hits, rows, direction, None, depth))
    expected = bounce._hit_rows(rows, hits, numpy_one._hit_parameters(hits, rows, direction, None, depth))
    exact = texture_filter in ("point", "bilinear") or depth > 0
    for got, reference in zip((params, seconds), expected):
        assert len(got) == len(rows) and np.isfinite(got).all()
        if exact:
            assert np.array_equal(got, reference)
        else:
            np.testing.assert_allclose(got, reference, rtol=1e-5, atol=1e-7)
    for geom, table in ((0, params), (1, params), (2, seconds)):  # each material's rows differ from hit to hit
        on = hits.geom[rows] == geom
        assert len(np.unique(table[on], axis=0)) > on.sum() // 4


@pytest.mark.parametrize("texture_filter", FILTERS)
def test_the_opencl_path_integrator_filters_every_image_on_the_device(texture_filter, monkeypatch):
    """Whole paths (depth 5) over ``_materials(texture_filter)``: per-hit rows, ``_shade``'s numpy
    bounce (the mix holding a mix) and the floor's albedo all filter their image textures through
    the device, so ``MipMap``'s numpy filters are never called on the OpenCL backend, and each ray's
    radiance is the numpy backend's to float32 rounding (a path may part only where rounding moves a
    sample across a threshold)."""
    scene = _scene(texture_filter)
    numpy_one, device_one = _pair(scene)
    origin, direction = _rays(scene, 4000, 9)
    rng = np.random.default_rng(10)
    pixel, sample = rng.integers(0, 1 << 20, len(origin)), rng.integers(0, 64, len(origin))
    expected, _ = numpy_one.radiance(origin, direction, pixel, sample)
    shaded: list[int] = []
    shade = device_one._shade
    monkeypatch.setattr(device_one, "_shade", lambda hits, surface, *rest: shaded.append(len(surface))
                        or shade(hits, surface, *rest))
    for name in NUMPY_FILTERS:
        monkeypatch.setattr(MipMap, name, lambda *_, name=name: pytest.fail(f"MipMap.{name} called"))
    got, _ = device_one.radiance(origin, direction, pixel, sample)
    assert sum(shaded) > 0  # the numpy bounce ran, with device lookups
    top = float(np.abs(expected).max())
    close = np.all(np.isclose(got, expected, rtol=1e-3, atol=1e-5 * top), axis=1)
    assert close.mean() > 0.99, close.mean()
    assert abs(float(got.mean()) / float(expected.mean()) - 1) < 2e-3


def test_the_opencl_path_integrator_has_one_backend_and_no_shading_kernel(monkeypatch):
    """The path integrator hands its backend to its ``DirectLighting`` part, whose footprints and
    image lookups then run on it (one backend, no second attribute), and builds no shading kernel
    (``shade.cl`` takes matte and measured materials alone and never shades a path): over
    ``_scene("ewa")`` (plastic, a mix, a mix holding a mix) it builds on "opencl", and its camera
    rays' first-hit albedo (the albedo AOV) filters through the device, never ``MipMap``'s numpy
    filters, and is the numpy backend's to float32 rounding."""
    scene = _scene("ewa")
    numpy_one, device_one = _pair(scene)
    assert (numpy_one.backend.name, device_one.backend.name) == ("numpy", "opencl")
    assert device_one._kernel is None and not hasattr(device_one, "_surface_backend")
    origin, direction = _rays(scene, 3000, 12)
    hits = Intersector(scene).closest(origin, direction)
    expected = numpy_one.first_hits(origin, direction, hits).albedo
    for name in NUMPY_FILTERS:
        monkeypatch.setattr(MipMap, name, lambda *_, name=name: pytest.fail(f"MipMap.{name} called"))
    got = device_one.first_hits(origin, direction, hits).albedo
    assert np.count_nonzero(hits.geom == 0) > 100  # the image-textured floor
    np.testing.assert_allclose(got, expected, rtol=1e-5, atol=1e-7)
