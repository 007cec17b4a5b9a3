"""The ``upm`` command line: ``upm demo [NAME]``, ``upm figures``, ``upm sweep``, ``upm emulate`` and
``upm --version``."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

import numpy as np

from . import __version__, theory
from ._errors import ParameterError, UpmError
from .feeding import feed_rate, mean_force
from .waveforms import TwoHarmonic


def _table(title: str, bs: np.ndarray, phis: np.ndarray, values: np.ndarray, mark: tuple[int, int]) -> str:
    head = "b \\ phi".ljust(9) + "".join(f"{p / np.pi:>8.3f}π" for p in phis)
    lines = [title, head]
    values = np.round(values, 12) + 0.0  # exact to rounding: show -1e-17 as 0.0000, not -0.0000
    for i, b in enumerate(bs):
        cells = []
        for j in range(len(phis)):
            star = "*" if (i, j) == mark else " "
            cells.append(f"{values[i, j]:>8.4f}{star}")
        lines.append(f"{b:<9.3f}" + "".join(cells))
    return "\n".join(lines)


def demo(out: Path, plots: bool = True) -> int:
    """Feed rate and force at rest of the two-harmonic drive over (b, phi); Fig. 3.6 to ``out``."""
    bs = np.array([0.0, 0.25, 0.5, 0.75, 1.0, 1.5, 2.0])
    phis = np.pi * np.array([0.0, 0.125, 0.25, 0.375, 0.5, 0.625, 0.75, 1.0])
    wave = TwoHarmonic(bs[:, None], phis[None, :])
    v_eq, force = feed_rate(wave), mean_force(wave)
    bi, bj = np.unravel_index(np.argmax(v_eq), v_eq.shape)
    best = (int(bi), int(bj))
    print(f"upm {__version__}: the two-harmonic Coulomb pump v(t) = sin t + b sin(2t + phi)  (thesis §3.2)")
    print("Exact values from the roots of v(t) = v_p; * marks the table's maximum feed rate.\n")
    print(
        _table(
            "Feed rate v_eq (median of v; units of the first-harmonic amplitude)",
            bs,
            phis,
            v_eq,
            best,
        )
    )
    print()
    print(_table("Average force at rest / (mu m g)", bs, phis, force, best))

    # A fine grid locates the optimum independently of the table's coarse spacing.
    fb = np.linspace(0.0, 2.0, 401)
    fp = np.linspace(-np.pi, np.pi, 721)
    fine = feed_rate(TwoHarmonic(fb[:, None], fp[None, :]))
    i, j = np.unravel_index(np.argmax(fine), fine.shape)
    print(
        f"\nOptimum on a {fb.size}x{fp.size} grid: b = {fb[i]:.3f}, phi = {fp[j] / np.pi:.3f} pi, "
        f"v_eq = {fine[i, j]:.6f}  (thesis: b = 1/2, phi = pi/2, v_eq = 0.5 = 2/3 v_max)"
    )
    bb = theory.bang_bang_efficiency(0.5)
    print(f"Bang-bang optimum z = 1/2: eta1 = {bb[0]:.4f}, eta2 = {bb[1]:.4f}  (thesis: 0.0625, 1/3)")
    nd = theory.normalized_drive(0.5)
    print(
        f"Normalised two-harmonic drive: gamma = {nd.gamma:.4f}, eta1 = {nd.eta1:.4f}, eta2 = {nd.eta2:.4f}"
    )

    if plots:
        from . import plot

        out.mkdir(parents=True, exist_ok=True)
        for name, fig in [
            ("fig3_6.png", plot.feeding_versus_b()),
            ("feed_rate_map.png", plot.feed_rate_map(fb[::4], fp[::6])),
        ]:
            fig.savefig(out / name, dpi=120)
            print(f"wrote {out / name}")
    return 0


def figures(out: Path) -> list[Path]:
    """The thesis's analytic figures (3.5, 3.6, 4.7, 6.2, 6.9) from the library, into ``out``."""
    from . import plot
    from .solvers import corner_centers, solve_rotations

    out.mkdir(parents=True, exist_ok=True)
    written = []
    # Fig. 4.7 left: 4 rotations about the square's corners (4.2.1); right: 3 rotations, zero force and
    # curl -0.05 at the part (4.2.3), a clockwise whirlpool. Known answers in docs/spec.md §4.
    centers = corner_centers((-1.0, -0.5, 1.0, 0.5))
    parts = np.array([[0.5, 0.0], [-0.75, 0.25]])
    left = solve_rotations(parts, [[0.01, 0.01], [-0.01, 0.0]], centers, mu_m_g=0.1)
    right = solve_rotations([[0.5, 0.0]], [[0.0, 0.0]], centers[:3], curls=[-0.05], mu_m_g=0.1)
    plt = plot._pyplot()
    fig, axes = plt.subplots(1, 2, figsize=(10.5, 4.6), layout="constrained")
    plot.field(
        "plan", (-1.2, -1.2, 1.2, 1.2), strengths=left.strengths, centers=centers, parts=parts, ax=axes[0]
    )
    plot.field("plan", (-1.2, -1.2, 1.2, 1.2), strengths=right.strengths, centers=centers[:3],
               parts=[[0.5, 0.0]], ax=axes[1])  # fmt: skip
    axes[0].set_title(f"Fig. 4.7 left: K = {np.round(left.strengths, 3)}", fontsize=9)
    axes[1].set_title(f"Fig. 4.7 right: K = {np.round(right.strengths, 3)}", fontsize=9)
    jet = plot.field("jet", (-2.0, -2.0, 2.0, 2.0), rho=1.0, direction=(0.0, 1.0), resolution=25)
    jet.axes[0].add_patch(plt.Circle((0, 0), 2.0, fill=False, ls=":", color="0.3"))
    jet.axes[0].set_title("Fig. 6.2: the jet (6.4), rho = 1; dotted: radius 2 rho", fontsize=10)
    for name, f in (("fig3_5.png", plot.bang_bang_feed_rate()), ("fig3_6.png", plot.feeding_versus_b()),
                    ("fig4_7.png", fig), ("fig6_2.png", jet), ("fig6_9.png", plot.theorem1())):  # fmt: skip
        f.savefig(out / name, dpi=120)
        plt.close(f)
        written.append(out / name)
    return written


