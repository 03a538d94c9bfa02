"""Any lens on any scene (issue 33): a pbrt scene's camera replaced or adjusted through the cameras'
``with_lens``, ``with_focus`` and ``with_stop`` (the CLI's options call the same methods), the film
sized to the lens, and a re-render after a focus or stop change that rebuilds neither the scene's
embree BVH nor a kernel program."""

import dataclasses
import gc
import json
import math

import numpy as np
import pytest

import realistic as rl
from conftest import shared_file
from realistic.camera.base import SampleBlock
from realistic.camera.lens_camera import LensCamera
from realistic.camera.thin_lens import ThinLensCamera
from realistic.cli import main
from realistic.core.image_files import read_exr
from realistic.device import opencl
from realistic.errors import UserError
from realistic.optics.field_curves import field_curves
from realistic.optics.formats import load_lens
from realistic.optics.library import image_circle_mm
from realistic.optics.paraxial import film_distance_for_focus, paraxial_data
from realistic.optics.tracer import trace_from_film
from realistic.renderer import passes
from realistic.renderer.inputs import RenderOptions, build_render_inputs
from realistic.scene.intersect import Intersector

HOMEWORK = "scenes/pbrt/dof-dragons.dgauss.pbrt"
PHONE = "phone-us10101561"
SMALL = ["--backend", "numpy", "--res", "24x16", "--spp", "1"]


def dark_fraction(camera: LensCamera, spp: int = 8) -> float:
    """Fraction of the frame's pixels that no camera ray reaches (every ray vignetted): the black
    the lens leaves, whatever the scene shows there (the homework scenes' sky is black too)."""
    camera = dataclasses.replace(camera, spp=spp, spectral=False)
    rays = camera.generate_rays(SampleBlock(0, camera.sample_count, spp))
    reached = np.zeros(camera.width * camera.height, bool)
    reached[rays.pixel[rays.weight != 0]] = True
    return 1.0 - float(reached.mean())


def render_cli(args: list[str], capsys: pytest.CaptureFixture) -> tuple[int, str]:
    status = main(["render", *args])
    return status, capsys.readouterr().err


def test_a_homework_scene_through_another_lens_stop_and_focus(tmp_path, capsys):
    scene, lenses = shared_file(HOMEWORK), shared_file("lenses")
    out = tmp_path / "tele.exr"
    status, err = render_cli([str(scene), "--search-path", str(lenses), *SMALL, "--lens", "telephoto.300mm-f2.8",
                              "--fstop", "4", "--focus", "3", "--out", str(out)], capsys)
    assert status == 0, err
    image, header = read_exr(out)
    assert image.shape == (16, 24, 3)
    assert header["lens"] == "telephoto.300mm-f2.8"
    assert float(header["fNumber"]) == pytest.approx(4.0, rel=1e-6)
    assert float(header["focusDistanceSceneUnits"]) == pytest.approx(3.0, rel=1e-6)
    assert float(header["focusDistanceMm"]) == pytest.approx(3 * 5000, rel=1e-6)  # the file's Scale 5000
    # issue 33's own example: the bundled "telephoto" (Sigler, f/5.6) cannot open to f/4, so it takes its
    # widest, f/5.42, as a camera does, and says so
    out = tmp_path / "sigler.exr"
    status, err = render_cli([str(scene), "--search-path", str(lenses), *SMALL, "--lens", "telephoto", "--fstop", "4",
                              "--focus", "3", "--out", str(out)], capsys)
    assert status == 0 and "--fstop 4 is faster than telephoto opens: f/5.42 is used" in err, err
    image, header = read_exr(out)
    assert header["lens"] == "telephoto" and float(header["fNumber"]) == pytest.approx(5.42, abs=0.005)
    assert float(header["focusDistanceSceneUnits"]) == pytest.approx(3.0, rel=1e-6)
    assert float(np.mean(image)) > 0


def test_the_phone_lens_on_a_homework_scene_gets_a_film_it_covers(tmp_path, capsys):
    scene, lenses = shared_file(HOMEWORK), shared_file("lenses")
    out = tmp_path / "phone.exr"
    status, err = render_cli([str(scene), "--search-path", str(lenses), *SMALL, "--lens", PHONE, "--out", str(out)],
                             capsys)
    assert status == 0, err
    assert "film is sized to the lens" in err
    _, header = read_exr(out)
    circle = image_circle_mm(load_lens(PHONE))
    assert header["lens"] == PHONE and float(header["filmDiagonalMm"]) == pytest.approx(circle, rel=1e-6)
    options = dict(scene=str(scene), search_paths=[lenses], resolution=(48, 32), lens=PHONE)
    camera = build_render_inputs(RenderOptions(**options)).camera
    assert isinstance(camera, LensCamera) and dark_fraction(camera) < 0.2
    # the scene's own 70 mm film, asked for, is nearly all dark, and the warning names the film to use
    inputs = build_render_inputs(RenderOptions(**options, film_diagonal_mm=70.0))
    assert dark_fraction(inputs.camera) > 0.9
    assert any(f"--film-diagonal {circle:.3g}" in w for w in inputs.warnings)


