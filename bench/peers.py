"""Peers benchmark: the dragons rendered by Mitsuba 3, pbrt-v4 and by us, side by side (issue 35).

    .venv/bin/python bench/peers.py [--mitsuba] [--spp 64] [--res 300x300] [--repeats 5]
    PBRT_V4=/path/to/pbrt .venv/bin/python bench/peers.py [--only-pbrt-v4] [--v4-spps 4,16,64]
        [--reference-spp 1024] [--target 0.02]

Renders ``scenes/dof-dragons/dgauss.pbrt`` (11 Stanford dragons on the homework's grid floor under
its disk light; needs ``../shared/meshes/dragon.ply`` and ``../shared/scenes/pbrt/textures``, and
says so and stops without them) three ways, in one process, taking turns each repeat:

- ``thin lens``: our render of the scene with its camera replaced by pbrt's perspective camera
  (``THIN_LENS``: a 50 degree field of view, a 12.3 mm lens radius focused 3534 mm away in the
  scene's camera space, which ``Scale 5000`` makes millimetres: about the dgauss 50 mm at f/2
  focused on the red dragon right of centre) and ``Integrator "directlighting"`` (pbrt-v3 would
  otherwise path trace), the OpenCL backend;
- ``thin bilinear``: ``thin lens`` with the floor's image texture filtered as Mitsuba's ``bitmap``
  filters it (``bilinear_filter``): pbrt-v4's "bilinear" (its imagemap's default, ``textures.cpp``)
  in place of the pbrt-v3 file's EWA (pbrt-v3 ``imagemap.cpp``: ``trilinear`` false); pbrt-v4 picks
  the level from the footprint's width, Mitsuba reads the full image, the same level on all but the
  far floor. Both ratios to Mitsuba are printed: EWA as the file says, bilinear as Mitsuba renders;
- ``lens``: our render of the scene as it is (the dgauss prescription traced by ``kernels/lens.cl``;
  the lens vignettes about 40 % of the film's rays, which then cost nothing more);
- ``mitsuba`` (``--mitsuba``; skipped with a line saying why when ``mitsuba`` is not importable:
  ``pip install 'realistic[peers]'``, or when a probe render in a child process fails: Dr.Jit 1.x
  aborts on LLVM 14 and 15, and ``DRJIT_LIBLLVM_PATH`` names a newer libLLVM.so, e.g. Debian's
  ``libllvm19`` unpacked with ``apt-get download`` and ``dpkg -x``): Mitsuba 3's ``llvm_ad_rgb``
  variant on the same world, described from the same numbers (``mitsuba_scene``):
  * sensor ``thinlens``: our parsed camera's pose (its rotation and translation; pbrt's camera space
    has +x to the image right where Mitsuba's has +x to the left, so x is mirrored), ``fov`` on the
    smaller axis as pbrt's, ``aperture_radius`` and ``focus_distance`` times the pose's scale
    (Mitsuba's are in world units, pbrt's in camera units), ``near_clip`` 1e-4;
  * ``hdrfilm`` of the same resolution with a ``box`` filter of radius 0.5 (the scene's filter),
    ``independent`` sampler with the same spp;
  * the floor: the two triangles, their uv (0..5; v mirrored, as pbrt-v3 flips an image map's rows
    on load) and ``textures/lines.exr`` times 0.5 as a ``bitmap`` (the scene's ``scale`` texture),
    ``diffuse`` inside ``twosided`` (Mitsuba's diffuse is black from behind, pbrt's matte is not, and
    the floor's triangles face down), as every material here;
  * each dragon: ``dragon.ply`` with face normals (the PLY has no normals, so pbrt and we shade
    with the geometric normal), two ``shapegroup``s (red 0.8 0.2 0.2, blue 0.2 0.2 0.5) and 11
    ``instance``s at the world file's transforms;
  * the light: a ``disk`` of radius 8 at y = 10 facing down, ``area`` emitter of radiance 40;
  * integrator ``direct`` with ``emitter_samples`` 4 and ``bsdf_samples`` 0: one shadow ray per
    light sample, as our direct lighting with the scene's four light samples (matched work).

Timed: Mitsuba's ``mi.render`` (its scene load and BVH build excluded; a first render compiles its
kernels, untimed), our ``passes.render`` less its "setup" and "exit pupil" stages (the embree
scene's build and the pupil table: likewise excluded; a first render builds the kernels, untimed).
CPU-seconds are the process's for the whole call (ours include the set-up). Each repeat renders each
peer once, in turn; ratios are taken within a repeat, and the median and spread (min to max) over
repeats are printed with each peer's samples/s, wall, CPU-s, camera rays traced per sample (ours:
those the lens lets through; Mitsuba: 1) and image mean (RGB mean of the film; the lens camera's
film is irradiance and vignetted, so its mean is not comparable), and for ours the median
thread-seconds of each render stage (``renderer/timing``) and its share: what bounds it. The load
average is printed before and after: on a shared machine the figures are noisy.
Writes bench/results/peers.json.

pbrt-v4 (``PBRT_V4`` names its executable; skipped with a line saying why when it is unset or not an
executable file): time to equal error, in CPU-seconds and wall, from one pbrt-v4 file.

- The file: ``pbrt --upgrade`` of the dragons as pbrt-v3 takes them (``pbrt_v3_scene``: the
  homework camera rewritten in pbrt-v3's convention, which ``--upgrade`` passes through), written
  with everything it makes into bench/results/pbrt-v4/. The upgrade makes the sampler
  ``paddedsobol`` (from ``lowdiscrepancy``), the light ``diffuse`` without ``nsamples``, the matte
  materials ``diffuse``; the file names no integrator nor filter, so both renderers take pbrt-v4's
  defaults: ``volpath`` (we render it as ``path``), ``maxdepth`` 5, the ``bvh`` light sampler, the
  gaussian filter of radius 1.5.
- Both render that file at each ``--v4-spps`` with two seeds, taking turns: pbrt-v4 as a child process
  (``--nthreads`` the CPU count, ``--spp``, ``--seed``), timed whole (parsing, BVH, render, EXR)
  in wall and in the child's CPU-seconds (``resource.getrusage(RUSAGE_CHILDREN)``); we time our scene
  load (once, added to each render) and ``render`` in wall and in the process's CPU-seconds.
  pbrt-v4 bounds its exit pupil at every start (``RealisticCamera``'s constructor); ours comes from
  the disk cache after the first render, as a user's second render of the lens finds it.
- Each render's noise is its relative RMSE from its two seeds (``convergence.two_seed_noise``, no
  reference); the spp to ``--target`` follows the 1/N law from the highest count
  (``converge.spp_to_noise``), the seconds there a line in spp through the measured seconds
  (``converge.extrapolated_seconds``), and the ratio pbrt-v4 / ours is printed in CPU-seconds and
  wall. ``noise_power_law``'s exponent over all counts is printed beside it (0.5: the 1/N law).
- Agreement: against our reference at ``--reference-spp`` (seed 1, cached as ``bench/converge.py``
  caches it), each renderer's image mean at its highest count (both seeds averaged) and that
  image's relative RMSE, beside the RMSE its noise alone explains. pbrt gives an area light's shape
  the material in effect where it is declared (pbrt-v4 src/pbrt/scene.cpp, ``CreateAggregate``: a
  ``GeometricPrimitive`` with ``mtl`` and the light; here the default diffuse 0.5 under the disk),
  and its path integrator reflects off it (src/pbrt/cpu/integrators.cpp, ``PathIntegrator::Li``: the
  emission, then the same surface's BSDF); so do we (``AreaLight.material``, ``renderer/path``), so
  the light reflected off the disk's underside from the third path vertex on is in both images.

Writes bench/results/peers-pbrt-v4.json.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "bench"))

import converge  # noqa: E402
import machine  # noqa: E402
from realistic.camera.lens_camera import LensCamera  # noqa: E402
from realistic.camera.thin_lens import ThinLensCamera  # noqa: E402
from realistic.cli import build_parser  # noqa: E402
from realistic.cli.scene_arguments import options_from_args  # noqa: E402
from realistic.cli.values import checked, parse_resolution, parse_spp_list, positive  # noqa: E402
from realistic.core import validation  # noqa: E402
from realistic.core.image_files import read_exr  # noqa: E402
from realistic.core.transforms import rotate, scale, translate  # noqa: E402
from realistic.optics.paraxial import focus_distance_for_film  # noqa: E402
from realistic.renderer.convergence import relative_rmse, two_seed_noise  # noqa: E402
from realistic.renderer.inputs import RenderInputs, RenderOptions, build_render_inputs  # noqa: E402
from realistic.renderer.job import RenderJob  # noqa: E402
from realistic.renderer.passes import ThreadPasses, render  # noqa: E402
from realistic.scene.surfaces import ImageTexture, Material  # noqa: E402
from scenes import positive_count  # noqa: E402

SHARED = ROOT.parent / "shared"
MESHES = SHARED / "meshes"
PBRT = SHARED / "scenes" / "pbrt"
SCENE = ROOT / "scenes" / "dof-dragons" / "dgauss.pbrt"
#: The lens the dgauss scene names (``"string specfile" "dgauss.50mm.dat"``).
LENS_FILE = SHARED / "lenses" / "dgauss.50mm.dat"
#: Where the pbrt-v4 comparison writes its scene files, images and cached reference.
V4_FOLDER = ROOT / "bench" / "results" / "pbrt-v4"
THIN_LENS = 'Camera "perspective" "float fov" [50] "float lensradius" [12.3] "float focaldistance" [3534]'
#: The dragons of scenes/dof-dragons/world.pbrt: per instance, its object's colour and turn about y (degrees).
BLUE, RED = (0.2, 0.2, 0.5), (0.8, 0.2, 0.2)
DRAGONS = [(BLUE, -10.0) if i % 2 == 0 else (RED, -17.0) for i in range(11)]

#: A child process's render of Mitsuba's Cornell box: an LLVM that Dr.Jit cannot use aborts the process.
PROBE = ("import mitsuba as mi; mi.set_variant('llvm_ad_rgb'); "
         "mi.render(mi.load_dict(mi.cornell_box()), spp=1).numpy()")
#: One peer's render: () -> (image (H, W, 3), render wall seconds, CPU-seconds, samples, camera rays traced,
#: thread-seconds per stage of ours (``renderer/timing``) and embree's CPU-s (``EMBREE_CPU``), empty for Mitsuba).
Render = Callable[[], tuple[np.ndarray, float, float, int, int, dict[str, float]]]
#: Our stages timed per render (the set-up ones are excluded from the timings, as above).
STAGES = ("ray generation", "embree", "shading", "accumulation")
#: The embree stage's CPU seconds on the render threads (``StageClock.cpu_seconds``): its thread-seconds
#: less the time those threads waited for a core or the GIL.
EMBREE_CPU = "embree CPU"


def thin_lens_scene(folder: Path) -> Path:
    """The dgauss dragons with pbrt's perspective camera (``THIN_LENS``) and direct lighting, in ``folder``."""
    lines, camera = [], False
    for line in SCENE.read_text(encoding="utf-8").splitlines():
        if line.startswith("Camera "):
            lines.append(THIN_LENS)
            camera = True
        elif camera and line.startswith("    "):
            continue  # the realistic camera's parameters
        else:
            camera = False
            lines.append('Integrator "directlighting"\nWorldBegin' if line.startswith("WorldBegin") else line)
    path = folder / "dgauss-thin-lens.pbrt"
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


