"""The library writes what the CLI writes: ``rl.save`` gives the header, exposure and rescue of ``render``."""

from pathlib import Path

import numpy as np
import pytest

import realistic as rl
from realistic.camera.exposure import exposure_scale
from realistic.cli import main
from realistic.core.image_files import read_exr
from realistic.renderer.job import RenderJob, RenderResult
from realistic.renderer.output import Photographic, image_metadata

SMALL = {"resolution": (8, 6), "spp": 2, "lens_sampling": "rear", "dispersion": False}
CLI = ["--backend", "numpy", "--res", "8x6", "--spp", "2", "--lens-sampling", "rear", "--dispersion", "off",
       "--threads", "1"]
#: Header fields that say how long the render took: the one thing two renders of a scene differ in.
TIMES = ("renderSeconds", "renderTimeSeconds", "exitPupilSeconds")


def _api_render(seed: int = 0) -> RenderResult:
    scene = rl.load_scene(**SMALL)
    return rl.render_job(RenderJob(scene, (scene.camera,), "numpy", seed), rl.ThreadPasses(1))[0]


def _same_header(api: dict, cli: dict) -> None:
    assert sorted(api) == sorted(cli)
    differ = [key for key in api if key not in TIMES and repr(api[key]) != repr(cli[key])]  # arrays: by repr
    assert not differ, {key: (api[key], cli[key]) for key in differ}


def test_the_api_writes_the_image_and_header_the_cli_writes(tmp_path):
    assert main(["render", *CLI, "--seed", "3", "--out", str(tmp_path / "cli.exr")]) == 0
    result = _api_render(seed=3)
    stops = rl.save(result, tmp_path / "api.exr")
    cli_image, cli_header = read_exr(tmp_path / "cli.exr")
    api_image, api_header = read_exr(tmp_path / "api.exr")
    _same_header(api_header, cli_header)
    assert {"scene", "spp", "seed", "backend", "samplesDone", "interrupted", "fNumber"} <= set(api_header)
    assert api_header["seed"] == 3 and api_header["scene"] == "default"
    np.testing.assert_array_equal(api_image, cli_image)  # the same job, bit for bit
    assert (tmp_path / "api.png").is_file() and np.isfinite(stops)


def test_a_photographic_exposure_is_the_cli_s_shutter_and_iso(tmp_path):
    assert main(["render", *CLI, "--shutter", "1/125", "--iso", "400", "--out", str(tmp_path / "cli.exr")]) == 0
    result = _api_render()
    assert rl.save(result, tmp_path / "api.exr", rl.Photographic(1 / 125, 400)) == 0.0  # exposed: no preview gain
    cli_image, cli_header = read_exr(tmp_path / "cli.exr")
    api_image, api_header = read_exr(tmp_path / "api.exr")
    _same_header(api_header, cli_header)
    assert api_header["exposureScale"] == pytest.approx(exposure_scale(1 / 125, 400))
    np.testing.assert_array_equal(api_image, cli_image)
    np.testing.assert_allclose(api_image, result.image * exposure_scale(1 / 125, 400), rtol=1e-6)


def test_a_failed_write_is_rescued_to_the_temporary_folder(tmp_path):
    result = _api_render()
    with pytest.raises(rl.UserError, match="the render was saved as") as caught:
        rl.save(result, tmp_path / "no such folder" / "x.exr")
    rescued = Path(str(caught.value).split("the render was saved as ")[1].split(" (and")[0])
    try:
        image, header = read_exr(rescued)
        np.testing.assert_array_equal(image, result.image)
        assert header["samplesDone"] == 8 * 6 * 2 and rescued.with_suffix(".png").is_file()
    finally:
        rescued.unlink()
        rescued.with_suffix(".png").unlink()


def test_a_sweep_frame_says_which_frame_of_which_sweep(tmp_path):
    scene = rl.load_scene(**SMALL)
    cameras = (scene.camera, scene.camera)
    job = RenderJob(scene, cameras, "numpy", sweep="focus=1:2:2")
    header = image_metadata(RenderResult(np.zeros((6, 8, 3), np.float32), 0, 96, 0, 0, 0.0, True, job=job, frame=1))
    assert (header["sweep"], header["frame"], header["frames"]) == ("focus=1:2:2", 2, 2)
    assert "sweep" not in image_metadata(_api_render())


def test_bad_output_settings_are_one_line_errors(tmp_path):
    with pytest.raises(rl.UserError, match="shutter time"):
        Photographic(0.0, 100)
    with pytest.raises(rl.UserError, match=r"\.exr file .*, a \.png or a \.pfm"):
        rl.save(_api_render(), tmp_path / "x.tif")
    with pytest.raises(rl.UserError, match="no render job"):
        rl.save(RenderResult(np.zeros((1, 1, 3), np.float32), 0, 1, 0, 0, 0.0, False), tmp_path / "x.exr")