def test_the_phone_lens_on_the_dragon_with_no_film_option():
    dragon = shared_file("meshes/dragon.ply")
    inputs = build_render_inputs(RenderOptions(scene=str(dragon), lens=PHONE, resolution=(48, 32)))
    assert dark_fraction(inputs.camera) < 0.2 and not inputs.warnings
    full_frame = build_render_inputs(RenderOptions(scene=str(dragon), lens=PHONE, resolution=(48, 32),
                                                   film_diagonal_mm=43.27))
    assert dark_fraction(full_frame.camera) > 0.9 and "outside the image circle" in full_frame.warnings[0]


def test_auto_film_is_the_image_circle_at_most_full_frame():
    for name in ("fisheye", PHONE, "dgauss", "telephoto"):
        camera = LensCamera(load_lens("dgauss"), 40.0).with_lens(name, film_diagonal_mm="auto")
        assert camera.film_diagonal_mm == pytest.approx(min(image_circle_mm(camera.lens), 43.27))


def _perspective(width: int = 48, height: int = 32) -> ThinLensCamera:
    rotation = np.array([[0.0, 0, 1, 2], [0, 1, 0, 1], [-1, 0, 0, 3], [0, 0, 0, 1]])
    return ThinLensCamera(40.0, 0.0, 1e6, width, height, 1, rotation)


