"""The diffraction starburst (``realistic.renderer.starburst``): the round stop's Airy ring, the
blades' spikes, the working f-number, energy kept by the convolution, and the option in the render."""

from pathlib import Path

import numpy as np
import pytest
from scipy.ndimage import map_coordinates

from realistic import load_lens, render
from realistic.camera.lens_camera import LensCamera
from realistic.camera.thin_lens import ThinLensCamera
from realistic.core.transforms import translate
from realistic.errors import UserError
from realistic.optics.paraxial import paraxial_data
from realistic.optics.stop_shape import bladed_stop
from realistic.renderer import starburst
from realistic.renderer.inputs import RenderOptions, build_render_inputs
from realistic.renderer.job import RenderJob
from realistic.scene.model import AreaLight, Scene

LAMBDA_N_MM = 0.55e-3 * 8  # 550 nm at f/8


def _radial_profile(psf: np.ndarray, step: float = 0.1) -> tuple[np.ndarray, np.ndarray]:
    """(radii, mean PSF) on circles about the middle pixel, bilinear on 720 angles each."""
    centre = (psf.shape[0] - 1) / 2
    radii = np.arange(1.0, centre / 2, step)
    angles = np.linspace(0, 2 * np.pi, 720, endpoint=False)
    rows = centre + radii[:, None] * np.sin(angles)
    cols = centre + radii[:, None] * np.cos(angles)
    values = map_coordinates(psf, [rows.ravel(), cols.ravel()], order=1).reshape(rows.shape)
    return radii, values.mean(axis=1)


def test_a_round_stops_psf_has_the_airy_patterns_first_dark_ring_at_1_22_lambda_n(
        monkeypatch: pytest.MonkeyPatch) -> None:
    # one fine sample per pixel (pitch under lambda N / 2), a large kernel so the pupil is well sampled
    monkeypatch.setattr(starburst, "MAX_KERNEL_PX", 1023)
    pitch = LAMBDA_N_MM / 8
    psf = starburst.pixel_psf(None, pitch, LAMBDA_N_MM)
    assert starburst.kernel_layout(pitch, LAMBDA_N_MM) == (1, 1023)
    radii, profile = _radial_profile(psf)
    first_minimum = radii[np.argmax(np.diff(profile) > 0)]  # where the profile stops falling
    assert first_minimum == pytest.approx(1.22 * LAMBDA_N_MM / pitch, abs=0.15)
    assert psf.sum() == pytest.approx(1.0)


@pytest.mark.parametrize("blades", [5, 6, 7, 8])
def test_n_straight_blades_give_n_spikes_when_n_is_even_and_2n_when_odd(blades: int) -> None:
    stop = bladed_stop(blades, rotation_deg=10.0)
    # spikes a few pixels wide (pitch lambda N): the angular profile on a ring is smooth
    psf = starburst.pixel_psf(stop, LAMBDA_N_MM, LAMBDA_N_MM)
    centre = (psf.shape[0] - 1) / 2
    angles = np.linspace(0, 2 * np.pi, 1440, endpoint=False)
    radius = 40.0
    ring = map_coordinates(psf, [centre + radius * np.sin(angles), centre + radius * np.cos(angles)], order=1)
    orders = np.abs(np.fft.rfft(ring - ring.mean()))[1:41]
    spikes = blades if blades % 2 == 0 else 2 * blades
    assert int(np.argmax(orders)) + 1 == spikes
    # spikes under a pixel wide (pitch 8 lambda N): each runs along a blade's normal, both ways, and
    # by symmetry they carry the same light
    psf = starburst.pixel_psf(stop, 8 * LAMBDA_N_MM, LAMBDA_N_MM)
    centre = (psf.shape[0] - 1) / 2
    rows, cols = np.mgrid[:psf.shape[0], :psf.shape[1]] - centre
    radius_px, angle = np.hypot(rows, cols), np.degrees(np.arctan2(-rows, cols))
    normals = 10.0 + (2 * np.arange(blades) + 1) * 180.0 / blades
    sectors = [psf[(radius_px > 5) & (radius_px < 45) & (np.abs((angle - direction + 180) % 360 - 180) < 6)].sum()
               for direction in np.concatenate([normals, normals + 180])]
    assert min(sectors) > 0.75 * max(sectors)  # equal but for the FFT's folded copies (``pupil_grid``)
    between = psf[(radius_px > 5) & (radius_px < 45) & (np.abs((angle - normals[0] - 180 / spikes + 180) % 360
                                                                 - 180) < 6)].sum()
    assert between < 0.05 * min(sectors)


