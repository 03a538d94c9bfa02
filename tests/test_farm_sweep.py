"""``--sweep NAME=START:STOP:N`` (renderer/sweep): parsing, the cameras it makes, frame names."""

import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from realistic import load_lens
from realistic.camera.lens_camera import LensCamera
from realistic.camera.thin_lens import ThinLensCamera
from realistic.errors import UserError
from realistic.optics.paraxial import paraxial_data
from realistic.renderer.sweep import QUANTITIES, frame_path, parse_sweep, sweep_cameras

CAMERA = LensCamera.looking_at(load_lens("dgauss"), np.array([0.0, 0.5, -3.0]), np.zeros(3), 3.0, 43.27, 32, 24, 1)


@given(st.text(max_size=40))
def test_any_text_is_a_sweep_or_one_line_error(text):
    try:
        sweep = parse_sweep(text)
    except UserError as err:
        assert "\n" not in str(err) and str(err).startswith("--sweep")
    else:
        assert sweep.quantity in QUANTITIES and sweep.values and all(v > 0 for v in sweep.values)


@given(st.sampled_from(QUANTITIES), st.floats(1.0, 20.0), st.floats(1.0, 20.0), st.integers(1, 50))
def test_values_run_evenly_from_start_to_stop(name, start, stop, count):
    sweep = parse_sweep(f"{name}={start!r}:{stop!r}:{count}")
    assert len(sweep.values) == count and sweep.values[0] == start
    if count > 1:
        assert sweep.values[-1] == pytest.approx(stop)
        assert np.allclose(np.diff(sweep.values), (stop - start) / (count - 1))


@pytest.mark.parametrize("text", ["focus=1:2", "zoom=1:2:3", "focus=-1:2:3", "focus=1:nan:3", "aperture=1:2:0",
                                  "fstop=a:b:c", "focus=1:2:3.5"])
def test_bad_sweeps_are_refused(text):
    with pytest.raises(UserError, match="--sweep"):
        parse_sweep(text)


def test_focus_sweep_moves_the_film_as_the_thick_lens_says():
    """Nearer focus needs the film farther from the lens; a far focus approaches the back focal length."""
    cameras = sweep_cameras(CAMERA, parse_sweep("focus=0.5:1000:4"))
    distances = [c.film_distance_mm for c in cameras]
    assert distances == sorted(distances, reverse=True)
    assert distances[-1] == pytest.approx(paraxial_data(CAMERA.lens).bfl_mm, abs=0.05)


def test_aperture_fstop_and_film_distance_sweeps_set_what_they_name():
    stops = sweep_cameras(CAMERA, parse_sweep("aperture=5:10:2"))
    assert [c.lens.stop_diameter_mm for c in stops] == [5.0, 10.0]
    films = sweep_cameras(CAMERA, parse_sweep("film-distance=36:38:3"))
    assert [c.film_distance_mm for c in films] == [36.0, 37.0, 38.0]
    slow, fast = sweep_cameras(CAMERA, parse_sweep("fstop=8:4:2"))
    assert fast.lens.stop_diameter_mm == pytest.approx(2 * slow.lens.stop_diameter_mm)


def test_sweeps_need_a_lens_camera():
    thin = ThinLensCamera(45.0, 0.0, 1.0, 16, 12, 1, np.eye(4))
    with pytest.raises(UserError, match="needs a lens camera"):
        sweep_cameras(thin, parse_sweep("focus=1:2:2"))


def test_frames_are_numbered_from_one_beside_the_output():
    assert frame_path(Path("shots/out.exr"), 0) == Path("shots/out_0001.exr")
    assert frame_path(Path("out.exr"), 23) == Path("out_0024.exr")
    assert math.isclose(parse_sweep("FOCUS=2:2:1").values[0], 2.0)


def _counting_prepares(monkeypatch) -> list[float]:
    """Patch ``LensCamera.prepare`` to record each camera's film distance as it is prepared."""
    prepared: list[float] = []
    original = LensCamera.prepare

    def prepare(camera: LensCamera) -> None:
        prepared.append(camera.film_distance_mm)
        original(camera)

    monkeypatch.setattr(LensCamera, "prepare", prepare)
    return prepared


def test_a_sweep_prepares_each_frame_as_it_starts_and_streams_its_frames(monkeypatch):
    """``--sweep focus=1:5:1000`` built every exit-pupil table before the first frame (issue 32)."""
    from realistic.renderer.job import RenderJob, RenderObserver
    from realistic.renderer.passes import ThreadPasses, render
    from realistic.scene.staging import default_setup

    setup = default_setup()
    camera = LensCamera.looking_at(load_lens("dgauss"), setup.eye, setup.target, None, 43.27, 8, 6, 1)
    cameras = sweep_cameras(camera, parse_sweep("focus=1:5:4"))
    prepared = _counting_prepares(monkeypatch)
    seen: list[tuple[int, int, int]] = []

    def on_frame(result) -> None:
        seen.append((result.frame, len(set(prepared)), result.image.shape[0]))

    results = render(RenderJob(setup.scene, cameras, "numpy", keep_images=False), ThreadPasses(1),
                     RenderObserver(on_frame=on_frame))
    assert seen == [(0, 1, 6), (1, 2, 6), (2, 3, 6), (3, 4, 6)]  # each frame handed on before the next is prepared
    assert sorted(set(prepared)) == sorted(c.film_distance_mm for c in cameras)
    assert all(r.image.size == 0 and r.samples_done == r.samples_total for r in results)  # not kept


def test_the_cli_writes_each_sweep_frame_before_preparing_the_next(tmp_path, monkeypatch, capsys):
    from realistic.cli import main

    prepared = _counting_prepares(monkeypatch)
    written: dict[str, int] = {}
    import realistic.renderer.output as output

    original_save = output.save

    def save(result, path, *args, **kwargs):
        written[Path(path).name] = len(set(prepared))
        return original_save(result, path, *args, **kwargs)

    monkeypatch.setattr(output, "save", save)
    assert main(["render", "--backend", "numpy", "--res", "8x6", "--spp", "1", "--threads", "1",
                 "--sweep", "focus=1:5:3", "--out", str(tmp_path / "s.exr")]) == 0
    assert written == {"s_0001.exr": 1, "s_0002.exr": 2, "s_0003.exr": 3}


def test_a_sweep_longer_than_the_bound_is_refused_in_one_line():
    with pytest.raises(UserError, match=r"COUNT must be between 1 and 10000, got 10001"):
        parse_sweep("focus=1:5:10001")
    assert len(parse_sweep("focus=1:5:1000").values) == 1000
