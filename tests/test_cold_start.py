"""A first render's start-up (issue 35): the programs a render builds.

A render that repays it times the lens kernel's choice among ``rays_per_item_choices`` at a
camera's first sight and stores it, a smaller one uses one ray per work item untimed; the programs
a large render builds store their binaries as its process exits, so the next process builds none
from source; a render builds the shading kernel variant its rays need, and no other.
"""

import subprocess
import sys

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from conftest import fresh_process_env, run_fresh
from realistic import load_scene
from realistic.renderer.job import PassSettings
from realistic.renderer.runner import PassRunner
from realistic.renderer.timing import StageClock

opencl = pytest.importorskip("realistic.device.opencl")

pytestmark = pytest.mark.usefixtures("opencl_platform")


@pytest.fixture()
def built(monkeypatch, opencl_platform, tmp_path):
    """An empty disk cache, no choice made yet in this process, and the rays per work item of
    every lens program ``LensKernel`` builds, in order."""
    monkeypatch.setenv("REALISTIC_CACHE_DIR", str(tmp_path))
    monkeypatch.setattr(opencl_platform, "_chosen", {})
    monkeypatch.setattr(opencl_platform, "_timing", [True])  # as a render that repays timing sets it
    monkeypatch.setattr(opencl, "_keeping_first_builds", [False])  # restored after a test's build_ahead
    monkeypatch.setattr(opencl, "_unstored", [])  # none of the binaries earlier tests left to store
    choices: list[int] = []
    original = opencl_platform.LensKernel._build

    def recording(kernel, rays_per_item):
        choices.append(rays_per_item)
        return original(kernel, rays_per_item)

    monkeypatch.setattr(opencl_platform.LensKernel, "_build", recording)
    return choices


def test_a_render_that_repays_it_times_a_camera_at_first_sight_and_later_ones_read_the_choice(
        built, opencl_platform, monkeypatch):
    """The first sight of a camera by a render that repays timing times its choice (both programs
    built, the faster one used) and stores it; the next process builds the chosen program alone.
    (Timing waited for a camera's second sight before, so a large render's second process timed
    and its third still compiled the chosen program's binaries.)"""
    from kernel_reference import reference_camera

    camera = reference_camera("wide", "rear")
    several, one = opencl_platform.rays_per_item_choices(camera)
    timed = opencl_platform.LensKernel(camera).rays_per_item
    assert timed in (several, one)
    assert built == [several, one, timed]  # both built to be timed, then the faster one used
    monkeypatch.setattr(opencl_platform, "_chosen", {})  # as in the next process
    built.clear()
    assert opencl_platform.LensKernel(camera).rays_per_item == timed
    assert built == [timed]  # read back from the disk cache


def test_only_a_render_that_repays_it_times_the_choice(built, opencl_platform, monkeypatch):
    """A camera not timed yet has its choice timed only by a render that repays it
    (``runner.repays_compiling``, passed on by ``Backend.build_ahead``): a small one (README's
    renders) builds the one-ray program alone, untimed, and leaves the choice to a larger render."""
    from kernel_reference import reference_camera
    from realistic.renderer.backends import backend_for

    camera = reference_camera("wide", "rear")
    several, one = opencl_platform.rays_per_item_choices(camera)
    backend = backend_for("opencl", None)
    for time_choices, expected in ((False, []), (False, []), (True, [several, one])):
        monkeypatch.setattr(opencl_platform, "_chosen", {})  # as in the next process
        built.clear()
        backend.build_ahead(camera, time_choices)
        chosen = opencl_platform.LensKernel(camera).rays_per_item
        assert built == expected + [chosen] and (chosen == one or time_choices)


def test_with_the_cache_off_every_process_times_its_choice(built, opencl_platform, monkeypatch):
    from kernel_reference import reference_camera

    monkeypatch.setenv("REALISTIC_CACHE_DIR", "off")
    camera = reference_camera("wide", "rear")
    several, one = opencl_platform.rays_per_item_choices(camera)
    timed = opencl_platform.LensKernel(camera).rays_per_item
    assert built == [several, one, timed]


