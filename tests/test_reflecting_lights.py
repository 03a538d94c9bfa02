"""Area lights that reflect by the material in effect where they are declared, as pbrt's do.

pbrt gives an area light's shape the current material (pbrt-v3 ``pbrtShape`` in
``src/core/api.cpp``, pbrt-v4 ``BasicScene::CreateAggregate`` in ``src/pbrt/scene.cpp``) and its path
integrator adds the emission at a hit on it and then bounces off that surface (pbrt-v3 and pbrt-v4
``PathIntegrator::Li``). Closed forms: inside a closed box whose walls are Lambertian emitters of
albedo a and radiance Le, the radiance to ``max_depth`` bounces is Le (1 + a + ... + a^max_depth);
pbrt-v3's direct lighting sees Le (1 + a). Walls without a material give Le alone (the path ends).
"""

import dataclasses

import numpy as np
import pytest

from realistic.core.transforms import rotate, translate
from realistic.renderer.from_dict import load_dict
from realistic.renderer.path import PathIntegrator
from realistic.scene.intersect import Intersector
from realistic.scene.materials import Dielectric, Plastic, SurfaceMaterial
from realistic.scene.model import AreaLight, Material, Scene
from realistic.scene.pbrt.importer import import_pbrt
from realistic.scene.shapes import quad

N = 20000
ALBEDO = np.array([0.5, 0.3, 0.7])
LE = np.array([1.0, 2.0, 0.5])
CAMERA = 'Film "image" "integer xresolution" [8] "integer yresolution" [8]\nCamera "perspective" "float fov" 40\n'


def _emitter_box(material: SurfaceMaterial | None) -> Scene:
    """A closed cube [-2, 2]^3 of six one-sided quad lights of radiance ``LE`` facing inward, each
    reflecting by ``material``."""
    scene = Scene()
    for face in (rotate(0, (1, 0, 0)), rotate(180, (1, 0, 0)), rotate(90, (1, 0, 0)), rotate(-90, (1, 0, 0)),
                 rotate(90, (0, 1, 0)), rotate(-90, (0, 1, 0))):
        scene.lights.append(AreaLight("quad", (4.0, 4.0), tuple(LE), face @ translate(0, 0, -2.0), material=material))
    return scene


