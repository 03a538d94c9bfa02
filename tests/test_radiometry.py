"""The estimate is unbiased: rendered irradiance against values derived independently of the renderer."""

import math

import numpy as np
import pytest

from realistic import load_lens
from realistic import render as render_image
from realistic.camera.lens_camera import LensCamera
from realistic.core.transforms import rotate, scale, translate
from realistic.optics.paraxial import film_distance_for_focus, paraxial_data
from realistic.optics.sampling import rear_surface_depths_mm
from realistic.optics.tracer import trace_from_film
from realistic.renderer.direct_lighting import DirectLighting
from realistic.renderer.job import RenderJob
from realistic.renderer.passes import ThreadPasses, render
from realistic.scene.intersect import Intersector
from realistic.scene.model import AreaLight, Material, Scene
from realistic.scene.shapes import quad

RHO, L, R, H = 0.6, 10.0, 2.0, 1.5  # albedo, light radiance, disk radius, disk height


def lit_plane(light_shape: str = "disk") -> Scene:
    """A diffuse plane z = 0 (facing +z) under a uniform emitter at height H facing down."""
    scene = Scene()
    scene.add(quad(200.0, 200.0), material=Material((RHO, RHO, RHO)))
    size = (R, R) if light_shape == "disk" else (2 * R, R)
    scene.lights.append(AreaLight(light_shape, size, (L, L, L), translate(0, 0, H) @ rotate(180, (1, 0, 0))))
    return scene


def disk_irradiance(x: float) -> float:
    """Irradiance at horizontal distance x from below the centre of a disk (radius R, height H, radiance L)."""
    a = H * H + x * x - R * R
    return math.pi * L / 2 * (1 - a / math.sqrt((H * H + x * x + R * R) ** 2 - 4 * R * R * x * x))


def shade_points(scene: Scene, xs: np.ndarray, light_samples: int = 1) -> np.ndarray:
    """Mean radiance leaving the plane at (x, 0, 0) toward +z over many samples."""
    integrator = DirectLighting(scene, Intersector(scene), light_samples, seed=3)
    n = 40_000
    values = []
    for i, x in enumerate(xs):
        origin = np.tile([x, 0.0, 0.5], (n, 1)).astype(np.float32)
        direction = np.tile([0.0, 0.0, -1.0], (n, 1)).astype(np.float32)
        pixel = np.full(n, i)
        radiance, shadow = integrator.radiance(origin, direction, pixel, np.arange(n))
        values.append(radiance.mean(axis=0))
    return np.array(values)


def test_disk_formula_matches_its_on_axis_closed_form():
    assert disk_irradiance(0.0) == pytest.approx(math.pi * L * R * R / (R * R + H * H), rel=1e-12)


def test_direct_lighting_from_a_disk_matches_the_analytic_irradiance():
    xs = np.array([0.0, 1.0, 2.5])
    got = shade_points(lit_plane(), xs)
    expected = np.array([RHO / math.pi * disk_irradiance(x) for x in xs])
    np.testing.assert_allclose(got[:, 0], expected, rtol=0.02)
    assert np.all(got[:, 0] == got[:, 1])


def test_more_light_samples_keep_the_mean_and_lower_the_noise():
    one = shade_points(lit_plane(), np.array([1.0]), 1)[0, 0]
    four = shade_points(lit_plane(), np.array([1.0]), 4)[0, 0]
    assert four == pytest.approx(one, rel=0.02)
    assert four == pytest.approx(RHO / math.pi * disk_irradiance(1.0), rel=0.01)


def test_direct_lighting_from_a_quad_matches_quadrature():
    x0 = 0.7
    # midpoint quadrature over the 2R x R rectangle: E = L * integral of cos cos' / d^2 dA
    n = 800
    gx = (np.arange(n) + 0.5) / n * 2 * R - R
    gy = (np.arange(n) + 0.5) / n * R - R / 2
    px, py = np.meshgrid(gx, gy)
    d2 = (px - x0) ** 2 + py**2 + H * H
    irradiance = L * np.sum(H * H / d2**2) * (2 * R / n) * (R / n)
    got = shade_points(lit_plane("quad"), np.array([x0]))[0, 0]
    assert got == pytest.approx(RHO / math.pi * irradiance, rel=0.02)


def test_emitters_are_one_sided_and_seen_directly():
    scene = lit_plane()
    integrator = DirectLighting(scene, Intersector(scene))
    origin = np.array([[0.0, 0.0, 0.5], [0.0, 0.0, 3.0]], np.float32)
    direction = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, -1.0]], np.float32)
    radiance, _ = integrator.radiance(origin, direction, np.zeros(2, int), np.arange(2))
    np.testing.assert_array_equal(radiance[0], [L, L, L])  # below the light: its emitting side
    np.testing.assert_array_equal(radiance[1], [0, 0, 0])  # from above: the disk's dark back hides the plane


