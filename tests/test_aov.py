"""AOVs (issue 33): what the camera rays first hit, per pixel, with pbrt-v4 GBufferFilm's names and averages.

Closed forms: a plane straight ahead at a known distance, a matte Kd, a mirror's Kr, and a pixel
split between two planes (or a plane and nothing) by an edge through its centre, whose depth and
albedo are the same mixture of the two sides."""

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from conftest import shared_file
from realistic import load_lens
from realistic.camera.lens_camera import LensCamera
from realistic.camera.thin_lens import ThinLensCamera
from realistic.core.image_files import read_exr
from realistic.core.transforms import translate
from realistic.core.validation import aovs as parse_aovs
from realistic.errors import UserError
from realistic.renderer.aov import AovLayout, CameraFrame
from realistic.renderer.checkpoint import checkpoint_path
from realistic.renderer.inputs import RenderOptions, build_render_inputs
from realistic.renderer.job import Checkpointing, RenderJob
from realistic.renderer.output import save
from realistic.renderer.passes import ThreadPasses, render
from realistic.scene.materials import Mirror
from realistic.scene.model import AreaLight, Scene
from realistic.scene.shapes import quad
from realistic.scene.surfaces import Material
from test_job import InterruptedAfterThirdTask

REPO = Path(__file__).resolve().parents[1]
ALL = "depth,normal,albedo,position"
FACING_CAMERA = np.diag([1.0, 1.0, -1.0, 1.0])  # a quad turned to face -z, toward a camera at the origin


def _scene(*planes: tuple[float, float, Material], integrator: str = "directlighting") -> Scene:
    """Quads facing the camera at depths z, each covering x >= x0 (x0 = -inf: everything)."""
    scene = Scene(integrator=integrator)
    for z, x0, material in planes:
        if np.isinf(x0):
            scene.add(quad(1000.0, 1000.0), translate(0, 0, z) @ FACING_CAMERA, material)
        else:
            scene.add(quad(1000.0, 1000.0), translate(x0 + 500.0, 0, z) @ FACING_CAMERA, material)
    scene.lights.append(AreaLight("quad", (1.0, 1.0), (1.0, 1.0, 1.0), translate(0, 0, -0.5)))
    return scene


def _pinhole(width: int = 6, height: int = 4, spp: int = 4) -> ThinLensCamera:
    return ThinLensCamera(40.0, 0.0, 1.0, width, height, spp, np.eye(4))


def _aovs(scene: Scene, camera, backend: str = "numpy", aovs: str = ALL, **job) -> dict[str, np.ndarray]:
    return render(RenderJob(scene, (camera,), backend, aovs=aovs, **job), ThreadPasses(2))[0].aovs


@pytest.mark.parametrize("backend", ["numpy", "opencl"])
def test_a_plane_at_a_known_distance_gives_that_depth_and_its_normal(backend):
    camera = _pinhole()
    aovs = _aovs(_scene((7.0, -np.inf, Material((0.5, 0.5, 0.5)))), camera, backend)
    assert sorted(aovs) == sorted(["P.X", "P.Y", "P.Z", "N.X", "N.Y", "N.Z", "Albedo.R", "Albedo.G", "Albedo.B"])
    np.testing.assert_allclose(aovs["P.Z"], 7.0, rtol=1e-6)
    np.testing.assert_array_equal(np.stack([aovs["N.X"], aovs["N.Y"], aovs["N.Z"]]),
                                  np.broadcast_to(np.array([0, 0, -1.0], np.float32)[:, None, None], (3, 4, 6)))
    # each pixel's mean position lies within what the pixel sees of the plane (box filter)
    half_x, half_y = camera.screen_window()
    tan = np.tan(np.radians(camera.fov_deg) / 2)
    edges_x = (np.arange(7) / 6 * 2 - 1) * half_x * tan * 7.0
    edges_y = (1 - np.arange(5) / 4 * 2) * half_y * tan * 7.0
    assert np.all((aovs["P.X"] > edges_x[:-1]) & (aovs["P.X"] < edges_x[1:]))
    assert np.all((aovs["P.Y"] < edges_y[:-1, None]) & (aovs["P.Y"] > edges_y[1:, None]))