def our_inputs(scene: Path, spp: int, res: tuple[int, int]) -> RenderInputs:
    """The scene's render inputs as ``realistic render`` would make them."""
    arguments = ["render", str(scene), "--spp", str(spp), "--res", f"{res[0]}x{res[1]}", "--backend", "opencl"]
    for folder in (MESHES, PBRT, SCENE.parent):
        arguments += ["--search-path", str(folder)]
    args = build_parser().parse_args(arguments)
    return build_render_inputs(options_from_args(args, args.spp))


def bilinear_filter(inputs: RenderInputs) -> RenderInputs:
    """``inputs`` with its image textures filtered with pbrt-v4's "bilinear" (a scene of its own)."""
    scene = replace(inputs.scene, instances=list(inputs.scene.instances))
    for k, instance in enumerate(scene.instances):
        material = instance.material
        if isinstance(material, Material) and isinstance(material.texture, ImageTexture):
            texture = replace(material.texture, filter="bilinear")
            scene.instances[k] = replace(instance, material=replace(material, texture=texture))
    return replace(inputs, scene=scene, intersector=None)


def our_render(inputs: RenderInputs) -> Render:
    """Our render of ``inputs`` on the OpenCL backend, rendered once now (kernel builds, caches)."""
    job = RenderJob(inputs.scene, (inputs.camera,), "opencl", 0)
    render(job, ThreadPasses())

    def run() -> tuple[np.ndarray, float, float, int, int, dict[str, float]]:
        cpu = time.process_time()
        result = render(job, ThreadPasses())[0]
        cpu = time.process_time() - cpu
        before_rays = result.stage_seconds.get("setup", 0.0) + result.stage_seconds.get("exit pupil", 0.0)
        stages = {stage: result.stage_seconds.get(stage, 0.0) for stage in STAGES}
        stages[EMBREE_CPU] = result.stage_cpu_seconds.get("embree", 0.0)
        return result.image, result.seconds - before_rays, cpu, result.samples_done, result.primary_rays, stages

    return run


