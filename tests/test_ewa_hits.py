"""``EwaKernel.at_hits`` (kernels/ewa.cl's hit_lookups and the filters' kernels): the albedo of
image-textured hits computed from embree's hit records on the device, against its numpy reference
``DirectLighting._albedo`` (uv interpolation, pixel footprint, st mapping, filtered lookup), per hit,
to float32 rounding; the renderer's choice of which materials go to the device; and whole renders
over point- and trilinear-filtered textures against the numpy backend's."""

from dataclasses import replace

import numpy as np
import pytest

from realistic.camera.base import SampleBlock
from realistic.camera.lens_camera import LensCamera
from realistic.camera.thin_lens import ThinLensCamera
from realistic.core.film_geometry import FULL_FRAME_DIAGONAL_MM
from realistic.core.jit import compiled
from realistic.core.transforms import look_at, rotate, scale, translate
from realistic.optics.formats import load_lens
from realistic.renderer.backends import backend_for
from realistic.renderer.direct_lighting import DirectLighting, _facing
from realistic.renderer.hit_rows import _place_rows, _rows_on_material
from realistic.renderer.job import RenderJob
from realistic.renderer.passes import ThreadPasses, render
from realistic.scene.ewa_kernel import MAPPING
from realistic.scene.intersect import Intersector
from realistic.scene.model import AreaLight, ImageTexture, Material, Scene
from realistic.scene.shapes import cone, quad, sphere
from test_shading_reference import textured_scene

pytestmark = pytest.mark.usefixtures("opencl_platform")

F32 = np.float32


def image(seed: int, shape: tuple[int, int]) -> np.ndarray:
    return np.random.default_rng(seed).random((*shape, 3)).astype(np.float32)


def instanced_scene() -> tuple[Scene, np.ndarray, np.ndarray]:
    """Image textures of every wrap and both v origins on instances whose linear maps are not
    rotations (a non-uniform scale, a mirror, a shear), on curved, sloped and grazing surfaces, with
    a trilinear texture beside them and a floor seen nearly edge on."""
    scene = Scene(background=(0.0, 0.0, 0.0))
    clamp = ImageTexture(image(1, (48, 80)), scale=(3.0, 2.0), v_origin="bottom", wrap="clamp",
                         offset=(-0.3, 0.1))
    black = ImageTexture(image(2, (64, 64)), scale=(2.5, 5.0), v_origin="top", wrap="black", max_anisotropy=3.0)
    repeat = ImageTexture(image(3, (16, 128)), scale=(7.0, 1.5), max_anisotropy=16.0)
    trilinear = ImageTexture(image(4, (32, 32)), scale=(4.0, 4.0), filter="trilinear")
    scene.add(quad(30.0, 30.0), rotate(-90, (1, 0, 0)), Material((0.9, 0.8, 0.7), repeat))
    ball = sphere(0.5, 40)
    scene.add(ball, translate(-0.9, 0.6, 0.3) @ scale(1.4, 0.8, 1.1) @ rotate(25, (0, 0, 1)),
              Material((0.6, 0.9, 0.5), clamp))
    scene.add(ball, translate(0.8, 0.5, -0.2) @ scale(-1.0, 1.0, 1.0), Material((1.0, 1.0, 1.0), black))
    shear = np.eye(4)
    shear[0, 1] = 0.6
    scene.add(cone(0.4, 1.0, 24), translate(0.1, 0.0, 1.0) @ shear @ rotate(-90, (1, 0, 0)),
              Material((0.7, 0.7, 0.9), clamp))
    scene.add(quad(0.8, 0.8), translate(0.0, 0.6, -1.0) @ rotate(35, (0, 1, 0)), Material((0.5, 0.5, 0.5), trilinear))
    scene.lights.append(AreaLight("disk", (1.0, 1.0), (20.0, 20.0, 20.0), translate(0, 3.0, 0) @ rotate(90, (1, 0, 0))))
    return scene, np.array([0.0, 0.35, 4.5]), np.array([0.0, 0.3, 0.0])


