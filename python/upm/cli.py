"""The ``upm`` command line: ``upm demo [NAME]``, ``upm figures``, ``upm sweep``, ``upm emulate`` and
``upm --version``."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from ._core import __version__
from ._errors import UpmError

#: Subcommands run by their own module's ``run(args)`` (its ``arguments(parser)`` adds the options).
DELEGATED = {"calibrate": ".vision.cli", "desk": ".desk.cli"}


def main(argv: list[str] | None = None) -> int:
    """The ``upm`` command. Errors end it with a one-line message and exit code 2 (1: a demo's
    task was not done; 130: interrupted), never a traceback."""
    try:
        return _main(sys.argv[1:] if argv is None else argv)
    except UpmError as error:  # a MissingExtraError among them
        print(f"upm: {error}", file=sys.stderr)
        return 2
    except BrokenPipeError:  # `upm sweep --list | head`
        return 0
    except OSError as error:  # an --out that cannot be written, a file that cannot be read
        where = f" {error.filename!r}" if error.filename else ""
        print(f"upm: cannot use{where}: {error.strerror or error}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("upm: interrupted", file=sys.stderr)
        return 130


def _main(argv: list[str]) -> int:
    if argv[:1] == ["emulate"]:  # its own options: hand them over untouched
        from .board import process

        return process.main(argv[1:])
    parser = argparse.ArgumentParser(prog="upm", description="Vibratory planar manipulation.")
    parser.add_argument("--version", action="version", version=f"upm {__version__}")
    commands = parser.add_subparsers(dest="command", required=True)
    commands.add_parser(
        "emulate", help="a board emulator on a pseudo-terminal or TCP port (see: upm emulate --help)"
    )
    d = commands.add_parser(
        "demo", help="a thesis experiment through the closed loop (NAME), or the feeding table ('feeding')"
    )
    d.add_argument(
        "name", nargs="?", default="feeding", help="feeding (the default), list (the demos), or a demo's name"
    )
    d.add_argument("--out", type=Path, default=Path("out"), help="directory for outputs (default: out)")
    d.add_argument("--no-plots", action="store_true", help="feeding: print the tables only")
    d.add_argument(
        "--board", action="store_true", help="run the plate in a board emulator process (protocol v1)"
    )
    d.add_argument("--quick", action="store_true", help="a short version")
    d.add_argument(
        "--points", action="store_true", help="parts are points that pass through each other (no contacts)"
    )
    d.add_argument("--mp4", action="store_true", help="also write animation.mp4 (needs imageio-ffmpeg)")
    d.add_argument(
        "--rrd", action="store_true", help="also record the run for rerun: OUT/NAME/run.rrd (upm[viz])"
    )
    d.add_argument("--seed", type=int, default=1, help="seed of the layout, the camera noise and the plant")
    d.add_argument(
        "--planner",
        choices=("predictive", "jets", "rotations", "displacement", "greedy"),
        default=None,
        help="the planner (default: the thesis's planner of the demo; scale demos: predictive or greedy)",
    )
    d.add_argument("--parts", type=int, default=None, help="shape demo: how many parts (default 12)")
    d.add_argument(
        "--pipeline",
        type=float,
        default=None,
        metavar="MM",
        help="plan while the plate plays, keeping plans whose parts end within MM of the prediction "
        "(predictive planner; the scale demos do by default, 6 mm)",
    )
    d.add_argument(
        "--shape", default=None, help="shape demo: ring, grid, a capital letter (T) or a mask image's path"
    )
    fg = commands.add_parser("figures", help="the thesis's analytic figures (3.5, 3.6, 4.7, 6.2, 6.9)")
    fg.add_argument("--out", type=Path, default=Path("out/figures"), help="directory (default: out/figures)")
    s = commands.add_parser(
        "sweep", help="a parameter sweep from a TOML file; --list: the built-in scenarios"
    )
    s.add_argument("config", nargs="?", type=Path, help="the sweep's TOML file")
    s.add_argument("--list", action="store_true", help="list the built-in scenarios and their parameters")
    s.add_argument(
        "--n-jobs", type=int, default=None, help="threads (default: the file's, else one per core)"
    )
    s.add_argument("--quiet", action="store_true", help="no progress bar")
    r = commands.add_parser("replay", help="open a .rrd recording in rerun's viewer (upm[viz])")
    r.add_argument("file", type=Path, help="the .rrd recording")
    r.add_argument("--web", action="store_true", help="serve rerun's web viewer on 127.0.0.1 instead")
    r.add_argument("--port", type=int, default=None, help="the web viewer's port (default: a free one)")
    r.add_argument(
        "--screenshot",
        type=Path,
        default=None,
        metavar="PNG",
        help="write a picture of the viewer (headless Chromium) and exit",
    )
    r.add_argument(
        "--wait",
        type=float,
        default=20.0,
        help="with --screenshot: seconds to let the viewer load (up to as many more until it holds still)",
    )
    c = commands.add_parser(
        "calibrate", help="calibrate the camera from frames of a ChArUco board (upm[vision])"
    )
    from .vision.cli import arguments as calibrate_arguments

    calibrate_arguments(c)
    k = commands.add_parser("desk", help="the live desk: steer parts by hand in a browser (upm[desk])")
    from .desk.cli import arguments as desk_arguments

    desk_arguments(k)
    args = parser.parse_args(argv)
    if args.command == "replay":
        from .viz import replay

        try:
            return replay(args.file, web=args.web, png=args.screenshot, port=args.port, wait=args.wait)
        except UpmError as error:
            print(f"upm replay: {error}", file=sys.stderr)
            return 2
    if args.command in DELEGATED:  # commands whose options and work live in their own module
        import importlib

        run = importlib.import_module(DELEGATED[args.command], __package__).run
        try:
            return int(run(args))
        except UpmError as error:
            print(f"upm {args.command}: {error}", file=sys.stderr)
            return 2
    if args.command == "demo":
        from .experiments import registry

        if args.name == "list":
            print(registry.listing())
            return 0
        options = registry.Options(
            out=args.out, quick=args.quick, seed=args.seed, board=args.board, mp4=args.mp4,
            contacts=not args.points, planner=args.planner, rrd=args.rrd,
            pipeline=None if args.pipeline is None else args.pipeline / 1000,  # mm on the command line
            parts=args.parts, shape=args.shape, plots=not args.no_plots,
        )  # fmt: skip
        try:
            return registry.run(args.name, options)
        except UpmError as error:
            print(f"upm demo: {error}", file=sys.stderr)
            return 2
    if args.command == "figures":
        from .experiments.figures import figures

        for path in figures(args.out):
            print(f"wrote {path}")
        return 0
    if args.command == "sweep":
        try:
            from .experiments.sweep_config import sweep_command

            return sweep_command(args.config, args.list, args.n_jobs, args.quiet)
        except UpmError as error:
            print(f"upm sweep: {error}", file=sys.stderr)
            return 2
    return 2  # pragma: no cover - argparse rejects unknown commands


if __name__ == "__main__":
    sys.exit(main())