def mitsuba_pose(world_from_camera: np.ndarray) -> tuple[np.ndarray, float]:
    """Mitsuba's sensor ``to_world`` for a pbrt camera pose (uniform scale, rotation, translation),
    and the pose's scale: the rotation and translation, x mirrored (pbrt's camera +x is the image's
    right, Mitsuba's its left)."""
    unit = float(np.cbrt(np.linalg.det(world_from_camera[:3, :3])))  # the dragons' 1 / 5000
    pose = np.eye(4)
    pose[:3, :3] = world_from_camera[:3, :3] / unit @ np.diag([-1.0, 1.0, 1.0])
    pose[:3, 3] = world_from_camera[:3, 3]
    return pose, unit


def mitsuba_scene(mi: Any, camera: ThinLensCamera, folder: Path) -> dict:
    """Mitsuba's description of the dragons seen by ``camera`` (see the module's docstring)."""
    pose, unit = mitsuba_pose(camera.world_from_camera)
    texture, _ = read_exr(PBRT / "textures" / "lines.exr")
    floor = folder / "floor.ply"
    _write_floor(floor)

    def dragon(colour: tuple[float, float, float]) -> dict:
        return {"type": "shapegroup", "dragon": {
            "type": "ply", "filename": str(MESHES / "dragon.ply"), "face_normals": True,
            "bsdf": {"type": "twosided", "bsdf": {"type": "diffuse", "reflectance": {
                "type": "rgb", "value": list(colour)}}}}}

    scene: dict = {
        "type": "scene",
        "integrator": {"type": "direct", "emitter_samples": 4, "bsdf_samples": 0},
        "sensor": {"type": "thinlens", "to_world": mi.ScalarTransform4f(pose.tolist()), "fov": camera.fov_deg,
                   "fov_axis": "smaller", "aperture_radius": camera.lens_radius * unit,
                   "focus_distance": camera.focal_distance * unit, "near_clip": 1e-4,
                   "film": {"type": "hdrfilm", "width": camera.width, "height": camera.height,
                            "rfilter": {"type": "box"}, "pixel_format": "rgb"},
                   "sampler": {"type": "independent", "sample_count": camera.spp}},
        "floor": {"type": "ply", "filename": str(floor), "face_normals": True,
                  "bsdf": {"type": "twosided", "bsdf": {"type": "diffuse", "reflectance": {
                      "type": "bitmap", "data": mi.TensorXf(np.ascontiguousarray(texture[..., :3] * 0.5)),
                      "raw": True, "filter_type": "bilinear", "wrap_mode": "repeat"}}}},
        "light": {"type": "disk", "to_world": mi.ScalarTransform4f((translate(0, 10, 0) @ rotate(90, (1, 0, 0))
                                                                    @ scale(8)).tolist()),
                  "emitter": {"type": "area", "radiance": {"type": "rgb", "value": [40.0, 40.0, 40.0]}}},
        "blue": dragon(BLUE), "red": dragon(RED),
    }
    for i, (colour, turn) in enumerate(DRAGONS):
        place = (translate(-0.6 + 0.26 * i, 0, 0) @ translate(-0.01, 0, 0) @ rotate(turn, (0, 1, 0))
                 @ translate(0.01, 0, 0))
        scene[f"dragon{i}"] = {"type": "instance", "to_world": mi.ScalarTransform4f(place.tolist()),
                               "shapegroup": {"type": "ref", "id": "blue" if colour == BLUE else "red"}}
    return scene


