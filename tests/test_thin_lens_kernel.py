"""The thin-lens (pbrt perspective) camera's OpenCL kernel (kernels/thin_lens.cl) against the
float64 numpy reference ``ThinLensCamera.generate_rays``, and the OpenCL backend's use of it.

Skips only when no OpenCL platform exists; CI installs PoCL through the package's dependencies.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from kernel_reference import world_from_camera
from realistic.camera.base import SampleBlock
from realistic.camera.thin_lens import ThinLensCamera
from realistic.core.pixel_filter import PIXEL_BOX, PixelFilter
from realistic.renderer.backends import backend_for

thin_lens_host = pytest.importorskip("realistic.camera.thin_lens_host")

pytestmark = pytest.mark.usefixtures("opencl_platform")

#: float32 against float64: unit directions to a few ulps; origins to float32's resolution of the
#: transform's translation (|t| about 430 mm: an ulp is 3e-5).
DIRECTION_TOLERANCE = 1e-6
ORIGIN_TOLERANCE = 1e-4

FILTERS = [PIXEL_BOX, PixelFilter("triangle", 2.0, 1.5), PixelFilter("gaussian", 1.5, 1.5, 2.0),
           PixelFilter("mitchell", 2.0, 2.0), PixelFilter("sinc", 3.0, 4.0)]


def camera(lens_radius: float, pixel_filter: PixelFilter = PIXEL_BOX, width: int = 64,
           height: int = 48) -> ThinLensCamera:
    """64 x 48 pixels x 33 samples at a 40 degree field of view, focused 900 mm away, posed by a
    rigid skew rotation and a translation (so every matrix entry is exercised)."""
    return ThinLensCamera(40.0, lens_radius, 900.0, width, height, 33, world_from_camera(), pixel_filter)


def assert_kernel_matches(subject: ThinLensCamera, block: SampleBlock, seed: int = 7) -> None:
    reference = subject.generate_rays(block, seed)
    rays = thin_lens_host.ThinLensKernel(subject).generate(block, seed)
    assert np.array_equal(rays.pixel, reference.pixel)
    np.testing.assert_allclose(rays.direction, reference.direction, rtol=0, atol=DIRECTION_TOLERANCE)
    np.testing.assert_allclose(rays.origin, reference.origin, rtol=0, atol=ORIGIN_TOLERANCE)
    np.testing.assert_allclose(rays.weight, reference.weight, rtol=1e-6, atol=0)
    assert rays.wavelength_nm is None


@pytest.mark.parametrize("lens_radius", [0.0, 3.0], ids=["pinhole", "thin lens"])
def test_kernel_matches_reference_over_the_whole_frame(lens_radius):
    subject = camera(lens_radius)
    assert_kernel_matches(subject, SampleBlock(0, subject.sample_count, subject.spp))


@pytest.mark.parametrize("pixel_filter", FILTERS, ids=lambda f: f.name)
def test_kernel_matches_reference_with_pixel_filters(pixel_filter):
    """Film offsets drawn from each filter (box, exact tent, tables with signed weights) agree,
    weights included."""
    subject = camera(3.0, pixel_filter)
    assert_kernel_matches(subject, SampleBlock(0, subject.sample_count, subject.spp))


@pytest.mark.parametrize("block", [SampleBlock.of_pixels(7, 300, 5, 11), SampleBlock(1000, 70_001, 33),
                                   SampleBlock.of_pixels(3000, 72, 32, 1)],
                         ids=["slice", "mid-pixel start", "last sample"])
def test_kernel_matches_reference_on_pass_blocks(block):
    """Blocks as the renderer's passes cut them: a slice of each pixel's samples, a block starting
    inside a pixel, and one sample of each pixel."""
    assert_kernel_matches(camera(3.0), block)


def test_kernel_on_a_wide_frame_and_a_tall_one():
    """The screen window's longer side spans [-aspect, aspect] either way round."""
    for width, height in ((97, 31), (31, 97)):
        subject = camera(1.5, width=width, height=height)
        assert_kernel_matches(subject, SampleBlock(0, subject.sample_count, subject.spp))


