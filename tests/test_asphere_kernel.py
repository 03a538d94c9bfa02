"""The OpenCL kernel against the float64 tracer for aspheric lenses, with the tolerances of the spheres."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from kernel_reference import aspherised_dgauss, assert_kernel_matches, camera_for_lens
from realistic import load_lens
from realistic.camera.base import SampleBlock
from realistic.renderer.backends import backend_for

pytestmark = pytest.mark.usefixtures("opencl_platform")


@pytest.mark.parametrize("sampling", ["pupil", "rear"])
def test_kernel_matches_tracer_for_an_aspheric_lens(sampling):
    lens = aspherised_dgauss()
    camera = camera_for_lens(lens)
    if sampling != "pupil":
        camera = dataclasses.replace(camera, lens_sampling=sampling)
    count, seed = camera.sample_count, 11
    kernel = backend_for("opencl").ray_generator(camera, seed)(SampleBlock(0, count, camera.spp))
    reference = camera.generate_rays(SampleBlock(0, count, camera.spp), seed)
    assert_kernel_matches(kernel, reference, camera, seed)
    block = SampleBlock(0, count, camera.spp)
    spherical = dataclasses.replace(camera, lens=load_lens("dgauss")).generate_rays(block, seed)
    both = (reference.weight != 0) & (spherical.weight != 0)
    assert np.max(np.abs(reference.direction[both] - spherical.direction[both])) > 1e-3  # the aspheres matter
