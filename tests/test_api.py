"""The Python API as README.md shows it: the example runs as written and does what it says."""

import re
from pathlib import Path

import numpy as np
import pytest

import realistic as rl
from realistic.core.image_files import read_exr

README = Path(__file__).resolve().parents[1] / "README.md"


def readme_example() -> str:
    section = README.read_text(encoding="utf-8").split("## Python API", 1)[1]
    return re.search(r"```python\n(.*?)```", section, re.S).group(1)


def test_readme_example_runs_and_writes_what_it_says(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    names: dict = {}
    exec(compile(readme_example(), str(README), "exec"), names)
    image, scene = names["image"], names["scene"]
    assert image.shape == (120, 160, 3) and image.dtype == np.float32
    assert np.all(np.isfinite(image)) and image.mean() > 0
    written, header = read_exr(tmp_path / "telephoto.exr")
    assert written.shape == (120, 160, 3) and written.mean() > 0
    # the scene's own camera is the default scene's 50 mm lens; the example's is the 250 mm one
    assert scene.camera.lens.name == "dgauss" and names["tele"].lens.name == "telephoto"


def test_readme_job_example_saves_what_the_cli_writes(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    section = README.read_text(encoding="utf-8").split("## Python API", 1)[1]
    first, job_example = re.findall(r"```python\n(.*?)```", section, re.S)[:2]
    names: dict = {}
    exec(compile(first.replace("spp=4", "spp=1"), str(README), "exec"), names)
    exec(compile(job_example, str(README), "exec"), names)
    image, header = read_exr(tmp_path / "telephoto.exr")
    assert header["shutterSeconds"] == pytest.approx(1 / 125) and header["iso"] == 400
    assert header["seed"] == 1 and header["samplesDone"] == header["samplesTotal"] == 160 * 120 * header["spp"]
    assert (tmp_path / "telephoto.png").is_file() and image.mean() > 0


def test_render_uses_the_scene_camera_unless_given_one():
    scene = rl.load_scene(resolution=(8, 6), spp=1, dispersion=False)
    assert rl.render(scene, backend="numpy").shape == (6, 8, 3)
    other = rl.LensCamera.looking_at(rl.load_lens("wide"), (1, 1, 1), (0, 0, 0), width=4, height=2, spp=1)
    assert rl.render(scene, other, "numpy").shape == (2, 4, 3)
    with pytest.raises(rl.UserError, match="no camera"):
        rl.render(rl.Scene(), backend="numpy")


def test_the_default_scene_renders_as_its_pbrt_file_does_without_dispersion_unless_asked():
    from pathlib import Path

    default_file = Path(__file__).resolve().parents[1] / "scenes" / "default.pbrt"
    assert not rl.load_scene(resolution=(8, 6), spp=1).camera.spectral
    with pytest.warns(UserWarning, match="bundled"):  # the lens file is not beside the scene
        assert not rl.load_scene(str(default_file), resolution=(8, 6), spp=1).camera.spectral
    assert rl.load_scene(resolution=(8, 6), spp=1, dispersion=True).camera.spectral


def test_public_names_resolve_and_unknown_ones_fail():
    for name in rl.__all__:
        assert getattr(rl, name) is not None
    with pytest.raises(AttributeError):
        rl.no_such_name  # noqa: B018


def test_render_stays_the_function_once_the_renderer_is_imported():
    import realistic.renderer.inputs  # noqa: F401  (binds realistic.renderer, never realistic.render)

    assert callable(rl.render) and rl.render.__module__ == "realistic"
