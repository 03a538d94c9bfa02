"""pbrt area lights on shapes other than disks: they emit through ``EmissiveInstance``.

Closed forms: a sphere of radius R and radiance L whose centre lies at distance d along the normal
of a plane gives E = pi L (R / d)^2 there (it fills a cone of half-angle asin(R / d)); a rectangle
of radiance L with a corner right above the point, sides a, b at height h, gives the point-to-
rectangle form factor F = (A / sqrt(1 + A^2) atan(B / sqrt(1 + A^2)) + B / sqrt(1 + B^2) atan(A /
sqrt(1 + B^2))) / (2 pi), A = a / h, B = b / h, and E = pi L F. A Lambertian plane of albedo k
under irradiance E reflects k E / pi.
"""

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from realistic.errors import UserError
from realistic.renderer.direct_lighting import DirectLighting
from realistic.renderer.integrators import make_integrator
from realistic.renderer.path import PathIntegrator
from realistic.scene.intersect import Intersector
from realistic.scene.lights import EmissiveInstance
from realistic.scene.model import AreaLight
from realistic.scene.pbrt.importer import import_pbrt

N = 40000
CAMERA = 'Film "image" "integer xresolution" [8] "integer yresolution" [8]\nCamera "perspective" "float fov" 40\n'
FLOOR = ('Material "matte" "rgb Kd" [0.5 0.5 0.5]\n'
         'Shape "trianglemesh" "point P" [-50 -50 0 50 -50 0 50 50 0 -50 50 0] "integer indices" [0 1 2 0 2 3]\n')
BLACK = 'Material "matte" "rgb Kd" [0 0 0]\n'


def _import(tmp_path, world: str, head: str = ""):
    path = tmp_path / "scene.pbrt"
    path.write_text(head + CAMERA + "WorldBegin\n" + world + "WorldEnd\n")
    return import_pbrt(path)


def _seen(scene, origin, target, depth: int = 1) -> tuple[float, float]:
    """Mean radiance (channel 0) and its standard error along N rays from ``origin`` to ``target``."""
    direction = np.asarray(target, float) - origin
    d = np.tile(direction / np.linalg.norm(direction), (N, 1)).astype(np.float32)
    o = np.tile(origin, (N, 1)).astype(np.float32)
    integrator = make_integrator(scene, Intersector(scene), 1, 7)
    integrator.max_depth = depth
    radiance, _ = integrator.radiance(o, d, np.arange(N), np.zeros(N, int))
    values = radiance[:, 0].astype(np.float64)
    return float(values.mean()), float(values.std() / math.sqrt(N))


def _square(size: float, height: float, facing_down: bool) -> str:
    s = size / 2
    order = "0 2 1 0 3 2" if facing_down else "0 1 2 0 2 3"
    return (f'Shape "trianglemesh" "point P" [{-s} {-s} {height} {s} {-s} {height} {s} {s} {height} '
            f'{-s} {s} {height}] "integer indices" [{order}]\n')


def _rectangle_irradiance(a: float, b: float, h: float, radiance: float) -> float:
    big_a, big_b = a / h, b / h
    f = (big_a / math.sqrt(1 + big_a ** 2) * math.atan(big_b / math.sqrt(1 + big_a ** 2))
         + big_b / math.sqrt(1 + big_b ** 2) * math.atan(big_a / math.sqrt(1 + big_b ** 2))) / (2 * math.pi)
    return math.pi * radiance * f


@pytest.mark.parametrize("integrator", ["directlighting", "path"])
def test_emitting_sphere_lights_a_plane_as_the_closed_form(tmp_path, integrator):
    radius, d, radiance, albedo = 0.5, 2.0, 3.0, 0.5
    world = (FLOOR + "AttributeBegin\n" + BLACK +
             f'AreaLightSource "diffuse" "rgb L" [{radiance} {radiance} {radiance}]\n'
             f'Translate 0 0 {d}\nShape "sphere" "float radius" {radius}\nAttributeEnd\n')
    imported = _import(tmp_path, world, f'Integrator "{integrator}" "integer maxdepth" [1]\n')
    scene = imported.scene
    (light,) = scene.lights
    assert isinstance(light, EmissiveInstance) and not imported.warnings
    expected = albedo / math.pi * math.pi * radiance * (radius / d) ** 2
    mean, error = _seen(scene, np.array([5.0, 0.0, 1.0]), [0.0, 0.0, 0.0])
    assert abs(mean - expected) < 4 * error + 2e-3 * expected


