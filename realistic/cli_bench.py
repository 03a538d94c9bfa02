"""The ``bench`` subcommand: render one scene at several sample counts and measure convergence."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from realistic.cli_render import add_scene_arguments, load_render_inputs, report_warnings
from realistic.errors import UserError

DESCRIPTION = """\
Render SCENE (as `render` takes it) at each sample count and print seconds, camera rays per second,
the fraction of lens samples vignetted, and the RMSE against --reference (an EXR of the same
resolution) or, without one, against the render with the most samples. Writes a log-log
convergence plot (RMSE against spp and against seconds) and, with --json, the table as JSON.
"""


def add_bench_command(commands: argparse._SubParsersAction) -> None:
    p = commands.add_parser("bench", help="render a scene at several sample counts: time and convergence",
                            description=DESCRIPTION, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_scene_arguments(p)
    p.add_argument("--spp", default="1,4,16,64,256", metavar="N,N,...",
                   help="sample counts to render (default: %(default)s)")
    p.add_argument("--reference", metavar="REF.exr", help="image to measure RMSE against")
    p.add_argument("--json", metavar="OUT.json", help="also write the table as JSON")
    p.add_argument("--plot", default="convergence.png", metavar="OUT.png",
                   help="convergence plot (default: %(default)s)")
    p.set_defaults(run=cmd_bench)


def cmd_bench(args: argparse.Namespace) -> int:
    from realistic.image_io import check_writable, read_exr, write_atomically
    from realistic.sample_bench import (convergence_slope, format_table, measure_sample_counts, parse_spp_list,
                                        plot_convergence)

    spp_list = parse_spp_list(args.spp)
    plot = Path(args.plot)
    check_writable(plot)
    if args.json:
        check_writable(Path(args.json))
    reference = None
    if args.reference:
        if not Path(args.reference).is_file():
            raise UserError(f"{args.reference}: no such reference image")
        reference = read_exr(Path(args.reference))[0]
    inputs = load_render_inputs(args, spp_list[0])
    report_warnings(inputs.warnings)
    rows, _ = measure_sample_counts(inputs.scene, inputs.camera, spp_list, args.backend, args.seed,
                                    inputs.light_samples, reference, args.cl_device)
    against = "reference" if reference is not None else f"{max(spp_list)} spp"
    camera = inputs.camera
    print(f"{args.scene or 'default scene'}: {camera.width}x{camera.height}, backend {args.backend}")
    print(format_table(rows, against))
    slope = convergence_slope(rows)
    print(f"RMSE ~ spp^{slope:.2f} (Monte Carlo: -0.5)")
    plot_convergence(rows, plot, f"{Path(args.scene).name if args.scene else 'default scene'}: RMSE vs {against}")
    written = [str(plot)]
    if args.json:
        report = {"scene": str(args.scene or "default"), "width": camera.width, "height": camera.height,
                  "backend": args.backend, "against": against, "slope": slope, "rows": rows}
        text = json.dumps(report, indent=1) + "\n"
        write_atomically(Path(args.json), lambda temporary: Path(temporary).write_text(text, encoding="utf-8"))
        written.append(args.json)
    print("wrote " + " and ".join(written))
    return 0
