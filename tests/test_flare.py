"""Lens flare (``realistic.renderer.flare``): the light-tracing estimator's normalisation against the
camera's own rays, the ghosts' symmetry and motion, and flare in the render (options, executors,
checkpoints)."""

import dataclasses
import math

import numpy as np
import pytest

from realistic import load_lens, render
from realistic.camera.base import SampleBlock
from realistic.camera.lens_camera import LensCamera
from realistic.camera.thin_lens import ThinLensCamera
from realistic.core.transforms import translate
from realistic.errors import UserError
from realistic.optics.ghosts import ghost_paths as lens_ghost_paths
from realistic.renderer.backends import NumpyBackend, backend_for
from realistic.renderer.checkpoint import checkpoint_path
from realistic.renderer.flare import FlareEstimator, direct_path, ghost_paths
from realistic.renderer.inputs import RenderOptions, build_render_inputs
from realistic.renderer.job import Checkpointing, RenderJob
from realistic.renderer.passes import ThreadPasses, scene_intersector
from realistic.renderer.passes import render as render_job
from realistic.renderer.runner import PassRunner
from realistic.renderer.timing import StageClock
from realistic.scene.lights import DistantLight, EmissiveInstance, PointLight, SpotLight
from realistic.scene.materials import Material
from realistic.scene.model import AreaLight, Scene
from realistic.scene.shapes import sphere
from test_job import InterruptedAfterThirdTask, NewestFirstWithRetries

WIDTH, HEIGHT = 40, 30
#: Independent batches each estimate is split into, for its standard error.
BATCHES = 6


def _scene(x: float = 0.0, y: float = 0.0, coating: str = "none", spp: int = 16,
           size: tuple[int, int] = (WIDTH, HEIGHT)) -> tuple[Scene, LensCamera]:
    """A disk light 3 cm across facing a dgauss camera 1 m away, at (x, y) m off the axis."""
    lens = load_lens("dgauss").with_coating(coating)
    camera = LensCamera.looking_at(lens, np.zeros(3), np.array([0.0, 0.0, -1.0]), width=size[0], height=size[1],
                                   spp=spp)
    scene = Scene(lights=[AreaLight("disk", (0.015, 0.015), (1.0, 1.0, 1.0), translate(x, y, -1.0))], camera=camera)
    return scene, camera


def _traced(scene: Scene, camera: LensCamera, paths: list, batch: int) -> np.ndarray:
    """The light-traced image (H, W, 3) of ``paths`` from the spp samples of batch ``batch`` of
    every pixel (samples batch spp .. (batch + 1) spp - 1: numbers independent of other batches')."""
    estimator = FlareEstimator(scene, camera, scene_intersector(scene), 0, paths)
    block = SampleBlock.of_pixels(0, camera.width * camera.height, batch * camera.spp, camera.spp)
    splats = estimator.splats(block)
    image = np.zeros((camera.width * camera.height, 3))
    image[splats.pixel] = splats.value / block.count
    return image.reshape(camera.height, camera.width, 3)


def _mean_and_error(values: list[float]) -> tuple[float, float]:
    """The mean of independent estimates and its standard error."""
    return float(np.mean(values)), float(np.std(values, ddof=1) / math.sqrt(len(values)))


def test_light_traced_direct_path_is_the_camera_render_of_a_small_light():
    """Light tracing the ordinary path through the lens gives the film irradiance the camera's rays
    give (cos^4 A / Z^2 weights, Fresnel transmittance of bare glass), summed over the image and over
    the pixels the light covers, to within both estimates' noise."""
    scene, camera = _scene(0.06, 0.03)
    tracer = NumpyBackend().ghost_tracer(camera.lens)
    traced = [_traced(scene, camera, [direct_path(camera, tracer)], batch)[..., 1] for batch in range(BATCHES)]
    rendered = [np.asarray(render(scene, camera, "numpy", seed=batch))[..., 1] for batch in range(BATCHES)]
    covered = np.mean(rendered, axis=0) > 0
    assert 4 < covered.sum() < 100  # a small light, away from the centre
    for region in (np.ones_like(covered), covered):
        light, light_error = _mean_and_error([image[region].sum() for image in traced])
        camera_value, camera_error = _mean_and_error([image[region].sum() for image in rendered])
        assert light_error < 0.02 * light  # the comparison is tight enough to mean something
        assert abs(light - camera_value) < 4 * math.hypot(light_error, camera_error) + 0.005 * camera_value, (
            light, camera_value)  # 0.5 %: the camera sees the disk as a 64-gon