def test_depth_alone_is_pbrt_v4s_p_z_channel():
    aovs = _aovs(_scene((3.0, -np.inf, Material((0.5, 0.5, 0.5)))), _pinhole(), aovs="depth")
    assert list(aovs) == ["P.Z"]
    np.testing.assert_allclose(aovs["P.Z"], 3.0, rtol=1e-6)


@pytest.mark.parametrize("spectral", [False, True])
def test_a_lens_camera_gives_depth_in_scene_units_from_its_film(spectral):
    """Camera space of a lens camera is in mm; the AOVs are in the scene's units (metres here). A
    spectral camera's rays of each wavelength count as samples of their own."""
    camera = LensCamera.looking_at(load_lens("dgauss"), np.zeros(3), np.array([0.0, 0.0, 4.0]), None, 43.27, 8, 6, 4)
    camera = camera.with_dispersion(spectral)
    assert camera.spectral == spectral
    scene = Scene()
    scene.add(quad(1000.0, 1000.0), translate(0, 0, 4.0) @ FACING_CAMERA, Material((0.5, 0.5, 0.5)))
    frame = CameraFrame.of(camera.world_from_camera)
    np.testing.assert_allclose(frame.points(np.array([[0.0, 0.0, 4.0]])), [[0.0, 0.0, 4.0]], atol=1e-12)
    aovs = render(RenderJob(scene, (camera,), "numpy", aovs="depth,normal"), ThreadPasses(1))[0].aovs
    centre = aovs["P.Z"][2:4, 3:5]
    np.testing.assert_allclose(centre, 4.0, rtol=1e-5)
    np.testing.assert_allclose(aovs["N.Z"][2:4, 3:5], -1.0, rtol=1e-6)


@pytest.mark.parametrize("integrator, backend", [("directlighting", "numpy"), ("directlighting", "opencl"),
                                                 ("path", "numpy")])
def test_a_matte_materials_albedo_is_its_kd(integrator, backend):
    aovs = _aovs(_scene((5.0, -np.inf, Material((0.2, 0.4, 0.6))), integrator=integrator), _pinhole(), backend,
                 aovs="albedo")
    for name, kd in zip(("Albedo.R", "Albedo.G", "Albedo.B"), (0.2, 0.4, 0.6), strict=True):
        np.testing.assert_allclose(aovs[name], kd, rtol=1e-6)


def test_a_mirrors_albedo_is_its_reflectance():
    """A mirror's one specular sample carries Kr: its directional albedo is Kr whatever the angle."""
    aovs = _aovs(_scene((5.0, -np.inf, Mirror((0.3, 0.5, 0.7))), integrator="path"), _pinhole(2, 2), aovs="albedo")
    for name, kr in zip(("Albedo.R", "Albedo.G", "Albedo.B"), (0.3, 0.5, 0.7), strict=True):
        np.testing.assert_allclose(aovs[name], kr, rtol=1e-6)


def test_a_pixel_half_on_two_surfaces_averages_them():
    """One pixel (2 x 1 image, pixel 0) split at x = 0 by a near plane's edge: half its samples at depth 2
    with Kd 0.2, half on the far plane at depth 6 with Kd 0.6."""
    camera = ThinLensCamera(40.0, 0.0, 1.0, 1, 1, 64, np.eye(4))
    scene = _scene((2.0, 0.0, Material((0.2, 0.2, 0.2))), (6.0, -np.inf, Material((0.6, 0.6, 0.6))))
    aovs = _aovs(scene, camera)
    near = (6.0 - aovs["P.Z"][0, 0]) / 4.0  # the fraction of samples on the near plane, from the depth
    assert abs(near - 0.5) < 0.1
    assert aovs["Albedo.R"][0, 0] == pytest.approx(0.2 * near + 0.6 * (1 - near), rel=1e-5)
    assert aovs["N.Z"][0, 0] == pytest.approx(-1.0, rel=1e-6)


