"""Scene benchmark: set-up, first pass and samples/s of the homework scenes, their dragons and ours.

    .venv/bin/python bench/scenes.py [--res 300x300] [--spp 32] [--light-samples N] [--repeats 1]
        [--empty-cache | --cold] [--backend opencl|numpy] [--only TEXT] [--flat]

Scenes: the homework's ``../shared/scenes/pbrt/dof-dragons.<lens>.pbrt``, their dragon versions
``scenes/dof-dragons/<lens>.pbrt`` (search paths ``../shared/meshes`` and ``../shared/scenes/pbrt``)
and ``scenes/default.pbrt``; scenes whose shared data is absent are skipped with the reason. Each
scene is measured in fresh processes, so imports and caches start as a user's command would (with
Python's bytecode cache allowed, as an installed package has it, even where PYTHONDONTWRITEBYTECODE is
set):

- ``cli s``: wall seconds of ``python -m realistic render SCENE --res --spp --out TMP.exr``;
- from the library (``build_render_inputs``, ``passes.render`` with an ``on_pass`` observer):
  ``setup s`` = process start and imports + scene load + the "exit pupil" and "setup" stages
  (everything before the first camera ray), ``first pass s`` = process start to the first finished
  pass, ``1st frame s`` = to the first whole frame (every pixel's first samples: the first slice),
  ``render s`` = the rest of ``render``, and samples/s = samples / render s;
  ``peak MiB`` = that process's peak resident set (``getrusage``'s ru_maxrss), whose interpreter
  baseline (python with numpy and pyopencl imported and embree loaded, nothing else) is measured first.

``--only TEXT`` keeps the scenes whose name contains TEXT ("dragons"); ``--flat`` measures the
library figures with every instance copied into one world-space embree scene
(``Intersector(scene, share=False)``, the renderer before geometry was shared between instances)
and skips the CLI column.

Light samples are the scenes' own (the homework gives 4) unless ``--light-samples`` is given. The
exit-pupil tables and the OpenCL programs' binaries come from the user's disk cache unless
``--empty-cache`` gives every process an empty one; ``--cold`` empties PoCL's kernel cache too (an
empty ``XDG_CACHE_HOME`` per process), so that every process renders as a user's first-ever render
of that scene does, compiling its kernels. Medians of ``--repeats`` (default 1, to keep the run
short). The machine's load is not controlled: on a shared machine the figures are upper bounds.
Writes bench/results/scenes.json.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "bench"))  # first already when run as a script; not when a test loads this file

import machine  # noqa: E402
from realistic.cli.values import checked, parse_resolution  # noqa: E402
from realistic.core import validation  # noqa: E402
from realistic.errors import UserError  # noqa: E402

SHARED = ROOT.parent / "shared"
LENSES = ("dgauss", "fisheye", "telephoto", "wide")
#: pbrt-v3 on the issue's machine, homework scenes at 300x300, 32 spp (issue 11): another processor than
#: this run's (machine.describe) makes the comparison one of machines as well.
PBRT_V3 = "pbrt-v3, 300x300x32: 6.9-9.6 s wall per lens, 4.1-5.2 s of it set-up"
FIRST_PASS_GOAL_S = 1.0


@dataclass(frozen=True)
class BenchScene:
    """A scene file to measure and the pbrt search paths it needs."""

    name: str
    path: Path
    search_paths: tuple[Path, ...] = field(default=())


def scene_list(root: Path = ROOT, shared: Path = SHARED) -> tuple[list[BenchScene], list[str]]:
    """The scenes whose files (and shared data) exist, and one message per scene skipped."""
    scenes, skipped = [], []
    pbrt_dir, meshes = shared / "scenes" / "pbrt", shared / "meshes"
    for lens in LENSES:
        homework = pbrt_dir / f"dof-dragons.{lens}.pbrt"
        if homework.is_file():
            scenes.append(BenchScene(f"homework {lens}", homework))
        else:
            skipped.append(f"homework {lens}: {homework} not found (no ../shared data)")
    for lens in LENSES:
        dragon = root / "scenes" / "dof-dragons" / f"{lens}.pbrt"
        missing = [p for p in (dragon, meshes, pbrt_dir) if not p.exists()]
        if missing:
            skipped.append(f"dragons {lens}: {missing[0]} not found (no ../shared data)")
        else:
            scenes.append(BenchScene(f"dragons {lens}", dragon, (meshes, pbrt_dir)))
    default = root / "scenes" / "default.pbrt"
    if default.is_file():
        scenes.append(BenchScene("default", default))
    else:
        skipped.append(f"default: {default} not found")
    return scenes, skipped


def render_arguments(scene: BenchScene, res: tuple[int, int], spp: int, light_samples: int | None,
                     backend: str) -> list[str]:
    """The ``realistic render`` arguments (without --out) that render ``scene`` as benchmarked."""
    arguments = [str(scene.path), "--res", f"{res[0]}x{res[1]}", "--spp", str(spp), "--backend", backend]
    for folder in scene.search_paths:
        arguments += ["--search-path", str(folder)]
    if light_samples is not None:
        arguments += ["--light-samples", str(light_samples)]
    return arguments


def measure_in_process(arguments: list[str], launched: float, flat: bool = False) -> dict:
    """Set-up, first-pass and render seconds of one render through the library; ``launched`` is the
    ``time.time()`` at which the parent started this process (the origin of every figure)."""
    if flat:
        import realistic.renderer.passes as passes
        from realistic.scene.intersect import Intersector

        passes.Intersector = lambda scene: Intersector(scene, share=False)
    from realistic.cli import build_parser
    from realistic.cli.scene_arguments import options_from_args
    from realistic.renderer.inputs import build_render_inputs
    from realistic.renderer.job import RenderJob, RenderObserver
    from realistic.renderer.pass_plan import default_pass_samples, plan_passes
    from realistic.renderer.passes import ThreadPasses, render

    imported = time.time()
    args = build_parser().parse_args(["render", *arguments])
    inputs = build_render_inputs(options_from_args(args, args.spp))
    loaded = time.time()
    camera = inputs.camera
    plan = plan_passes(camera.width * camera.height, camera.spp,
                       default_pass_samples(camera.rays_per_sample, inputs.light_samples))
    frame_passes = sum(1 for block in plan if block.first_sample == 0)  # the first slice: every pixel once
    first_pass: list[float] = []
    first_frame: list[float] = []

    def on_pass(result) -> None:
        if not first_pass:
            first_pass.append(time.time())
        if not first_frame and result.passes_done >= frame_passes:
            first_frame.append(time.time())

    job = RenderJob(inputs.scene, (inputs.camera,), args.backend, args.seed)
    result = render(job, ThreadPasses(pin_threads=True), RenderObserver(on_pass=on_pass))[0]
    stages = result.stage_seconds
    before_rays = stages.get("exit pupil", 0.0) + stages.get("setup", 0.0)
    render_s = result.seconds - before_rays
    return {"import_s": imported - launched, "load_s": loaded - imported,
            "exit_pupil_s": stages.get("exit pupil", 0.0), "setup_stage_s": stages.get("setup", 0.0),
            "setup_s": loaded - launched + before_rays, "first_pass_s": first_pass[0] - launched,
            "first_frame_s": first_frame[0] - launched,
            "render_s": render_s, "samples": result.samples_done,
            "samples_per_s": result.samples_done / render_s, "light_samples": inputs.light_samples,
            "peak_rss_mib": peak_rss_mib()}


def peak_rss_mib() -> float:
    """This process's peak resident set size so far, MiB (Linux's ru_maxrss is in KiB)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


