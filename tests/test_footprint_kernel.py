"""Camera hits' texture footprints on the device (issue 35): ``kernels/ewa.cl``'s
``triangle_footprints`` (``FootprintKernel``, the "opencl" backend's ``triangle_footprint``) against
the numpy reference ``footprint.triangle_footprint``, and OpenCL renders of image-textured mixes that
take every footprint from it, none from the host.

Tolerance: the kernel runs the reference's float64 operations in its order (FP_CONTRACT off), from
the same float64 inputs, but for the world edges: numpy's ``einsum`` sums the linear map's products
in an order of its own, the kernel left to right. Given the edges summed left to right the kernel is
the reference bit for bit (checked); against ``triangle_footprint`` itself the edges differ by an
ulp or so, which the 2 x 2 solve of ``to_uv`` grows by the triangle's condition number: relative
1e-10 at worst on these random (some nearly degenerate) triangles, far inside the float32 rounding
(relative 6e-8) of the colours the filters make from them. The test asserts each axis within
relative 1e-6 of the footprint's size (its longer axis: float32 rounding of the ellipse, which is
what the filters read; an axis may itself be tiny and ill-conditioned, as the along axis of a ray
down the normal, whose direction is the rounding residue of the float32 ray and normal) and
bit-equal zeros where the reference has them.
"""

from dataclasses import replace

import numpy as np
import pytest

from realistic.camera.thin_lens import ThinLensCamera
from realistic.core.transforms import look_at
from realistic.renderer import backends, footprint
from realistic.renderer.backends import NumpyBackend, backend_for
from realistic.renderer.direct_lighting import DirectLighting
from realistic.renderer.job import RenderJob
from realistic.renderer.passes import ThreadPasses, render
from realistic.scene.intersect import Intersector
from realistic.scene.materials import Plastic
from realistic.scene.model import ImageTexture
from realistic.scene.textures import Footprint
from test_hit_image_lookups import _scene as mixes_scene
from test_light_albedo_filter import _rays as light_rays
from test_light_albedo_filter import _scene as light_scene

# pyopencl's modules: the tests skip without it
OpenCLBackend = pytest.importorskip("realistic.renderer.opencl_backend").OpenCLBackend
FootprintKernel = pytest.importorskip("realistic.scene.ewa_kernel").FootprintKernel
pytestmark = pytest.mark.usefixtures("opencl_platform")

SPREAD = 2e-3


def _triangles(seed: int, n: int) -> dict[str, np.ndarray]:
    """``n`` hits on random triangles of a random mesh under random instance maps (rotations,
    non-uniform scales, shears, mirrors), with: triangles of zero uv area (one uv for all corners, and
    corners on a uv line), triangles of zero world area, rays along the normal (the fallback axis),
    grazing rays (cos 0, 1e-5, 1e-3 and 2e-3) and ordinary ones, normals facing the rays or not (the
    triangle's own normal, but for the rays along an axis-aligned one)."""
    rng = np.random.default_rng(seed)
    vertices = rng.normal(size=(3 * n, 3))
    uv = rng.uniform(-1, 2, (3 * n, 2)).astype(np.float32)
    face = np.arange(3 * n).reshape(n, 3)
    kind = np.arange(n) % 8
    uv[face[kind == 1]] = uv[face[kind == 1, :1]]  # one uv at every corner
    line = face[kind == 2]
    uv[line[:, 2]] = uv[line[:, 0]] + 0.5 * (uv[line[:, 1]] - uv[line[:, 0]])  # corners on one uv line
    flat = face[kind == 3]
    vertices[flat[:, 2]] = vertices[flat[:, 0]] + 0.25 * (vertices[flat[:, 1]] - vertices[flat[:, 0]])
    linear = rng.normal(size=(6, 3, 3))
    linear[0] = np.eye(3)
    linear[1] = np.diag([-1.0, 1.0, 1.0])  # a mirror
    linear[2] = np.diag([3.0, 0.2, 1.0])
    linear[3, :, :] = np.eye(3)
    linear[3, 0, 1] = 0.7  # a shear
    geom = rng.integers(0, 6, n).astype(np.int32)
    edge1 = np.einsum("nij,nj->ni", linear[geom], vertices[face[:, 1]] - vertices[face[:, 0]])
    edge2 = np.einsum("nij,nj->ni", linear[geom], vertices[face[:, 2]] - vertices[face[:, 0]])
    normal = np.cross(edge1, edge2)
    length = np.linalg.norm(normal, axis=1, keepdims=True)
    normal = np.where(length > 0, normal / np.where(length > 0, length, 1), [[0.0, 0.0, 1.0]])
    normal *= rng.choice([-1.0, 1.0], (n, 1))
    # rays down the normal take the fallback axis where the ray is the normal to the last bit: axis-aligned
    # normals (x: crossed with y, else with x); where the two differ by float32 rounding, the along axis is
    # the rounding's residue in both footprints, which the bit-for-bit comparison covers
    down = kind == 4
    normal[down] = np.eye(3)[rng.integers(0, 3, down.sum())] * rng.choice([-1.0, 1.0], (down.sum(), 1))
    # a direction at a chosen cosine to the normal: cos = 1 (along it) or grazing for some kinds
    cosine = rng.uniform(-1, 1, n)
    cosine[kind == 4] = rng.choice([1.0, -1.0], (kind == 4).sum())
    cosine[kind == 5] = rng.choice([0.0, 1e-5, -1e-3, 2e-3], (kind == 5).sum())
    side = rng.normal(size=(n, 3))
    side -= (side * normal).sum(axis=1, keepdims=True) * normal
    side /= np.linalg.norm(side, axis=1, keepdims=True)
    direction = cosine[:, None] * normal + np.sqrt(1 - cosine ** 2)[:, None] * side
    return {"vertices": vertices, "uv": uv, "linear": linear, "face": face, "geom": geom,
            "direction": direction.astype(np.float32), "normal": normal.astype(np.float32),
            "distance": rng.uniform(0.05, 50.0, n).astype(np.float32)}