def test_the_working_f_number_at_infinity_focus_is_the_paraxial_f_number() -> None:
    lens = load_lens("dgauss")
    data = paraxial_data(lens, 550.0)
    camera = LensCamera(lens, data.bfl_mm, width=64, height=48)
    assert starburst.working_f_number(camera, 550.0) == pytest.approx(data.f_number, rel=1e-9)
    closer = LensCamera(lens, data.bfl_mm + 5.0, width=64, height=48)  # focused nearer: the film moves back
    assert starburst.working_f_number(closer, 550.0) == pytest.approx(
        data.f_number + 5.0 / data.exit_pupil_diameter_mm, rel=1e-9)


def _image_with_sources() -> np.ndarray:
    rng = np.random.default_rng(7)
    image = rng.uniform(0.1, 0.3, (40, 60, 3)).astype(np.float32)
    for row, col in ((0, 0), (20, 30), (39, 58), (5, 59)):  # corners and edges send much of the PSF off
        image[row, col] = (500.0, 800.0, 300.0)
    return image


def test_the_starburst_keeps_each_channels_sum_and_changes_nothing_without_sources() -> None:
    image = _image_with_sources()
    bright = starburst.sources(image)
    assert bright.sum() == 4
    psfs = [starburst.pixel_psf(bladed_stop(6), LAMBDA_N_MM * scale, LAMBDA_N_MM) for scale in (1.1, 1.0, 0.85)]
    out = starburst.convolve_sources(image, bright, psfs)
    assert out.dtype == np.float32
    np.testing.assert_allclose(out.astype(np.float64).sum(axis=(0, 1)), image.astype(np.float64).sum(axis=(0, 1)),
                               rtol=1e-6)
    assert np.all(out[~bright] >= image[~bright])  # light only moves out of the sources
    assert np.all(out[bright] < image[bright])
    lens = load_lens("dgauss").with_stop_shape(bladed_stop(6))
    camera = LensCamera(lens, paraxial_data(lens).bfl_mm, width=60, height=40)
    uniform = np.full((40, 60, 3), 0.2, np.float32)
    assert starburst.starburst(uniform, camera) is uniform  # nothing above the metered white
    assert not starburst.sources(np.zeros((4, 4, 3), np.float32)).any()


def _scene() -> tuple[Scene, LensCamera]:
    """A disk light 3 cm across facing a six-bladed dgauss camera at f/16 1 m away, before a dim disk 6 m
    across that fills the frame (the meter's reading, so the small light is far above white)."""
    lens = load_lens("dgauss").with_stop_shape(bladed_stop(6))
    camera = LensCamera.looking_at(lens, np.zeros(3), np.array([0.0, 0.0, -1.0]), width=96, height=72,
                                   spp=2).with_stop(f_number=16)  # a PSF kernel of some 20 pixels
    scene = Scene(lights=[AreaLight("disk", (0.015, 0.015), (1.0, 1.0, 1.0), translate(0.0, 0.0, -1.0)),
                          AreaLight("disk", (3.0, 3.0), (1e-3, 1e-3, 1e-3), translate(0.0, 0.0, -2.0))],
                  camera=camera)
    return scene, camera


def test_starburst_in_the_render_moves_light_only_and_off_changes_nothing() -> None:
    scene, camera = _scene()
    plain = np.asarray(render(scene, camera, "numpy"))
    np.testing.assert_array_equal(np.asarray(render(scene, camera, "numpy", starburst=False)), plain)
    burst = np.asarray(render(scene, camera, "numpy", starburst=True))
    np.testing.assert_array_equal(burst, starburst.starburst(plain, camera))
    assert not np.array_equal(burst, plain)
    np.testing.assert_allclose(burst.sum(axis=(0, 1), dtype=np.float64), plain.sum(axis=(0, 1), dtype=np.float64),
                               rtol=1e-6)


def test_starburst_needs_a_real_lens(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from realistic.cli import main

    thin = ThinLensCamera(40.0, 0.0, 1.0, 8, 8, 1, np.eye(4))
    with pytest.raises(UserError, match="--starburst on needs a real lens"):
        RenderJob(Scene(camera=thin), (thin,), starburst=True)
    scene = tmp_path / "pinhole.pbrt"
    scene.write_text('Film "image" "integer xresolution" [8] "integer yresolution" [8]\n'
                     'Camera "perspective" "float fov" 40\nWorldBegin\n')
    with pytest.raises(UserError, match="--starburst on needs a real lens"):
        build_render_inputs(RenderOptions(scene=str(scene), starburst=True))
    assert main(["render", str(scene), "--starburst", "on", "-o", str(tmp_path / "out.exr")]) == 2
    err = capsys.readouterr().err
    assert "--starburst on needs a real lens" in err and err.count("\n") == 1  # one line
    inputs = build_render_inputs(RenderOptions(lens="dgauss", resolution=(16, 12), starburst=True))
    assert inputs.starburst and "starburst" in inputs.metadata