def _write_floor(path: Path) -> None:
    """world.pbrt's floor as a PLY with uv: the square +-4 on y = 0, uv 0..5 (v mirrored: see the docstring)."""
    from plyfile import PlyData, PlyElement

    vertices = np.array([(-4, 0, -4, 0, 1), (4, 0, -4, 5, 1), (4, 0, 4, 5, -4), (-4, 0, 4, 0, -4)],
                        dtype=[("x", "f4"), ("y", "f4"), ("z", "f4"), ("u", "f4"), ("v", "f4")])
    faces = np.array([([0, 1, 2],), ([2, 3, 0],)], dtype=[("vertex_indices", "i4", (3,))])
    PlyData([PlyElement.describe(vertices, "vertex"), PlyElement.describe(faces, "face")]).write(str(path))


def mitsuba_render(camera: ThinLensCamera, folder: Path) -> Render | str:
    """Mitsuba's render of the dragons, rendered once now (its kernels compile), or why not."""
    try:
        import mitsuba as mi
    except ImportError as err:
        return f"not importable ({err}); pip install 'realistic[peers]'"
    probe = subprocess.run([sys.executable, "-c", PROBE], capture_output=True, timeout=600)
    if probe.returncode != 0:
        return (f"its LLVM backend failed a probe render (exit status {probe.returncode}): Dr.Jit 1.x needs an "
                "LLVM that lowers fminimum (17 or newer; Debian 12's 14 and 15 abort): set DRJIT_LIBLLVM_PATH to "
                "one's libLLVM.so")
    mi.set_variant("llvm_ad_rgb")
    scene = mi.load_dict(mitsuba_scene(mi, camera, folder))
    np.asarray(mi.render(scene, spp=camera.spp))

    def run() -> tuple[np.ndarray, float, float, int, int, dict[str, float]]:
        cpu, wall = time.process_time(), time.perf_counter()
        image = np.asarray(mi.render(scene, spp=camera.spp))
        wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
        return image, wall, cpu, camera.sample_count, camera.sample_count, {}

    return run