def _device_footprint(case: dict[str, np.ndarray]) -> Footprint:
    return FootprintKernel(backend_for("opencl").device)(**case, spread_radians=SPREAD)


@pytest.mark.parametrize("seed", [1, 2])
def test_kernel_footprints_are_the_references(seed):
    """``triangle_footprints`` against ``triangle_footprint`` (see the module docstring): bit for bit
    given edges summed as the kernel sums them, to relative 1e-6 of each axis against the reference
    itself, over every kind of ``_triangles``' hits, and zero where the reference is."""
    case = _triangles(seed, 40000)
    got = _device_footprint(case)
    linear = case["linear"][case["geom"]]
    expected = footprint.triangle_footprint(case["vertices"], case["uv"], case["face"], linear, case["direction"],
                                            case["normal"], case["distance"], SPREAD)
    corner = [case["vertices"][case["face"][:, k]] for k in range(3)]
    corner_uv = [case["uv"][case["face"][:, k]].astype(np.float64) for k in range(3)]

    def edge(q: np.ndarray) -> np.ndarray:
        return np.stack([linear[:, i, 0] * q[:, 0] + linear[:, i, 1] * q[:, 1] + linear[:, i, 2] * q[:, 2]
                         for i in range(3)], axis=1)

    same_edges = footprint.uv_footprint(case["direction"].astype(np.float64), case["normal"].astype(np.float64),
                                        case["distance"].astype(np.float64), SPREAD, edge(corner[1] - corner[0]),
                                        edge(corner[2] - corner[0]), corner_uv[1] - corner_uv[0],
                                        corner_uv[2] - corner_uv[0])
    kind = np.arange(len(case["face"])) % 8
    size = np.maximum(*(np.linalg.norm(reference, axis=1) for reference in expected))  # the ellipse's major axis
    for axis, reference, exact in zip(got, expected, same_edges):
        assert axis.dtype == np.float64 and axis.shape == reference.shape
        assert np.array_equal(axis, exact)
        length = np.linalg.norm(reference, axis=1)
        assert np.all(np.linalg.norm(axis - reference, axis=1) <= 1e-6 * size)
        assert np.all(axis[kind == 1] == 0) and np.all(axis[kind == 3] == 0)  # no uv area; no world area
        assert np.all(length[(kind != 1) & (kind != 3)] > 0)
    across, along = expected
    grazing = (kind == 5) & (np.abs((case["direction"] * case["normal"]).sum(axis=1)) < 1e-3)
    ordinary = (kind == 0) & (np.linalg.norm(across, axis=1) > 0)
    assert grazing.sum() > 100 and ordinary.sum() > 100
    # the along axis is stretched by 1 / max(|cos|, 1e-3) over the across axis: 1000x at grazing hits
    stretch = np.linalg.norm(along, axis=1) / np.maximum(np.linalg.norm(across, axis=1), 1e-300)
    assert np.median(stretch[grazing]) > 50 and np.median(stretch[ordinary]) < 50


def test_no_hits_make_no_launch():
    case = _triangles(3, 8)
    case = {key: value if key in ("vertices", "uv", "linear") else value[:0] for key, value in case.items()}
    axes = _device_footprint(case)
    assert [a.shape for a in axes] == [(0, 2), (0, 2)]