def test_point_spot_and_distant_lights_bring_the_flux_of_the_area_light_they_stand_for():
    """Through the direct path, a point light of intensity L A and a spot light pointing at the lens
    bring what the small disk of radiance L and area A brings (which the camera's render checks
    above); a distant light of irradiance E what a point light of intensity E D^2 brings from a
    distance D far beyond the lens."""
    scene, camera = _scene(coating="ideal", spp=8)
    disk = scene.lights[0]
    direct = [direct_path(camera, NumpyBackend().ghost_tracer(camera.lens))]

    def brought(light: object) -> tuple[float, float]:
        scene.lights = [light]
        return _mean_and_error([_traced(scene, camera, direct, batch)[..., 1].sum() for batch in range(BATCHES)])

    reference, reference_error = brought(disk)
    intensity = (disk.area(),) * 3
    toward_lens = translate(0.0, 0.0, -1.0)  # the spot at z = -1, its axis (+z) toward the camera
    for light in (PointLight(intensity, np.array([0.0, 0.0, -1.0])),
                  SpotLight(intensity, toward_lens, math.cos(math.radians(30)), math.cos(math.radians(20)))):
        value, error = brought(light)
        assert abs(value - reference) < 4 * math.hypot(error, reference_error) + 1e-3 * reference, (light, value)
    far = 1000.0
    value, error = brought(DistantLight((1.0, 1.0, 1.0), np.array([0.0, 0.0, -1.0])))
    point, point_error = brought(PointLight((far * far,) * 3, np.array([0.0, 0.0, -far])))
    assert value > 0 and abs(value - point) < 4 * math.hypot(error, point_error) + 1e-3 * point


def test_an_emitting_sphere_brings_the_flux_of_a_point_light_of_its_projected_area():
    """Through the direct path, a small emitting sphere (a pbrt AreaLightSource on a sphere: points
    drawn by area on its triangles, occluded by nothing but itself) of radiance L and radius r brings
    what a point light of intensity L pi r^2 brings; its 256-segment mesh's projected area is within
    1e-3 of the circle's."""
    scene, camera = _scene(coating="ideal", spp=8)
    radius = 0.015
    direct = [direct_path(camera, NumpyBackend().ghost_tracer(camera.lens))]

    def brought(scene: Scene) -> tuple[float, float]:
        return _mean_and_error([_traced(scene, camera, direct, batch)[..., 1].sum() for batch in range(BATCHES)])

    emitting = Scene(camera=camera)
    emitting.add(sphere(radius, segments=256), translate(0.0, 0.0, -1.0), Material((0.0, 0.0, 0.0)))
    emitting.lights.append(EmissiveInstance(0, (1.0, 1.0, 1.0)))
    value, error = brought(emitting)
    point, point_error = brought(Scene(lights=[PointLight((math.pi * radius ** 2,) * 3, np.array([0.0, 0.0, -1.0]))],
                                       camera=camera))
    assert value > 0 and abs(value - point) < 4 * math.hypot(error, point_error) + 2e-3 * point, (value, point)


def _centroid(image: np.ndarray) -> np.ndarray:
    """The luminance-weighted centroid (x, y) of an image, from its centre, in pixels."""
    weight = image.sum(axis=2)
    ys, xs = np.indices(weight.shape) + 0.5
    return np.array([(weight * xs).sum(), (weight * ys).sum()]) / weight.sum() - [weight.shape[1] / 2,
                                                                                   weight.shape[0] / 2]


def _ghosts(x: float, y: float, paths: slice = slice(None)) -> tuple[list[list[np.ndarray]], np.ndarray]:
    """Per ghost path (of the brightest, ``paths``), its images (batches) of the light at (x, y); and
    the centroid of the light's direct image."""
    scene, camera = _scene(x, y, spp=32, size=(48, 36))
    tracer = NumpyBackend().ghost_tracer(camera.lens)
    ghosts = ghost_paths(camera, 1e-4, tracer)
    assert len(ghosts) > 10
    direct = _traced(scene, camera, [direct_path(camera, tracer)], 0)
    return [[_traced(scene, camera, [ghost], batch) for batch in range(BATCHES)] for ghost in ghosts[paths]], \
        _centroid(direct)