#: What the interpreter alone costs before any scene, in a bare ``python -c``: numpy and pyopencl
#: imported and embree's library loaded, nothing loaded or rendered; then the renderer's own modules.
BASELINE_CODE = """
import json, resource, time
start = time.perf_counter()
import numpy, pyopencl
from realistic.scene import embree
embree.EmbreeScene()
peak = lambda: resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
bare, imported = peak(), time.perf_counter() - start
from realistic.renderer.passes import render
print(json.dumps({"import_s": imported, "peak_rss_mib": bare, "with_renderer_mib": peak()}))
"""


#: What the caches a measuring process starts with are called in the table's heading.
CACHE_WORDS = {"user": "the user's caches", "empty": "empty exit-pupil and program-binary cache",
               "cold": "every cache empty (PoCL's kernels too)"}


def _child_environment(caches: str, empty_folder: str) -> dict[str, str]:
    """The measuring processes' environment: Python's bytecode cache allowed, as in an installed
    package (pip compiles it at install), so start-up is not timed compiling the sources; with
    ``caches`` "empty", realistic's disk cache in ``empty_folder``; "cold", every cache under
    ``XDG_CACHE_HOME`` (realistic's, PoCL's kernels, pyopencl's) there."""
    env = dict(os.environ)
    env.pop("PYTHONDONTWRITEBYTECODE", None)
    if caches == "empty":
        env["REALISTIC_CACHE_DIR"] = empty_folder
    elif caches == "cold":
        for name in ("REALISTIC_CACHE_DIR", "POCL_CACHE_DIR"):
            env.pop(name, None)
        env["XDG_CACHE_HOME"] = empty_folder
    return env


