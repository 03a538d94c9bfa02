"""PoCL's work-group vectoriser widens the ghost kernel (kernels/ghost.cl) for a lens of spheres and one
with aspheres, each with layer coatings: no call to a builtin math function is left to stop it, and
the region of one step is a loop over the work items that it vectorises. The remarks need a fresh
build, so each check runs in a process of its own."""

from __future__ import annotations

import pytest

from conftest import vectoriser_remarks

pytestmark = pytest.mark.usefixtures("opencl_platform")

SCRIPT = """
import sys
from realistic import load_lens
from realistic.camera.ghost_host import GhostKernel
from realistic.optics.ghosts import collimated_rays, ghost_paths

lens = load_lens(sys.argv[1]).with_coating("mgf2")
origins, directions = collimated_rays(lens, 50.0, 5.0, across=16)
GhostKernel(lens).trace(50.0, ghost_paths(lens)[0], origins, directions)
"""


@pytest.mark.parametrize("lens", ["dgauss", "phone-us10101561"])
def test_ghost_kernel_vectorises(tmp_path, lens):
    remarks = vectoriser_remarks(SCRIPT, lens, pocl_cache=tmp_path)
    assert "call instruction cannot be vectorized" not in remarks and "vectorized loop" in remarks, remarks[-2000:]