@pytest.mark.usefixtures("opencl_platform")
def test_the_opencl_backend_lands_the_flare_where_the_float64_reference_does():
    """The same light paths (same numbers) through ``kernels/ghost.cl`` and through the reference."""
    scene, camera = _scene(0.05, 0.03, spp=8)
    images = [_traced(scene, camera, ghost_paths(camera, 1e-4, backend_for(name).ghost_tracer(camera.lens)), 0)
              for name in ("numpy", "opencl")]
    assert images[0].sum() > 0
    np.testing.assert_allclose(images[1].sum(), images[0].sum(), rtol=1e-3)
    assert np.abs(images[1] - images[0]).sum() < 0.01 * images[0].sum()  # a path or two crosses a pixel edge


def test_an_on_axis_light_has_ghosts_symmetric_about_the_image_centre():
    scene, camera = _scene(spp=32, size=(48, 36))
    tracer = NumpyBackend().ghost_tracer(camera.lens)
    assert np.all(np.abs(_centroid(_traced(scene, camera, [direct_path(camera, tracer)], 0))) < 0.05)
    images = [_traced(scene, camera, ghost_paths(camera, 1e-4, tracer), batch) for batch in range(BATCHES)]
    for axis in (0, 1):  # the halves either side of each axis through the centre carry the same light
        halves = [np.array_split(image, 2, axis=axis) for image in images]
        first, first_error = _mean_and_error([h[0].sum() for h in halves])
        second, second_error = _mean_and_error([h[1].sum() for h in halves])
        assert first > 0 and abs(first - second) < 4 * math.hypot(first_error, second_error) + 1e-3 * first
    rotated, rotated_error = _mean_and_error([float(np.abs(i - i[::-1, ::-1]).sum() / i.sum()) for i in images])
    noise, _ = _mean_and_error([float(np.abs(a - b).sum() / a.sum()) for a, b in zip(images, images[1:])])
    assert rotated < noise + 4 * rotated_error  # turned half a turn, an image differs only by its noise


def _across(vector: np.ndarray, line: np.ndarray) -> float:
    """The distance of the point ``vector`` from the line through 0 along ``line``."""
    return float(abs(vector[0] * line[1] - vector[1] * line[0]) / np.linalg.norm(line))


def test_ghosts_move_with_the_light_along_the_line_through_the_centre():
    """The lens is symmetric about the plane through its axis and the light, so a ghost wholly on
    the film is symmetric about the line through the image centre and the light's image: its
    centroid lies on that line, and moves along it as the light moves."""
    found: dict[int, list[tuple[np.ndarray, float]]] = {}
    for scale in (1.0, 2.0):
        ghosts, light = _ghosts(0.05 * scale, 0.03 * scale, slice(0, 4))
        for index, images in enumerate(ghosts):
            if any(np.any(image[[0, -1]]) or np.any(image[:, [0, -1]]) for image in images):
                continue  # cut by the frame's edge: no longer symmetric about the line
            centroids = np.array([_centroid(image) for image in images])
            centre = centroids.mean(axis=0)
            error = float(np.linalg.norm(centroids.std(axis=0, ddof=1)) / math.sqrt(len(centroids)))
            assert _across(centre, light) < 4 * error + 0.02, (index, centre, light)
            found.setdefault(index, []).append((centre, error))
    moving = [where for where in found.values() if len(where) == 2]
    assert moving  # at least one ghost lies inside the frame at both positions
    for (first, first_error), (second, second_error) in moving:
        moved = second - first
        assert np.linalg.norm(moved) > max(1.0, 8 * math.hypot(first_error, second_error))  # pixels
        assert _across(moved, light) < 4 * math.hypot(first_error, second_error) + 0.02


def test_the_ideal_coating_has_no_flare_and_flare_off_changes_nothing():
    scene, camera = _scene(0.05, 0.03, coating="ideal", spp=4)
    assert lens_ghost_paths(camera.lens) == []
    off = render(scene, camera, "numpy")
    np.testing.assert_array_equal(render(scene, camera, "numpy", flare=True), off)
    scene, camera = _scene(0.05, 0.03, spp=4)
    job = RenderJob(scene, (camera,), "numpy")
    block = SampleBlock.of_pixels(0, WIDTH * HEIGHT, 0, 4)
    without = PassRunner(scene, camera, job.settings, StageClock())(0, block)
    with_flare = PassRunner(scene, camera, dataclasses.replace(job, flare=True).settings, StageClock())(0, block)
    assert without.flare is None and with_flare.flare is not None and with_flare.flare.value.sum() > 0
    np.testing.assert_array_equal(with_flare.sums, without.sums)  # the camera's estimate is untouched
    assert (with_flare.primary_rays, with_flare.shadow_rays) == (without.primary_rays, without.shadow_rays)


