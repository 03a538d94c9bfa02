"""Crops (``--cropwindow``, ``--pixelbounds``; renderer/crop): pbrt-v4's pixel bounds, bit-identical
pixels, the EXR's windows, and checkpoints that refuse another crop.

pbrt-v4 (``src/pbrt/film.cpp``) turns an NDC crop window into pixels with ``ceil(resolution *
crop)`` at both ends, renders those pixels only, and writes an image of the bounds' size whose
EXR data window is the bounds and display window the full resolution (``util/image.cpp``)."""

import re

import imageio.v3 as iio
import numpy as np
import pytest

from realistic import load_lens
from realistic.camera.lens_camera import LensCamera
from realistic.cli import main
from realistic.core.image_files import read_exr
from realistic.errors import UserError
from realistic.renderer.crop import PixelBounds
from realistic.renderer.job import Checkpointing, RenderJob, RenderObserver
from realistic.renderer.output import save
from realistic.renderer.pass_plan import plan_passes
from realistic.renderer.passes import ThreadPasses, render
from realistic.scene.staging import default_setup

FAST = ["--backend", "numpy", "--res", "20x12", "--spp", "3", "--pass-samples", "40"]


@pytest.fixture(scope="module")
def tiny():
    setup = default_setup()
    return setup.scene, LensCamera.looking_at(load_lens("dgauss"), setup.eye, setup.target, None, 43.27, 20, 12, 6)


def test_a_crop_window_takes_the_pixels_pbrt_v4_takes():
    # ceil(10 * 0.25) = 3, ceil(10 * 0.75) = 8; ceil(5 * 0.25) = 2, ceil(5 * 0.75) = 4
    assert PixelBounds.of_crop_window((0.25, 0.75, 0.25, 0.75), 10, 5) == PixelBounds(3, 8, 2, 4)
    assert PixelBounds.of_crop_window((0, 1, 0, 1), 7, 3) == PixelBounds.whole(7, 3)
    assert PixelBounds.of_crop_window((0.5, 1, 0, 0.5), 20, 12) == PixelBounds(10, 20, 0, 6)


@pytest.mark.parametrize("crop", [(0.5, 0.5, 0, 1), (0, 1.5, 0, 1), (0.6, 0.4, 0, 1), (0, 1, float("nan"), 1)])
def test_a_bad_crop_window_is_one_line(crop):
    with pytest.raises(UserError) as err:
        PixelBounds.of_crop_window(crop, 10, 10)
    assert "\n" not in str(err.value) and "crop window" in str(err.value)


def test_a_crop_window_between_pixels_is_refused():
    with pytest.raises(UserError, match="covers no pixel of the 64x48 image"):
        PixelBounds.of_crop_window((0.1, 0.101, 0, 1), 64, 48)


@pytest.mark.parametrize("bounds", [PixelBounds(0, 21, 0, 12), PixelBounds(-1, 3, 0, 2), PixelBounds(4, 4, 0, 2)])
def test_a_job_refuses_bounds_outside_its_image(tiny, bounds):
    scene, camera = tiny
    with pytest.raises(UserError, match="pixel bounds .* 20x12"):
        RenderJob(scene, (camera,), "numpy", crop=bounds)


@pytest.mark.parametrize("bounds", [PixelBounds(3, 17, 2, 9), PixelBounds(0, 20, 4, 7), PixelBounds(5, 6, 11, 12)])
@pytest.mark.parametrize("pass_samples", [7, 40, 100000])
def test_a_crop_runs_the_whole_plans_passes_that_hold_its_pixels(bounds, pass_samples):
    """The sample ids of a pixel, and the passes that group them, do not change with a crop."""
    width, height, spp = 20, 12, 13
    whole = plan_passes(width * height, spp, pass_samples)
    cropped = bounds.passes(whole, width)
    inside = {y * width + x for y in range(bounds.y0, bounds.y1) for x in range(bounds.x0, bounds.x1)}
    holding = [block for block in whole
               if inside & set(range(block.first_pixel, block.first_pixel + block.pixel_count))]
    assert cropped == holding
    assert sum(bounds.samples_in(block, width) for block in cropped) == len(inside) * spp


@pytest.mark.parametrize("backend", ["numpy", "opencl"])
def test_cropped_pixels_are_bit_identical_to_the_whole_render(tiny, backend):
    scene, camera = tiny
    whole = render(RenderJob(scene, (camera,), backend, seed=3, pass_samples=50), ThreadPasses(2))[0].image
    for bounds in (PixelBounds(3, 17, 2, 9), PixelBounds(0, 20, 5, 8), PixelBounds(19, 20, 0, 1)):
        cropped = render(RenderJob(scene, (camera,), backend, seed=3, pass_samples=50, crop=bounds),
                         ThreadPasses(2))[0]
        assert cropped.image.shape == (bounds.height, bounds.width, 3)
        assert cropped.samples_total == bounds.width * bounds.height * camera.spp == cropped.samples_done
        assert 0 < cropped.primary_rays <= cropped.samples_total  # the crop's rays alone are traced
        assert np.array_equal(cropped.image, whole[bounds.y0:bounds.y1, bounds.x0:bounds.x1])
    assert whole.max() > 0


