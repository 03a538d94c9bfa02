"""Checkpoints (renderer/checkpoint): identity, refusals in one line, resume bit-identical, SIGKILL."""

import dataclasses
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from realistic import load_lens
from realistic.camera.lens_camera import LensCamera
from realistic.core.image_files import read_exr
from realistic.errors import UserError
from realistic.renderer.checkpoint import RenderIdentity, content_hash, load_checkpoint
from realistic.renderer.job import Checkpointing, RenderJob, RenderObserver
from realistic.renderer.output import save
from realistic.renderer.pass_plan import plan_passes
from realistic.renderer.passes import ThreadPasses, render
from realistic.scene.staging import default_setup

REPO = Path(__file__).resolve().parents[1]
QUICK = ["--backend", "numpy", "--lens-sampling", "rear", "--dispersion", "off"]


@pytest.fixture(scope="module")
def tiny():
    setup = default_setup()
    return setup.scene, LensCamera.looking_at(load_lens("dgauss"), setup.eye, setup.target, None, 43.27, 32, 32, 4)


def test_content_hash_follows_content_not_identity(tiny):
    scene, camera = tiny
    again = default_setup().scene
    assert content_hash(again.meshes) == content_hash(scene.meshes) and again is not scene
    moved = dataclasses.replace(camera, film_distance_mm=camera.film_distance_mm + 1e-9)
    assert content_hash(moved) != content_hash(camera)
    assert content_hash({"a": 1, "b": 2}) == content_hash({"b": 2, "a": 1}) != content_hash({"a": 2, "b": 1})


def test_identity_is_the_same_in_another_process(tiny):
    """A checkpoint is resumed by a new process: the identity cannot depend on pickling or hash seeds."""
    scene, camera = tiny
    code = ("from realistic import load_lens; from realistic.camera.lens_camera import LensCamera;"
            "from realistic.scene.staging import default_setup;"
            "from realistic.renderer.checkpoint import RenderIdentity; s = default_setup();"
            "c = LensCamera.looking_at(load_lens('dgauss'), s.eye, s.target, None, 43.27, 32, 32, 4);"
            "i = RenderIdentity.of(s.scene, c, 3, 256, 'numpy', 1); print(i.scene, i.camera)")
    out = subprocess.run([sys.executable, "-c", code], cwd=REPO, capture_output=True, text=True, timeout=60,
                         env={**os.environ, "PYTHONHASHSEED": "12345"})
    ours = RenderIdentity.of(scene, camera, 3, 256, "numpy", 1)
    assert out.stdout.split() == [ours.scene, ours.camera], out.stderr


def _interrupted(scene, camera, path, passes_before_stop=2, seed=0):
    calls = []

    def stop(result):
        calls.append(1)
        if len(calls) == passes_before_stop:
            raise KeyboardInterrupt

    job = RenderJob(scene, (camera,), "numpy", seed, pass_samples=256, checkpoint=Checkpointing(path, None))
    return render(job, ThreadPasses(2), RenderObserver(on_pass=stop))[0]


def test_resume_is_bit_identical_and_the_saved_image_removes_the_checkpoint(tiny, tmp_path):
    scene, camera = tiny
    path = tmp_path / "r.exr.partial"
    whole = render(RenderJob(scene, (camera,), "numpy", pass_samples=256), ThreadPasses(threads=2))[0]
    first = _interrupted(scene, camera, path)
    assert first.interrupted and path.is_file() and 0 < first.samples_done < first.samples_total
    resumed = render(RenderJob(scene, (camera,), "numpy", pass_samples=256,
                               checkpoint=Checkpointing(path, None, resume=True)), ThreadPasses(threads=2))[0]
    assert not resumed.interrupted and resumed.samples_done == resumed.samples_total
    assert np.array_equal(resumed.image, whole.image)
    assert path.exists()  # until the image is written: a failed write must not lose the work
    save(resumed, tmp_path / "r.exr")
    assert not path.exists()


@pytest.mark.parametrize("change, word", [
    (lambda c: dataclasses.replace(c, width=33), "resolution"),
    (lambda c: dataclasses.replace(c, spp=8), "spp"),
    (lambda c: c.refocused_mm(2500.0), "camera"),
])
def test_a_checkpoint_of_another_render_is_refused_in_one_line(tiny, tmp_path, change, word):
    scene, camera = tiny
    path = tmp_path / "r.exr.partial"
    _interrupted(scene, camera, path)
    with pytest.raises(UserError) as err:
        render(RenderJob(scene, (change(camera),), "numpy", pass_samples=256,
                         checkpoint=Checkpointing(path, None, True)))
    assert f"another {word}" in str(err.value) and "\n" not in str(err.value) and str(path) in str(err.value)