def pbrt_v4_executable() -> Path | str:
    """pbrt-v4's executable from ``PBRT_V4``, or why there is none."""
    value = os.environ.get("PBRT_V4", "")
    if not value:
        return "PBRT_V4 is not set (the path of a pbrt-v4 executable)"
    if not (Path(value).is_file() and os.access(value, os.X_OK)):
        return f"PBRT_V4={value} is not an executable file"
    return Path(value)


def pbrt_v3_scene(folder: Path, res: tuple[int, int]) -> Path:
    """The dgauss dragons as pbrt-v3 reads them, the input of ``pbrt --upgrade``, written in ``folder``.

    ``scenes/dof-dragons/dgauss.pbrt`` has the homework's camera (``specfile``, ``filmdistance`` in mm
    from the rear vertex, ``aperture_diameter``, ``filmdiag``; camera space in mm with the front lens
    vertex at its origin), which neither pbrt-v3 nor pbrt-v4 reads and ``--upgrade`` copies unchanged.
    So it is written in pbrt-v3's convention, which pbrt-v4 keeps (pbrt-v4 src/pbrt/cameras.cpp,
    ``RealisticCamera::Create``): ``lensfile``, ``aperturediameter`` (mm), ``focusdistance`` (m from the
    film: the distance the homework's film distance focuses, ``paraxial.focus_distance_for_film``),
    ``Film "diagonal"``, and camera space in metres with the film centre at its origin
    (``Translate 0 0`` the film-to-front-vertex distance and ``Scale .001`` ahead of the file's own
    transforms). ``world.pbrt`` is inlined and the mesh, texture and lens are named by absolute paths.
    """
    camera = our_inputs(SCENE, 1, res).camera
    assert isinstance(camera, LensCamera)
    focus_m = focus_distance_for_film(camera.lens, camera.film_distance_mm) / 1000.0
    front_m = (camera.film_distance_mm + camera.lens.track_length_mm) / 1000.0
    world = (SCENE.parent / "world.pbrt").read_text(encoding="utf-8")
    world = world.replace('"dragon.ply"', f'"{MESHES / "dragon.ply"}"').replace(
        '"textures/lines.exr"', f'"{PBRT / "textures" / "lines.exr"}"')
    lines = [f'Film "image" "integer xresolution" [{res[0]}] "integer yresolution" [{res[1]}] '
             f'"float diagonal" [{camera.film_diagonal_mm:g}] "string filename" ["dragons.exr"]']
    for line in SCENE.read_text(encoding="utf-8").splitlines():
        if line.startswith("Camera "):
            lines.append(f'Camera "realistic" "string lensfile" "{LENS_FILE}" "float aperturediameter" '
                         f'[{camera.lens.stop_diameter_mm:g}] "float focusdistance" [{focus_m:.9g}]')
        elif line.startswith("Scale "):
            lines += [f"Translate 0 0 {front_m:.9g}", "Scale .001 .001 .001", line]
        elif line.startswith("Include "):
            lines.append(world)
        elif not line.startswith(("Film ", "    ")):  # the homework camera's parameters are indented
            lines.append(line)
    path = folder / "dragons-v3.pbrt"
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


def child_seconds(command: list[str]) -> tuple[float, float]:
    """Run ``command``: its wall seconds and CPU-seconds (user + system, from RUSAGE_CHILDREN); a
    failure stops the bench with its last line of output."""
    before, start = resource.getrusage(resource.RUSAGE_CHILDREN), time.perf_counter()
    result = subprocess.run(command, capture_output=True, text=True)
    wall, after = time.perf_counter() - start, resource.getrusage(resource.RUSAGE_CHILDREN)
    if result.returncode != 0:
        last = (result.stderr.strip() or result.stdout.strip() or "no output").splitlines()[-1]
        raise SystemExit(f"pbrt-v4: {' '.join(command)} failed (exit status {result.returncode}): {last}")
    return wall, after.ru_utime - before.ru_utime + after.ru_stime - before.ru_stime