def test_occluder_casts_a_shadow():
    scene = lit_plane()
    scene.add(quad(1.0, 1.0), translate(0, 0, 0.7), Material((0.5, 0.5, 0.5)))
    lit = shade_points(lit_plane(), np.array([0.0]))[0, 0]
    shadowed = shade_points(scene, np.array([0.0]))[0, 0]
    assert shadowed < 0.9 * lit


def camera_looking_down(lens_name: str, stop_mm: float, width: int, height: int, spp: int, diagonal_mm: float,
                        eye_height: float = 1.0):
    lens = load_lens(lens_name).with_stop_diameter(stop_mm)
    film = film_distance_for_focus(lens, eye_height * 1000.0)
    world = translate(0, 0, eye_height) @ rotate(180, (1, 0, 0)) @ scale(1e-3)  # camera +z -> world -z
    return lens, LensCamera(lens, film, diagonal_mm, width, height, spp, world)


def test_tiny_aperture_film_irradiance_is_radiance_times_exit_pupil_solid_angle():
    lens, camera = camera_looking_down("dgauss", 1.0, 5, 5, 2048, 1.0)
    image = render_image(lit_plane(), camera, "numpy", seed=1, pass_samples=1 << 16)
    radiance = RHO / math.pi * disk_irradiance(0.0)
    p = paraxial_data(lens)
    z_exit = camera.film_distance_mm - p.exit_pupil_mm  # film to exit pupil (exit_pupil_mm is + toward film)
    solid_angle = math.pi * (p.exit_pupil_diameter_mm / 2) ** 2 / z_exit**2
    assert image[..., 0].mean() == pytest.approx(radiance * solid_angle, rel=0.02)


def uniform_emitter_scene() -> Scene:
    """A huge emitter of radiance 1 filling the view of a camera looking along world -z from z = 1."""
    scene = Scene()
    scene.lights.append(AreaLight("quad", (1e4, 1e4), (1.0, 1.0, 1.0), translate(0, 0, -50.0)))
    return scene


def irradiance_by_quadrature(lens, film_distance_mm: float, film_x_mm: float, plane_z_mm: float = 20.0,
                             grid: int = 600) -> float:
    """Film irradiance per unit radiance at (film_x_mm, 0): the integral of cos^4(theta) / z^2 over
    the points of the plane z = plane_z_mm whose rays pass the lens (reference tracer), by the
    midpoint rule over a square around the paraxial exit pupil's image three times its size."""
    p = paraxial_data(lens)
    z_exit = film_distance_mm - p.exit_pupil_mm
    centre = film_x_mm * (1 - plane_z_mm / z_exit)
    half = 1.5 * p.exit_pupil_diameter_mm * plane_z_mm / z_exit
    steps = (np.arange(grid) + 0.5) / grid * 2 * half - half
    x, y = (a.ravel() for a in np.meshgrid(centre + steps, steps))
    directions = np.column_stack([x - film_x_mm, y, np.full(x.size, plane_z_mm)])
    origins = np.zeros_like(directions)
    origins[:, 0] = film_x_mm
    passed = trace_from_film(lens, film_distance_mm, origins, directions).passed.reshape(grid, grid)
    assert not (passed[0].any() or passed[-1].any() or passed[:, 0].any() or passed[:, -1].any())
    cos_theta = plane_z_mm / np.linalg.norm(directions, axis=1).reshape(grid, grid)
    return float(np.sum(passed * cos_theta**4) * (2 * half / grid) ** 2 / plane_z_mm**2)


def test_tiny_aperture_falls_off_as_cos4_across_the_film():
    """The rendered falloff equals the irradiance integrated over the exact passing directions; that
    in turn is the cos^4 law to the paraxial exit pupil within the lens's pupil aberration."""
    width = 41
    lens, camera = camera_looking_down("dgauss", 1.0, width, 1, 2048, 30.0)
    image = render_image(uniform_emitter_scene(), camera, "numpy", seed=2, pass_samples=1 << 16)[0, :, 0]
    p = paraxial_data(lens)
    z_exit = camera.film_distance_mm - p.exit_pupil_mm
    pixel_mm = camera.film_size_mm[0] / width
    film_x = (np.arange(width) + 0.5 - width / 2) * pixel_mm
    cos4 = np.cos(np.arctan(np.abs(film_x) / z_exit)) ** 4
    centre = width // 2
    exact_centre = irradiance_by_quadrature(lens, camera.film_distance_mm, 0.0)
    for k in (centre + 8, centre + 14, centre + 20):
        exact = irradiance_by_quadrature(lens, camera.film_distance_mm, film_x[k]) / exact_centre
        assert image[k] / image[centre] == pytest.approx(exact, rel=0.012), k
        assert exact == pytest.approx(cos4[k], rel=0.025), k
    assert cos4[-1] < 0.93  # the test spans a real falloff