def test_the_exr_says_where_the_crop_lies(tmp_path, capsys):
    out = tmp_path / "c.exr"
    assert main(["render", *FAST, "--cropwindow", "0.25", "0.75", "0", "0.5", "-o", str(out)]) == 0
    image, header = read_exr(out)
    assert image.shape == (6, 10, 3)  # x: ceil(5) .. ceil(15); y: 0 .. ceil(6)
    assert [list(v) for v in header["dataWindow"]] == [[5, 0], [14, 5]]
    assert [list(v) for v in header["displayWindow"]] == [[0, 0], [19, 11]]
    assert "pixels 5 15 0 6 of 20x12" in capsys.readouterr().out
    assert iio.imread(tmp_path / "c.png").shape == (6, 10, 3)


def test_pbrt_v4_comma_form_and_pixelbounds_give_the_same_image(tmp_path, capsys):
    outs = [tmp_path / f"{name}.exr" for name in "abcd"]
    assert main(["render", *FAST, "--cropwindow", "0.25,0.75,0,0.5", "-o", str(outs[0])]) == 0
    assert main(["render", *FAST, "--pixelbounds", "5", "15", "0", "6", "-o", str(outs[1])]) == 0
    assert main(["render", *FAST, "--pixelbounds", "5,15,0,6", "-o", str(outs[2])]) == 0
    assert main(["render", *FAST, "-o", str(outs[3])]) == 0
    images = [read_exr(out)[0] for out in outs]
    assert all(np.array_equal(image, images[0]) for image in images[1:3])
    assert np.array_equal(images[0], images[3][0:6, 5:15])


@pytest.mark.parametrize("args, message", [
    (["--cropwindow", "0", "2", "0", "1"], "crop window 0 2 0 1 is not"),
    (["--cropwindow", "0,1,0"], "expected 4 arguments"),
    (["--pixelbounds", "0", "30", "0", "4"], "pixel bounds 0 30 0 4 are not .*the image is 20x12"),
    (["--pixelbounds", "0", "1.5", "0", "4"], "'1.5' is not a whole number"),
    (["--pixelbounds", "0", "1", "0", "1", "--cropwindow", "0", "1", "0", "1"], "not allowed with"),
])
def test_bad_crops_on_the_command_line_are_one_line(tmp_path, args, message, capsys):
    assert main(["render", *FAST, *args, "-o", str(tmp_path / "x.exr")]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1
    assert re.search(message, err), err
    assert not (tmp_path / "x.exr").exists()


def test_a_checkpoint_resumes_its_crop_and_refuses_another(tiny, tmp_path):
    scene, camera = tiny
    bounds = PixelBounds(3, 17, 2, 9)
    path = tmp_path / "c.exr.partial"
    calls = []

    def stop(result):
        calls.append(1)
        if len(calls) == 2:
            raise KeyboardInterrupt

    job = RenderJob(scene, (camera,), "numpy", pass_samples=20, checkpoint=Checkpointing(path, None), crop=bounds)
    assert render(job, ThreadPasses(1), RenderObserver(on_pass=stop))[0].interrupted and path.is_file()
    for other in (None, PixelBounds(3, 17, 2, 8)):
        with pytest.raises(UserError, match="cannot resume: the checkpoint is for another crop"):
            render(RenderJob(scene, (camera,), "numpy", pass_samples=20, checkpoint=Checkpointing(path, None, True),
                             crop=other), ThreadPasses(1))
    resumed = render(RenderJob(scene, (camera,), "numpy", pass_samples=20, checkpoint=Checkpointing(path, None, True),
                               crop=bounds), ThreadPasses(1))[0]
    whole = render(RenderJob(scene, (camera,), "numpy", pass_samples=20, crop=bounds), ThreadPasses(1))[0]
    assert np.array_equal(resumed.image, whole.image)
    save(resumed, tmp_path / "c.exr")
    assert not path.exists()


def test_a_crop_on_a_dask_farm_is_the_crop_rendered_here(tiny):
    distributed = pytest.importorskip("distributed", reason="dask[distributed] is the farm extra")
    from realistic.renderer.farm import DaskPasses

    scene, camera = tiny
    bounds = PixelBounds(3, 17, 2, 9)
    here = render(RenderJob(scene, (camera,), "numpy", seed=2, pass_samples=50, crop=bounds), ThreadPasses(2))[0]
    cluster = distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=True, dashboard_address=None)
    with cluster, distributed.Client(cluster) as client:
        there = render(RenderJob(scene, (camera,), "numpy", seed=2, pass_samples=50, crop=bounds),
                       DaskPasses(client))[0]
    assert np.array_equal(there.image, here.image) and there.image.shape == (7, 14, 3)