def pbrt_v4_scene(pbrt: Path, folder: Path, res: tuple[int, int]) -> Path:
    """The dragons' pbrt-v4 file: ``pbrt --upgrade`` of ``pbrt_v3_scene``, in ``folder``."""
    v3 = pbrt_v3_scene(folder, res)
    result = subprocess.run([str(pbrt), "--upgrade", str(v3)], capture_output=True, text=True)
    if result.returncode != 0:
        raise SystemExit(f"pbrt-v4: --upgrade {v3} failed: {result.stderr.strip()}")
    path = folder / "dragons-v4.pbrt"
    path.write_text(result.stdout, encoding="utf-8")
    return path


def pbrt_v4_run(pbrt: Path, scene: Path, spp: int, seed: int) -> tuple[np.ndarray, float, float]:
    """pbrt-v4's render of ``scene`` at ``spp`` with ``seed``: (RGB image, wall s, CPU-s), the whole process."""
    out = scene.with_name(f"pbrt-v4-{spp}spp-seed{seed}.exr")
    wall, cpu = child_seconds([str(pbrt), "--nthreads", str(os.cpu_count() or 1), "--spp", str(spp),
                               "--seed", str(seed), "--outfile", str(out), "--quiet", str(scene)])
    return read_exr(out)[0][..., :3], wall, cpu


def our_v4_run(inputs: RenderInputs, load: tuple[float, float], spp: int, seed: int
               ) -> tuple[np.ndarray, float, float]:
    """Our render of the loaded pbrt-v4 file at ``spp`` with ``seed``: (RGB image, wall s, CPU-s), the
    scene load's (wall, CPU) ``load`` added."""
    cpu = time.process_time()
    image, wall = converge.render_seconds(inputs, spp, seed)
    return image[..., :3], load[0] + wall, load[1] + time.process_time() - cpu


#: One renderer's render of the pbrt-v4 file: (spp, seed) -> (RGB image, wall s, CPU-s).
V4Run = Callable[[int, int], tuple[np.ndarray, float, float]]


def equal_error(runs: dict[str, V4Run], spps: list[int], ref: np.ndarray, target: float) -> dict[str, dict]:
    """Per renderer: its rows (spp, wall, CPU-s, noise from two seeds), its fitted times to ``target``
    (see the module's docstring), and its highest count's image mean and RMSE against ``ref``. The
    renderers take turns at each count and seed, so the machine's load falls on both alike."""
    rows: dict[str, list[dict]] = {name: [] for name in runs}
    last: dict[str, np.ndarray] = {}
    for spp in spps:
        renders: dict[str, list[tuple[np.ndarray, float, float]]] = {name: [] for name in runs}
        for seed in (converge.TEST_SEED, converge.NOISE_SEED):
            for name, run in runs.items():
                renders[name].append(run(spp, seed))
        for name, ((first, wall, cpu), (second, wall2, cpu2)) in renders.items():
            rows[name].append({"spp": spp, "wall_s": (wall + wall2) / 2, "cpu_s": (cpu + cpu2) / 2,
                               "noise": two_seed_noise(first, second), "mean": float(np.mean(first))})
            last[name] = 0.5 * (first.astype(np.float64) + second)
            print(f"{name:8s} {spp:5d} spp {rows[name][-1]['wall_s']:8.2f} s wall {rows[name][-1]['cpu_s']:8.2f} "
                  f"CPU-s noise {rows[name][-1]['noise']:.4f}", flush=True)
    results = {}
    for name, table in rows.items():
        top = table[-1]
        spp_target = converge.spp_to_noise(top["noise"] * math.sqrt(top["spp"]), 0.5, target)
        _, q = converge.noise_power_law(spps, [r["noise"] for r in table])
        results[name] = {
            "rows": table, "spp_to_target": spp_target, "exponent": q,
            "wall_s_to_target": converge.extrapolated_seconds(spps, [r["wall_s"] for r in table], 0.0, spp_target),
            "cpu_s_to_target": converge.extrapolated_seconds(spps, [r["cpu_s"] for r in table], 0.0, spp_target),
            "mean": float(np.mean(last[name])), "reference_mean": float(np.mean(ref)),
            "rel_rmse_to_reference": relative_rmse(last[name], ref),
            # the two seeds' average has half a render's variance: this much of its RMSE is its noise
            "noise_of_average": top["noise"] / math.sqrt(2.0)}
    return results