def quadrature_irradiance(lens, film_distance_mm: float, film_x_mm: float, n: int = 500) -> float:
    """E = integral over directions the lens passes of cos(theta) d omega, on a grid over the rear plane."""
    near, far = rear_surface_depths_mm(lens, film_distance_mm)
    half = lens.aperture_mm[-1] / 2 + abs(film_x_mm) * (1 - near / far) + 1.0  # covers the rear cap
    g = (np.arange(n) + 0.5) / n * 2 * half - half
    gx, gy = np.meshgrid(g, g)
    targets = np.column_stack([gx.ravel(), gy.ravel(), np.full(n * n, near)])
    film = np.tile([film_x_mm, 0.0, 0.0], (n * n, 1))
    passed = trace_from_film(lens, film_distance_mm, film, targets - film).passed
    delta = targets - film
    cos = delta[:, 2] / np.linalg.norm(delta, axis=1)
    return float(np.sum(cos[passed] ** 4) / near**2 * (2 * half / n) ** 2)


@pytest.mark.parametrize("sampling", ["pupil", "rear"])
def test_wide_aperture_film_irradiance_matches_quadrature(sampling):
    width = 41
    lens = load_lens("dgauss")
    film = film_distance_for_focus(lens, 1000.0)
    world = translate(0, 0, 1.0) @ rotate(180, (1, 0, 0)) @ scale(1e-3)
    camera = LensCamera(lens, film, 40.0, width, 1, 2048, world, lens_sampling=sampling)
    image = render_image(uniform_emitter_scene(), camera, "numpy", seed=4, pass_samples=1 << 17)[0, :, 0]
    pixel_mm = camera.film_size_mm[0] / width
    centre = width // 2
    expected = {k: quadrature_irradiance(lens, film, k * pixel_mm) for k in (0, 7, 13, 19)}
    for k, value in expected.items():
        assert image[centre + k] == pytest.approx(value, rel=0.02), k
    # vignetting makes the wide-open falloff steeper than cos^4 alone
    assert expected[19] / expected[0] < 0.8


def test_render_is_independent_of_pass_size_and_thread_count():
    _, camera = camera_looking_down("dgauss", 4.0, 6, 4, 8, 20.0)
    a = render(RenderJob(lit_plane(), (camera,), "numpy", seed=9, pass_samples=50), ThreadPasses(threads=2))[0].image
    b = render(RenderJob(lit_plane(), (camera,), "numpy", seed=9, pass_samples=1000), ThreadPasses(threads=1))[0].image
    np.testing.assert_allclose(a, b, rtol=1e-5, atol=1e-9)
    assert a.max() > 0


def test_the_default_thread_count_is_one_per_usable_core(monkeypatch):
    from realistic.renderer import thread_count

    monkeypatch.setattr(thread_count.os, "sched_getaffinity", lambda pid: {0, 3, 5}, raising=False)
    assert thread_count.default_threads() == 3
    monkeypatch.delattr(thread_count.os, "sched_getaffinity", raising=False)  # as on macOS and Windows
    monkeypatch.setattr(thread_count.os, "cpu_count", lambda: 6)
    assert thread_count.default_threads() == 6


def test_a_render_given_no_thread_count_runs_the_default_and_matches_one_thread(monkeypatch, thread_pools):
    from realistic.renderer import passes

    monkeypatch.setattr(passes, "default_threads", lambda: 5)
    _, camera = camera_looking_down("dgauss", 4.0, 6, 4, 8, 20.0)
    default = render(RenderJob(lit_plane(), (camera,), "numpy", seed=9, pass_samples=50))[0].image
    one = render(RenderJob(lit_plane(), (camera,), "numpy", seed=9, pass_samples=50), ThreadPasses(threads=1))[0].image
    assert [threads for threads, _ in thread_pools] == [5, 1]
    np.testing.assert_array_equal(default, one)  # pass sums are added in pass order: bit-identical
    assert default.max() > 0


def test_opencl_and_numpy_backends_render_the_same_image():
    from realistic.errors import UserError

    _, camera = camera_looking_down("dgauss", 6.0, 40, 30, 16, 20.0)
    reference = render_image(lit_plane(), camera, "numpy", seed=5, pass_samples=4096)
    try:
        for _ in range(2):  # passes run on several threads: the generator must not mix them up
            image = render_image(lit_plane(), camera, "opencl", seed=5, pass_samples=4096)
            np.testing.assert_allclose(image, reference, rtol=1e-3, atol=1e-6)
    except UserError as err:
        pytest.skip(f"OpenCL backend unavailable: {err}")