def _inside_rays(n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Rays from points inside the box in uniform directions."""
    rng = np.random.default_rng(seed)
    origin = rng.uniform(-1.5, 1.5, (n, 3)).astype(np.float32)
    direction = rng.normal(size=(n, 3))
    return origin, (direction / np.linalg.norm(direction, axis=1, keepdims=True)).astype(np.float32)


def _radiance(scene: Scene, max_depth: int, mode: str, backend: str) -> np.ndarray:
    integrator = PathIntegrator(scene, Intersector(scene), 1, 3, 0.0, max_depth, mode, backend=backend)
    assert (integrator._bounce is not None) == (backend == "opencl")
    origin, direction = _inside_rays(N, max_depth)
    radiance, _ = integrator.radiance(origin, direction, np.arange(N), np.zeros(N, int))
    return radiance.astype(np.float64)


def _agrees(radiance: np.ndarray, expected: np.ndarray) -> None:
    """Each channel's mean within 4 standard errors (and 1e-3 relative) of ``expected``."""
    error = radiance.std(axis=0) / np.sqrt(len(radiance))
    assert np.all(np.abs(radiance.mean(axis=0) - expected) < 4 * error + 1e-3 * expected), (
        radiance.mean(axis=0), expected, error)


@pytest.mark.parametrize("max_depth", [0, 1, 2, 5])
def test_box_of_reflecting_emitters_sums_the_geometric_series(max_depth):
    """Path mode, numpy: Le (1 - a^(D + 1)) / (1 - a) per channel to D bounces (light sampling and
    BSDF sampling weighted by MIS, roulette after the third bounce)."""
    expected = LE * (1 - ALBEDO ** (max_depth + 1)) / (1 - ALBEDO)
    _agrees(_radiance(_emitter_box(Material(tuple(ALBEDO))), max_depth, "path", "numpy"), expected)


@pytest.mark.usefixtures("opencl_platform")
@pytest.mark.parametrize("max_depth", [1, 5])
def test_box_of_reflecting_emitters_through_the_bounce_kernel(max_depth):
    """The fused bounce kernel at hits on the emitters: the same series, and each ray's radiance the
    numpy backend's to float32 rounding (the same random numbers)."""
    scene = _emitter_box(Material(tuple(ALBEDO)))
    got = _radiance(scene, max_depth, "path", "opencl")
    _agrees(got, LE * (1 - ALBEDO ** (max_depth + 1)) / (1 - ALBEDO))
    expected = _radiance(scene, max_depth, "path", "numpy")
    close = np.all(np.isclose(got, expected, rtol=1e-3, atol=1e-5 * float(expected.max())), axis=1)
    assert close.mean() > 0.99, close.mean()


@pytest.mark.parametrize("backend", ["numpy", "opencl"])
def test_direct_lighting_reflects_the_other_emitters_once(backend, request):
    """pbrt-v3 ``DirectLightingIntegrator``: the emission seen plus the light the emitter's surface
    reflects directly, Le (1 + a)."""
    if backend == "opencl":
        request.getfixturevalue("opencl_platform")
    _agrees(_radiance(_emitter_box(Material(tuple(ALBEDO))), 5, "direct", backend), LE * (1 + ALBEDO))


def test_emitters_without_material_end_paths():
    """No material (a scene that gave none): every ray sees Le and nothing reflected."""
    radiance = _radiance(_emitter_box(None), 5, "path", "numpy")
    assert np.allclose(radiance, LE.astype(np.float32), rtol=1e-6)


@pytest.mark.usefixtures("opencl_platform")
@pytest.mark.parametrize("material", [Material(tuple(ALBEDO)), Plastic((0.4, 0.3, 0.2), (0.3, 0.3, 0.3), 0.1)])
@pytest.mark.parametrize("depth", [0, 2])
def test_bounce_kernel_shades_emitter_hits_as_the_numpy_reference(material, depth):
    """Per hit on an emitter, with the same random numbers: the kernel's light samples (summed per
    ray) and next rays are ``_shade``'s to float32 rounding."""
    scene = _emitter_box(material)
    numpy_one = PathIntegrator(scene, Intersector(scene), 3, 7, 0.0, 5, "path", backend="numpy")
    device_one = PathIntegrator(scene, Intersector(scene), 3, 7, 0.0, 5, "path", backend="opencl")
    assert device_one._bounce is not None and device_one._bounce.covered.all()
    n = 4000
    origin, direction = _inside_rays(n, 11)
    hits = Intersector(scene).closest(origin, direction)
    surface = np.flatnonzero(hits.geom >= device_one.instance_count)
    assert len(surface) == n
    rng = np.random.default_rng(depth)
    path = rng.permutation(n)
    beta = rng.uniform(0.2, 1.0, (n, 3)).astype(np.float32)
    pixel, sample = rng.integers(0, 1 << 20, n), rng.integers(0, 64, n)
    lights = 3 if depth == 0 else 1
    expected = numpy_one._shade(hits, surface, path, origin, direction, beta, None, pixel, sample, depth)
    got = device_one._bounce(surface, path, pixel.astype(np.uint32), sample.astype(np.uint32), origin, direction,
                             hits, beta, depth=depth, light_samples=lights, seed=7,
                             mode_flags=device_one._bounce_flags, max_depth=5)
    shadow = expected["shadow"]
    sums = [np.stack([np.bincount(rows, values[:, c], minlength=n) for c in range(3)], axis=1)
            for rows, values in ((np.tile(path[surface], lights), got.contribution),
                                 (shadow["rows"], shadow["contribution"]))]
    assert float(sums[1].max()) > 0
    close = np.all(np.isclose(sums[0], sums[1], rtol=2e-3, atol=1e-6 * float(sums[1].max())), axis=1)
    assert close.mean() > 0.998, close.mean()
    goes = np.flatnonzero(got.flags & 1)
    both, mine, ref = np.intersect1d(path[surface][goes], expected["path"], return_indices=True)
    assert len(both) > 0.99 * max(len(goes), len(expected["path"]))
    rows = goes[mine]
    assert np.allclose(got.origin[rows], expected["origin"][ref], atol=1e-4)
    assert np.mean(np.all(np.isclose(got.direction[rows], expected["direction"][ref], atol=2e-4), axis=1)) > 0.998
    assert np.mean(np.all(np.isclose(got.beta[rows], expected["beta"][ref], rtol=2e-3, atol=1e-7), axis=1)) > 0.998


@pytest.mark.parametrize("version, material, expected", [
    ("v3", 'Material "matte" "rgb Kd" [0.2 0.3 0.4]', Material((0.2, 0.3, 0.4))),
    ("v4", 'Material "diffuse" "rgb reflectance" [0.2 0.3 0.4]', Material((0.2, 0.3, 0.4))),
    ("v3", 'Material "none"', Dielectric(1.0))])
def test_imported_disk_light_keeps_the_material_in_effect(tmp_path, version, material, expected):
    """A pbrt disk area light reflects by the material in effect (an "interface" or "none" one lets
    light through, as pbrt-v3's missing BSDF does)."""
    path = tmp_path / "scene.pbrt"
    path.write_text(CAMERA + "WorldBegin\n" + material + '\nAttributeBegin\nAreaLightSource "diffuse" "rgb L" [1 1 1]\n'
                    'Shape "disk" "float radius" 1\nAttributeEnd\n' + ("" if version == "v4" else "WorldEnd\n"))
    (light,) = import_pbrt(path, dialect=version).scene.lights
    assert isinstance(light, AreaLight) and light.material == expected


def test_pbrt_v4_ignores_the_light_of_an_interface_shape(tmp_path):
    """pbrt-v4 (``BasicScene::CreateLights``) skips an area light whose shape's material is
    "interface", with a warning; the shape stays, letting light through."""
    path = tmp_path / "scene.pbrt"
    path.write_text(CAMERA + 'WorldBegin\nMaterial "interface"\nAttributeBegin\nAreaLightSource "diffuse" '
                    '"rgb L" [1 1 1]\nShape "disk" "float radius" 1\nAttributeEnd\n')
    imported = import_pbrt(path, dialect="v4")
    assert imported.scene.lights == [] and len(imported.scene.instances) == 1
    assert any('Material "interface"' in line and "pbrt-v4" in line for line in imported.warnings)


def test_dict_emitter_reflects_only_by_a_material_it_names():
    """``load_dict``: an emitting disk with a ``material`` reflects by it; one without only emits."""
    scene = load_dict({"shapes": [{"type": "disk", "emission": 1, "material": {"type": "diffuse", "reflectance": 0.3}},
                                  {"type": "quad", "emission": 2}]})
    with_material, without = scene.area_lights
    assert with_material.material == Material((0.3, 0.3, 0.3)) and without.material is None


@pytest.mark.parametrize("backend", ["numpy", "opencl"])
def test_direct_lighting_of_lights_that_light_each_other_is_the_reflecting_route(backend, request):
    """``Integrator "directlighting"`` on lights that reflect one another's light takes the path
    integrator's "direct" mode (the fast route ends rays at lights): the box reads Le (1 + a); one
    reflecting light alone, or several pure emitters, keep the fast route, which is exact there."""
    from realistic.renderer.direct_lighting import DirectLighting
    from realistic.renderer.integrators import make_integrator

    if backend == "opencl":
        request.getfixturevalue("opencl_platform")
    box = _emitter_box(Material(tuple(ALBEDO)))
    box.integrator = "directlighting"
    integrator = make_integrator(box, Intersector(box), 1, 3, backend=backend)
    assert isinstance(integrator, PathIntegrator) and integrator.mode == "direct"
    origin, direction = _inside_rays(N, 7)
    radiance, _ = integrator.radiance(origin, direction, np.arange(N), np.zeros(N, int))
    _agrees(radiance.astype(np.float64), LE * (1 + ALBEDO))
    for scene in (_emitter_box(None), Scene(lights=box.lights[:1])):
        scene.integrator = "directlighting"
        assert type(make_integrator(scene, Intersector(scene), 1, 3, backend=backend)) is DirectLighting


def _albedo_aov(scene: Scene, backend: str) -> np.ndarray:
    """The albedo AOV (3, 4, 6) of ``scene`` seen by a pinhole at the origin looking down +z."""
    from realistic.camera.thin_lens import ThinLensCamera
    from realistic.renderer.job import RenderJob
    from realistic.renderer.passes import ThreadPasses, render

    camera = ThinLensCamera(40.0, 0.0, 1.0, 6, 4, 4, np.eye(4))
    aovs = render(RenderJob(scene, (camera,), backend, aovs="albedo"), ThreadPasses(2))[0].aovs
    return np.stack([aovs["Albedo.R"], aovs["Albedo.G"], aovs["Albedo.B"]])


def _light_before_the_camera(material: SurfaceMaterial | None, integrator: str) -> Scene:
    """A quad light filling the view at z = 5, emitting toward the camera and reflecting by ``material``."""
    facing = translate(0, 0, 5.0) @ np.diag([1.0, 1.0, -1.0, 1.0])
    return Scene(lights=[AreaLight("quad", (1000.0, 1000.0), tuple(LE), facing, material=material)],
                 integrator=integrator)


@pytest.mark.parametrize("integrator", ["directlighting", "path"])
@pytest.mark.parametrize("backend", ["numpy", "opencl"])
def test_albedo_aov_on_a_reflecting_light_is_its_materials(backend, integrator, request):
    """pbrt-v4 ``PathIntegrator::Li`` fills the first hit's ``VisibleSurface`` with ``bsdf.rho`` of
    the shape's material whether or not it emits: a Lambertian light of albedo a reads a (through
    ``DirectLighting``, the single light's fast route, and ``PathIntegrator``); a pure emitter,
    which has no BSDF, reads 0."""
    if backend == "opencl":
        request.getfixturevalue("opencl_platform")
    got = _albedo_aov(_light_before_the_camera(Material(tuple(ALBEDO)), integrator), backend)
    np.testing.assert_allclose(got, np.broadcast_to(ALBEDO[:, None, None], got.shape), rtol=1e-6)
    assert not _albedo_aov(_light_before_the_camera(None, integrator), backend).any()


def test_albedo_of_a_light_is_the_same_through_either_integrator():
    """``DirectLighting._light_albedo`` (the light's own tessellation, its uv and outside) and
    ``PathIntegrator.first_albedo`` (the light in its per-geometry tables) agree on a checker-textured
    plastic light, reversed and mirrored (pbrt-v4 ``BSDF::rho`` over the same 16 samples)."""
    from realistic.renderer.direct_lighting import DirectLighting
    from realistic.scene.surfaces import CheckerTexture

    plastic = Plastic(CheckerTexture((0.6, 0.2, 0.1), (0.1, 0.3, 0.5), 4.0), (0.3, 0.3, 0.3), 0.2)
    light = AreaLight("disk", (3.0, 3.0), (1.0, 1.0, 1.0), translate(0, 0, 2.0) @ np.diag([-1.0, 1.0, 1.0, 1.0]),
                      reverse_orientation=True, material=plastic)
    scene = Scene(lights=[light])
    rng = np.random.default_rng(3)
    origin = np.zeros((500, 3), np.float32)
    direction = np.column_stack([rng.uniform(-0.6, 0.6, (500, 2)), np.where(np.arange(500) % 2, 1.0, -1.0)])
    origin[:, 2] = np.where(np.arange(500) % 2, 0.0, 4.0)  # half the rays from above the disk, half from below
    direction = (direction / np.linalg.norm(direction, axis=1, keepdims=True)).astype(np.float32)
    hits = Intersector(scene).closest(origin, direction)
    assert np.all(hits.geom == 0)
    fast = DirectLighting(scene, Intersector(scene)).first_hits(origin, direction, hits).albedo
    path = PathIntegrator(scene, Intersector(scene)).first_hits(origin, direction, hits).albedo
    assert len(np.unique(fast[:, 0])) > 10  # the checker and the glossy lobe vary over the hits
    np.testing.assert_allclose(fast, path, rtol=1e-5, atol=1e-6)


ETA = 1.5
INCIDENCE = np.radians(60.0)  # beyond the critical angle from inside glass of index 1.5 (41.8 degrees)
BELOW = np.array([0.4, 0.8, 1.2])


def _fresnel(cos_i: float, eta: float) -> float:
    """Unpolarised Fresnel reflectance entering a medium of index ``eta`` from index 1."""
    cos_t = np.sqrt(1 - (1 - cos_i ** 2) / eta ** 2)
    s = (cos_i - eta * cos_t) / (cos_i + eta * cos_t)
    p = (eta * cos_i - cos_t) / (eta * cos_i + cos_t)
    return float((s * s + p * p) / 2)


def _through_the_sheet(scene: Scene, backend: str = "numpy") -> np.ndarray:
    """Radiance of rays from (0, 0, 1) down at 60 degrees through a glass sheet at z = 0 onto an
    emitter below: seen from outside, the sheet passes 1 - F of it (the path tracer's lobe choice);
    from inside, total internal reflection sends every ray up, into nothing."""
    scene.lights.append(AreaLight("quad", (1000.0, 1000.0), tuple(BELOW), translate(0, 0, -1.0)))
    integrator = PathIntegrator(scene, Intersector(scene), 1, 5, 0.0, 5, "path", backend=backend)
    n = 4000
    origin = np.tile(np.array([0.0, 0.0, 1.0], np.float32), (n, 1))
    azimuth = 0.3  # off the disk's and the quad's edges through the origin
    direction = np.tile(np.array([np.sin(INCIDENCE) * np.cos(azimuth), np.sin(INCIDENCE) * np.sin(azimuth),
                                  -np.cos(INCIDENCE)], np.float32), (n, 1))
    radiance, _ = integrator.radiance(origin, direction, np.arange(n), np.zeros(n, int))
    return radiance.astype(np.float64)


@pytest.mark.parametrize("mirror", [False, True])
@pytest.mark.parametrize("backend", ["numpy", "opencl"])
def test_reversed_glass_light_has_its_inside_where_the_same_sheet_would(backend, mirror, request):
    """A glass quad light at z = 0 whose ReverseOrientation turns it to emit down has its outside
    below too, as the same quad has, light or not, when its triangles are wound the other way
    (pbrt hands a shape the same ``reverseOrientation`` either way): rays from above are inside,
    totally reflected, and see nothing; unreversed, they see the light and 1 - F of the emitter
    below. The same under a mirroring transform (x to -x), which leaves the emitting side up."""
    if backend == "opencl":
        request.getfixturevalue("opencl_platform")
    glass, place = Dielectric(ETA), np.diag([-1.0 if mirror else 1.0, 1.0, 1.0, 1.0])
    outside = (1 - _fresnel(np.cos(INCIDENCE), ETA)) * BELOW
    for reverse in (False, True):
        light = AreaLight("quad", (1000.0, 1000.0), (0.5, 0.5, 0.5), place, reverse_orientation=reverse,
                          material=glass)
        seen = _through_the_sheet(Scene(lights=[light]), backend)
        if reverse:
            np.testing.assert_array_equal(seen, 0.0)
        else:
            _agrees(seen, 0.5 + outside)
    sheet = quad(1000.0, 1000.0)
    for wound_back in (False, True):
        scene = Scene()
        scene.add(dataclasses.replace(sheet, faces=sheet.faces[:, ::-1] if wound_back else sheet.faces), place, glass)
        seen = _through_the_sheet(scene, backend)
        if wound_back:
            np.testing.assert_array_equal(seen, 0.0)
        else:
            _agrees(seen, outside)


@pytest.mark.parametrize("light", ["", 'AreaLightSource "diffuse" "rgb L" [0.5 0.5 0.5]\n'])
@pytest.mark.parametrize("version", ["v3", "v4"])
def test_pbrt_reverse_orientation_turns_a_glass_shape_inside_out(tmp_path, version, light):
    """A pbrt glass disk or triangle mesh at z = 0, emitting or not, under ReverseOrientation has its
    outside below (pbrt-v3 ``pbrtShape``, pbrt-v4 ``BasicScene::CreateAggregate``: every shape gets
    the ``reverseOrientation`` in effect, and its normal flips by it), as the mesh declared wound
    the other way has: rays from above are then totally reflected and see nothing."""
    glass = 'Material "dielectric" "float eta" 1.5\n' if version == "v4" else 'Material "glass" "float index" 1.5\n'
    disk = 'Shape "disk" "float radius" 1000\n'
    mesh = ('Shape "trianglemesh" "integer indices" [{}] "point3 P" [-500 -500 0 500 -500 0 500 500 0 '
            '-500 500 0]\n')
    outside = (0.5 if light else 0.0) + (1 - _fresnel(np.cos(INCIDENCE), ETA)) * BELOW
    for shape, reverse, expected in ((disk, "", outside), (disk, "ReverseOrientation\n", 0.0),
                                     (mesh.format("0 1 2 0 2 3"), "", outside),
                                     (mesh.format("0 1 2 0 2 3"), "ReverseOrientation\n", 0.0),
                                     (mesh.format("0 2 1 0 3 2"), "", 0.0)):
        path = tmp_path / "scene.pbrt"
        path.write_text(CAMERA + "WorldBegin\n" + glass + "AttributeBegin\n" + reverse + light + shape +
                        "AttributeEnd\n" + ("" if version == "v4" else "WorldEnd\n"))
        got = _through_the_sheet(import_pbrt(path, dialect=version).scene)
        if expected is outside:
            _agrees(got, outside)
        else:
            np.testing.assert_array_equal(got, 0.0, err_msg=shape + reverse)


def test_reverse_orientation_stores_the_mesh_inside_out_alone(tmp_path):
    """Under ReverseOrientation the importer stores each mesh once, turned inside out (faces wound
    back, vertex normals negated, as pbrt-v4's ``TriangleMesh``), not beside the original."""
    shapes = ('Shape "sphere" "float radius" 1\nShape "trianglemesh" "integer indices" [0 1 2] '
              '"point3 P" [0 0 0 1 0 0 0 1 0] "normal N" [0 0 1 0 0 1 0 0 1]\n')
    scenes = []
    for reverse in ("", "ReverseOrientation\n"):
        path = tmp_path / "scene.pbrt"
        path.write_text(CAMERA + "WorldBegin\n" + reverse + shapes)
        scenes.append(import_pbrt(path, dialect="v4").scene)
    plain, reversed_ = scenes
    assert len(reversed_.meshes) == len(reversed_.instances) == 2
    for a, b in zip(plain.instances, reversed_.instances, strict=True):
        mesh, inside_out = plain.meshes[a.mesh], reversed_.meshes[b.mesh]
        np.testing.assert_array_equal(inside_out.faces, mesh.faces[:, ::-1])
        np.testing.assert_array_equal(inside_out.normals, -mesh.normals)


@pytest.mark.parametrize("version", ["v3", "v4"])
def test_mirrored_glass_mesh_has_the_same_outside_emitting_or_not(tmp_path, version):
    """A glass triangle mesh wound to face +z under ``Scale -1 1 1``: pbrt gives it the normal of its
    world winding flipped by the mirror (+z), emitting or not, and emits on that side; rays from
    above see 1 - F of the emitter below either way, and the light's own emission besides."""
    glass = 'Material "dielectric" "float eta" 1.5\n' if version == "v4" else 'Material "glass" "float index" 1.5\n'
    mesh = ('Shape "trianglemesh" "integer indices" [0 1 2 0 2 3] "point3 P" [-500 -500 0 500 -500 0 500 500 0 '
            '-500 500 0]\n')
    for light in ("", 'AreaLightSource "diffuse" "rgb L" [0.5 0.5 0.5]\n'):
        path = tmp_path / "scene.pbrt"
        path.write_text(CAMERA + "WorldBegin\n" + glass + "AttributeBegin\nScale -1 1 1\n" + light + mesh +
                        "AttributeEnd\n" + ("" if version == "v4" else "WorldEnd\n"))
        _agrees(_through_the_sheet(import_pbrt(path, dialect=version).scene),
                (0.5 if light else 0.0) + (1 - _fresnel(np.cos(INCIDENCE), ETA)) * BELOW)