def pbrt_v4_peer(pbrt: Path, args: argparse.Namespace) -> None:
    """Time to ``args.target`` of pbrt-v4 and of us from one pbrt-v4 file; prints and writes JSON."""
    V4_FOLDER.mkdir(parents=True, exist_ok=True)
    scene = pbrt_v4_scene(pbrt, V4_FOLDER, args.res)
    load_wall, load_cpu = time.perf_counter(), time.process_time()
    inputs = build_render_inputs(RenderOptions(scene=str(scene)))
    load = (time.perf_counter() - load_wall, time.process_time() - load_cpu)
    ref = converge.reference(inputs, converge.reference_path(V4_FOLDER, scene, args.res, args.reference_spp,
                                                             converge.source_hash(ROOT, scene)), args.reference_spp)
    converge.render_seconds(inputs, args.v4_spps[0], converge.TEST_SEED)  # kernels built, untimed
    load_before = os.getloadavg()
    runs: dict[str, V4Run] = {"pbrt-v4": lambda spp, seed: pbrt_v4_run(pbrt, scene, spp, seed),
                              "ours": lambda spp, seed: our_v4_run(inputs, load, spp, seed)}
    results = equal_error(runs, args.v4_spps, ref, args.target)
    load_after = os.getloadavg()
    theirs, ours = results["pbrt-v4"], results["ours"]
    ratios = {f"pbrt-v4 / ours, {unit} to {args.target:g}": theirs[key] / ours[key]
              for unit, key in (("CPU-s", "cpu_s_to_target"), ("wall s", "wall_s_to_target"))}
    print(f"{machine.describe()}; {scene} ({args.res[0]}x{args.res[1]}), our reference {args.reference_spp} spp; "
          f"load average {load_before[0]:.2f} before, {load_after[0]:.2f} after (shared machine: noisy)")
    print(f"{'peer':8s} {'spp to ' + format(args.target, 'g'):>11s} {'CPU s':>9s} {'wall s':>9s} {'exponent':>9s} "
          f"{'mean':>9s} {'mean/ref':>9s} {'RMSE/ref':>9s} {'its noise':>9s}")
    for name, r in results.items():
        print(f"{name:8s} {r['spp_to_target']:11.0f} {r['cpu_s_to_target']:9.1f} {r['wall_s_to_target']:9.1f} "
              f"{r['exponent']:9.3f} {r['mean']:9.5g} {r['mean'] / r['reference_mean']:9.4f} "
              f"{r['rel_rmse_to_reference']:9.4f} {r['noise_of_average']:9.4f}")
    for label, value in ratios.items():
        print(f"{label}: {value:.2f}x")
    out = ROOT / "bench" / "results" / "peers-pbrt-v4.json"
    out.write_text(json.dumps({"machine": machine.describe(), "scene": str(scene), "resolution": list(args.res),
                               "reference_spp": args.reference_spp, "target": args.target,
                               "load_average": [load_before, load_after], "our_scene_load_s": list(load),
                               "results": results, "ratios": ratios}, indent=1))
    print(f"wrote {out}")


def spread(values: list[float]) -> dict:
    """The median, least and greatest of ``values``."""
    return {"median": statistics.median(values), "min": min(values), "max": max(values)}


def cell(figure: dict, factor: float) -> str:
    """A figure's median [min-max] times ``factor``, to two decimals."""
    return f"{figure['median'] * factor:.2f} [{figure['min'] * factor:.2f}-{figure['max'] * factor:.2f}]"


def build_parser_() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--mitsuba", action="store_true", help="render with Mitsuba 3 too (llvm_ad_rgb)")
    parser.add_argument("--spp", type=checked(int, validation.samples_per_pixel), default=64)
    parser.add_argument("--res", type=parse_resolution, default=(300, 300), metavar="WxH")
    parser.add_argument("--repeats", type=checked(int, positive_count), default=5)
    parser.add_argument("--only-pbrt-v4", action="store_true", help="only the pbrt-v4 comparison (needs PBRT_V4)")
    parser.add_argument("--v4-spps", type=checked(str, parse_spp_list), default=[4, 16, 64], metavar="N,N,...",
                        help="samples per pixel of the pbrt-v4 comparison's renders (default 4,16,64)")
    parser.add_argument("--reference-spp", type=checked(int, validation.samples_per_pixel), default=1024,
                        metavar="N", help="samples per pixel of our reference for pbrt-v4 (default 1024)")
    parser.add_argument("--target", type=positive("target relative RMSE"), default=0.02,
                        help="relative RMSE the pbrt-v4 comparison times (default 0.02)")
    return parser