def test_a_pixel_half_on_the_background_keeps_its_depth_and_halves_its_albedo():
    """pbrt-v4: position over the samples that hit, albedo over all; a pixel that sees nothing is 0."""
    camera = ThinLensCamera(40.0, 0.0, 1.0, 3, 1, 64, np.eye(4))  # the middle pixel straddles x = 0
    scene = _scene((2.0, 0.0, Material((0.2, 0.2, 0.2))))
    aovs = _aovs(scene, camera)
    assert aovs["P.Z"][0, 1] == pytest.approx(2.0, rel=1e-6) and aovs["P.Z"][0, 0] == 0.0
    assert abs(aovs["Albedo.R"][0, 1] / 0.2 - 0.5) < 0.1 and aovs["Albedo.R"][0, 0] == 0.0
    assert aovs["N.Z"][0, 0] == 0.0 and aovs["N.Z"][0, 1] == pytest.approx(-1.0)


def test_aovs_do_not_change_the_image_and_are_the_same_bits_for_any_threads_and_pass_size():
    scene, camera = _scene((5.0, 1.0, Material((0.2, 0.4, 0.6))), (9.0, -np.inf, Material((0.5, 0.5, 0.5)))), \
        _pinhole(12, 10, 6)
    plain = render(RenderJob(scene, (camera,), "numpy", seed=3, pass_samples=17), ThreadPasses(1))[0]
    one = render(RenderJob(scene, (camera,), "numpy", seed=3, pass_samples=17, aovs=ALL), ThreadPasses(1))[0]
    three = render(RenderJob(scene, (camera,), "numpy", seed=3, pass_samples=17, aovs=ALL), ThreadPasses(3))[0]
    np.testing.assert_array_equal(plain.image, one.image)
    assert plain.aovs == {} and sorted(one.aovs) == sorted(three.aovs)
    for name in one.aovs:
        np.testing.assert_array_equal(one.aovs[name], three.aovs[name])


def test_the_dragons_textures_give_the_same_image_with_aovs_through_the_shading_kernel():
    """With the OpenCL shading kernel, image-textured albedo is computed once for the AOVs and the
    kernel: the image is the same bits as without AOVs, and the albedo is within the textures' range."""
    meshes, pbrt = shared_file("meshes"), shared_file("scenes/pbrt")
    inputs = build_render_inputs(RenderOptions(scene=str(REPO / "scenes" / "dof-dragons" / "dgauss.pbrt"),
                                               resolution=(48, 32), search_paths=[str(meshes), str(pbrt)]))
    camera = dataclasses.replace(inputs.camera, spp=2)
    plain = render(RenderJob(inputs.scene, (camera,), "opencl", seed=2), ThreadPasses(2))[0]
    with_aovs = render(RenderJob(inputs.scene, (camera,), "opencl", seed=2, aovs="albedo,normal"), ThreadPasses(2))[0]
    np.testing.assert_array_equal(plain.image, with_aovs.image)
    albedo = np.stack([with_aovs.aovs[f"Albedo.{c}"] for c in "RGB"])
    assert albedo.max() > 0 and albedo.min() >= 0 and albedo.max() <= 1


def test_aovs_are_written_as_exr_channels_with_pbrt_v4s_names(tmp_path):
    scene = _scene((5.0, -np.inf, Material((0.2, 0.4, 0.6))))
    result = render(RenderJob(scene, (_pinhole(),), "numpy", aovs=ALL), ThreadPasses(1))[0]
    save(result, tmp_path / "out.exr")
    import OpenEXR

    with OpenEXR.File(str(tmp_path / "out.exr"), separate_channels=True) as exr:
        channels = exr.channels()
        assert set(channels) == {"R", "G", "B", "Albedo.R", "Albedo.G", "Albedo.B", "P.X", "P.Y", "P.Z",
                                 "N.X", "N.Y", "N.Z"}
        np.testing.assert_allclose(channels["P.Z"].pixels, 5.0, rtol=1e-6)
    np.testing.assert_array_equal(read_exr(tmp_path / "out.exr")[0], result.image)