def _axis(name: str, spec: Any) -> Any:
    """A grid axis from TOML: a list, or a table ``{start, stop, num[, log]}``."""
    if isinstance(spec, dict):
        unknown = set(spec) - {"start", "stop", "num", "log"}
        if unknown or not {"start", "stop", "num"} <= set(spec):
            raise ParameterError(f"grid.{name} must be a list or {{start, stop, num[, log]}}; got {spec}")
        space = np.geomspace if spec.get("log", False) else np.linspace
        return space(float(spec["start"]), float(spec["stop"]), int(spec["num"]))
    return spec


def sweep_command(config: Path | None, listing: bool, n_jobs: int | None, quiet: bool) -> int:
    """``upm sweep CONFIG.toml`` and ``upm sweep --list``."""
    from .sweeps import SCENARIOS, sweep

    if listing or config is None:
        import textwrap

        for s in SCENARIOS.values():
            print(textwrap.fill(f"{s.name}: {s.doc}", width=100, subsequent_indent="    "))
            for k, (low, high) in s.ranges.items():
                kind = "integer" if k in s.integers else "number"
                default = f", default {s.defaults[k]:g}" if k in s.defaults else ", required"
                print(f"    {k:16s} {kind} in [{low:g}, {high:g}]{default}")
            for k, unit in s.outputs.items():
                print(textwrap.fill(f"    -> {k}: {unit}", width=100, subsequent_indent="       "))
        if config is None and not listing:
            print("\nusage: upm sweep CONFIG.toml  (keys: target, [grid], [fixed], store, n_jobs, backend, "
                  "scheduler, chunk, plot)")  # fmt: skip
        return 0
    import importlib
    import tomllib

    try:
        spec = tomllib.loads(config.read_text())
    except (OSError, tomllib.TOMLDecodeError) as error:
        raise ParameterError(f"cannot read sweep config {str(config)!r}: {error}") from error
    allowed = {
        "target",
        "grid",
        "fixed",
        "store",
        "n_jobs",
        "backend",
        "scheduler",
        "chunk",
        "plot",
        "resume",
    }
    unknown = set(spec) - allowed
    if unknown:
        raise ParameterError(f"unknown keys {sorted(unknown)} in {config}; allowed: {sorted(allowed)}")
    if "target" not in spec or "grid" not in spec:
        raise ParameterError(f"{config} needs target = ... and a [grid] table")
    target: Any = spec["target"]
    if isinstance(target, str) and ":" in target:  # "package.module:function"
        module, _, attr = target.partition(":")
        target = getattr(importlib.import_module(module), attr)
    grid = {k: _axis(k, v) for k, v in spec["grid"].items()}
    name = spec["target"].split(":")[-1]
    store = Path(spec.get("store", f"out/{name}.zarr"))
    store.parent.mkdir(parents=True, exist_ok=True)
    ds = sweep(
        target,
        grid,
        n_jobs=n_jobs if n_jobs is not None else spec.get("n_jobs"),
        backend=spec.get("backend", "threads"),
        client=spec.get("scheduler"),
        store=store,
        resume=spec.get("resume", True),
        progress=not quiet,
        chunk=spec.get("chunk"),
        **spec.get("fixed", {}),
    )
    print(ds)
    print(f"wrote {store}")
    if "plot" in spec:
        from . import plot

        out = Path(spec["plot"])
        out.parent.mkdir(parents=True, exist_ok=True)
        plot.sweep(ds).savefig(out, dpi=120)
        print(f"wrote {out}")
    return 0