@pytest.mark.parametrize("size", [(48, 32), (32, 48)])
def test_a_perspective_camera_replaced_by_a_lens_keeps_its_field_of_view(size):
    thin = _perspective(*size)
    camera = thin.with_lens("dgauss")
    short_half_mm = min(camera.film_size_mm) / 2
    # the real chief ray from the middle of the film's shorter edge (pbrt's fov spans the shorter side)
    edge = field_curves(camera.lens, 2 * short_half_mm / 0.999, camera.film_distance_mm, points=2)[-1]
    distortion = edge["distortion_percent"] / 100
    assert abs(distortion) < 0.02  # dgauss is close to rectilinear: what the match is exact for
    assert math.tan(math.radians(edge["field_angle_deg"])) * (1 + distortion) == pytest.approx(
        math.tan(math.radians(20.0)), rel=1e-3)
    # the same pose: each camera's rays through the centre and toward the right and top edges agree
    for pixel in (size[0] // 2 + size[1] // 2 * size[0], size[0] - 1 + size[1] // 2 * size[0],
                  size[0] // 2):
        block = SampleBlock.of_pixels(pixel, 1, 0, 32)
        lens_rays = dataclasses.replace(camera, spp=32).generate_rays(block)
        passed = lens_rays.weight != 0
        assert passed.any()
        lens_mean = lens_rays.direction[passed].mean(axis=0)
        thin_mean = dataclasses.replace(thin, spp=32).generate_rays(block).direction.mean(axis=0)
        assert np.dot(lens_mean / np.linalg.norm(lens_mean), thin_mean / np.linalg.norm(thin_mean)) > 0.999
    assert np.allclose(camera.world_from_lens[:3, 3], thin.world_from_camera[:3, 3])  # film centre at the pinhole


def test_with_focus_puts_the_paraxial_image_of_a_point_at_that_distance_on_the_film():
    metres = np.diag([1e-3, 1e-3, 1e-3, 1.0])  # world from camera: scene units of 1000 mm
    camera = LensCamera(load_lens("dgauss"), 40.0, world_from_camera=metres).with_focus(2.0)
    # near-axis rays from the film centre leave the lens and cross the axis at the object in focus
    angles = np.array([1e-4, -2e-4, 3e-4])
    directions = np.column_stack([np.sin(angles), np.zeros(3), np.cos(angles)])
    traced = trace_from_film(camera.lens, camera.film_distance_mm, np.zeros((3, 3)), directions)
    assert traced.passed.all()
    crossing = traced.origin[:, 2] - traced.origin[:, 0] * traced.direction[:, 2] / traced.direction[:, 0]
    assert crossing == pytest.approx(2000.0, rel=1e-4)
    assert camera.focus_distance == pytest.approx(2.0, rel=1e-12)
    assert camera.with_focus(math.inf).film_distance_mm == film_distance_for_focus(camera.lens, math.inf)


def test_with_stop_sizes_the_stop_for_the_f_number():
    camera = LensCamera(load_lens("dgauss"), 40.0)
    f4, f8 = camera.with_stop(f_number=4.0), camera.with_stop(f_number=8.0)
    assert paraxial_data(f4.lens).f_number == pytest.approx(4.0, rel=1e-9)
    # the entrance pupil is the stop's image: EFL / N, so halving N doubles the stop's diameter
    assert f4.lens.stop_diameter_mm == pytest.approx(2 * f8.lens.stop_diameter_mm, rel=1e-12)
    assert f4.film_distance_mm == camera.film_distance_mm  # the focus stays
    assert camera.with_stop(aperture_mm=5.0).lens.stop_diameter_mm == 5.0
    with pytest.raises(UserError, match="give one"):
        camera.with_stop(f_number=4.0, aperture_mm=5.0)
    with pytest.raises(UserError, match="give --lens too"):
        _perspective().with_stop(f_number=4.0)


def test_a_thin_lens_autofocuses_on_the_depth_of_what_it_sees():
    thin = dataclasses.replace(_perspective(), lens_radius=0.01)
    axis = thin.world_from_camera[:3, 2]

    def plane_at_depth_5(origin: np.ndarray, direction: np.ndarray) -> float:
        return 5.0 / float(np.dot(direction, axis))  # the plane 5 units along the view axis

    assert thin.autofocused(3.0, 29.0, plane_at_depth_5).focal_distance == pytest.approx(5.0, rel=1e-12)


def test_a_refocused_or_stopped_rerender_rebuilds_no_bvh_and_no_kernel(monkeypatch):
    built = []

    class Counted(Intersector):
        def __init__(self, scene: rl.Scene) -> None:
            built.append(scene)
            super().__init__(scene)

    monkeypatch.setattr(passes, "Intersector", Counted)
    scene = rl.load_scene(resolution=(16, 12), spp=1)
    camera = scene.camera
    first = rl.render(scene, camera)
    misses = opencl.build_program.cache_info().misses
    refocused = rl.render(scene, camera.with_focus(2.0))
    stopped = rl.render(scene, camera.with_stop(f_number=8.0))
    assert len(built) == 1
    assert opencl.build_program.cache_info().misses == misses
    assert first.shape == refocused.shape == stopped.shape == (12, 16, 3)
    assert not np.array_equal(first, refocused) and stopped.mean() < first.mean()



def test_every_lens_command_takes_the_focus_in_metres_from_the_film(tmp_path, capsys):
    lens = load_lens("dgauss")
    report, plot = tmp_path / "spot.json", tmp_path / "spot.png"
    for focus, film in (("2", film_distance_for_focus(lens, 2000.0)), ("inf", film_distance_for_focus(lens, math.inf)),
                        ("paraxial", paraxial_data(lens).bfl_mm)):
        assert main(["lens", "spot", "dgauss", "--focus", focus, "--field", "0", "--samples", "8",
                     "--json", str(report), "--out", str(plot)]) == 0
        assert json.loads(report.read_text())["film_distance_mm"] == pytest.approx(film, rel=1e-12)
    psf = tmp_path / "psf.exr"
    assert main(["lens", "psf", "dgauss", "--depth", "3", "--focus", "2", "--size", "4", "--spp", "1",
                 "--out", str(psf)]) == 0
    assert float(read_exr(psf)[1]["filmDistanceMm"]) == pytest.approx(film_distance_for_focus(lens, 2000.0))
    assert main(["lens", "curves", "dgauss", "--focus", "inf", "--out", str(tmp_path / "c.png")]) == 0
    capsys.readouterr()
    assert main(["lens", "ghosts", "dgauss", "--focus", "2", "--threshold", "2e-3"]) == 0
    assert f"{film_distance_for_focus(lens, 2000.0):.3f} mm behind the rear vertex" in capsys.readouterr().out


def test_render_focus_takes_inf_and_the_film_distance_in_mm():
    at_infinity = build_render_inputs(RenderOptions(focus_distance=math.inf, resolution=(8, 8))).camera
    assert at_infinity.film_distance_mm == film_distance_for_focus(at_infinity.lens, math.inf)
    placed = build_render_inputs(RenderOptions(film_distance_mm=37.0, resolution=(8, 8))).camera
    assert placed.film_distance_mm == 37.0
    with pytest.raises(UserError, match="--focus and --film-distance-mm each set the focus"):
        RenderOptions(focus_distance=2.0, film_distance_mm=37.0)


def test_a_scene_keeps_its_intersector_until_its_geometry_changes_or_it_goes():
    scene = rl.load_scene(resolution=(8, 8), spp=1)
    first = passes.scene_intersector(scene)
    assert passes.scene_intersector(scene) is first
    scene.add(scene.meshes[0], np.eye(4))  # one more instance: another BVH
    second = passes.scene_intersector(scene)
    assert second is not first and second.instance_count == first.instance_count + 1
    key = id(scene)
    del scene
    gc.collect()
    assert key not in passes._intersectors