@pytest.mark.parametrize("facing_down,two_sided,reverse,lit", [
    (True, False, False, True), (False, False, False, False), (False, True, False, True),
    (False, False, True, True), (True, False, True, False)])
def test_triangle_mesh_emitter_front_back_and_two_sided(tmp_path, facing_down, two_sided, reverse, lit):
    size, h, radiance, albedo = 2.0, 1.0, 2.0, 0.5
    flag = '"bool twosided" true' if two_sided else ""
    world = (FLOOR + "AttributeBegin\n" + BLACK + ("ReverseOrientation\n" if reverse else "") +
             f'AreaLightSource "diffuse" "rgb L" [{radiance} {radiance} {radiance}] {flag}\n' +
             _square(size, h, facing_down) + "AttributeEnd\n")
    scene = _import(tmp_path, world).scene
    expected = albedo / math.pi * 4 * _rectangle_irradiance(size / 2, size / 2, h, radiance) if lit else 0.0
    mean, error = _seen(scene, np.array([0.3, 0.0, 0.5]), [0.0, 0.0, 0.0])
    assert abs(mean - expected) < 4 * error + 2e-3 * max(expected, 1.0)
    # a camera ray from below sees L on a front (or two-sided) face, nothing on a one-sided back
    seen, _ = _seen(scene, np.array([0.1, 0.2, 0.5]), [0.1, 0.2, 2.0], depth=0)
    assert seen == pytest.approx(radiance if lit else 0.0, abs=1e-5)


def test_camera_rays_see_the_sphere_radiance_on_its_front_only(tmp_path):
    world = (BLACK + 'AreaLightSource "diffuse" "rgb L" [1 2 3]\nShape "sphere" "float radius" 1\n')
    scene = _import(tmp_path, world).scene
    outside, _ = _seen(scene, np.array([0.0, 0.1, 5.0]), [0.0, 0.1, 0.0], depth=0)
    inside, _ = _seen(scene, np.array([0.0, 0.1, 0.2]), [0.0, 0.1, 5.0], depth=0)
    assert outside == pytest.approx(1.0, abs=1e-5) and inside == 0.0


def test_disk_area_lights_stay_area_lights_on_the_fast_path(tmp_path):
    world = (FLOOR + 'AttributeBegin\nAreaLightSource "diffuse" "rgb L" [1 1 1]\nTranslate 0 0 2\n'
             'Shape "disk" "float radius" 0.5\nAttributeEnd\n')
    scene = _import(tmp_path, world, 'Integrator "directlighting"\n').scene
    assert [type(light) for light in scene.lights] == [AreaLight]
    assert type(make_integrator(scene, Intersector(scene))) is DirectLighting
    world = world.replace('"disk" "float radius" 0.5', '"sphere" "float radius" 0.5')
    scene = _import(tmp_path, world).scene
    assert type(make_integrator(scene, Intersector(scene))) is PathIntegrator


def test_unsupported_emission_is_reported_with_file_and_line(tmp_path):
    world = ('AreaLightSource "diffuse" "rgb L" [1 1 1] "float power" 10\n'
             'Shape "sphere" "float radius" 1 "float zmax" 0.5\n'
             'AreaLightSource "goniometric"\nShape "cylinder"\n')
    imported = _import(tmp_path, world)
    text = "\n".join(imported.warnings)
    assert 'scene.pbrt:4: unsupported: area light "power"' in text
    assert "scene.pbrt:5: unsupported: partial sphere" in text
    assert 'scene.pbrt:6: unsupported: AreaLightSource "goniometric"' in text
    assert [type(light) for light in imported.scene.lights] == [EmissiveInstance]


def test_mirrored_triangle_mesh_keeps_its_object_space_front(tmp_path):
    """pbrt flips a triangle's winding normal under a handedness-swapping transform, so a mirrored
    mesh emits on the side its object-space winding names (here down, toward the floor)."""
    world = (FLOOR + "AttributeBegin\n" + BLACK + 'AreaLightSource "diffuse" "rgb L" [1 1 1]\nScale 1 -1 1\n' +
             _square(2.0, 1.0, True) + "AttributeEnd\n")
    scene = _import(tmp_path, world).scene
    mean, _ = _seen(scene, np.array([0.3, 0.0, 0.5]), [0.0, 0.0, 0.0])
    assert mean > 0.1


