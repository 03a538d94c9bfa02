"""Shared fixtures: where the project's shared reference data lives (skips when it is absent)."""

import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest
from hypothesis import HealthCheck, settings

#: Property-based tests: a fixed, derandomised profile keeps CI's fuzzing short and repeatable;
#: ``pytest --hypothesis-profile=long`` explores far more inputs by hand (docs/robustness.md).
#: The fuzz tests read ``capsys`` afresh per example and make their own folders per example, so
#: function-scoped fixtures are safe there.
_QUIET = [HealthCheck.too_slow, HealthCheck.function_scoped_fixture]
settings.register_profile("ci", max_examples=60, deadline=None, derandomize=True, suppress_health_check=_QUIET)
settings.register_profile("long", max_examples=5000, deadline=None, suppress_health_check=_QUIET)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "ci"))

SHARED = Path(__file__).resolve().parents[2] / "shared"


def fresh_process_env(**overrides: str) -> dict[str, str]:
    """The environment for a script run in a process of its own (a fresh kernel build, say):
    this one with ``overrides``, and this folder first on PYTHONPATH so the script can import the
    tests' helpers (``busy_scene``, ``kernel_reference``)."""
    path = os.pathsep.join([os.path.dirname(__file__), os.environ.get("PYTHONPATH", "")])
    return dict(os.environ, **overrides, PYTHONPATH=path)


def run_fresh(script: str, *args: str, timeout: float = 600, **env: str) -> subprocess.CompletedProcess:
    """``script`` (with ``args``) run by Python in a process of its own (``fresh_process_env`` with
    ``env``), which must succeed; its output captured as text."""
    run = subprocess.run([sys.executable, "-c", script, *args], capture_output=True, text=True, timeout=timeout,
                         env=fresh_process_env(**env))
    assert run.returncode == 0, run.stderr[-2000:]
    return run


def vectoriser_remarks(script: str, *args: str, pocl_cache: Path) -> str:
    """The output of ``script`` run in a process of its own whose kernels PoCL compiles from source
    into ``pocl_cache`` (not realistic's binary cache, not PoCL's kernel cache) with its vectoriser's
    remarks on; the calling test is skipped where this PoCL prints none."""
    run = run_fresh(script, *args, POCL_KERNEL_CACHE="0", POCL_VECTORIZER_REMARKS="1", POCL_CACHE_DIR=str(pocl_cache),
                    REALISTIC_CACHE_DIR="off")
    remarks = run.stdout + run.stderr
    if "vectorized loop" not in remarks and "not vectorized" not in remarks:
        pytest.skip("this PoCL prints no vectoriser remarks")
    return remarks


def built_from_source(script: str, cache_home: Path, *args: str) -> str:
    """The standard output of ``script`` run in a process of its own whose kernels PoCL builds from
    source into ``cache_home`` (neither realistic's binary cache nor an earlier PoCL build)."""
    return run_fresh(script, *args, XDG_CACHE_HOME=str(cache_home), REALISTIC_CACHE_DIR="off").stdout


@pytest.fixture(scope="module")
def opencl_platform():
    """``realistic.camera.opencl_host``; skips the module's tests when no OpenCL platform exists (CI
    installs PoCL with the package)."""
    from realistic.errors import UserError

    opencl_host = pytest.importorskip("realistic.camera.opencl_host")
    from realistic.device.opencl import Device

    try:
        Device.for_spec()
    except UserError as err:
        pytest.skip(f"no OpenCL platform: {err}")
    return opencl_host


@pytest.fixture(autouse=True, scope="session")
def fresh_disk_cache(tmp_path_factory):
    """Tests (and the CLI processes they start) cache exit-pupil tables in a folder of this session's
    own, so a run neither reads tables an older build cached nor fills the user's cache."""
    previous = os.environ.get("REALISTIC_CACHE_DIR")
    os.environ["REALISTIC_CACHE_DIR"] = str(tmp_path_factory.mktemp("cache"))
    yield
    if previous is None:
        del os.environ["REALISTIC_CACHE_DIR"]
    else:
        os.environ["REALISTIC_CACHE_DIR"] = previous


