"""Autofocus: a point at an unknown depth ends up sharp, measured on the rendered edge it sits on."""

import numpy as np
import pytest

from realistic import UserError, load_lens
from realistic.camera.autofocus import autofocus_distance_mm
from realistic.camera.lens_camera import LensCamera
from realistic.core.transforms import rotate, translate
from realistic.renderer.job import RenderJob
from realistic.renderer.passes import render
from realistic.scene.intersect import Intersector
from realistic.scene.model import AreaLight, Scene

DEPTH = 1.5  # m from the camera (the film centre) to the edge


def edge_scene() -> Scene:
    """A glowing rectangle facing the camera whose right edge is the vertical line x = 0.2 m."""
    scene = Scene()
    scene.lights.append(AreaLight("quad", (1.0, 2.0), (1.0, 1.0, 1.0),
                                  translate(-0.3, 0.0, DEPTH) @ rotate(180, (0, 1, 0))))
    return scene


def camera(focus_m):
    # a wide strip of small pixels (0.11 mm): the blur of the edge spans several of them
    return LensCamera.looking_at(load_lens("dgauss"), np.zeros(3), np.array([0.0, 0.0, DEPTH]), focus_m, 43.27,
                                 384, 64, 32)


def edge_width_px(image: np.ndarray) -> tuple[float, float]:
    """10-90 % width and 50 % position (pixels) of the bright-to-dark edge in the middle rows.

    The bright side falls off toward the image side (vignetting and cos^4): it is flat-fielded by
    a straight line fitted to it away from the edge.
    """
    profile = image[24:40, :, 1].mean(axis=0)
    edge = int(np.argmin(np.diff(profile)))  # the steepest drop
    columns = np.arange(len(profile))
    trend = np.polyval(np.polyfit(columns[edge - 16:edge - 6], profile[edge - 16:edge - 6], 1), columns)
    dark = profile[edge + 9:edge + 15].mean()
    level = (profile - dark) / (trend - dark)
    crossing = []
    for q in (0.9, 0.5, 0.1):  # first column after edge - 8 whose level is below q, interpolated
        i = edge - 8 + int(np.argmax(level[edge - 8:] < q))
        crossing.append(i - 1 + (level[i - 1] - q) / (level[i - 1] - level[i]) + 0.5)
    return crossing[2] - crossing[0], crossing[1]


def test_autofocus_makes_the_edge_sharp():
    scene = edge_scene()
    far = camera(6.0)  # focused well behind the edge: f/2 blurs it over several pixels
    blurred, edge_x = edge_width_px(render(RenderJob(scene, (far,), "numpy"))[0].image)
    focus_mm = autofocus_distance_mm(far, edge_x - 3, 32, Intersector(scene).hit_distance)
    # within a few % of the thick-lens distance: the real-ray best focus of an f/2 double Gauss sits
    # about 0.06 mm in front of the paraxial one (spherical aberration), a few % in object space
    assert focus_mm == pytest.approx(DEPTH * 1000, rel=0.05)
    sharp, _ = edge_width_px(render(RenderJob(scene, (camera(focus_mm / 1000),), "numpy"))[0].image)
    # defocused by 6 m vs 1.5 m the blur disk is about 0.49 mm (4.4 pixels) wide; in focus the edge
    # spreads over little more than the pixel it falls in
    assert sharp < 2.0
    assert blurred > 2 * sharp


def test_autofocus_errors_are_clear():
    scene = edge_scene()
    far = camera(6.0)
    with pytest.raises(UserError, match="outside the 384x64 image"):
        autofocus_distance_mm(far, 500, 10, Intersector(scene).hit_distance)
    with pytest.raises(UserError, match="nothing at the focus pixel"):
        autofocus_distance_mm(far, 380, 32, Intersector(scene).hit_distance)  # right of the edge: nothing there


def test_focus_on_through_the_cli(tmp_path):
    from realistic.cli import main
    from realistic.core.image_files import read_exr

    out = tmp_path / "af.exr"
    # the default scene's middle object sits at the image centre, 2.74 m from the camera
    assert main(["render", "--backend", "numpy", "--res", "60x60", "--spp", "1", "--focus-on", "30,30",
                 "--dispersion", "off", "--out", str(out)]) == 0
    header = read_exr(out)[1]
    assert header["focusOn"].dtype == np.float32 and header["focusOn"].tolist() == [30, 30]  # a V2f
    assert float(header["focusDistanceMm"]) == pytest.approx(2737, rel=0.05)


def test_focus_on_builds_one_embree_scene_for_autofocus_and_render(tmp_path, monkeypatch):
    """The autofocus pick's Intersector is the one the render uses: built once, not twice."""
    from realistic.cli import main
    from realistic.scene.intersect import Intersector

    built = []
    build = Intersector.__init__

    def counting(self, *args, **kwargs):
        built.append(1)
        build(self, *args, **kwargs)

    monkeypatch.setattr(Intersector, "__init__", counting)
    assert main(["render", "--backend", "numpy", "--res", "16x16", "--spp", "1", "--focus-on", "8,8",
                 "--dispersion", "off", "--threads", "2", "--out", str(tmp_path / "af.exr")]) == 0
    assert len(built) == 1
    assert main(["render", "--backend", "numpy", "--res", "16x16", "--spp", "1", "--dispersion", "off",
                 "--threads", "2", "--out", str(tmp_path / "plain.exr")]) == 0
    assert len(built) == 2  # a render without --focus-on builds its own, once