@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(shape=st.sampled_from(['"sphere" "float radius" {r}', '"cylinder" "float radius" {r}',
                              '"cone" "float radius" {r}', '"trianglemesh" "point P" [0 0 0 {r} 0 0 0 {r} 0] '
                              '"integer indices" [0 1 2]', '"curve"', '"bilinearmesh" "point P" '
                              '[0 0 0 {r} 0 0 0 {r} 0 {r} {r} 0] "integer indices" [0 1 2 3]']),
       r=st.one_of(st.floats(-1e30, 1e30, allow_nan=False), st.just(0.0)),
       light=st.sampled_from(['"rgb L" [1 1 1]', '"rgb L" [-1 nan 1]', '"blackbody L" 5000', '"bool twosided" "x"',
                              '"rgb scale" [1e40 1 1]', '"rgb L" [1 1]']),
       reverse=st.booleans(), squash=st.sampled_from(["", "Scale 1 1 0\n", "Scale 1 -1 1\n", "Scale 1e-200 1 1\n"]))
def test_area_lights_on_any_shape_import_or_fail_in_one_line(tmp_path, shape, r, light, reverse, squash):
    world = ("ReverseOrientation\n" if reverse else "") + squash + f'AreaLightSource "diffuse" {light}\n' + \
        f"Shape {shape.format(r=r)}\n"
    try:
        scene = _import(tmp_path, world).scene
    except UserError as error:
        assert "\n" not in str(error) and "scene.pbrt" in str(error)
        return
    for light in scene.lights:
        assert isinstance(light, EmissiveInstance) and 0 <= light.instance < len(scene.instances)
        inst = scene.instances[light.instance]
        corners = (scene.meshes[inst.mesh].vertices @ inst.transform[:3, :3].T)[scene.meshes[inst.mesh].faces]
        area = np.linalg.norm(np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]), axis=1).sum()
        assert 0 < area < np.inf


def test_reversed_sphere_emits_inward(tmp_path):
    """ReverseOrientation turns a sphere's emitting side inward (pbrt-v4 src/pbrt/shapes.h: a quadric's
    normal is its object-space outside, flipped by ReverseOrientation)."""
    world = (BLACK + 'ReverseOrientation\nAreaLightSource "diffuse" "rgb L" [1 2 3]\nShape "sphere" "float radius" 1\n')
    scene = _import(tmp_path, world).scene
    outside, _ = _seen(scene, np.array([0.0, 0.1, 5.0]), [0.0, 0.1, 0.0], depth=0)
    inside, _ = _seen(scene, np.array([0.0, 0.1, 0.2]), [0.0, 0.1, 5.0], depth=0)
    assert outside == 0.0 and inside == pytest.approx(1.0, abs=1e-5)


def test_equal_emitting_spheres_share_one_tessellation(tmp_path):
    """A thousand equal spheres are one mesh placed a thousand times (and its reversed twin), not a
    thousand 65536-triangle copies: this is what let 2000 emissive spheres take 27 s of import and
    30 GiB of estimated geometry before the memory refusal (issue 32)."""
    spheres = "".join(f'AttributeBegin\n{"ReverseOrientation" if i % 3 == 0 else ""}\nTranslate {i} 0 0\n'
                      f'AreaLightSource "diffuse" "rgb L" [1 1 1]\nShape "sphere" "float radius" 0.25\n'
                      f'AttributeEnd\n' for i in range(60))
    scene = _import(tmp_path, BLACK + spheres + 'Shape "sphere" "float radius" 0.5\n').scene
    assert len(scene.lights) == 60 and len(scene.instances) == 61
    assert len(scene.meshes) == 3  # radius 0.25, its reversed twin, radius 0.5
    small, reversed_small = (scene.meshes[scene.instances[i].mesh] for i in (1, 0))
    assert small is not reversed_small
    np.testing.assert_array_equal(reversed_small.faces, small.faces[:, ::-1])
    np.testing.assert_array_equal(reversed_small.vertices, small.vertices)