def main() -> None:
    args = build_parser_().parse_args()
    missing = [p for p in (MESHES / "dragon.ply", PBRT / "textures" / "lines.exr") if not p.exists()]
    if missing:
        print(f"peers: skipped: {missing[0]} not found (no ../shared data)")
        return
    pbrt = pbrt_v4_executable()
    if isinstance(pbrt, str):
        print(f"pbrt-v4: skipped: {pbrt}")
    elif not LENS_FILE.is_file():
        print(f"pbrt-v4: skipped: {LENS_FILE} not found (no ../shared data)")
    else:
        pbrt_v4_peer(pbrt, args)
    if args.only_pbrt_v4:
        return
    load_before = os.getloadavg()
    with tempfile.TemporaryDirectory() as temporary:
        folder = Path(temporary)
        thin = our_inputs(thin_lens_scene(folder), args.spp, args.res)
        assert isinstance(thin.camera, ThinLensCamera)
        peers: dict[str, Render] = {"thin lens": our_render(thin), "thin bilinear": our_render(bilinear_filter(thin)),
                                    "lens": our_render(our_inputs(SCENE, args.spp, args.res))}
        skipped = {}
        if args.mitsuba:
            made = mitsuba_render(thin.camera, folder)
            if isinstance(made, str):
                print(f"mitsuba: skipped: {made}")
                skipped["mitsuba"] = made
            else:
                peers["mitsuba"] = made
        runs: dict[str, list[dict]] = {name: [] for name in peers}
        for _ in range(args.repeats):
            for name, run in peers.items():
                image, wall, cpu, samples, traced, stages = run()
                runs[name].append({"wall_s": wall, "cpu_s": cpu, "samples_per_s": samples / wall,
                                   "samples_per_cpu_s": samples / cpu, "traced_per_sample": traced / samples,
                                   "mean": float(np.mean(image[..., :3]))}
                                  | {f"{stage} thread_s": seconds for stage, seconds in stages.items()})
    load_after = os.getloadavg()
    summary = {name: {key: spread([run[key] for run in values]) for key in values[0]} for name, values in runs.items()}
    ratios = {"lens / thin lens samples/s": [lens["samples_per_s"] / thin_["samples_per_s"]
                                             for lens, thin_ in zip(runs["lens"], runs["thin lens"])]}
    if "mitsuba" in runs:
        for thin_name, key, label in [(n, k, la) for n in ("thin lens", "thin bilinear") for k, la in (
                ("samples_per_s", "samples/s"), ("samples_per_cpu_s", "samples/CPU-s"), ("mean", "image mean"))]:
            ratios[f"{thin_name} / mitsuba {label}"] = [ours[key] / theirs[key]
                                                        for ours, theirs in zip(runs[thin_name], runs["mitsuba"])]
    print(f"{machine.describe()}; {args.res[0]}x{args.res[1]}, {args.spp} spp, {args.repeats} repeats; load average "
          f"{load_before[0]:.2f} before, {load_after[0]:.2f} after (shared machine: noisy)")
    print(f"{'peer':13s} {'M samples/s':>22s} {'wall s':>18s} {'CPU s':>18s} {'traced':>7s} {'image mean':>12s}")
    for name, figures in summary.items():
        cells = [cell(figures[key], factor) for key, factor in (("samples_per_s", 1e-6), ("wall_s", 1), ("cpu_s", 1))]
        print(f"{name:13s} {cells[0]:>22s} {cells[1]:>18s} {cells[2]:>18s} "
              f"{figures['traced_per_sample']['median']:7.3f} {figures['mean']['median']:12.5g}")
    for label, values in ratios.items():
        print(f"{label}: median {statistics.median(values):.3f} [{min(values):.3f}-{max(values):.3f}]")
    # what bounds ours: each stage's share of the stages' thread-seconds
    for name in ("thin lens", "thin bilinear", "lens"):
        seconds = {stage: summary[name][f"{stage} thread_s"]["median"] for stage in STAGES}
        print(f"{name} stages, median thread-s (share): " + ", ".join(
            f"{stage} {value:.2f} ({100 * value / sum(seconds.values()):.0f} %)" for stage, value in seconds.items())
            + f"; embree's CPU-s on the render threads {summary[name][f'{EMBREE_CPU} thread_s']['median']:.2f}")
    out = ROOT / "bench" / "results" / "peers.json"
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps({"machine": machine.describe(), "resolution": list(args.res), "spp": args.spp,
                               "repeats": args.repeats, "load_average": [load_before, load_after],
                               "skipped": skipped, "runs": runs, "summary": summary,
                               "ratios": {k: spread(v) for k, v in ratios.items()}}, indent=1))
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
