"""Camera rays' texture footprints shrink with the samples per pixel as each pbrt's do (issue 34:
textures were filtered over a whole pixel where pbrt filters over 1/sqrt(spp) of one, so the
homework floor's lines came out blurred at useful sample counts)."""

import math

import numpy as np
import pytest

from realistic.camera.thin_lens import ThinLensCamera
from realistic.renderer.footprint import differential_scale
from realistic.renderer.job import PassSettings
from realistic.renderer.runner import PassRunner
from realistic.renderer.timing import StageClock
from realistic.scene.model import Scene
from realistic.scene.pbrt.importer import import_pbrt
from realistic.scene.shapes import quad


@pytest.mark.parametrize("spp,floor,expected", [(1, 0.0, 1.0), (16, 0.0, 0.25), (1024, 0.0, 1 / 32),
                                                (16, 0.125, 0.25), (64, 0.125, 0.125), (1024, 0.125, 0.125)])
def test_differential_scale_is_one_over_root_spp_above_the_floor(spp, floor, expected):
    assert differential_scale(spp, floor) == pytest.approx(expected, rel=1e-15)


@pytest.mark.parametrize("directive,floor", [("", 0.0), ('ColorSpace "srgb"\n', 0.125),
                                             ('SurfaceIntegrator "directlighting"\n', 0.0)])
def test_each_pbrt_version_sets_its_floor(tmp_path, directive, floor):
    path = tmp_path / "s.pbrt"
    path.write_text(f'{directive}Camera "perspective"\nWorldBegin\nWorldEnd\n')
    assert import_pbrt(path).scene.differential_floor == floor


@pytest.mark.parametrize("spp,floor", [(4, 0.0), (256, 0.0), (256, 0.125)])
def test_the_runner_hands_the_integrator_the_scaled_footprint(spp, floor):
    scene = Scene(differential_floor=floor)
    scene.add(quad(1.0, 1.0))
    camera = ThinLensCamera(40.0, 0.0, 1e6, 32, 24, spp, np.eye(4))
    runner = PassRunner(scene, camera, PassSettings(backend="numpy"), StageClock())
    expected = camera.pixel_spread_radians() * max(floor, 1 / math.sqrt(spp))
    assert runner.integrator.pixel_spread_radians == pytest.approx(expected, rel=1e-12)
