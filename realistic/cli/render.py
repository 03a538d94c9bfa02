"""The ``render`` subcommand: render a pbrt scene, a mesh or the default scene to EXR and PNG,
optionally cropped (``renderer.crop``) and shown live in tev (``renderer.display``).

Argument definitions and output only; the scene and camera come from ``realistic.renderer.inputs``.
The renderer is imported when the command runs, so ``--help`` and the lens commands start fast.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from functools import partial
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from realistic.camera.exposure import meter_reading, parse_exposure, parse_shutter
from realistic.cli.scene_arguments import add_scene_arguments, options_from_args
from realistic.cli.values import checked, positive
from realistic.core import validation
from realistic.core.atomic_files import check_writable, signals_deferred
from realistic.errors import UserError
from realistic.renderer.crop import PixelBounds
from realistic.renderer.job import Checkpointing, PassExecutor, RenderJob, RenderObserver, RenderResult
from realistic.renderer.thread_count import default_threads

if TYPE_CHECKING:  # the renderer itself is imported when a command runs
    from realistic.scene.intersect import Intersector

DESCRIPTION = """\
SCENE is a pbrt scene file (.pbrt: the classic dof-dragons homework scenes and common simple pbrt
scenes), or a mesh file (OBJ, PLY, STL, GLB/GLTF, OFF) that is set on a grid floor under a disk
light, or nothing for the default scene (a row of spheres and cones receding in depth).

For a mesh or the default scene, scene units are metres: the mesh is scaled so its largest side
is 1 m, the camera frame's origin is the film centre (pbrt-v3 convention), and --focus is the
distance in metres from the film plane to the plane in focus (thick-lens focusing), by default
the distance to the target. A pbrt scene brings its own camera, resolution and samples; --lens,
--film-diagonal, --fstop/--aperture, --blades, --focus (scene units from the film), --focus-on,
--res, --spp and --light-samples change them, keeping the camera's pose (a perspective camera
given a --lens keeps its field of view unless --film-diagonal is given).

With --dispersion on (the default for a mesh or the default scene through a lens whose prescription
has Abbe numbers; pbrt scenes render without it unless asked, as pbrt does), each camera
sample carries a wavelength, the glasses' indices follow it, and the film integrates through the
CIE 1931 colour matching functions to linear sRGB: the lens's chromatic aberration shows. Off
traces at the d line in RGB. --wavelengths-per-sample K traces each spectral sample at K
stratified wavelengths sharing its film, lens and light samples, which turns the colour speckle of
one wavelength per sample into plain luminance noise, at K times the camera rays.

The EXR holds the film irradiance (float32 RGB, metadata in the header); the PNG preview beside
it is sRGB, exposed by an averaging meter (--exposure auto). --out x.png writes that PNG alone (8
bits, or 16 with --png-bits 16), --out x.pfm the float image alone. With --shutter/--iso the
meter's reading is printed: the EV the scene wants, the EV the settings give, and the shutter
that would meter correctly. -o/--outfile, --nthreads, --spp, --seed, --quiet, --cropwindow,
--pixelbounds and --display(-server) are named and behave as pbrt-v4's. A crop (--cropwindow in
fractions of the image, --pixelbounds in pixels) renders those pixels only, each bit-identical to
the same pixel of the whole render; the image holds the crop, and the EXR's data window places it
in the full image. --display HOST:PORT shows the render in tev (https://github.com/Tom94/tev;
start it first, it listens on 127.0.0.1:14158) as the passes come in.