#: Subcommands run by their own module's ``run(args)`` (its ``arguments(parser)`` adds the options).
DELEGATED = {"calibrate": ".cli_calibrate", "desk": ".desk.cli"}


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
    from .cli_calibrate import arguments as calibrate_arguments

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
        ahead = None if args.pipeline is None else args.pipeline / 1000  # mm on the command line
        if args.name == "feeding":
            return demo(args.out, plots=not args.no_plots)
        if args.name == "list":
            from .demos import DEMOS

            for entry in DEMOS.values():
                print(f"{entry.name:12s} {entry.figure:14s} {entry.summary}")
            from .mchip_demos import DEMOS as MCHIP

            for name, (summary, _) in MCHIP.items():
                print(f"{name:12s} {'chapter 2':14s} {summary}")
            from .ppod_demos import DEMOS as PPOD

            for name, (summary, _) in PPOD.items():
                print(f"{name:14s} {'6-DOF plate':12s} {summary}")
            from .orient_demos import DEMOS as ORIENT

            for name, (summary, _) in ORIENT.items():
                print(f"{name:12s} {'polygons':14s} {summary}")
            from .scale_demos import DEMOS as SCALE

            for entry in SCALE.values():
                print(f"{entry.name:12s} {'many parts':14s} {entry.summary}")
            return 0
        from .scale_demos import DEMOS as SCALE_TABLE

        if args.name in SCALE_TABLE:
            from .scale_demos import run_scale_demo

            try:
                metrics = run_scale_demo(args.name, args.out, parts=args.parts, shape=args.shape,
                                         planner=args.planner or "predictive", seed=args.seed,
                                         quick=args.quick, rrd=args.rrd, pipeline=ahead,
                                         board=args.board)  # fmt: skip
            except UpmError as error:
                print(f"upm demo: {error}", file=sys.stderr)
                return 2
            return 0 if metrics["done"] and not metrics["fallen"] else 1
        from .orient_demos import DEMOS as ORIENT_TABLE

        if (
            args.name.startswith("mchip-")
            or args.name in ("ppod", *ORIENT_TABLE)
            or args.name.startswith("ppod-")
        ):
            from ._experiments import run_named
            from .mchip_demos import DEMOS as MCHIP_TABLE
            from .ppod_demos import DEMOS as PPOD_TABLE

            try:
                run_named(
                    {**MCHIP_TABLE, **PPOD_TABLE, **ORIENT_TABLE},
                    args.name,
                    args.out,
                    args.quick,
                    verbose=True,
                    rrd=args.rrd,
                )
            except UpmError as error:
                print(f"upm demo: {error}", file=sys.stderr)
                return 2
            return 0
        from .demos import DEMOS, run_demo
        from .mchip_demos import DEMOS as MCHIP
        from .ppod_demos import DEMOS as PPOD

        if args.name not in DEMOS:
            every = ["feeding", "list", *sorted(DEMOS), *sorted(MCHIP), *sorted(PPOD), *sorted(ORIENT_TABLE),
                     *sorted(SCALE_TABLE)]  # fmt: skip
            print(f"upm demo: no demo {args.name!r}; the demos: {', '.join(every)}", file=sys.stderr)
            return 2
        try:
            metrics = run_demo(args.name, args.out, board=args.board, quick=args.quick, seed=args.seed,
                               mp4=args.mp4, contacts=not args.points, planner=args.planner,
                               rrd=args.rrd, pipeline=ahead)  # fmt: skip
        except UpmError as error:
            print(f"upm demo: {error}", file=sys.stderr)
            return 2
        if not metrics["done"] or metrics["fallen"]:
            print(
                f"upm demo {args.name}: the task was not done ({metrics['fallen']} parts lost)",
                file=sys.stderr,
            )
            return 1
        return 0
    if args.command == "figures":
        for path in figures(args.out):
            print(f"wrote {path}")
        return 0
    if args.command == "sweep":
        try:
            return sweep_command(args.config, args.list, args.n_jobs, args.quiet)
        except UpmError as error:
            print(f"upm sweep: {error}", file=sys.stderr)
            return 2
    return 2  # pragma: no cover - argparse rejects unknown commands


if __name__ == "__main__":
    sys.exit(main())