def test_flare_is_bit_identical_whatever_the_executor_and_pass_order():
    scene, camera = _scene(0.05, 0.03, spp=6, size=(12, 10))
    job = RenderJob(scene, (camera, dataclasses.replace(camera, spp=3)), "numpy", seed=4, pass_samples=17,
                    flare=True)
    odd = render_job(job, NewestFirstWithRetries())
    threads = render_job(job, ThreadPasses(3))
    without = render_job(dataclasses.replace(job, flare=False), ThreadPasses(2))
    for a, b, c in zip(odd, threads, without, strict=True):
        np.testing.assert_array_equal(a.image, b.image)
        assert a.image.sum() > c.image.sum()  # the flare adds light


def test_flare_on_a_dask_farm_is_the_same_bits_as_in_process():
    distributed = pytest.importorskip("distributed")
    from realistic.renderer.farm import DaskPasses

    scene, camera = _scene(0.05, 0.03, spp=6, size=(12, 10))
    job = RenderJob(scene, (camera,), "numpy", seed=3, pass_samples=40, flare=True)
    local = render_job(job, ThreadPasses(1))[0]
    cluster = distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None)
    try:
        with distributed.Client(cluster) as client:
            farm = render_job(job, DaskPasses(client, task_samples=80))[0]
    finally:
        cluster.close()
    assert local.image.sum() > 0
    np.testing.assert_array_equal(farm.image, local.image)


def test_a_checkpoint_keeps_the_flare_and_resumes_only_with_the_same_flare(tmp_path):
    scene, camera = _scene(0.05, 0.03, spp=8, size=(12, 10))
    job = RenderJob(scene, (camera,), "numpy", pass_samples=120, flare=True)
    whole = render_job(job, ThreadPasses(1))[0]
    path = checkpoint_path(tmp_path / "out.exr")
    job = dataclasses.replace(job, checkpoint=Checkpointing(path, None))

    partial = render_job(job, InterruptedAfterThirdTask(2))[0]
    assert partial.interrupted and path.exists()
    resume = Checkpointing(path, None, resume=True)
    for other in ({"flare": False}, {"flare_threshold": 1e-3}):
        with pytest.raises(UserError, match="another flare setting"):
            render_job(dataclasses.replace(job, checkpoint=resume, **other))
    saved = dict(np.load(path))
    for damage, message in (({"flare": np.full_like(saved["flare"], np.nan)}, "flare not finite"),
                            ({"flare": saved["flare"][:-1]}, "flare of the wrong shape")):
        damaged = tmp_path / "damaged.exr.partial"
        with open(damaged, "wb") as handle:
            np.savez(handle, **{**saved, **damage})
        with pytest.raises(UserError, match=f"damaged \\({message}"):
            render_job(dataclasses.replace(job, checkpoint=Checkpointing(damaged, None, resume=True)))
    resumed = render_job(dataclasses.replace(job, checkpoint=resume), ThreadPasses(2))[0]
    np.testing.assert_array_equal(resumed.image, whole.image)


def test_flare_options_are_checked_and_an_ideal_lens_is_rendered_bare(capsys):
    from realistic.cli import main

    inputs = build_render_inputs(RenderOptions(flare=True, resolution=(8, 8), spp=1))
    assert inputs.flare and set(inputs.camera.lens.coating) == {"none"}
    assert any("--coating none" in line for line in inputs.warnings)
    inputs = build_render_inputs(RenderOptions(flare=True, coating="mgf2", flare_threshold=1e-6, resolution=(8, 8)))
    assert set(inputs.camera.lens.coating) == {"mgf2"} and inputs.flare_threshold == 1e-6 and not inputs.warnings
    inputs = build_render_inputs(RenderOptions(flare=True, coating="mgf2", flare_threshold=1e-3, resolution=(8, 8)))
    assert [line for line in inputs.warnings if "reaches the threshold 0.001" in line]  # coated: every ghost dimmer
    with pytest.raises(UserError, match="applies with --flare on"):
        RenderOptions(flare_threshold=1e-3)
    with pytest.raises(UserError, match="ghost threshold"):
        RenderOptions(flare=True, flare_threshold=2.0)
    with pytest.raises(UserError, match="no ghosts"):
        RenderJob(_scene()[0], (ThinLensCamera(40.0, 0.0, 1.0, 8, 8, 1, np.eye(4)),), flare=True)
    assert main(["render", "--flare", "on", "--flare-threshold", "-1", "--res", "8x8"]) == 2
    assert "ghost threshold" in capsys.readouterr().err

