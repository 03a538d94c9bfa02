"""PoCL's work-group vectoriser widens the ghost kernel (kernels/ghost.cl) for a lens of spheres and one
with aspheres, each with layer coatings: no call to a builtin math function is left to stop it, and
the region of one step is a loop over the work items that it vectorises. The remarks need a fresh
build, so each check runs in a process of its own."""

from __future__ import annotations

import pytest

from conftest import run_fresh

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
    run = run_fresh(SCRIPT, lens, POCL_KERNEL_CACHE="0", POCL_VECTORIZER_REMARKS="1", POCL_CACHE_DIR=str(tmp_path),
                    REALISTIC_CACHE_DIR="off")  # compiled from source, not loaded from realistic's cache
    remarks = run.stdout + run.stderr
    if "vectorized loop" not in remarks and "not vectorized" not in remarks:
        pytest.skip("this PoCL prints no vectoriser remarks")
    assert "call instruction cannot be vectorized" not in remarks and "vectorized loop" in remarks, remarks[-2000:]
