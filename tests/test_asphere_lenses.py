"""The bundled aspheric lenses against the figures their sources state, and the kernel on them."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from kernel_reference import assert_kernel_matches, world_from_camera
from realistic import load_lens
from realistic.camera.base import SampleBlock
from realistic.camera.lens_camera import LensCamera
from realistic.errors import UserError
from realistic.optics.paraxial import film_distance_for_focus, paraxial_data
from realistic.optics.tracer import trace_from_film
from realistic.renderer.backends import backend_for

#: name: (source named in the description, stated focal length mm, stated F-number)
STATED = {
    "phone-us10101561": ("US 10,101,561 B2, Embodiment 3", 3.35, 2.2),
    "canon-ef24-f1.4": ("US 2010/0033848 A1, Example 3", 24.54, 1.45),
    "canon-rf50-f1.2": ("US 2019/0265441 A1, Example 2", 51.10, 1.25),
}


@pytest.mark.parametrize("name", list(STATED))
def test_paraxial_focal_length_and_f_number_match_the_source(name):
    source, focal_length, f_number = STATED[name]
    lens = load_lens(name)
    assert source in lens.description
    assert lens.asphere_count >= 2
    data = paraxial_data(lens)
    assert data.efl_mm == pytest.approx(focal_length, rel=0.01)
    assert data.f_number == pytest.approx(f_number, rel=0.01)


@pytest.mark.parametrize("name", list(STATED))
def test_the_sources_image_distance_is_the_paraxial_focus(name):
    """The last gap is the patent's back focus (image distance at infinity focus): an independent check
    of the transcribed radii, thicknesses and indices, since it must equal the paraxial BFL."""
    lens = load_lens(name)
    data = paraxial_data(lens)
    assert abs(data.bfl_mm - lens.film_gap_mm) < 0.01 * data.efl_mm


@pytest.mark.parametrize("name", list(STATED))
def test_an_on_axis_beam_through_the_pupil_passes_and_leaves_nearly_parallel(name):
    """Rays from the paraxial focus through 70 % of the paraxial exit pupil all pass the lens and
    leave the front nearly parallel to the axis (the lens is corrected for infinity): a
    transcription error in a radius or an aspheric coefficient would block or scatter them."""
    lens = load_lens(name)
    data = paraxial_data(lens)
    film = data.bfl_mm
    pupil_z = film - data.exit_pupil_mm
    heights = np.linspace(-0.35, 0.35, 41) * data.exit_pupil_diameter_mm
    targets = np.column_stack([heights, np.zeros_like(heights), np.full_like(heights, pupil_z)])
    result = trace_from_film(lens, film, np.zeros_like(targets), targets)
    assert result.passed.all()
    # angle x focal length = the blur a collimated beam would form: well under 1 % of the focal length
    blur_mm = np.max(np.abs(result.direction[:, 0])) * data.efl_mm
    assert blur_mm < 0.002 * data.efl_mm


opencl_host = pytest.importorskip("realistic.camera.opencl_host")
Device = pytest.importorskip("realistic.device.opencl").Device


@pytest.mark.parametrize("name, film_diagonal_mm, samplings, direction_atol", [
    ("canon-ef24-f1.4", 43.27, ("pupil", "rear"), 1e-5),
    ("phone-us10101561", 6.0, ("pupil",), 5e-5),
])
def test_kernel_matches_tracer_on_bundled_aspheric_lenses(name, film_diagonal_mm, samplings, direction_atol):
    """As for the spherical lenses (tests/test_kernel.py). The phone lens's rear element is far wider
    than its beam, so its rear-element sampler passes too few rays to compare; its pupil sampler is used.
    Its polynomials cancel heavily: at the rim of surface 8 the terms of the sag slope sum to about
    3900 in magnitude against a slope of 153 (``sum |m A_m| r^(2m-2)``), so float32's 24 bits leave the
    slope a few 1e-5 uncertain near the rims, and directions are compared to 5e-5 there."""
    try:
        Device.for_spec()
    except UserError as err:
        pytest.skip(f"no OpenCL platform: {err}")
    lens = load_lens(name)
    film = film_distance_for_focus(lens, 100 * paraxial_data(lens).efl_mm)
    camera = LensCamera(lens, film, film_diagonal_mm, 64, 48, spp=33, world_from_camera=world_from_camera(),
                        origin="front_vertex")
    for sampling in samplings:
        cam = dataclasses.replace(camera, lens_sampling=sampling) if sampling != "pupil" else camera
        count = cam.sample_count
        block = SampleBlock(0, count, cam.spp)
        kernel = backend_for("opencl").ray_generator(cam, 11)(block)
        assert_kernel_matches(kernel, cam.generate_rays(block, 11), cam, 11, direction_atol)