def _stored_entry(opencl_host, camera, rays_per_item: int) -> list[str]:
    """The arrays the disk cache holds for ``camera``'s lens program (``[]``: no entry)."""
    from realistic.core import disk_cache

    source, _ = opencl_host.lens_program(camera, rays_per_item)
    device = opencl.Device.for_spec()
    entry = disk_cache.load_arrays(disk_cache.cache_key(opencl.CACHE_KIND, device.identity(), source.encode(), ()))
    return [] if entry is None else sorted(entry)


def test_the_program_not_chosen_stores_no_binaries(built, opencl_platform, monkeypatch):
    """Built to be timed, the program not chosen leaves its build's mark alone at exit, while the
    chosen one stores its binaries: the other's would cost a compile of every kernel and never be
    loaded."""
    from kernel_reference import reference_camera

    camera = reference_camera("telephoto", "rear")
    several, one = opencl_platform.rays_per_item_choices(camera)
    opencl.keep_first_builds(True)  # as a render that repays compiling sets it
    opencl.build_program.cache_clear()  # as in a process of its own
    chosen = opencl_platform.LensKernel(camera).rays_per_item
    opencl.store_built_binaries()
    opencl.build_program.cache_clear()
    assert _stored_entry(opencl_platform, camera, several if chosen == one else one) == ["built"]
    assert _stored_entry(opencl_platform, camera, chosen) == ["device0"]


@pytest.mark.parametrize("repays", [True, False])
def test_the_next_process_loads_every_program_a_large_render_built(built, opencl_platform, monkeypatch, repays):
    """After a render that repays compiling (``Backend.build_ahead(camera, True)``), the programs it
    built from source (its lens program and any other, as the shading one) store their binaries as
    its process exits, and the next process builds none from source and times nothing; a small
    render's programs leave a mark alone, and the next process builds them from source again (its
    exit stores them)."""
    from kernel_reference import reference_camera
    from realistic.renderer.backends import backend_for

    camera = reference_camera("dgauss", "rear")
    device = opencl.Device.for_spec()
    backend = backend_for("opencl", None)
    from_source: list[str] = []
    remember = opencl._remember

    def recording(key: str, program, built_before: bool) -> None:
        from_source.append(key)
        remember(key, program, built_before)

    monkeypatch.setattr(opencl, "_remember", recording)
    other = "__kernel void next_process(__global float* out) { out[get_global_id(0)] = 2.0f; }"

    def render() -> int:
        backend.build_ahead(camera, repays)
        rays_per_item = opencl_platform.LensKernel(camera, device).rays_per_item
        device.build_program(other, "next_process.cl")
        return rays_per_item

    opencl.build_program.cache_clear()  # as in a process of its own
    first = render()
    assert len(from_source) == (3 if repays else 2)  # both lens programs where timed, and the other
    opencl.store_built_binaries()  # the process exits
    opencl.build_program.cache_clear()
    monkeypatch.setattr(opencl_platform, "_chosen", {})
    from_source.clear()
    built.clear()
    assert render() == first
    assert built == [first]  # the choice read back, untimed
    assert len(from_source) == (0 if repays else 2)
    opencl.build_program.cache_clear()


#: What a choice's disk-cache entry might hold: arbitrary arrays (digest valid) under any names,
#: among them the few that are, or nearly are, a choice.
CHOICE_ARRAYS = st.one_of(
    hnp.arrays(st.sampled_from([np.int64, np.int32, np.uint8, np.float64, np.bool_, np.dtype("<U3")]),
               hnp.array_shapes(min_dims=0, max_dims=2, min_side=0, max_side=3)),
    st.sampled_from([np.array([4]), np.array([1], np.uint8), np.array([2]), np.array([3]), np.array([4.0]),
                     np.array(4), np.array([4, 1]), np.array([-1]), np.array([2**40])]))