Passes are ordered so that any prefix of them is spread over the whole frame. They run on threads
in this process, one per core unless --threads says how many; --workers N renders
on N worker processes of a Dask LocalCluster on this machine (at most one per CPU), --scheduler
on an existing Dask cluster (never one named only by DASK_SCHEDULER_ADDRESS: a scheduler and its
workers can run code as you; tls:// addresses with --tls-ca-file, --tls-cert and --tls-key
authenticate it); the image is bit-identical to an in-process render. --sweep renders a sequence
(OUT_0001.exr, ...) as one job, each frame written as it completes. Renders save a checkpoint
(OUT.exr.partial) every --checkpoint-every seconds and when interrupted; --resume continues one.
docs/farm.md has the details.
"""


def add_render_command(commands: argparse._SubParsersAction) -> None:
    """Register ``render`` on the CLI's subcommand parser."""
    parser = commands.add_parser("render", help="render a pbrt scene, a mesh, or the default scene through a lens",
                                 description=DESCRIPTION, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_scene_arguments(parser)
    parser.add_argument("--spp", type=checked(int, validation.samples_per_pixel), metavar="N",
                        help=f"samples per pixel, 1 to {validation.MAX_SPP} (default: the scene's, else 16)")
    parser.add_argument("-o", "--out", "--outfile", dest="out", metavar="FILE",
                        help="output (-o and --outfile as pbrt-v4 names it): an EXR (the PNG preview is written "
                             "beside it), a PNG or a PFM (that file alone) (default: the scene's film file name, "
                             "else render.exr)")
    parser.add_argument("--exposure", type=checked(str, parse_exposure), metavar="EV|auto",
                        help="PNG exposure in stops, or auto: an averaging meter maps the scene to middle grey "
                             "(default: auto, or 0 with --shutter/--iso)")
    parser.add_argument("--png-bits", type=int, choices=(8, 16), default=8,
                        help="bits per sample of the PNG (default: %(default)s)")
    parser.add_argument("--shutter", type=checked(str, parse_shutter), metavar="SECONDS",
                        help="shutter time (e.g. 1/125): with --iso, the EXR holds a photographic exposure, "
                             "calibrated so a metered middle grey reads 0.18, instead of film irradiance")
    parser.add_argument("--iso", type=checked(float, validation.iso_speed),
                        help="ISO speed (default with --shutter: 100)")
    parser.add_argument("--sweep", metavar="NAME=START:STOP:N",
                        help="render N frames with NAME (focus, aperture, fstop, film-distance) going from START to "
                             "STOP, to OUT_0001.exr onwards, as one job (focus in scene units, the others as their "
                             "options take them)")
    parser.add_argument("--checkpoint-every", type=positive("checkpoint interval (seconds)"), default=60.0,
                        metavar="SECONDS",
                        help="save the film to OUT.exr.partial this often, and when interrupted (default: "
                             "%(default)g; removed once the complete image is written; without --resume an "
                             "existing one is refused, not replaced)")
    parser.add_argument("--resume", action="store_true",
                        help="continue from OUT.exr.partial, or without one render from the start (refused if "
                             "made for another scene, camera, seed, resolution or crop)")
    parser.add_argument("--preview-every", type=positive("preview interval (seconds)"), metavar="SECONDS",
                        help="rewrite the PNG preview this often while rendering (default: only at the end)")
    parser.add_argument("--pass-samples", type=checked(int, validation.pass_samples), metavar="N",
                        help="sample ids per pass (default: about 2^19 camera and shadow rays' worth, 262144 "
                             "samples at one light sample, 104857 at four); checkpoints hold whole passes, and a farm "
                             "task is about 2^20 samples of passes")
    parser.add_argument("--display", "--display-server", dest="display", type=checked(str, validation.display_address),
                        metavar="HOST:PORT",
                        help="show the image in tev (github.com/Tom94/tev, listening on 127.0.0.1:14158 by default) as "
                             "it renders, after each pass, as pbrt-v4's --display-server does; the render goes on "
                             "whether tev is there or not")
    crop = parser.add_mutually_exclusive_group()
    crop.add_argument("--cropwindow", nargs=4, type=checked(float, partial(validation.finite, name="crop window")),
                      metavar=("X0", "X1", "Y0", "Y1"),
                      help="render only this part of the image, in fractions of it (0 0.5 0 1: the left half; y "
                           "down), as pbrt-v4's --cropwindow (also written x0,x1,y0,y1): its pixels run from "
                           "ceil(x0 * width) to ceil(x1 * width) - 1, likewise in y; the image holds them alone and "
                           "the EXR's data window says where they lie in the full image")
    crop.add_argument("--pixelbounds", nargs=4, type=checked(int, int),
                      metavar=("X0", "X1", "Y0", "Y1"),
                      help="render only pixels X0 to X1 - 1 and Y0 to Y1 - 1, as pbrt-v4's --pixelbounds (also "
                           "written x0,x1,y0,y1); a crop's pixels are bit-identical to the same pixels of the whole "
                           "render")
    parser.add_argument("--quiet", action="store_true",
                        help="no progress bar and no information lines; warnings and errors still print (pbrt-v4's "
                             "--quiet)")
    parser.add_argument("--aov", type=checked(str, validation.aovs), default=(), metavar="LIST",
                        help=f"also write what the camera rays first hit, as EXR channels with pbrt-v4's GBuffer "
                             f"names: comma-separated from {', '.join(validation.AOV_NAMES)} (depth and position in "
                             f"camera space, scene units; normal in camera space)")
    parser.add_argument("--denoise", action="store_true",
                        help="denoise the image with Open Image Denoise, guided by the albedo and normal AOVs "
                             "(computed for it); the film's own image is kept as the EXR's Noisy layer "
                             "(needs the denoise extra: pip install 'realistic[denoise]')")
    add_farm_arguments(parser)
    parser.set_defaults(run=cmd_render)


def add_farm_arguments(parser: argparse.ArgumentParser) -> None:
    """``--threads``, ``--workers``, ``--scheduler`` and ``--pin-threads`` (shared by ``render`` and ``bench``)."""
    farm = parser.add_mutually_exclusive_group()
    farm.add_argument("--threads", "--nthreads", dest="threads", type=checked(int, validation.threads), metavar="N",
                      help="render on N threads in this process (--nthreads as pbrt-v4 names it; default: one per "
                           f"core, {default_threads()} here)")
    farm.add_argument("--workers", type=checked(int, local_workers), metavar="N",
                      help="render on a Dask LocalCluster of N worker processes on this machine, at most one per "
                           f"CPU ({default_threads()} here), listening on 127.0.0.1 only (default: threads in this "
                           "process)")
    farm.add_argument("--scheduler", metavar="ADDRESS",
                      help="render on the Dask cluster whose scheduler is at ADDRESS, e.g. tls://host:8786 with the "
                           "--tls options, or tcp://host:8786 (unencrypted, unauthenticated); its scheduler and "
                           "workers can run code as you, so name only a cluster you trust (DASK_SCHEDULER_ADDRESS "
                           "is never used)")
    tls = parser.add_argument_group("TLS for --scheduler tls://...", "PEM files, as dask's Security takes them")
    tls.add_argument("--tls-ca-file", metavar="FILE", help="the CA certificate that signed the cluster's certificates")
    tls.add_argument("--tls-cert", metavar="FILE", help="this client's certificate")
    tls.add_argument("--tls-key", metavar="FILE", help="this client's private key")
    parser.add_argument("--pin-threads", action="store_true",
                        help="keep each of this process's render threads on one CPU (Linux; default: the system "
                             "places them)")


def local_workers(count: int) -> int:
    """``--workers``: 1 to one per CPU this process may run on (``farm.check_local_workers``; dask
    is imported only when the option is given)."""
    from realistic.renderer.farm import check_local_workers

    return check_local_workers(count)


def farm_security(args: argparse.Namespace) -> Any:
    """The ``distributed.security.Security`` that ``--tls-ca-file``, ``--tls-cert`` and ``--tls-key``
    make (None without them), checked against ``--scheduler`` before any work (one-line UserErrors)."""
    files = (args.tls_ca_file, args.tls_cert, args.tls_key)
    tls = bool(args.scheduler) and args.scheduler.lower().startswith("tls://")
    if not any(files):
        if tls:
            raise UserError(f"--scheduler {args.scheduler}: a tls:// scheduler needs --tls-ca-file, --tls-cert and "
                            "--tls-key")
        return None
    if not all(files):
        raise UserError("--tls-ca-file, --tls-cert and --tls-key go together")
    if not tls:
        raise UserError("--tls-ca-file, --tls-cert and --tls-key are for a --scheduler tls://... address")
    from realistic.renderer.farm import tls_security

    return tls_security(*files)


@contextmanager
def farm_client(args: argparse.Namespace, security: Any, quiet: bool = False) -> Iterator[object | None]:
    """The Dask client that ``--workers`` or ``--scheduler`` asks for (with ``security``, what
    ``farm_security`` made of the TLS options), or None (render on threads); dask is imported only
    here, and only when one is asked for. Only the command line names a cluster:
    ``DASK_SCHEDULER_ADDRESS`` in the environment is never used (its scheduler and workers could run
    code as the user). ``quiet``: the cluster's information line is not printed (the warning is)."""
    if not args.workers and not args.scheduler:
        yield None
        return
    from realistic.renderer.farm import farm_client as open_client

    def announce(line: str) -> None:
        print(f"realistic: {line}", file=sys.stderr)

    if args.scheduler and security is None:
        announce(f"{args.scheduler} is neither encrypted nor authenticated: whoever runs that scheduler or its "
                 "workers can run code as you (a tls:// address with the --tls options authenticates it)")
    with open_client(args.workers, args.scheduler, (lambda line: None) if quiet else announce, security) as client:
        yield client


def report_warnings(warnings: list[str]) -> None:
    for warning in warnings:
        print(f"realistic: {warning}", file=sys.stderr)


def report_warnings_of_display(warning: str) -> None:
    """A display's warning (from its thread): one line on stderr, ``--quiet`` or not."""
    print(f"realistic: warning: {warning}", file=sys.stderr, flush=True)


def executor_for(args: argparse.Namespace, client: Any,
                 intersector: Intersector | None = None) -> PassExecutor:
    """Where the passes run: on the Dask ``client`` when there is one, else on ``--threads`` threads
    here (pinned with ``--pin-threads``), reusing ``intersector`` (an ``Intersector`` of the
    job's scene) when one was built already."""
    if client is None:
        from realistic.renderer.passes import ThreadPasses

        return ThreadPasses(args.threads, args.pin_threads, intersector)
    from realistic.renderer.farm import DaskPasses

    return DaskPasses(client)


def cmd_render(args: argparse.Namespace) -> int:
    from realistic.renderer.checkpoint import checkpoint_path, refuse_unless_resuming
    from realistic.renderer.denoise import GUIDE_AOVS, check_available, denoised
    from realistic.renderer.display import TevDisplay
    from realistic.renderer.inputs import build_render_inputs
    from realistic.renderer.output import (
        BetterImageKept,
        Photographic,
        exposed,
        render_output,
        save,
        write_preview,
        written_files,
    )
    from realistic.renderer.passes import render
    from realistic.renderer.sweep import frame_path, parse_sweep, sweep_cameras

    if args.out is not None:
        render_output(args.out)
        if args.aov and Path(args.out).suffix.lower() != ".exr":
            raise UserError(f"--aov writes EXR channels: {args.out} would hold the image alone (give an .exr --out)")
    if args.out is not None and not args.sweep and not args.resume:
        refuse_unless_resuming(checkpoint_path(Path(args.out)))  # now, before the scene is read; render() does too
    if args.denoise:
        check_available()
    security = farm_security(args)  # TLS options checked before any work
    crop_window = validation.crop_window(*args.cropwindow) if args.cropwindow else None  # before the scene is read
    sweep = parse_sweep(args.sweep) if args.sweep else None
    if sweep is not None and args.resume:
        raise UserError("--resume continues one image, not a --sweep sequence")
    photographic = (Photographic(args.shutter or 1 / 60, 100.0 if args.iso is None else args.iso)
                    if args.shutter or args.iso else None)
    def info(line: str) -> None:
        """An information line on stderr, unless ``--quiet``."""
        if not args.quiet:
            print(f"realistic: {line}", file=sys.stderr)

    inputs = build_render_inputs(options_from_args(args, args.spp))
    report_warnings(inputs.warnings)
    if "pbrtDialect" in inputs.metadata:
        info(f"{args.scene}: read as {inputs.metadata['pbrtDialect']}")
    out = Path(args.out or inputs.default_out)
    cameras = sweep_cameras(inputs.camera, sweep) if sweep is not None else [inputs.camera]
    outs = [frame_path(out, i) for i in range(len(cameras))] if sweep is not None else [out]
    for path in outs:
        for file in written_files(path):
            check_writable(file)
    if args.preview_every:
        check_writable(out.with_suffix(".png"))  # beside a PFM too
    checkpoint = None
    if sweep is None:
        resume = args.resume
        if resume and not os.path.lexists(checkpoint_path(out)):  # a checkpoint for another render is refused
            info(f"{checkpoint_path(out)}: no checkpoint to resume: rendering from the start")
            resume = False
        checkpoint = Checkpointing(checkpoint_path(out), args.checkpoint_every, resume)
        check_writable(checkpoint.path)
    width, height = inputs.camera.width, inputs.camera.height
    crop = (PixelBounds.of_crop_window(crop_window, width, height) if crop_window is not None
            else PixelBounds(*args.pixelbounds) if args.pixelbounds else None)  # RenderJob checks them
    job = RenderJob(inputs.scene, tuple(cameras), args.backend, args.seed, args.cl_device, inputs.light_samples,
                    args.pass_samples, max_memory_bytes=args.max_memory, checkpoint=checkpoint, sweep=args.sweep,
                    keep_images=sweep is None, crop=crop,  # a sequence's frames are written as they complete
                    aovs=tuple({*args.aov, *(GUIDE_AOVS if args.denoise else ())}), flare=inputs.flare,
                    flare_threshold=inputs.flare_threshold, starburst=inputs.starburst)
    written: dict[int, float] = {}
    display = None
    if args.display is not None:  # tev shows what the EXR holds: the crop, exposed as it is written
        shown = crop or PixelBounds.whole(width, height)
        host, port = args.display
        display = TevDisplay(host, port, str(out), shown.width, shown.height, report_warnings_of_display)

    def save_frame(result: RenderResult) -> None:
        if display is not None and result.image.size:
            display.show(exposed(result.image, photographic))
        try:
            written[result.frame] = save(denoised(result) if args.denoise else result, outs[result.frame],
                                         photographic, args.exposure, args.png_bits)
        except BetterImageKept as err:
            print(f"realistic: {err}", file=sys.stderr)

    png_written = [time.monotonic()]

    def preview(image: np.ndarray) -> None:
        """The image so far to tev (after each pass) and to the PNG (every --preview-every seconds)."""
        if display is not None:
            display.show(exposed(image, photographic))
        if args.preview_every and time.monotonic() - png_written[0] >= args.preview_every:
            write_preview(out.with_suffix(".png"), image, photographic, args.exposure, args.png_bits)
            png_written[0] = time.monotonic()

    observer = RenderObserver(on_frame=save_frame if sweep is not None else None,
                              preview=preview if args.preview_every or display is not None else None,
                              preview_every=0.0 if display is not None else args.preview_every,
                              progress=not args.quiet)
    with farm_client(args, security, args.quiet) as client:
        results = render(job, executor_for(args, client, inputs.intersector), observer)
    interrupted = any(result.interrupted for result in results)
    try:
        with signals_deferred():  # an interrupt now waits until every file is written
            for result in results:
                if result.frame not in written and (sweep is None or result.samples_done > 0):
                    save_frame(result)  # a single image always; a sequence's unfinished frames that have samples
    except KeyboardInterrupt:
        interrupted = True
    if display is not None:
        display.close()
    if interrupted:
        done = sum(r.samples_done for r in results)
        total = sum(r.samples_total for r in results)
        where = (f"{len(written)} frames named like {outs[0]}" if sweep is not None
                 else out if written else "no file (the one there holds more)")
        resume = f"; the checkpoint {checkpoint.path} lets --resume continue" \
            if checkpoint is not None and checkpoint.path.is_file() else ""
        print(f"realistic: interrupted: wrote the {done} of {total} samples taken to {where}{resume}",
              file=sys.stderr)
        return 130
    result, camera = results[-1], cameras[-1]
    rays = sum(r.primary_rays + r.shadow_rays for r in results)
    seconds = max(r.seconds for r in results)
    names = (f"{outs[0]} .. {outs[-1]} ({len(outs)} frames)" if sweep is not None
             else " and ".join(str(path) for path in written_files(out)))
    if args.quiet:
        return 0
    png_exposure = f", preview exposure {written[len(outs) - 1]:+.2f} EV" if out.suffix.lower() != ".pfm" else ""
    wavelengths = camera.metadata().get("wavelengthsPerSample")
    spectral = f" x {wavelengths} wavelengths" if wavelengths else ""
    size = f"{camera.width}x{camera.height}" if crop is None else f"pixels {crop} of {camera.width}x{camera.height}"
    print(f"{names}: {size}, {camera.spp} spp{spectral}, "
          f"{camera.metadata()['pixelFilter']} filter, {seconds:.1f} s "
          f"(exit pupil {result.stage_seconds.get('exit pupil', 0.0):.2f} s), "
          f"{rays / max(seconds, 1e-9) / 1e6:.2f} M rays/s{png_exposure}")
    if photographic is not None:
        f_number = camera.metadata().get("fNumber")
        reading = meter_reading(result.image, photographic.shutter_seconds, photographic.iso,
                                None if f_number is None else float(f_number))
        print(f"realistic: {reading.describe() if reading is not None else 'meter: the image is black'}",
              file=sys.stderr)
    return 0