class ChildFailed(Exception):
    """A measuring process exited with an error; the message is its last line of stderr."""


def _run_child(command: list[str], caches: str) -> str:
    """Run ``command`` from the repository root and return its stdout, or raise ``ChildFailed``."""
    with tempfile.TemporaryDirectory(prefix="realistic-bench-cache-") as empty_folder:
        run = subprocess.run(command, cwd=ROOT, env=_child_environment(caches, empty_folder), capture_output=True,
                             text=True)
    if run.returncode != 0:
        lines = run.stderr.strip().splitlines() or [f"exit status {run.returncode}"]
        raise ChildFailed(lines[-1])
    return run.stdout


def cli_seconds(arguments: list[str], caches: str) -> float:
    """Wall seconds of ``python -m realistic render`` with ``arguments``."""
    with tempfile.TemporaryDirectory() as folder:
        start = time.perf_counter()
        _run_child([sys.executable, "-m", "realistic", "render", *arguments, "--out", str(Path(folder) / "r.exr")],
                   caches)
        return time.perf_counter() - start


def library_figures(arguments: list[str], caches: str, flat: bool = False) -> dict:
    """``measure_in_process`` run in a fresh Python process (this script with ``--child``)."""
    command = [sys.executable, str(Path(__file__).resolve()), "--child", json.dumps([time.time(), arguments, flat])]
    return json.loads(_run_child(command, caches).strip().splitlines()[-1])


def baseline_figures() -> dict:
    """``BASELINE_CODE`` in a fresh Python process."""
    return json.loads(_run_child([sys.executable, "-c", BASELINE_CODE], "user").strip().splitlines()[-1])


def median_figures(runs: list[dict]) -> dict:
    """The per-key median of several runs' figures."""
    return {key: statistics.median(run[key] for run in runs) for key in runs[0]}


def positive_count(value: int) -> int:
    """``value`` when it is at least 1 (``--repeats``)."""
    if value < 1:
        raise UserError(f"{value} is not a positive count")
    return value