def test_a_checkpoint_resumes_only_with_the_same_aovs_and_to_the_same_bits(tmp_path):
    scene, camera = _scene((5.0, 1.0, Material((0.2, 0.4, 0.6)))), _pinhole(8, 6, 8)
    whole = render(RenderJob(scene, (camera,), "numpy", pass_samples=24, aovs="depth,albedo"), ThreadPasses(1))[0]
    path = checkpoint_path(tmp_path / "out.exr")
    job = RenderJob(scene, (camera,), "numpy", pass_samples=24, aovs="depth,albedo",
                    checkpoint=Checkpointing(path, None))

    partial = render(job, InterruptedAfterThirdTask(1))[0]
    assert partial.interrupted and path.exists()
    with pytest.raises(UserError, match="another set of AOVs"):
        render(dataclasses.replace(job, aovs="depth", checkpoint=Checkpointing(path, None, resume=True)))
    with pytest.raises(UserError, match="another set of AOVs"):
        render(dataclasses.replace(job, aovs=(), checkpoint=Checkpointing(path, None, resume=True)))
    resumed = render(dataclasses.replace(job, checkpoint=Checkpointing(path, None, resume=True)),
                     ThreadPasses(2))[0]
    np.testing.assert_array_equal(resumed.image, whole.image)
    for name in whole.aovs:
        np.testing.assert_array_equal(resumed.aovs[name], whole.aovs[name])


@pytest.mark.parametrize("value, message", [("depth,colour", "unknown AOV 'colour'"), ("depth,depth", "twice"),
                                            (("normal", 3), "unknown AOV 3")])
def test_aov_names_are_checked_in_one_line(value, message):
    with pytest.raises(UserError, match=message):
        parse_aovs(value)


def test_aov_names_are_put_in_one_order():
    assert parse_aovs(" normal,depth ") == ("depth", "normal") == parse_aovs(["normal", "depth"])
    assert parse_aovs("") == () == parse_aovs(None)
    assert AovLayout(("depth", "position")).channel_names == ("P.X", "P.Y", "P.Z")
    assert AovLayout(()).columns == 3 and AovLayout(("normal",)).columns == 3 + 3 + 2


def test_aovs_on_a_dask_farm_are_the_same_bits_as_in_process():
    distributed = pytest.importorskip("distributed")
    from realistic.renderer.farm import DaskPasses

    scene, camera = _scene((5.0, 1.0, Material((0.2, 0.4, 0.6))), (9.0, -np.inf, Material((0.5, 0.5, 0.5)))), \
        _pinhole(12, 10, 6)
    job = RenderJob(scene, (camera,), "numpy", seed=3, pass_samples=40, aovs=ALL)
    local = render(job, ThreadPasses(1))[0]
    cluster = distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None)
    try:
        with distributed.Client(cluster) as client:
            farm = render(job, DaskPasses(client, task_samples=80))[0]
    finally:
        cluster.close()
    np.testing.assert_array_equal(farm.image, local.image)
    assert sorted(farm.aovs) == sorted(local.aovs)
    for name in local.aovs:
        np.testing.assert_array_equal(farm.aovs[name], local.aovs[name])


def test_a_pass_with_no_rays_left_gives_float64_sums():
    """np.bincount of no weights is int64: a wholly vignetted pass's sums are float64 all the same."""
    from realistic.renderer.film import pass_sums

    sums = pass_sums(np.zeros(0, np.int64), np.zeros((0, 5)), 10, 4)
    assert sums.dtype == np.float64 and sums.shape == (4, 5) and not sums.any()


def test_a_pass_whose_sums_are_not_the_plans_is_refused_on_arrival():
    from realistic.renderer.film import Film, PassFilm
    from realistic.renderer.pass_plan import plan_passes

    plan = plan_passes(12, 4, 6)
    film = PassFilm(Film(4, 3, 4, columns=AovLayout(("albedo",)).columns), plan)
    with pytest.raises(RuntimeError, match="expected float64"):
        film.add(0, plan[0].first_pixel, np.zeros((plan[0].pixel_count, 3)))  # the radiance's columns alone
    with pytest.raises(RuntimeError, match="not in the plan"):
        film.add(len(plan), 0, np.zeros((1, 8)))
    assert film.passes_taken == 0


def test_aovs_into_a_png_or_pfm_are_refused_before_any_work(tmp_path, capsys):
    """A PNG or PFM holds the image alone: the AOVs asked for would be dropped without a word."""
    from realistic.cli import main

    for name in ("x.png", "x.pfm"):
        assert main(["render", "--aov", "depth", "--res", "8x8", "--out", str(tmp_path / name)]) == 2
        err = capsys.readouterr().err
        assert "--aov writes EXR channels" in err and err.count("\n") == 1
    assert list(tmp_path.iterdir()) == []
