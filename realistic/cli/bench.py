"""The ``bench`` subcommand: render one scene at several sample counts and measure convergence.

Argument definitions and the printed table; the measuring is ``realistic.renderer.convergence``.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from realistic.cli.render import add_farm_arguments, executor_for, farm_client, farm_security, report_warnings
from realistic.cli.scene_arguments import add_scene_arguments, options_from_args
from realistic.cli.values import checked_plot, parse_spp_list
from realistic.core.atomic_files import check_writable, write_text_atomically
from realistic.core.image_files import read_exr
from realistic.core.input_files import input_file
from realistic.renderer.job import RenderJob
from realistic.renderer.thread_count import default_threads

DESCRIPTION = """\
Render SCENE (as `render` takes it) at each sample count and print seconds, camera rays per second,
the fraction of lens samples vignetted, and the RMSE against --reference (an EXR of the same
resolution) or, without one, against the render with the most samples. Writes a log-log
convergence plot (RMSE against spp and against seconds) and, with --json, the table as JSON.
--threads, --workers and --scheduler choose where to render as `render` does (docs/farm.md).
"""


def add_bench_command(commands: argparse._SubParsersAction) -> None:
    parser = commands.add_parser("bench", help="render a scene at several sample counts: time and convergence",
                                 description=DESCRIPTION, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_scene_arguments(parser)
    parser.add_argument("--spp", default="1,4,16,64,256", metavar="N,N,...",
                        help="sample counts to render (default: %(default)s)")
    parser.add_argument("--reference", metavar="REF.exr", help="image to measure RMSE against")
    parser.add_argument("--json", metavar="OUT.json", help="also write the table as JSON")
    parser.add_argument("--plot", default="convergence.png", metavar="OUT.png",
                        help="convergence plot (default: %(default)s)")
    add_farm_arguments(parser)
    parser.set_defaults(run=cmd_bench)


def cmd_bench(args: argparse.Namespace) -> int:
    from realistic.renderer.convergence import convergence_slope, measure_sample_counts
    from realistic.renderer.convergence_plot import plot_convergence
    from realistic.renderer.inputs import build_render_inputs

    spp_list = parse_spp_list(args.spp)
    plot = checked_plot(Path(args.plot))
    if args.json:
        check_writable(Path(args.json))
    security = farm_security(args)  # TLS options checked before any work
    reference = None
    if args.reference:
        reference = read_exr(input_file(args.reference, "reference image"))[0]
    inputs = build_render_inputs(options_from_args(args, spp_list[0]))
    report_warnings(inputs.warnings)
    job = RenderJob(inputs.scene, (inputs.camera,), args.backend, args.seed, args.cl_device, inputs.light_samples,
                    max_memory_bytes=args.max_memory, flare=inputs.flare, flare_threshold=inputs.flare_threshold)
    with farm_client(args, security) as client:
        rows, _ = measure_sample_counts(job, spp_list, executor_for(args, client, inputs.intersector), reference)
    against = "reference" if reference is not None else f"{max(spp_list)} spp"
    camera = inputs.camera
    where = (f", {args.workers} workers" if args.workers else ", on the Dask cluster" if client is not None
             else f", {args.threads or default_threads()} threads")
    print(f"{args.scene or 'default scene'}: {camera.width}x{camera.height}, backend {args.backend}{where}")
    print(format_table(rows, against))
    slope = convergence_slope(rows)
    print(f"RMSE ~ spp^{slope:.2f} (Monte Carlo: -0.5)")
    plot_convergence(rows, plot, f"{Path(args.scene).name if args.scene else 'default scene'}: RMSE vs {against}")
    written = [str(plot)]
    if args.json:
        report = {"scene": str(args.scene or "default"), "width": camera.width, "height": camera.height,
                  "backend": args.backend, "against": against, "slope": slope, "rows": rows}
        write_text_atomically(Path(args.json), json.dumps(report, indent=1) + "\n")
        written.append(args.json)
    print("wrote " + " and ".join(written))
    return 0


def format_table(rows: list[dict], against: str) -> str:
    """The rows of ``measure_sample_counts`` as a text table."""
    lines = [f"{'spp':>6} {'seconds':>9} {'camera rays/s':>14} {'vignetted':>10} {'RMSE vs ' + against:>24}"]
    for r in rows:
        lines.append(f"{r['spp']:6d} {r['seconds']:9.2f} {r['camera_rays_per_second'] / 1e6:12.2f} M "
                     f"{r['vignetted_fraction']:10.3f} {r['rmse']:24.5g}")
    return "\n".join(lines)