def test_pinhole_rays_leave_the_camera_centre_through_the_screen_window():
    """A closed form, apart from the reference: every pinhole ray starts at the camera's position,
    and its direction in camera space, scaled to z = 1, lies inside the screen window
    [-aspect, aspect] x [-1, 1] times tan(fov / 2) (box filter: within the frame)."""
    subject = camera(0.0)
    rays = thin_lens_host.ThinLensKernel(subject).generate(SampleBlock(0, subject.sample_count, subject.spp))
    np.testing.assert_allclose(rays.origin, np.broadcast_to(world_from_camera()[:3, 3], rays.origin.shape),
                               atol=ORIGIN_TOLERANCE)
    local = rays.direction @ world_from_camera()[:3, :3]  # the inverse rotation
    assert np.all(local[:, 2] > 0)
    tan_half = math.tan(math.radians(subject.fov_deg) / 2)
    half_x, half_y = subject.screen_window()
    assert np.all(np.abs(local[:, 0] / local[:, 2]) <= half_x * tan_half * (1 + 1e-6))
    assert np.all(np.abs(local[:, 1] / local[:, 2]) <= half_y * tan_half * (1 + 1e-6))


def test_opencl_backend_makes_thin_lens_rays_with_the_kernel():
    """The OpenCL backend's ray generator for a ``ThinLensCamera`` is the kernel's (float32), with
    the seed bound; the numpy backend's is the reference (float64)."""
    subject = camera(3.0)
    block = SampleBlock(0, 5000, subject.spp)
    rays = backend_for("opencl").ray_generator(subject, 11)(block)
    reference = backend_for("numpy").ray_generator(subject, 11)(block)
    assert rays.direction.dtype == np.float32 and reference.direction.dtype == np.float64
    np.testing.assert_allclose(rays.direction, reference.direction, rtol=0, atol=DIRECTION_TOLERANCE)


def test_launches_keep_to_the_grid_variant_of_the_first_and_make_the_same_rays():
    """``opencl_host.LaunchSizes``: after a first launch of at least ``SMALL_GRID_LIMIT`` work items,
    smaller launches are padded up to it (one PoCL variant); after a smaller first launch nothing is
    padded beyond whole work groups, a larger launch included; per work item rays scale both. A
    block's rays are the same bits from a padded launch as from an unpadded one."""
    from realistic.camera.opencl_host import SMALL_GRID_LIMIT, LaunchSizes
    from realistic.device.opencl import LOCAL_SIZE

    small, large = SampleBlock(5, 3000, 33), SampleBlock(0, SMALL_GRID_LIMIT + 1, 33)
    padded = LaunchSizes()
    assert padded.layout(large)[1] == SMALL_GRID_LIMIT + LOCAL_SIZE
    assert padded.layout(small)[1] == SMALL_GRID_LIMIT
    unpadded = LaunchSizes()
    assert unpadded.layout(small)[1] == 3072
    assert unpadded.layout(large)[1] == SMALL_GRID_LIMIT + LOCAL_SIZE
    four = LaunchSizes()  # the lens kernel's four rays a work item: 2^18 - 1024 rays are a small grid
    assert four.layout(SampleBlock(0, 4 * SMALL_GRID_LIMIT - 1024, 33), per_item=4)[1] == 4 * SMALL_GRID_LIMIT - 1024
    assert four.layout(small, per_item=4)[1] == 3072
    assert LaunchSizes().layout(SampleBlock(0, 4 * SMALL_GRID_LIMIT - 1, 33), per_item=4)[1] == 4 * SMALL_GRID_LIMIT
    subject = camera(3.0)
    first_large, first_small = thin_lens_host.ThinLensKernel(subject), thin_lens_host.ThinLensKernel(subject)
    first_large.generate(SampleBlock(0, SMALL_GRID_LIMIT, 33), 7)
    first_small.generate(small, 7)
    a, b = first_large.generate(small, 7), first_small.generate(small, 7)
    for field in ("origin", "direction", "weight", "pixel"):
        assert getattr(a, field).tobytes() == getattr(b, field).tobytes()
