"""``upm calibrate``: the camera's calibration from frames of a ChArUco board, written as JSON for
``Loop(table=...)`` and ``upm desk --calibration``; ``--print-board`` writes the board to print."""

from __future__ import annotations

import argparse
from pathlib import Path

from .._errors import ParameterError

__all__ = ["arguments", "run"]


def arguments(parser: argparse.ArgumentParser) -> None:
    """The options of ``upm calibrate``."""
    parser.add_argument(
        "frames", nargs="*", type=Path, help="images of the board; the last lies flat on the plate"
    )
    parser.add_argument("--out", type=Path, default=Path("calibration.json"), help="where to write (JSON)")
    parser.add_argument(
        "--print-board",
        type=Path,
        default=None,
        metavar="FILE",
        help="write the board at true scale (.pdf or .png) and calibrate nothing",
    )
    parser.add_argument("--squares", default="9x6", help="squares across x down (default 9x6)")
    parser.add_argument("--square", type=float, default=30.0, help="a square's side [mm] (default 30)")
    parser.add_argument("--marker", type=float, default=22.0, help="a marker's side [mm] (default 22)")
    parser.add_argument("--dictionary", default="5x5_100", help="ArUco dictionary (default 5x5_100)")
    parser.add_argument("--center", default="0,0", help="the flat board's centre on the plate, x,y [mm]")
    parser.add_argument(
        "--on-plate", type=int, default=-1, help="index of the frame with the board flat (default -1)"
    )


def _pair(text: str, name: str, sep: str, kind: type) -> tuple[float, float] | tuple[int, int]:
    try:
        a, b = (kind(v) for v in text.split(sep))
    except ValueError:
        raise ParameterError(f"{name} must be two numbers separated by {sep!r}; got {text!r}") from None
    return (a, b)


def run(args: argparse.Namespace) -> int:
    """Print the board, or calibrate from the frames and write the result."""
    import cv2

    from .calibration import CharucoBoard, calibrate

    cx, cy = _pair(args.center, "--center", ",", float)
    board = CharucoBoard(
        squares=_pair(args.squares.lower(), "--squares", "x", int),  # type: ignore[arg-type]
        square=args.square / 1000,
        marker=args.marker / 1000,
        dictionary=args.dictionary,
        center=(cx / 1000, cy / 1000),
    )
    if args.print_board is not None:
        out = board.save(args.print_board)
        w, h = board.size
        print(
            f"upm calibrate: wrote {out}: {1000 * w:.0f} x {1000 * h:.0f} mm; print at 100 % and check a "
            f"square measures {args.square:g} mm"
        )
        return 0
    if not args.frames:
        raise ParameterError("frames: give the images of the board (or --print-board FILE)")
    frames = []
    for path in args.frames:
        image = cv2.imread(str(path), cv2.IMREAD_COLOR)
        if image is None:
            raise ParameterError(f"frames: {str(path)!r} is not an image OpenCV can read")
        frames.append(image)
    result = calibrate(frames, board, on_plate=args.on_plate)
    out = result.save(args.out)
    k = result.camera_matrix
    print(
        f"upm calibrate: the board in {result.frames} of {len(frames)} frames; reprojection error "
        f"{result.rms:.3f} px; focal length {k[0, 0]:.1f} px; distortion k1 {result.distortion[0]:+.4f}"
    )
    print(f"  wrote {out} (for Loop(table=...) and upm desk --calibration)")
    return 0
