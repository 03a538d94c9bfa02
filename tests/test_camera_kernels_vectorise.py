"""PoCL's work-group vectoriser widens both camera kernels (kernels/lens.cl, kernels/thin_lens.cl)
with every pixel filter kind: a kernel it cannot widen runs one work item at a time, several times
slower. The filter offsets live once in kernels/common.cl (CAMERA_SAMPLES), written so that LLVM's
SLP vectoriser does not pack the x and y chains (see the comments there). The remarks need a fresh
build, so each check runs in a process of its own."""

from __future__ import annotations

import pytest

from conftest import vectoriser_remarks

pytestmark = pytest.mark.usefixtures("opencl_platform")

SCRIPT = """
import dataclasses
import sys
import numpy as np
from realistic import load_lens
from realistic.camera.base import SampleBlock
from realistic.camera.lens_camera import LensCamera
from realistic.camera.opencl_host import LensKernel
from realistic.camera.thin_lens import ThinLensCamera
from realistic.camera.thin_lens_host import ThinLensKernel
from realistic.core.pixel_filter import PixelFilter

pixel_filter = PixelFilter(*{"box": ("box",), "triangle": ("triangle", 2.0, 2.0),
                             "gaussian": ("gaussian", 1.5, 1.5, 2.0)}[sys.argv[1]])
lens_camera = dataclasses.replace(LensCamera.looking_at(load_lens("dgauss"), np.zeros(3), np.array([0.0, 0.0, -1.0]),
                                                       width=16, height=12, spp=2), pixel_filter=pixel_filter)
thin = ThinLensCamera(40.0, 1.0, 900.0, 16, 12, 2, np.eye(4), pixel_filter)
for kernel in (LensKernel(lens_camera), ThinLensKernel(thin)):
    kernel.generate(SampleBlock(0, 16 * 12 * 2, 2), 1)
"""


@pytest.mark.parametrize("kind", ["box", "triangle", "gaussian"])
def test_both_camera_kernels_vectorise_with_each_filter_kind(tmp_path, kind):
    remarks = vectoriser_remarks(SCRIPT, kind, pocl_cache=tmp_path)
    assert "loop not vectorized" not in remarks and remarks.count("vectorized loop") >= 2, remarks[-2000:]