def _spied(monkeypatch: pytest.MonkeyPatch) -> tuple[list[int], list[int]]:
    """Counters of ``triangle_footprint`` calls (host footprints, through any module's name for it)
    and of ``FootprintKernel`` launches, counting hits."""
    host: list[int] = []
    device: list[int] = []
    reference = footprint.triangle_footprint
    kernel = FootprintKernel.__call__

    def counted(*args, **kwargs):
        host.append(len(args[2]))
        return reference(*args, **kwargs)

    def launched(self, *args, **kwargs):
        device.append(len(args[3]))
        return kernel(self, *args, **kwargs)

    for module in (footprint, backends):
        monkeypatch.setattr(module, "triangle_footprint", counted)
    monkeypatch.setattr(FootprintKernel, "__call__", launched)
    return host, device


def _render(scene, backend: str) -> np.ndarray:
    """``scene`` path traced through a thin lens (pixel footprints), 48 x 32, 3 spp."""
    eye, target = np.array([0.0, 1.0, 4.0]), np.array([0.0, 0.4, 0.0])
    camera = ThinLensCamera(40.0, 0.02, float(np.linalg.norm(target - eye)), 48, 32, 3, look_at(eye, target))
    job = RenderJob(replace(scene, integrator="path"), (camera,), backend, 3, light_samples=2, pass_samples=1500)
    return render(job, ThreadPasses(threads=2))[0].image


def test_an_opencl_render_of_textured_mixes_takes_its_footprints_from_the_device(monkeypatch):
    """A path-traced render of image-textured roughness, ``Ks`` and mixes (a textured second material,
    a mix holding a mix: ``_hit_parameters`` and ``_shade`` at depth 0) on the OpenCL backend calls
    ``triangle_footprint`` never and the kernel instead; its image is the one the same render gets
    with the host's footprints (the module's tolerance, through the filters' float32 colours: equal
    but where a texel's weight or a path's threshold flips), and the numpy backend's within float32
    rounding of the paths (as ``test_hit_image_lookups``)."""
    scene = mixes_scene("ewa")
    host, device = _spied(monkeypatch)
    got = _render(scene, "opencl")
    assert host == [] and sum(device) > 300
    with monkeypatch.context() as numpy_footprints:
        numpy_footprints.setattr(OpenCLBackend, "triangle_footprint", NumpyBackend.triangle_footprint)
        with_host = _render(scene, "opencl")
    assert sum(host) == sum(device)  # the same camera hits
    assert got.max() > 0
    close = np.all(np.isclose(got, with_host, rtol=1e-5, atol=1e-6 * with_host.max()), axis=-1)
    assert close.mean() > 0.999, close.mean()
    assert abs(float(got.mean()) / float(with_host.mean()) - 1) < 1e-4
    host.clear()
    expected = _render(scene, "numpy")
    assert sum(host) > 300  # the numpy backend keeps the reference
    close = np.all(np.isclose(got, expected, rtol=1e-3, atol=1e-4 * expected.max()), axis=-1)
    assert close.mean() > 0.99, close.mean()
    assert abs(float(got.mean()) / float(expected.mean()) - 1) < 2e-3


@pytest.mark.parametrize("mirrored", [False, True])
def test_an_image_textured_lights_albedo_takes_its_footprints_from_the_device(monkeypatch, mirrored):
    """``DirectLighting._light_albedo`` (a plastic light whose Kd is an image, footprints of a few
    texels) on the OpenCL backend: no host footprint, and the numpy backend's albedo to float32
    rounding."""
    pixels = np.random.default_rng(7).random((64, 64, 3)).astype(np.float32)
    scene = light_scene(Plastic(ImageTexture(pixels, scale=(2.0, 3.0)), (0.3, 0.3, 0.3), 0.2), mirrored)
    origin, direction = light_rays(2)
    hits = Intersector(scene).closest(origin, direction)
    expected = DirectLighting(scene, Intersector(scene), 1, 0, 0.01).first_hits(origin, direction, hits).albedo
    host, device = _spied(monkeypatch)
    got = DirectLighting(scene, Intersector(scene), 1, 0, 0.01, backend="opencl").first_hits(origin, direction,
                                                                                             hits).albedo
    assert host == [] and sum(device) == len(origin)
    np.testing.assert_allclose(got, expected, rtol=1e-6, atol=1e-7)


def test_the_footprint_kernel_vectorises(tmp_path):
    """PoCL's work-group vectoriser widens ``triangle_footprints`` (both of the work-group functions
    PoCL makes of it, the only kernel this process launches), its shared footprint code inlined.
    Its remarks need a fresh build, so this runs in a process of its own."""
    from conftest import vectoriser_remarks

    script = ("from test_footprint_kernel import _device_footprint, _triangles\n"
              "_device_footprint(_triangles(1, 5000))\n")
    remarks = vectoriser_remarks(script, pocl_cache=tmp_path)
    assert remarks.count("vectorized loop (") >= 2