CHOICE_ENTRIES = st.dictionaries(st.sampled_from(["rays_per_item", "seen", "other"]), CHOICE_ARRAYS, max_size=3)


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(arrays=CHOICE_ENTRIES, raw=st.none() | st.binary(max_size=200))
def test_a_stored_choice_is_used_only_where_it_is_one_of_the_choices_never_a_crash(opencl_platform, cache, arrays,
                                                                                  raw):
    """Arbitrary arrays stored under a choice's key (digest valid: another version's entry, say), or
    arbitrary bytes in its file: the choice read back is a single integer among the choices, and
    anything else reads as no choice (timed again, or one ray untimed), never an error."""
    from realistic.core import disk_cache

    key, choices = disk_cache.cache_key("lens-rays-per-item", "property test"), (4, 1)
    if raw is None:
        disk_cache.store_arrays(key, arrays)
    else:
        (cache / f"{key}.npz").write_bytes(raw)
    value = arrays.get("rays_per_item")
    valid = raw is None and list(arrays) == ["rays_per_item"] and value is not None and value.shape == (1,) \
        and value.dtype.kind in "iu" and int(value[0]) in choices
    for timing, untimed in ((True, None), (False, 1)):
        opencl_platform._chosen.pop(key, None)
        opencl_platform.time_choices(timing)
        assert opencl_platform._untimed_choice(key, choices) == (int(value[0]) if valid else untimed)
    opencl_platform._chosen.pop(key, None)
    opencl_platform.time_choices(True)


def test_a_foreign_choice_entry_is_timed_again_and_replaced(built, opencl_platform):
    """A camera whose choice entry holds something else (digest valid) has its choice timed and
    stored over it."""
    from kernel_reference import reference_camera
    from realistic.core import disk_cache

    camera = reference_camera("wide", "rear")
    several, one = opencl_platform.rays_per_item_choices(camera)
    key = opencl_platform._choice_key(camera, opencl.Device.for_spec())
    disk_cache.store_arrays(key, {"rays_per_item": np.array([several + one])})
    timed = opencl_platform.LensKernel(camera).rays_per_item
    assert built == [several, one, timed]
    assert int(disk_cache.load_arrays(key)["rays_per_item"][0]) == timed


DOUBLING = "__kernel void doubling(__global float* a) { a[get_global_id(0)] *= 2.0f; }"
PROGRAM_ARRAYS = st.dictionaries(
    st.sampled_from(["device0", "device1", "built", "other"]),
    hnp.arrays(st.sampled_from([np.uint8, np.int32, np.float64]),
               hnp.array_shapes(min_dims=0, max_dims=2, min_side=0, max_side=64)),
    max_size=2)


@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(arrays=PROGRAM_ARRAYS, raw=st.none() | st.binary(max_size=200))
def test_any_program_entry_is_rebuilt_never_run_or_a_crash(opencl_platform, cache, monkeypatch, arrays, raw):
    """Arbitrary arrays stored under a program's key (digest valid), or arbitrary bytes in its file:
    the program is built from source (its binaries stored at exit), and it computes what its source
    says."""
    import pyopencl as cl

    from realistic.core import disk_cache

    monkeypatch.setattr(opencl, "_unstored", [])  # this example's alone
    device = opencl.Device.for_spec()
    key = disk_cache.cache_key(opencl.CACHE_KIND, device.identity(), DOUBLING.encode(), ())
    if raw is None:
        disk_cache.store_arrays(key, arrays)
    else:
        (cache / f"{key}.npz").write_bytes(raw)
    opencl.build_program.cache_clear()
    program = device.build_program(DOUBLING, "doubling.cl")
    opencl.build_program.cache_clear()
    values = np.arange(256, dtype=np.float32)
    queue = device.queue()
    buffer = cl.Buffer(device.context, cl.mem_flags.READ_WRITE | cl.mem_flags.COPY_HOST_PTR, hostbuf=values)
    cl.Kernel(program, "doubling")(queue, (256,), None, buffer)
    doubled = np.empty_like(values)
    cl.enqueue_copy(queue, doubled, buffer)
    assert np.array_equal(doubled, 2 * values)
    assert [stored for stored, _ in opencl._unstored] == ([key] if raw is None else [])  # a mark where unread