def test_another_seed_or_scene_is_refused(tiny, tmp_path):
    scene, camera = tiny
    path = tmp_path / "r.exr.partial"
    _interrupted(scene, camera, path)
    with pytest.raises(UserError, match="another seed"):
        render(RenderJob(scene, (camera,), "numpy", seed=1, pass_samples=256,
                         checkpoint=Checkpointing(path, None, True)))
    other = dataclasses.replace(scene, background=(0.5, 0.5, 0.5))
    with pytest.raises(UserError, match="another scene"):
        render(RenderJob(other, (camera,), "numpy", pass_samples=256, checkpoint=Checkpointing(path, None, True)))


@given(st.binary(max_size=300))
def test_any_file_is_resumed_or_refused_in_one_line(tmp_path_factory, content):
    path = tmp_path_factory.mktemp("cp") / "x.exr.partial"
    path.write_bytes(content)
    identity = RenderIdentity("2x2", 0, "s", "c", 1, 4, "numpy", 1)
    with pytest.raises(UserError) as err:
        load_checkpoint(path, identity, plan_passes(4, 1, 4))
    assert "\n" not in str(err.value) and str(path) in str(err.value)


def test_resume_without_a_checkpoint_says_so(tiny, tmp_path):
    scene, camera = tiny
    with pytest.raises(UserError, match="no checkpoint to resume"):
        render(RenderJob(scene, (camera,), "numpy", checkpoint=Checkpointing(tmp_path / "none.partial", None, True)))


def _render(out: Path, *extra: str) -> list[str]:
    return [sys.executable, "-m", "realistic", "render", *QUICK, "--res", "64x64", "--spp", "64",
            "--pass-samples", "1024", "--out", str(out), *extra]


def _killed_after_first_checkpoint(out: Path) -> Path:
    """Start a CLI render to ``out`` that checkpoints often, SIGKILL it once its checkpoint exists;
    the checkpoint's path."""
    partial = out.with_name(out.name + ".partial")
    process = subprocess.Popen(_render(out, "--checkpoint-every", "0.05"), cwd=REPO,
                               stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.monotonic() + 90
    while not partial.exists() and process.poll() is None and time.monotonic() < deadline:
        time.sleep(0.01)
    process.send_signal(signal.SIGKILL)
    process.wait(timeout=30)
    assert process.returncode == -signal.SIGKILL
    return partial


@pytest.mark.skipif(os.name != "posix", reason="POSIX signals")
def test_sigkill_then_resume_is_bit_identical_to_an_uninterrupted_render(tmp_path):
    whole = tmp_path / "whole.exr"
    subprocess.run(_render(whole), cwd=REPO, check=True, capture_output=True, timeout=120)
    out = tmp_path / "killed.exr"
    partial = _killed_after_first_checkpoint(out)
    assert partial.is_file() and not out.exists()
    resumed = subprocess.run(_render(out, "--resume"), cwd=REPO, capture_output=True, text=True, timeout=120)
    assert resumed.returncode == 0, resumed.stderr
    assert np.array_equal(read_exr(out)[0], read_exr(whole)[0]) and not partial.exists()
    header = read_exr(out)[1]  # and the header is true: complete, every sample counted
    assert header["interrupted"] == 0 and header["samplesDone"] == header["samplesTotal"] == 64 * 64 * 64


def test_cli_refuses_a_checkpoint_for_another_seed_in_one_line(tmp_path):
    out = tmp_path / "r.exr"
    _killed_after_first_checkpoint(out)
    refused = subprocess.run(_render(out, "--resume", "--seed", "7"), cwd=REPO, capture_output=True, text=True,
                             timeout=120)
    assert refused.returncode == 2 and refused.stderr.count("\n") == 1 and "another seed" in refused.stderr


def test_a_checkpoint_of_the_contiguous_pass_plan_is_refused_in_one_line(tmp_path):
    """Format 1 numbered contiguous ranges of sample ids; its pass indices mean other passes now."""
    path = tmp_path / "x.exr.partial"
    with path.open("wb") as out:
        np.savez(out, header=np.array(json.dumps({"format": "realistic checkpoint 1"})))
    identity = RenderIdentity("2x2", 0, "s", "c", 1, 4, "numpy", 1)
    with pytest.raises(UserError, match="realistic checkpoint 1, this version reads realistic checkpoint 2") as err:
        load_checkpoint(path, identity, plan_passes(4, 1, 4))
    assert "\n" not in str(err.value)