def filtered_scene(texture_filter: str) -> tuple[Scene, np.ndarray, np.ndarray]:
    """``instanced_scene`` with its EWA textures filtered with ``texture_filter`` instead."""
    scene, eye, target = instanced_scene()
    for k, instance in enumerate(scene.instances):
        texture = instance.material.texture
        if texture.filter == "ewa":
            scene.instances[k] = replace(instance, material=replace(instance.material,
                                                                    texture=replace(texture, filter=texture_filter)))
    return scene, eye, target


def bilinear_scene() -> tuple[Scene, np.ndarray, np.ndarray]:
    """``instanced_scene`` with its EWA textures filtered with pbrt-v4's bilinear filter instead."""
    return filtered_scene("bilinear")


def hits_of(scene: Scene, eye: np.ndarray, target: np.ndarray, width: int = 96, height: int = 64):
    camera = LensCamera.looking_at(load_lens("dgauss"), eye, target, None, FULL_FRAME_DIAGONAL_MM, width, height, 2)
    rays = backend_for("numpy").ray_generator(camera, 3)(SampleBlock(0, camera.sample_count, 2))
    alive = np.flatnonzero(rays.weight != 0)
    origin, direction = rays.origin[alive].astype(F32), rays.direction[alive].astype(F32)
    intersector = Intersector(scene)
    return intersector, origin, direction, intersector.closest(origin, direction), camera.pixel_spread_radians()


def reference_albedo(integrator: DirectLighting, host: np.ndarray, direction: np.ndarray, hits) -> np.ndarray:
    """``_albedo`` in numpy on the surface hits of the materials ``host`` marks; zero elsewhere."""
    out = np.zeros((len(direction), 3), F32)
    surface = (hits.geom >= 0) & (hits.geom < integrator.instance_count)
    rows = np.flatnonzero(surface & host[integrator._geom_material[np.where(surface, hits.geom, 0)]])
    d = direction[rows]
    face, bary = integrator._triangles(hits, rows)
    out[rows] = integrator._albedo(face, bary, hits.geom[rows], d, _facing(hits.normal[rows], d), hits.t[rows])
    return out


def v4_trilinear_scene() -> tuple[Scene, np.ndarray, np.ndarray]:
    """``instanced_scene`` with its EWA textures trilinear as pbrt-v4 filters (blending from level 1),
    beside its trilinear texture blending from level 0 as pbrt-v3."""
    scene, eye, target = filtered_scene("trilinear")
    for k, instance in enumerate(scene.instances[:4]):
        texture = replace(instance.material.texture, trilinear_blend_from=1)
        scene.instances[k] = replace(instance, material=replace(instance.material, texture=texture))
    return scene, eye, target


@pytest.mark.parametrize("name", ["textured", "instanced", "bilinear", "point", "trilinear", "trilinear v4"])
def test_device_albedo_matches_numpy(name):
    scene, eye, target = {"textured": textured_scene, "instanced": instanced_scene, "bilinear": bilinear_scene,
                          "point": lambda: filtered_scene("point"),
                          "trilinear": lambda: filtered_scene("trilinear"),
                          "trilinear v4": v4_trilinear_scene}[name]()
    intersector, origin, direction, hits, spread = hits_of(scene, eye, target)
    device = DirectLighting(scene, intersector, 1, 5, spread, backend="opencl")
    numpy_path = DirectLighting(scene, intersector, 1, 5, spread, backend="numpy")
    host = device._kernel.host_albedo
    on_device = host & ~device._numpy_albedo
    assert on_device.any()
    albedo = device._host_albedo(origin, direction, hits)
    reference = reference_albedo(numpy_path, host, direction, hits)
    textured = np.flatnonzero(reference.any(axis=1))
    assert len(textured) > 1000 and reference.max() > 0.3
    # the same float64 operations in the same order: bit for bit here (numpy's einsum may sum a machine's
    # way, moving an edge by an ulp; a tap can then change table bin, moving the albedo by far under 1e-5)
    np.testing.assert_allclose(albedo, reference, rtol=1e-5, atol=1e-6)
    assert np.mean(albedo == reference) > 0.99