@pytest.fixture
def cache(tmp_path, monkeypatch):
    """A disk cache of the test's own (``REALISTIC_CACHE_DIR``), with the exit-pupil tables' cache in
    this process emptied before and after, so that each table is read from disk or built."""
    from realistic.optics import sampling

    monkeypatch.setenv("REALISTIC_CACHE_DIR", str(tmp_path))
    sampling._cached_table.cache_clear()
    yield tmp_path
    sampling._cached_table.cache_clear()


@pytest.fixture
def thread_pools(monkeypatch) -> list[tuple[int, bool]]:
    """(threads, pin_threads) of each pool in-process renders start while the test runs, in order."""
    from realistic.renderer import passes

    pools = []
    start = passes.ThreadPasses.open

    def recording(self, job, clock):
        pools.append((self.threads, self.pin_threads))
        start(self, job, clock)

    monkeypatch.setattr(passes.ThreadPasses, "open", recording)
    return pools


def shared_file(relative: str) -> Path:
    """Path of a file in ../shared, or skip the test with the reason."""
    path = SHARED / relative
    if not path.exists():
        pytest.skip(f"shared data not available: {path} (a clone without ../shared skips this test)")
    return path


def sigint_by_default() -> None:
    """``preexec_fn`` of the CLI processes a test interrupts: SIGINT back to its default, so the
    child's Python installs its Ctrl-C handler even when the test run ignores SIGINT (a shell starts
    background jobs, a CI run under ``nohup ... &`` among them, with SIGINT ignored, and children
    inherit that)."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def flat_field_brightness(lens, spp: int = 256) -> float:
    """Film irradiance at the image centre of a uniform emitter (radiance 1) filling the view 10 m
    away, the lens focused on it (8 x 8 pixels, numpy backend)."""
    import numpy as np

    from realistic.camera.lens_camera import LensCamera
    from realistic.core.transforms import rotate, translate
    from realistic.renderer.job import RenderJob
    from realistic.renderer.passes import render
    from realistic.scene.model import AreaLight, Scene

    wall = Scene()
    wall.lights.append(AreaLight("quad", (40.0, 40.0), (1.0, 1.0, 1.0), translate(0, 0, 10) @ rotate(180, (0, 1, 0))))
    camera = LensCamera.looking_at(lens, np.zeros(3), np.array([0, 0, 10.0]), 10.0, 43.27, 8, 8, spp)
    return float(render(RenderJob(wall, (camera,), "numpy"))[0].image[3:5, 3:5].mean())


def rays_the_pupil_table_loses(lens, film_distance_mm: float, table, seed: int, count: int = 300_000,
                               film_radius_mm: float = 17.5) -> tuple[int, int]:
    """(rays that pass the lens, passing rays outside the table's box) among ``count`` rays from film
    points uniform over a disk of ``film_radius_mm``, aimed by the rear-element sampler (which
    reaches every direction the lens can pass)."""
    import numpy as np

    from realistic.optics.sampling import rear_element_sampler
    from realistic.optics.tracer import trace_from_film

    rng = np.random.default_rng(seed)
    radius = film_radius_mm * np.sqrt(rng.random(count))
    angle = rng.uniform(0, 2 * np.pi, count)
    film_xy = np.column_stack([radius * np.cos(angle), radius * np.sin(angle)])
    points, _ = rear_element_sampler(lens, film_distance_mm).sample(film_xy, rng.random(count), rng.random(count))
    origins = np.column_stack([film_xy, np.zeros(count)])
    passed = trace_from_film(lens, film_distance_mm, origins, points - origins).passed
    return int(passed.sum()), int(np.sum(passed & ~table.contains(film_xy, points[:, :2])))
