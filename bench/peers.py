"""Peers benchmark: the dragons rendered by Mitsuba 3 and by us, samples/s side by side (issue 35).

    .venv/bin/python bench/peers.py [--mitsuba] [--spp 64] [--res 300x300] [--repeats 5]

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
"""

from __future__ import annotations

import argparse
import json
import os
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

import machine  # noqa: E402
from realistic.camera.thin_lens import ThinLensCamera  # noqa: E402
from realistic.cli import build_parser  # noqa: E402
from realistic.cli.scene_arguments import options_from_args  # noqa: E402
from realistic.cli.values import checked, parse_resolution  # noqa: E402
from realistic.core import validation  # noqa: E402
from realistic.core.image_files import read_exr  # noqa: E402
from realistic.core.transforms import rotate, scale, translate  # noqa: E402
from realistic.renderer.inputs import RenderInputs, build_render_inputs  # noqa: E402
from realistic.renderer.job import RenderJob  # noqa: E402
from realistic.renderer.passes import ThreadPasses, render  # noqa: E402
from realistic.scene.surfaces import ImageTexture, Material  # noqa: E402
from scenes import positive_count  # noqa: E402

SHARED = ROOT.parent / "shared"
MESHES = SHARED / "meshes"
PBRT = SHARED / "scenes" / "pbrt"
SCENE = ROOT / "scenes" / "dof-dragons" / "dgauss.pbrt"
THIN_LENS = 'Camera "perspective" "float fov" [50] "float lensradius" [12.3] "float focaldistance" [3534]'
#: The dragons of scenes/dof-dragons/world.pbrt: per instance, its object's colour and turn about y (degrees).
BLUE, RED = (0.2, 0.2, 0.5), (0.8, 0.2, 0.2)
DRAGONS = [(BLUE, -10.0) if i % 2 == 0 else (RED, -17.0) for i in range(11)]

#: A child process's render of Mitsuba's Cornell box: an LLVM that Dr.Jit cannot use aborts the process.
PROBE = ("import mitsuba as mi; mi.set_variant('llvm_ad_rgb'); "
         "mi.render(mi.load_dict(mi.cornell_box()), spp=1).numpy()")
#: One peer's render: () -> (image (H, W, 3), render wall seconds, CPU-seconds, samples, camera rays traced,
#: thread-seconds per stage of ours (``renderer/timing``), empty for Mitsuba).
Render = Callable[[], tuple[np.ndarray, float, float, int, int, dict[str, float]]]
#: Our stages timed per render (the set-up ones are excluded from the timings, as above).
STAGES = ("ray generation", "embree", "shading", "accumulation")


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
    return parser


def main() -> None:
    args = build_parser_().parse_args()
    missing = [p for p in (MESHES / "dragon.ply", PBRT / "textures" / "lines.exr") if not p.exists()]
    if missing:
        print(f"peers: skipped: {missing[0]} not found (no ../shared data)")
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
            f"{stage} {value:.2f} ({100 * value / sum(seconds.values()):.0f} %)" for stage, value in seconds.items()))
    out = ROOT / "bench" / "results" / "peers.json"
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps({"machine": machine.describe(), "resolution": list(args.res), "spp": args.spp,
                               "repeats": args.repeats, "load_average": [load_before, load_after],
                               "skipped": skipped, "runs": runs, "summary": summary,
                               "ratios": {k: spread(v) for k, v in ratios.items()}}, indent=1))
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