def test_build_ahead_builds_what_the_lens_kernel_uses_without_the_exit_pupil(built, opencl_platform, monkeypatch):
    """``build_ahead`` (run while the exit-pupil table is made) builds, without that table, the
    programs the camera's ``LensKernel`` then uses: at a camera's first sight, when its choice is
    timed, and when it is read back; the kernel builds none of its own."""
    from kernel_reference import reference_camera
    from realistic.camera.lens_camera import LensCamera

    device = opencl.Device.for_spec()
    camera = reference_camera("telephoto", "pupil")
    several, one = opencl_platform.rays_per_item_choices(camera)
    pupil = LensCamera.pupil
    for sight in range(3):
        opencl.build_program.cache_clear()  # each sight as in a process of its own
        monkeypatch.setattr(opencl_platform, "_chosen", {})
        with monkeypatch.context() as no_table:
            no_table.setattr(LensCamera, "pupil", property(lambda camera: pytest.fail("the table was made")))
            opencl_platform.build_ahead(camera, device)
        ahead = opencl.build_program.cache_info().misses
        assert LensCamera.pupil is pupil
        opencl_platform.LensKernel(camera, device)
        assert opencl.build_program.cache_info().misses == ahead, f"sight {sight} built a program again"
    assert built[:2] == [several, one]  # first sight: both built and timed