def test_image_textures_of_every_filter_with_footprints_go_to_the_device():
    scene, eye, target = instanced_scene()
    intersector, *_ = hits_of(scene, eye, target, 8, 8)
    with_spread = DirectLighting(scene, intersector, 1, 5, 1e-3, backend="opencl")
    materials = with_spread._materials
    on_device = [i for i, _, _, _ in with_spread._device_textures]
    assert [materials[i].texture.filter for i in on_device] == ["ewa"] * 4 + ["trilinear"]
    assert not any(with_spread._numpy_albedo[i] for i, m in enumerate(materials) if isinstance(m.texture, ImageTexture))
    for texture_filter in ("bilinear", "point"):
        scene, eye, target = filtered_scene(texture_filter)
        intersector, *_ = hits_of(scene, eye, target, 8, 8)
        filtered = DirectLighting(scene, intersector, 1, 5, 1e-3, backend="opencl")
        assert [f for _, _, _, f in filtered._device_textures] == [texture_filter] * 4 + ["trilinear"]
    point_sampled = DirectLighting(scene, intersector, 1, 5, 0.0, backend="opencl")
    assert point_sampled._device_textures == []  # no footprint: level 0 bilinearly, in numpy


def test_each_textures_rows_are_the_hits_on_its_material():
    """``_host_albedo`` gives each device texture the rays whose hits are on its material's instances
    (``hit_rows._rows_on_material``: one numba pass, in order) and places the colours ``at_hits`` returns in
    those rows (``hit_rows._place_rows``); at_hits refuses rows it would have to convert."""
    scene, eye, target = instanced_scene()
    intersector, origin, direction, hits, spread = hits_of(scene, eye, target, 32, 24)
    device = DirectLighting(scene, intersector, 1, 5, spread, backend="opencl")
    surface = (hits.geom >= 0) & (hits.geom < device.instance_count)
    material = device._geom_material[np.where(surface, hits.geom, 0)]
    rows = np.empty(len(direction), np.int32)
    for index, ewa, mapping, texture_filter in device._device_textures:
        mine = np.flatnonzero(surface & (material == index))
        count = compiled(_rows_on_material)(hits.geom, device._geom_material, index, rows)
        assert count > 0 and np.array_equal(rows[:count], mine)
        out = np.full((len(direction), 3), -7.0, F32)
        colours = ewa.at_hits(device._surface_tables, rows[:count], mapping, direction, hits, texture_filter)
        compiled(_place_rows)(colours, rows[:count], out)
        assert np.array_equal(out[mine], colours) and np.all(np.delete(out, mine, axis=0) == -7.0)
    with pytest.raises(ValueError, match="int32"):
        ewa.at_hits(device._surface_tables, mine, mapping, direction, hits)


def test_at_hits_filters_the_lookups_on_the_device_as_read_back_lookups_are_filtered():
    """``at_hits`` passes ``hit_lookups``' buffer to the filters without reading the lookups back: the
    colours equal the filter's over the lookups ``hit_lookups`` reads back, bit for bit, for every
    material's texture and filter (EWA's large footprints, left by its small kernel, among them)."""
    scene, eye, target = instanced_scene()
    intersector, origin, direction, hits, spread = hits_of(scene, eye, target, 32, 24)
    device = DirectLighting(scene, intersector, 1, 5, spread, backend="opencl")
    surface = (hits.geom >= 0) & (hits.geom < device.instance_count)
    material = device._geom_material[np.where(surface, hits.geom, 0)]
    diffuse = MAPPING.offset("diffuse")
    for index, ewa, mapping, texture_filter in device._device_textures:
        rows = np.flatnonzero(surface & (material == index)).astype(np.int32)
        assert len(rows)
        colours = ewa.at_hits(device._surface_tables, rows, mapping, direction, hits, texture_filter)
        lookups, used = ewa.hit_lookups(device._surface_tables, rows, mapping, direction, hits, texture_filter)
        read_back = ewa._filter(lookups, mapping[diffuse:diffuse + 3].astype(F32), used)
        assert colours.shape == (len(rows), 3) and colours.dtype == F32
        assert colours.tobytes() == read_back.tobytes()
    assert ewa.at_hits(device._surface_tables, rows[:0], mapping, direction, hits, texture_filter).shape == (0, 3)


