"""The pure helpers of bench/scenes.py and bench/converge.py (no timing is asserted)."""

import importlib.util
import math
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from realistic.renderer.convergence import relative_rmse, two_seed_noise

ROOT = Path(__file__).resolve().parents[1]


def _bench_module(name: str):
    spec = importlib.util.spec_from_file_location(f"bench_{name}", ROOT / "bench" / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses look their module up while the class is made
    spec.loader.exec_module(module)
    return module


scenes = _bench_module("scenes")
converge = _bench_module("converge")


# --- relative RMSE -----------------------------------------------------------------------------

def test_relative_rmse_of_a_known_error():
    """An error of +a and -a on alternating pixels of a constant c has RMSE a, so relRMSE a / c."""
    reference = np.full((4, 6, 3), 2.0, dtype=np.float32)
    sign = np.where(np.indices((4, 6, 3)).sum(axis=0) % 2 == 0, 1.0, -1.0)
    assert relative_rmse(reference + 0.5 * sign, reference) == pytest.approx(0.25)
    assert relative_rmse(reference, reference) == 0.0


def test_relative_rmse_divides_by_the_mean_of_the_reference_not_per_pixel():
    """A reference of 1 and 3 (mean 2) with the error 1 on every pixel: 1 / 2, not mean(1/ref)."""
    reference = np.array([1.0, 3.0] * 8).reshape(4, 4, 1)
    assert relative_rmse(reference + 1.0, reference) == pytest.approx(0.5)


@given(st.floats(1e-3, 1e3), st.integers(0, 2**32 - 1))
def test_relative_rmse_is_scale_free(scale, seed):
    rng = np.random.default_rng(seed)
    reference = rng.uniform(0.5, 2.0, (5, 7, 3))
    image = reference + rng.normal(0, 0.1, reference.shape)
    assert relative_rmse(scale * image, scale * reference) == pytest.approx(
        relative_rmse(image, reference), rel=1e-9)


# --- time to a target error --------------------------------------------------------------------

@given(st.floats(0.05, 5.0), st.floats(0.2, 1.0), st.floats(0.0, 1.0))
def test_time_to_error_is_exact_on_a_power_law(c, slope, where):
    """Errors c * t^-slope are a line in log-log, so interpolation between any two points is exact."""
    seconds = [1.0, 4.0, 16.0, 64.0]
    errors = [c * t ** -slope for t in seconds]
    target = math.exp(math.log(errors[1]) + where * (math.log(errors[2]) - math.log(errors[1])))
    expected = (c / target) ** (1 / slope)
    assert converge.time_to_error(seconds, errors, target) == pytest.approx(expected, rel=1e-9)


def test_time_to_error_takes_the_first_crossing_of_noisy_errors():
    """0.1 is first reached between 2 s (0.2) and 8 s (0.05): halfway in log error, so 4 s."""
    seconds, errors = [1.0, 2.0, 8.0, 16.0, 32.0], [0.4, 0.2, 0.05, 0.12, 0.01]
    assert converge.time_to_error(seconds, errors, 0.1) == pytest.approx(4.0)


def test_time_to_error_not_reached_and_reached_at_once():
    seconds, errors = [1.0, 2.0, 4.0], [0.5, 0.3, 0.2]
    assert converge.time_to_error(seconds, errors, 0.1) is None
    assert converge.time_to_error(seconds, errors, 0.6) == 1.0  # the first point: an upper bound
    assert converge.time_to_error(seconds, errors, 0.2) == pytest.approx(4.0)  # a measured point exactly
    assert converge.time_to_error([1.0, 2.0], [0.5, 0.0], 0.1) == 2.0  # no log of a zero error


# --- the reference cache key -------------------------------------------------------------------

def _package(root: Path) -> Path:
    (root / "realistic").mkdir()
    (root / "kernels").mkdir()
    (root / "realistic" / "a.py").write_text("x = 1\n")
    (root / "kernels" / "lens.cl").write_text("kernel void k() {}\n")
    scene = root / "s.pbrt"
    scene.write_text("WorldBegin\nWorldEnd\n")
    return scene


@pytest.mark.parametrize("changed", ["realistic/a.py", "kernels/lens.cl", "s.pbrt"])
def test_source_hash_changes_with_the_package_kernels_and_scene(tmp_path, changed):
    scene = _package(tmp_path)
    before = converge.source_hash(tmp_path, scene)
    assert converge.source_hash(tmp_path, scene) == before
    (tmp_path / changed).write_text((tmp_path / changed).read_text() + "// changed\n")
    assert converge.source_hash(tmp_path, scene) != before


def test_reference_path_names_scene_resolution_spp_and_version(tmp_path):
    scene = ROOT / "scenes" / "dof-dragons" / "dgauss.pbrt"
    path = converge.reference_path(tmp_path, scene, (512, 256), 1024, "abc123")
    assert path.parent == tmp_path and path.suffix == ".npy"
    assert all(part in path.name for part in ("dof-dragons-dgauss", "512x256", "1024spp", "abc123"))
    assert converge.reference_path(tmp_path, scene, (512, 256), 1024, "abc124") != path
    assert converge.reference_path(tmp_path, ROOT / "scenes" / "dof-dragons" / "wide.pbrt",
                                   (512, 256), 1024, "abc123") != path


# --- the scene list ----------------------------------------------------------------------------

def test_scene_list_without_shared_data_keeps_only_the_default(tmp_path):
    found, skipped = scenes.scene_list(ROOT, tmp_path / "no-shared")
    assert [s.name for s in found] == ["default"]
    assert len(skipped) == 2 * len(scenes.LENSES)
    assert all("not found" in message and "no-shared" in message for message in skipped)


def test_scene_list_with_shared_data_has_homework_and_dragons(tmp_path):
    pbrt_dir, meshes = tmp_path / "scenes" / "pbrt", tmp_path / "meshes"
    pbrt_dir.mkdir(parents=True)
    meshes.mkdir()
    for lens in scenes.LENSES[:2]:  # half of the homework present
        (pbrt_dir / f"dof-dragons.{lens}.pbrt").write_text("")
    found, skipped = scenes.scene_list(ROOT, tmp_path)
    names = {s.name: s for s in found}
    assert {f"homework {lens}" for lens in scenes.LENSES[:2]} <= set(names)
    assert [m.split(":")[0] for m in skipped] == [f"homework {lens}" for lens in scenes.LENSES[2:]]
    for lens in scenes.LENSES:
        dragon = names[f"dragons {lens}"]
        assert dragon.path == ROOT / "scenes" / "dof-dragons" / f"{lens}.pbrt"
        assert dragon.search_paths == (meshes, pbrt_dir)
    assert names["homework dgauss"].search_paths == ()


@pytest.mark.parametrize("caches", ["user", "empty", "cold"])
def test_child_caches_start_where_the_option_says(monkeypatch, caches):
    """--empty-cache moves realistic's disk cache to the empty folder; --cold moves every cache under
    XDG_CACHE_HOME there (PoCL's too), leaving no cache variable that points elsewhere."""
    for name, value in (("REALISTIC_CACHE_DIR", "/mine"), ("POCL_CACHE_DIR", "/pocl"), ("XDG_CACHE_HOME", "/xdg"),
                        ("PYTHONDONTWRITEBYTECODE", "1")):
        monkeypatch.setenv(name, value)
    env = scenes._child_environment(caches, "/empty")
    assert "PYTHONDONTWRITEBYTECODE" not in env
    expected = {"user": ("/mine", "/pocl", "/xdg"), "empty": ("/empty", "/pocl", "/xdg"),
                "cold": (None, None, "/empty")}[caches]
    assert tuple(env.get(name) for name in ("REALISTIC_CACHE_DIR", "POCL_CACHE_DIR", "XDG_CACHE_HOME")) == expected
    option = {"user": [], "empty": ["--empty-cache"], "cold": ["--cold"]}[caches]
    assert scenes.build_parser().parse_args(option).caches == caches


def test_render_arguments_carry_search_paths_and_light_samples(tmp_path):
    scene = scenes.BenchScene("x", tmp_path / "x.pbrt", (tmp_path / "m", tmp_path / "p"))
    arguments = scenes.render_arguments(scene, (300, 300), 32, None, "opencl")
    assert arguments[:5] == [str(scene.path), "--res", "300x300", "--spp", "32"]
    assert arguments.count("--search-path") == 2 and "--light-samples" not in arguments
    assert scenes.render_arguments(scene, (300, 300), 32, 4, "numpy")[-2:] == ["--light-samples", "4"]


def test_render_arguments_parse_as_the_render_command(tmp_path):
    """The benchmark's arguments are ones ``realistic render`` accepts, with the values intended."""
    from realistic.cli import build_parser

    scene = scenes.BenchScene("x", tmp_path / "x.pbrt", (tmp_path / "m",))
    args = build_parser().parse_args(["render", *scenes.render_arguments(scene, (64, 48), 8, 2, "numpy")])
    assert (args.spp, args.light_samples, args.backend) == (8, 2, "numpy")
    assert args.res == "64x48"
    assert [Path(p) for p in args.search_path] == [tmp_path / "m"]


def test_median_figures_per_key():
    runs = [{"a": 1.0, "b": 9.0}, {"a": 3.0, "b": 1.0}, {"a": 2.0, "b": 5.0}]
    assert scenes.median_figures(runs) == {"a": 2.0, "b": 5.0}


# --- the command lines -------------------------------------------------------------------------

_TEXT = st.one_of(st.text(max_size=12), st.from_regex(r"-?[0-9]{1,6}(x[0-9]{0,6})?(,[0-9x]{0,4}){0,3}", fullmatch=True))


@pytest.mark.parametrize("module,option", [(scenes, "--res"), (scenes, "--spp"), (scenes, "--light-samples"),
                                           (scenes, "--repeats"), (converge, "--res"), (converge, "--spps"),
                                           (converge, "--reference-spp"), (converge, "--target"),
                                           (converge, "--light-samples")])
@given(text=_TEXT)
def test_options_parse_or_refuse_in_one_line(module, option, text, capsys):
    """Any value is either accepted (and then valid) or refused by argparse with exit status 2 and a
    one-line message naming the option; never another exception."""
    try:
        args = module.build_parser().parse_args([f"{option}={text}"])
    except SystemExit as stop:
        assert stop.code == 2
        message = capsys.readouterr().err.strip().splitlines()[-1]
        assert option in message and "Traceback" not in message
        return
    value = getattr(args, option[2:].replace("-", "_"))
    values = value if isinstance(value, (tuple, list)) else [value]
    assert all(v > 0 for v in values)


@given(st.floats(1e-3, 10.0), st.floats(0.5, 1.5))
@settings(max_examples=30, deadline=None)
def test_the_noise_power_law_is_recovered_and_inverted(c, q):
    spps = [64, 128, 256]
    fit_c, fit_q = converge.noise_power_law(spps, [c * n ** -q for n in spps])
    assert fit_c == pytest.approx(c, rel=1e-6) and fit_q == pytest.approx(q, rel=1e-6)
    assert converge.spp_to_noise(fit_c, fit_q, c * 1000.0 ** -q) == pytest.approx(1000.0, rel=1e-6)


def test_one_noise_point_extrapolates_by_the_1_over_n_law():
    c, q = converge.noise_power_law([100], [0.04])
    assert q == 0.5 and converge.spp_to_noise(c, q, 0.02) == pytest.approx(400.0)


def test_extrapolated_seconds_follow_the_linear_render_time():
    spps, render_s = [4, 16, 64], [1.0 + 0.5 * n for n in (4, 16, 64)]
    assert converge.extrapolated_seconds(spps, render_s, 2.0, 100.0) == pytest.approx(2.0 + 1.0 + 0.5 * 100.0)


def test_two_seed_noise_is_each_renders_error_against_the_truth():
    """Two independent unbiased renders of an image with per-pixel noise sigma: the estimate is
    sigma / mean, the RMSE each has against the true image, which it never sees."""
    rng = np.random.default_rng(5)
    truth = rng.uniform(0.5, 1.5, (200, 300, 3))
    first, second = (truth + rng.normal(0.0, 0.1, truth.shape) for _ in range(2))
    expected = relative_rmse(first, truth)
    assert two_seed_noise(first, second) == pytest.approx(expected, rel=0.02)
    assert expected == pytest.approx(0.1 / truth.mean(), rel=0.02)


def test_pbrt_v3_time_by_the_same_law_hits_its_own_measured_point():
    assert converge.pbrt_v3_seconds(converge.PBRT_V3["rel_rmse"]) == pytest.approx(converge.PBRT_V3["wall_s"], rel=0.01)
    assert converge.pbrt_v3_seconds(0.02) == pytest.approx(5.6 + 24.0 * (0.073 / 0.02) ** 2)


def test_scene_bench_measures_peak_memory_and_the_interpreter_baseline():
    baseline = scenes.baseline_figures()
    assert 0 < baseline["peak_rss_mib"] <= baseline["with_renderer_mib"] and baseline["import_s"] > 0
    assert scenes.build_parser().parse_args(["--only", "dragons", "--flat"]).flat


render_bench = _bench_module("render")


@pytest.mark.parametrize("pixels, spp, samples", [(64 * 64, 4, 131072), (512 * 512, 64, 131072), (1, 1, 8)])
def test_middle_block_stays_inside_the_render_however_small(pixels, spp, samples):
    class Camera:
        sample_count = pixels * spp

    Camera.spp = spp
    block = render_bench.middle_block(Camera, samples)
    assert block.first >= 0 and block.first + block.count <= Camera.sample_count
    assert block.count == min(samples, Camera.sample_count)


# --- the processor a bench names ----------------------------------------------------------------

machine = _bench_module("machine")


def test_the_machine_is_named_by_the_first_processors_model_family_and_the_usable_cores(tmp_path):
    cpuinfo = tmp_path / "cpuinfo"
    cpuinfo.write_text("processor\t: 0\ncpu family\t: 26\nmodel\t\t: 2\nmodel name\t: AMD EPYC\n\n"
                       "processor\t: 1\ncpu family\t: 25\nmodel name\t: other\n")
    from realistic.renderer.thread_count import default_threads

    cores = default_threads()
    assert machine.describe(cpuinfo) == f"AMD EPYC, family 26 model 2, {cores} cores"
    assert machine.describe(tmp_path / "absent").endswith(f", {cores} cores")


@pytest.mark.parametrize("backend", ["numpy", "opencl"])
def test_the_ceiling_traces_every_ray_the_render_traced(backend):
    """The ceiling's rays are the render's own, all of them: as many primary and (live) shadow rays as
    ``render`` reports for the same camera, not one pass's."""
    from realistic.renderer.job import RenderJob
    from realistic.renderer.passes import render

    setup, camera, _, _ = render_bench.staged_subject("dgauss", 24, 16, 4)
    rendered = render(RenderJob(setup.scene, (camera,), backend, seed=0, pass_samples=512))[0]
    recorder = render_bench.recorded_rays(setup, camera, backend, pass_samples=512)
    assert len(recorder.primary) == len(recorder.shadow) > 1  # one closest and one occluded call per pass
    assert sum(len(o) for o, _, _ in recorder.primary) == rendered.primary_rays > 0
    assert all(coherent for _, _, coherent in recorder.primary)  # camera rays, traced as such (and so in the ceiling)
    assert sum(int(np.count_nonzero(t > 0)) for _, _, t in recorder.shadow) == rendered.shadow_rays > 0


# --- bench/peers.py ------------------------------------------------------------------------------

peers = _bench_module("peers")


def test_peers_thin_lens_scene_swaps_only_the_camera_and_asks_for_direct_lighting(tmp_path):
    """The dragons' file with pbrt's perspective camera in place of the realistic one (none of its
    parameters left) and pbrt-v3's direct lighting named before the world, the rest unchanged."""
    text = peers.thin_lens_scene(tmp_path).read_text()
    original = peers.SCENE.read_text()
    assert [line for line in text.splitlines() if line.startswith("Camera")] == [peers.THIN_LENS]
    assert not any(word in text for word in ("specfile", "filmdistance", "aperture_diameter", "filmdiag"))
    assert text.index('Integrator "directlighting"') < text.index("WorldBegin")
    assert text[text.index("WorldBegin"):] == original[original.index("WorldBegin"):]


def test_peers_bilinear_filter_changes_only_the_image_textures_filter():
    """The 'thin bilinear' peer's scene: each image texture filtered with pbrt-v4's bilinear, the
    rest of every material and instance as it was, and the original inputs untouched."""
    from realistic.renderer.inputs import RenderInputs
    from realistic.scene.model import Scene
    from realistic.scene.shapes import quad
    from realistic.scene.surfaces import ImageTexture, Material

    scene = Scene()
    texture = ImageTexture(np.ones((4, 4, 3), np.float32), scale=(5.0, 5.0))
    scene.add(quad(1.0, 1.0), np.eye(4), Material((0.5, 0.5, 0.5), texture))
    scene.add(quad(1.0, 1.0), np.eye(4), Material((0.8, 0.2, 0.2)))
    inputs = RenderInputs(scene, "out.exr")
    changed = peers.bilinear_filter(inputs)
    floor, plain = changed.scene.instances
    assert floor.material.texture.filter == "bilinear" and floor.material.texture.scale == (5.0, 5.0)
    assert floor.material.diffuse == (0.5, 0.5, 0.5) and plain is scene.instances[1]
    assert scene.instances[0].material.texture is texture and texture.filter == "ewa"


def test_peers_mitsuba_pose_sees_what_the_pbrt_camera_sees():
    """Mitsuba's sensor looks along the same world direction from the same point, its -x (image
    right) is the pbrt camera's +x, and the scale comes back apart (lens radius and focus in world units)."""
    rotation = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    world = np.eye(4)
    world[:3, :3] = rotation / 5000
    world[:3, 3] = [2.3, 0.05, -0.5]
    pose, unit = peers.mitsuba_pose(world)
    assert unit == pytest.approx(1 / 5000)
    np.testing.assert_allclose(pose[:3, 3], world[:3, 3])
    np.testing.assert_allclose(pose[:3, 2], rotation[:, 2])
    np.testing.assert_allclose(pose[:3, 1], rotation[:, 1])
    np.testing.assert_allclose(-pose[:3, 0], rotation[:, 0])


def test_peers_pbrt_v4_executable_says_why_it_is_skipped(tmp_path, monkeypatch):
    """Unset, a missing path and a file that is not executable each give a reason; an executable its path."""
    monkeypatch.delenv("PBRT_V4", raising=False)
    assert "not set" in peers.pbrt_v4_executable()
    monkeypatch.setenv("PBRT_V4", str(tmp_path / "nowhere"))
    assert "not an executable file" in peers.pbrt_v4_executable()
    plain = tmp_path / "pbrt"
    plain.write_text("")
    monkeypatch.setenv("PBRT_V4", str(plain))
    assert "not an executable file" in peers.pbrt_v4_executable()
    plain.chmod(0o755)
    assert peers.pbrt_v4_executable() == plain


@pytest.mark.skipif(not (peers.MESHES / "dragon.ply").is_file() or not peers.LENS_FILE.is_file(),
                    reason="needs ../shared/meshes/dragon.ply and ../shared/lenses (not in the repository)")
def test_peers_pbrt_v3_scene_keeps_the_homework_camera(tmp_path):
    """The dragons in pbrt-v3's camera convention (metres from the film centre, focus by distance)
    put the lens frame where the homework file puts it, at the same film distance, stop and film,
    with none of the homework's parameters and the world inlined."""
    text = peers.pbrt_v3_scene(tmp_path, (64, 48)).read_text()
    statements = "\n".join(line.split("#")[0] for line in text.splitlines())
    homework_words = ("specfile", "filmdistance", "aperture_diameter", "filmdiag", "Include")
    assert not any(word in statements for word in homework_words)
    assert statements.count("ObjectInstance") == 11
    converted = peers.our_inputs(tmp_path / "dragons-v3.pbrt", 1, (64, 48)).camera
    homework = peers.our_inputs(peers.SCENE, 1, (64, 48)).camera
    assert converted.origin == "film" and homework.origin == "front_vertex"
    np.testing.assert_allclose(converted.world_from_lens, homework.world_from_lens, rtol=1e-9, atol=1e-12)
    assert converted.film_distance_mm == pytest.approx(homework.film_distance_mm, rel=1e-9)
    assert converted.lens.stop_diameter_mm == homework.lens.stop_diameter_mm
    assert converted.film_diagonal_mm == homework.film_diagonal_mm


# --- light kinds ----------------------------------------------------------------------------------

light_kinds = _bench_module("light_kinds")


@pytest.mark.parametrize("name, kinds", [("point", {"PointLight"}), ("sky", {"DistantLight", "InfiniteLight"}),
                                         ("mesh", {"EmissiveInstance"}), ("sphere", {"EmissiveInstance"})])
@pytest.mark.parametrize("integrator", ["path", "direct"])
def test_light_kinds_scenes_import_with_their_lights_and_integrator(tmp_path, name, kinds, integrator):
    """Each scene of bench/light_kinds.py imports (no dragon: ../shared may be missing) with the light
    kinds its name says, nothing else lighting it, and the integrator it asks for."""
    import realistic

    scene_file = tmp_path / "scene.pbrt"
    scene_file.write_text(light_kinds.scene_text(light_kinds.SCENES[name], light_kinds.INTEGRATORS[integrator], None))
    scene = realistic.load_scene(str(scene_file))
    assert {type(light).__name__ for light in scene.lights} == kinds
    assert scene.integrator == {"path": "path", "direct": "directlighting"}[integrator]