def test_a_program_asked_for_while_it_builds_is_built_once(opencl_platform):
    """Two threads asking for one new program get the same program from one build (a render's
    ``build_ahead`` and its ``LensKernel`` ask for the same)."""
    import threading

    device = opencl.Device.for_spec()
    opencl.build_program.cache_clear()
    source = "__kernel void once(__global float* out) { out[get_global_id(0)] = 1.0f; }"
    programs = []
    threads = [threading.Thread(target=lambda: programs.append(device.build_program(source, "once.cl")))
               for _ in range(2)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert len(programs) == 2 and programs[0] is programs[1]
    assert opencl.build_program.cache_info().misses == 1


@pytest.mark.parametrize("dispersion", [False, True])
def test_a_render_builds_only_the_shading_variant_its_rays_need(monkeypatch, dispersion):
    """A spectral render's shading kernel is built for spectral rays alone, an RGB render's for RGB
    rays alone (the spectral one used to build the RGB variant too, unused)."""
    from realistic.camera.base import SampleBlock

    variants: list[str] = []
    original = opencl.build_program

    def recording(device, source, name, options=()):
        if name == "shade.cl":
            variants.extend(option for option in options if option.startswith("-DSPECTRAL="))
        return original(device, source, name, options)

    monkeypatch.setattr(opencl, "build_program", recording)
    scene = load_scene(resolution=(12, 10), spp=2, lens_sampling="rear", dispersion=dispersion)
    runner = PassRunner(scene, scene.camera, PassSettings("opencl"), StageClock())
    assert runner(0, SampleBlock(0, 240, 2)).shadow_rays > 0  # shaded by the kernel
    assert variants and set(variants) == {f"-DSPECTRAL={int(dispersion)}"}


def test_the_loops_compiled_ahead_are_those_a_pass_runs():
    """A render compiles embree's packet loops and the pass's own loops (the live rays' pick, ray gathers, film sums,
    shading sums) on render threads as it starts (``ThreadPasses.open`` runs ``compile_trace_loops``
    and ``compile_pass_loops``), for exactly the argument types its passes then use: a pass compiles
    nothing more (checked in a process of its own, whose loops nothing compiled)."""
    run = run_fresh("""
from realistic import load_scene
from realistic.camera.base import SampleBlock
from realistic.core.jit import compiled
from realistic.renderer import direct_lighting, film, hit_rows, runner
from realistic.renderer.job import PassSettings
from realistic.renderer.runner import PassRunner, compile_pass_loops
from realistic.renderer.timing import StageClock
from realistic.scene import intersect, packet_loop
from realistic.scene.embree import compile_trace_loops

loops = (packet_loop.closest_loop(), packet_loop.occluded_loop(), packet_loop.occluded_lanes_loop(),
         compiled(runner._gather, runner.GATHER_SIGNATURE), compiled(runner._pick_live, runner.PICK_SIGNATURE),
         compiled(film._add_rows), compiled(direct_lighting._visible_sums),
         compiled(hit_rows._rows_on_material), compiled(hit_rows._place_rows),
         compiled(intersect._instances_to_world))
compile_trace_loops()
compile_pass_loops()
print([len(loop.signatures) for loop in loops])
scene = load_scene(resolution=(12, 10), spp=2, lens_sampling="rear", dispersion=False)
PassRunner(scene, scene.camera, PassSettings("opencl"), StageClock())(0, SampleBlock(0, 240, 2))
print([len(loop.signatures) for loop in loops])
""")
    assert run.stdout.split("\n")[:2] == ["[1, 1, 1, 1, 1, 1, 1, 1, 1, 1]", "[1, 1, 1, 1, 1, 1, 1, 1, 1, 1]"]


@pytest.mark.parametrize("outputs", ["arrays", "block"])
def test_other_threads_run_while_a_kernel_first_launch_compiles(tmp_path, outputs):
    """PoCL compiles a kernel at its first launch; ``Device.run_into`` waits for that without the
    GIL, so other Python threads run: in ``CommandQueue.finish`` before the arrays' non-blocking
    reads (one queued behind the launch made the compile happen inside ``enqueue_copy``, the GIL
    held: the render's other threads stood still), or in an ``OutputBlock``'s one blocking read.
    A thread sleeping a millisecond at a time counts its wake-ups meanwhile."""
    run = run_fresh("""
import sys, threading, time
import numpy as np
from realistic.device.opencl import LOCAL_SIZE, Device, OutputBlock

device = Device.for_spec()
source = '''__kernel void f(uint n, __global float* out) {
    float x = get_global_id(0);
    for (int k = 0; k < 64; k++) x = sin(x) * cos(x) + sqrt(fabs(x)) + exp(-x * x) + log1p(fabs(x));
    out[get_global_id(0)] = x;
}'''
kernel = device.build_program(source, "test.cl").f
ticks, done = [0], threading.Event()

def count() -> None:
    while not done.is_set():
        time.sleep(0.001)
        ticks[0] += 1

threading.Thread(target=count).start()
time.sleep(0.05)
before, start = ticks[0], time.perf_counter()
outputs = ((np.empty(LOCAL_SIZE, np.float32),) if sys.argv[1] == "arrays"
           else OutputBlock(device, (((LOCAL_SIZE,), np.float32),)))
device.run_into(device.queue(), kernel, (LOCAL_SIZE,), (LOCAL_SIZE,), (np.uint32(LOCAL_SIZE),), outputs)
print(time.perf_counter() - start, ticks[0] - before)
done.set()
""", outputs, POCL_CACHE_DIR=str(tmp_path), REALISTIC_CACHE_DIR="off")
    seconds, ticks = run.stdout.split()
    if float(seconds) < 0.05:
        pytest.skip(f"the first launch took {float(seconds):.3f} s: nothing compiled at it")
    assert int(ticks) >= 10, f"{ticks} wake-ups in the {float(seconds):.2f} s of a first launch"


def test_the_ray_gather_compiles_once_for_strided_and_contiguous_rays():
    """The kernel's rays are views of its (columns, stride) output: strided where a launch is padded,
    F-contiguous where it is not (a default render has both). The gather compiled ahead serves both:
    it used to compile again in a pass for the layout not seen ahead (checked in a process of its own)."""
    run = run_fresh("""
import numpy as np
from realistic.core.jit import compiled
from realistic.renderer import runner

runner.compile_pass_loops()
output = np.arange(24, dtype=np.float32).reshape(6, 4)
for points in (output[0:3, :3].T, output[3:6].T):  # a padded launch's rays, an unpadded one's
    assert np.array_equal(runner.gather_rows(points, np.array([2, 0])), points[[2, 0]])
print(len(compiled(runner._gather, runner.GATHER_SIGNATURE).signatures))
""")
    assert run.stdout.split() == ["1"]


@pytest.mark.parametrize(("argv", "renders"), [
    (["render"], True),
    (["render", "scene.pbrt", "--spp", "4"], True),
    (["render", "--backend", "opencl"], True),
    (["render", "--backend", "numpy"], False),
    (["render", "--backend=numpy"], False),
    (["render", "--help"], False),
    (["render", "-h"], False),
    (["lens", "info", "dgauss"], False),
    ([], False),
])
def test_the_compiler_is_loaded_early_only_for_an_opencl_render(argv, renders):
    from realistic.__main__ import renders_on_opencl

    assert renders_on_opencl(argv) is renders


@pytest.mark.parametrize(("argv", "spec"), [
    (["render"], None),
    (["render", "--cl-device", "1:0"], "1:0"),
    (["render", "--cl-device=pthread"], "pthread"),
    (["render", "--cl-device=a", "--cl-device", "b"], "b"),  # the last given, as argparse keeps
    (["render", "--cl-device", "a", "--cl-device=b"], "b"),
    (["render", "--cl-device"], None),  # argparse reports it
])
def test_the_early_compiler_load_uses_the_device_the_render_names(argv, spec):
    from realistic.__main__ import device_spec

    assert device_spec(argv) == spec


def test_loading_the_compiler_builds_no_program_the_render_keeps(monkeypatch, tmp_path):
    """``Device.load_compiler`` leaves nothing in the program cache or the disk cache."""
    monkeypatch.setenv("REALISTIC_CACHE_DIR", str(tmp_path))
    device = opencl.Device.for_spec()
    before = opencl.build_program.cache_info().currsize
    device.load_compiler()
    assert opencl.build_program.cache_info().currsize == before
    assert not any(tmp_path.iterdir())


def test_a_render_on_a_device_that_cannot_be_had_says_so_in_one_line(tmp_path):
    """The early compiler load meets the bad device first and leaves it to the render: one line,
    exit status 2, no traceback from the loading thread."""
    run = subprocess.run([sys.executable, "-m", "realistic", "render", "--res", "8x6", "--spp", "1", "--quiet",
                          "--out", str(tmp_path / "r.exr")], capture_output=True, text=True,
                         env=fresh_process_env(PYOPENCL_CTX="no such device"), timeout=600)
    assert run.returncode == 2
    assert run.stderr.strip().splitlines() == [
        next(line for line in run.stderr.splitlines() if "no OpenCL device matches" in line)]


@pytest.fixture()
def numpy_loops(monkeypatch):
    """The loops' numpy forms (``core.jit.use_compiled_loops(False)``, whatever numba made before)."""
    from realistic.core import jit

    monkeypatch.setattr(jit, "_use_compiled", [False])


def _random_instances():
    """An embree scene of two instances of 2000 random triangles."""
    import numpy as np

    from realistic.scene.embree import EmbreeScene

    rng = np.random.default_rng(3)
    mesh = EmbreeScene()
    mesh.add_triangles(rng.random((3000, 3)).astype(np.float32), rng.integers(0, 3000, (2000, 3)), 0)
    mesh.commit()
    scene = EmbreeScene()
    shifted = np.eye(4)
    shifted[0, 3] = 0.5
    scene.add_instance(mesh, np.eye(4), 5)
    scene.add_instance(mesh, shifted, 7)
    scene.commit()
    return scene


@pytest.mark.parametrize("coherent", [False, True])
@pytest.mark.parametrize("count", [0, 1, 15, 16, 17, 5000])
def test_packets_called_from_python_answer_as_the_compiled_loops(count, coherent, monkeypatch):
    """embree's packets made by numpy and called from Python (a small render's) hold the compiled
    loops' rays lane for lane, with the same query arguments: the same hits and occlusions, bit for
    bit (NaN and negative distances included), coherent camera-ray queries too."""
    import numpy as np

    from realistic.core import jit

    scene = _random_instances()
    rng = np.random.default_rng(count)
    origin = (rng.random((count, 3)) * 2 - 0.5).astype(np.float32)
    direction = (rng.random((count, 3)) - 0.5).astype(np.float32)
    distance = (rng.random(count) * 2 - 0.3).astype(np.float32)
    distance[:count // 7] = np.nan
    answers = []
    for compiled in (True, False):
        monkeypatch.setattr(jit, "_use_compiled", [compiled])
        hits = scene.intersect(origin, direction, coherent=coherent)
        answers.append((*vars(hits).values(), scene.occluded(origin, direction, distance)))
    assert count < 100 or answers[0][4].max() >= 0  # some rays hit
    for compiled, python in zip(*answers):
        assert compiled.dtype == python.dtype and np.array_equal(compiled, python)


@pytest.mark.parametrize("groups, per", [(0, 1), (1, 1), (3, 4), (40, 8)])
def test_lanes_called_from_python_answer_as_the_compiled_loop(groups, per, monkeypatch):
    """Shadow rays in lanes (``occluded_lanes``) traced as point-major rows by numpy's packets
    called from Python get the compiled loop's answers, bit for bit (NaN and negative lengths
    included)."""
    import numpy as np

    from realistic.core import jit
    from realistic.scene.packet_loop import PACKET

    scene = _random_instances()
    rng = np.random.default_rng(groups)
    origin = (rng.random((groups, per, 3, PACKET)) * 2 - 0.5).astype(np.float32)
    vector = (rng.random((groups, per, 3, PACKET)) - 0.5).astype(np.float32)
    length = (rng.random((groups, per, PACKET)) * 2 - 0.3).astype(np.float32)
    length[:, :, ::7] = np.nan
    answers = []
    for compiled in (True, False):
        monkeypatch.setattr(jit, "_use_compiled", [compiled])
        answers.append(scene.occluded_lanes(origin, vector, length))
    assert groups < 40 or 0 < np.count_nonzero(answers[0] & (length >= 0)) < np.count_nonzero(length >= 0)
    assert answers[0].shape == length.shape and np.array_equal(*answers)


def test_the_numpy_forms_of_the_pass_loops_give_the_same_bits(numpy_loops, monkeypatch):
    import numpy as np

    from realistic.core import jit
    from realistic.renderer import direct_lighting, film, runner

    rng = np.random.default_rng(5)
    n, per_ray, groups = 3000, 3, 188  # 3008 hits in lanes (``packet_loop.LANE_DEFINES``)
    output = rng.random((7, n + 37)).astype(np.float32)
    rows = np.sort(rng.choice(n, n - 400, replace=False))
    pixel = np.sort(rng.integers(100, 900, n))
    value, weight = rng.random((n, 3)).astype(np.float32), (rng.random(n) - 0.2).astype(np.float32)
    contribution = rng.random((groups, per_ray, 3, 16)).astype(np.float32)
    blocked = rng.random((groups, per_ray, 16)) < 0.4
    length = (rng.random((groups, per_ray, 16)) - 0.3).astype(np.float32)

    def run() -> list:
        out = [np.full((n, 3), 7.0, np.float32) for _ in range(2)]
        counts = [direct_lighting.visible_sums(contribution, blocked, length, n, fresh, o)
                  for fresh, o in zip((True, False), out)]
        return [runner.gather_rows(output[0:3, :n].T, rows), runner.gather_rows(output[3:6].T, rows),
                runner.gather_rows(output[0:3, :n].T.astype(np.float64), rows),
                film.pass_sums(pixel, value, 100, 800, weight),
                film.pass_sums(pixel, value.astype(np.float64), 100, 800),
                *out, np.array(counts)]

    numpy_forms = run()
    monkeypatch.setattr(jit, "_use_compiled", [True])
    for compiled, numpy_form in zip(run(), numpy_forms):
        assert compiled.dtype == numpy_form.dtype and compiled.flags.c_contiguous == numpy_form.flags.c_contiguous
        assert np.array_equal(compiled, numpy_form)


def test_the_numpy_forms_of_the_texture_and_instance_loops_give_the_same_bits(numpy_loops, monkeypatch):
    """The device textures' row pick and place and the instanced hits' normals to the world, in numpy
    (a small render's) and compiled: the same rows, the same float32 sums."""
    import numpy as np

    from realistic.core import jit
    from realistic.renderer import hit_rows
    from realistic.scene import intersect

    rng = np.random.default_rng(9)
    n = 4000
    geom = rng.integers(-1, 12, n).astype(np.int32)  # ids past the instances' are lights
    geom_material = rng.integers(0, 3, 9)
    values = rng.random((n, 3)).astype(np.float32)
    instance = rng.integers(-1, 5, n).astype(np.int32)
    normal_to_world_t = rng.standard_normal((5, 3, 3)).astype(np.float32)
    normal = rng.standard_normal((n, 3)).astype(np.float32)

    def run() -> list:
        rows = np.full(n, -7, np.int32)
        count = hit_rows.rows_on_material(geom, geom_material, 1, rows)
        out = np.zeros((n, 3), np.float32)
        hit_rows.place_rows(values[:count], rows[:count], out)
        hit_geom, hit_normal = geom.copy(), normal.copy()
        intersect.instances_to_world(instance, normal_to_world_t, hit_geom, hit_normal)
        return [rows, np.array([count]), out, hit_geom, hit_normal]

    numpy_forms = run()
    assert 0 < numpy_forms[1][0] < n
    monkeypatch.setattr(jit, "_use_compiled", [True])
    for compiled, numpy_form in zip(run(), numpy_forms):
        assert compiled.dtype == numpy_form.dtype and np.array_equal(compiled, numpy_form)


def test_the_numpy_forms_refuse_what_the_loops_refuse(numpy_loops):
    import numpy as np

    from realistic.renderer import film, runner

    with pytest.raises(IndexError, match="a row outside 0 .. 3"):
        runner.gather_rows(np.zeros((4, 3), np.float32), np.array([0, 4]))
    with pytest.raises(ValueError, match="a pixel outside 10 .. 11"):
        film.pass_sums(np.array([10, 12]), np.zeros((2, 3), np.float32), 10, 2)


def test_a_small_render_never_imports_numba_and_a_large_one_compiles_its_loops():
    """README's first render (300x300, 16 spp) is too small to repay numba's import and first
    compiles (``COMPILED_LOOPS_RAYS``): its passes run the loops' numpy forms and embree's packets
    from Python (checked in a process of its own); a render of more rays runs numba's loops."""
    import dataclasses

    from realistic.core import jit
    from realistic.renderer.job import RenderJob
    from realistic.renderer.runner import COMPILED_LOOPS_RAYS, choose_loops

    run = run_fresh("""
import sys
from realistic import load_scene
from realistic.renderer.job import RenderJob
from realistic.renderer.passes import ThreadPasses, render

scene = load_scene()
print(scene.camera.width, scene.camera.height, scene.camera.spp, scene.light_samples)
render(RenderJob(scene, (scene.camera,), "opencl"), ThreadPasses())
print("numba" in sys.modules)
""")
    assert run.stdout.split() == ["300", "300", "16", "1", "False"]
    scene = load_scene(resolution=(30, 20), spp=1)
    big = dataclasses.replace(scene.camera, spp=COMPILED_LOOPS_RAYS // (30 * 20 * 2) + 1)
    assert choose_loops(RenderJob(scene, (big,), "opencl")) and jit.compiled_loops()
    assert choose_loops(RenderJob(scene, (big,), "opencl")) and jit.compiled_loops()


def test_an_8_bit_png_is_the_file_imageio_wrote_without_importing_it():
    """``png_bytes`` writes 8-bit PNGs through Pillow itself: the bytes imageio's Pillow plugin wrote."""
    import imageio.v3 as iio
    import numpy as np

    from realistic.core.image_files import png_bytes, preview_pixels

    image = np.random.default_rng(2).random((17, 23, 3)).astype(np.float32)
    assert png_bytes(image, 0.5) == bytes(iio.imwrite("<bytes>", preview_pixels(image, 0.5), plugin="pillow",
                                                      extension=".png"))