def test_the_hit_lookups_vectorise(tmp_path):
    """PoCL's work-group vectoriser widens ``hit_lookups`` and ``hit_lookups_single`` (both of the
    work-group functions PoCL makes of each): a process that launches those two kernels alone, on one
    EWA texture and the trilinear one, prints four "vectorized loop" remarks (a loop left in their
    body, as their store loop was without its unroll pragma, keeps the work-item loop scalar: none).
    ``ewa_small`` vectorises too (``test_ewa_kernel``). Its remarks need a fresh build, so this runs in
    a process of its own."""
    from conftest import vectoriser_remarks

    script = (
        "import numpy as np\n"
        "from realistic.renderer.direct_lighting import DirectLighting\n"
        "from test_ewa_hits import hits_of, instanced_scene\n"
        "scene, eye, target = instanced_scene()\n"
        "intersector, origin, direction, hits, spread = hits_of(scene, eye, target, 32, 24)\n"
        "lighting = DirectLighting(scene, intersector, 1, 5, spread, backend='opencl')\n"
        "material = lighting._geom_material[np.where(hits.geom >= 0, hits.geom, 0)]\n"
        "picked = {f: t for t in lighting._device_textures for f in [t[3]]}\n"
        "for index, ewa, mapping, texture_filter in (picked['ewa'], picked['trilinear']):\n"
        "    rows = np.flatnonzero((hits.geom >= 0) & (material == index)).astype(np.int32)\n"
        "    assert len(rows) and ewa.hit_lookups(lighting._surface_tables, rows, mapping, direction, hits,\n"
        "                                         texture_filter)[1] == texture_filter\n")
    remarks = vectoriser_remarks(script, pocl_cache=tmp_path)
    assert remarks.count("vectorized loop (") >= 4


@pytest.mark.parametrize("integrator", ["directlighting", "path"])
def test_renders_over_point_and_trilinear_textures_match_the_numpy_backend(integrator):
    """``textured_scene`` with its floor filtered trilinearly and a point-filtered image on its quad,
    through a thin lens (both backends trace the same camera rays), rendered by each integrator on
    the OpenCL backend (the textures' albedo by ``at_hits``) and on the numpy one: the same image
    within float32 rounding, but where rounding moves a path's sample across a threshold."""
    scene, eye, target = textured_scene()
    floor, board = scene.instances[0], scene.instances[3]
    scene.instances[0] = replace(floor, material=replace(floor.material, texture=replace(floor.material.texture,
                                                                                         filter="trilinear")))
    scene.instances[3] = replace(board, material=Material((0.3, 0.6, 0.9), ImageTexture(image(6, (16, 16)),
                                                                                         scale=(3.0, 3.0),
                                                                                         filter="point")))
    scene = replace(scene, integrator=integrator)
    camera = ThinLensCamera(40.0, 0.02, float(np.linalg.norm(target - eye)), 48, 32, 4, look_at(eye, target))
    images = {backend: render(RenderJob(scene, (camera,), backend, 3, light_samples=2, pass_samples=1500),
                              ThreadPasses(threads=2))[0].image for backend in ("numpy", "opencl")}
    expected, got = images["numpy"], images["opencl"]
    assert expected.max() > 0
    assert abs(float(got.mean()) / float(expected.mean()) - 1) < 1e-3
    close = np.all(np.isclose(got, expected, rtol=1e-4, atol=1e-5 * expected.max()), axis=-1)
    assert close.mean() > 0.99, close.mean()