def build_parser() -> argparse.ArgumentParser:
    """The command line: what to render and how often."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--res", type=checked(str, parse_resolution), default=(300, 300), metavar="WxH",
                        help="resolution of every scene (default 300x300)")
    parser.add_argument("--spp", type=checked(int, validation.samples_per_pixel), default=32, metavar="N",
                        help="samples per pixel (default 32)")
    parser.add_argument("--light-samples", type=checked(int, validation.light_samples), metavar="N",
                        help="light samples per hit (default: each scene's own)")
    parser.add_argument("--repeats", type=checked(int, positive_count), default=1, metavar="N",
                        help="runs per figure; the median is shown (default 1)")
    caches = parser.add_mutually_exclusive_group()
    caches.add_argument("--empty-cache", action="store_const", dest="caches", const="empty", default="user",
                        help="an empty realistic disk cache (exit-pupil tables, program binaries) per process")
    caches.add_argument("--cold", action="store_const", dest="caches", const="cold",
                        help="every cache empty (PoCL's kernels too) per process: a first-ever render")
    parser.add_argument("--backend", default="opencl", choices=("opencl", "numpy"))
    parser.add_argument("--only", metavar="TEXT", help="only the scenes whose name contains TEXT (e.g. dragons)")
    parser.add_argument("--flat", action="store_true",
                        help="copy every instance into one world-space embree scene (as before sharing); no CLI column")
    parser.add_argument("--child", help=argparse.SUPPRESS)
    return parser


def main() -> None:
    args = build_parser().parse_args()
    if args.child:
        launched, arguments, flat = json.loads(args.child)
        print(json.dumps(measure_in_process(arguments, launched, flat)))
        return

    scenes, skipped = scene_list()
    if args.only:
        scenes = [scene for scene in scenes if args.only in scene.name]
    for message in skipped:
        print(f"skipped: {message}")
    print(f"{args.res[0]}x{args.res[1]}, {args.spp} spp, backend {args.backend}, median of {args.repeats}, "
          f"{'flat (unshared) embree scene, ' if args.flat else ''}"
          f"{CACHE_WORDS[args.caches]}; the machine's load is not controlled; "
          f"processor: {machine.describe()}")
    header = (f"{'scene':<20}{'cli s':>8}{'setup s':>9}{'(import':>8}{'load':>7}{'pupil':>7}{'stage)':>7}"
              f"{'1st pass s':>11}{'1st frame s':>12}{'render s':>10}{'M samples/s':>12}{'lights':>7}{'peak MiB':>9}")
    baseline = median_figures([baseline_figures() for _ in range(args.repeats)])
    print(f"interpreter baseline (python + numpy + pyopencl + embree loaded, nothing rendered): "
          f"peak RSS {baseline['peak_rss_mib']:.0f} MiB ({baseline['with_renderer_mib']:.0f} MiB with the "
          f"renderer's modules imported), imports {baseline['import_s']:.2f} s")
    print(header)
    rows = []
    for scene in scenes:
        arguments = render_arguments(scene, args.res, args.spp, args.light_samples, args.backend)
        try:
            cli = (float("nan") if args.flat else
                   statistics.median(cli_seconds(arguments, args.caches) for _ in range(args.repeats)))
            lib = median_figures([library_figures(arguments, args.caches, args.flat) for _ in range(args.repeats)])
        except ChildFailed as err:
            skipped.append(f"{scene.name}: failed: {err}")
            print(f"{scene.name:<20}failed: {err}", flush=True)
            continue
        rows.append({"scene": scene.name, "path": str(scene.path), "cli_s": cli, **lib})
        print(f"{scene.name:<20}{cli:>8.2f}{lib['setup_s']:>9.2f}{lib['import_s']:>8.2f}{lib['load_s']:>7.2f}"
              f"{lib['exit_pupil_s']:>7.2f}{lib['setup_stage_s']:>7.2f}{lib['first_pass_s']:>11.2f}"
              f"{lib['first_frame_s']:>12.2f}{lib['render_s']:>10.2f}{lib['samples_per_s'] / 1e6:>12.3f}"
              f"{int(lib['light_samples']):>7d}"
              f"{lib['peak_rss_mib']:>9.0f}",
              flush=True)
    slow = [r["scene"] for r in rows if r["first_pass_s"] >= FIRST_PASS_GOAL_S]
    print(f"\nfor comparison, measured on the issue's machine, not by this run: {PBRT_V3}")
    print(f"first pass under {FIRST_PASS_GOAL_S:g} s: " + ("every scene" if not slow else f"not {', '.join(slow)}"))
    report = {"machine": machine.describe(), "resolution": list(args.res), "spp": args.spp,
              "light_samples": args.light_samples,
              "backend": args.backend, "repeats": args.repeats, "caches": args.caches, "flat": args.flat,
              "skipped": skipped, "baseline": baseline, "rows": rows, "pbrt_v3": PBRT_V3,
              "first_pass_goal_s": FIRST_PASS_GOAL_S}
    out = ROOT / "bench" / "results" / "scenes.json"
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(report, indent=2) + "\n")
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
