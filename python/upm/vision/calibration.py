"""Metric calibration of the camera with a ChArUco board (OpenCV's ``objdetect`` API).

A ChArUco board is a chessboard whose white squares hold ArUco markers, so every corner found
is known by its id even when the board is partly hidden or seen at a slant. Calibration has two
parts, both from frames of one board (:class:`CharucoBoard`):

* the camera's **intrinsics and lens distortion**, from frames of the board held at several
  slants across the view (``cv2.aruco.CharucoDetector``, ``CharucoBoard.matchImagePoints``,
  ``cv2.calibrateCamera``);
* the **plate's pose** in the camera, from one frame of the board lying flat on the plate at its
  known place (:attr:`CharucoBoard.center`, its x axis along the plate's x).

The result, a :class:`Calibration`, maps camera pixels to plate coordinates [m] and back through
the lens model (``cv2.undistortPoints`` and the ray's meeting with the plate;
``cv2.projectPoints``), and gives a :class:`~upm.vision.Table` that the closed loop and the desk
use in place of the plate found from its outline. ``upm calibrate`` runs it on image files and
writes the result as JSON; ``upm calibrate --print-board`` writes the board at true scale.

>>> import upm.vision as v
>>> board = v.CharucoBoard()
>>> board.size  # metres: 9 x 6 squares of 30 mm, fits A4
(0.27, 0.18)
"""

from __future__ import annotations

import dataclasses
import json
import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._arrays import as_float, check_range
from .._errors import ParameterError, VisionError
from .table import PLATE_SIZE, Table, check_frame, grey_of, plate_corners

__all__ = ["Calibration", "CharucoBoard", "calibrate", "find_board", "table_of"]

FloatArray = NDArray[np.float64]

#: The ArUco dictionaries a board may use (OpenCV's predefined ones).
DICTIONARIES = {
    f"{bits}x{bits}_{n}": getattr(cv2.aruco, f"DICT_{bits}X{bits}_{n}")
    for bits in (4, 5, 6, 7)
    for n in (50, 100, 250, 1000)
}

#: The plate's axes in the board's (OpenCV: x along the columns, y down the rows, z into the
#: board): a board lying face up on the plate has its y along the plate's -y.
_FLIP = np.diag([1.0, -1.0, -1.0])


@dataclass(frozen=True)
class CharucoBoard:
    """A printed ChArUco board.

    Parameters
    ----------
    squares : (int, int)
        Squares across and down (columns, rows), each at least 3.
    square : float
        Side of a chessboard square [m].
    marker : float
        Side of an ArUco marker [m], less than ``square``.
    dictionary : str
        The markers' dictionary, e.g. ``"5x5_100"`` (see :data:`DICTIONARIES`); it must hold a
        marker for every white square.
    center : (float, float)
        Where the board's centre lies on the plate [m] when it is laid flat for the plate's pose,
        its columns along the plate's x and its first row towards the plate's +y.
    """

    squares: tuple[int, int] = (9, 6)
    square: float = 0.03
    marker: float = 0.022
    dictionary: str = "5x5_100"
    center: tuple[float, float] = (0.0, 0.0)

    def __post_init__(self) -> None:
        cols, rows = self.squares if len(self.squares) == 2 else (0, 0)
        if not all(isinstance(n, int) and not isinstance(n, bool) and 3 <= n <= 64 for n in (cols, rows)):
            raise ParameterError(
                f"squares must be two integers in [3, 64] (columns, rows); got {self.squares!r}"
            )
        check_range("square", as_float("square", self.square), low=0.0, low_open=True, high=1.0)
        check_range("marker", as_float("marker", self.marker), low=0.0, low_open=True)
        if not self.marker < self.square:
            raise ParameterError(f"marker must be smaller than square ({self.square} m); got {self.marker} m")
        if self.dictionary not in DICTIONARIES:
            raise ParameterError(f"dictionary must be one of {sorted(DICTIONARIES)}; got {self.dictionary!r}")
        size = int(self.dictionary.split("_")[1])
        if cols * rows // 2 > size:
            raise ParameterError(
                f"dictionary {self.dictionary!r} holds {size} markers; a {cols} x {rows} board needs "
                f"{cols * rows // 2}: use a larger dictionary"
            )
        c = as_float("center", self.center)
        if c.shape != (2,) or not np.all(np.isfinite(c)):
            raise ParameterError(f"center must be two finite numbers (x, y) [m]; got {self.center!r}")

    @property
    def size(self) -> tuple[float, float]:
        """The board's width and height [m]."""
        return (round(self.squares[0] * self.square, 12), round(self.squares[1] * self.square, 12))

    def cv(self) -> Any:
        """The board as a ``cv2.aruco.CharucoBoard`` (lengths in metres)."""
        words = cv2.aruco.getPredefinedDictionary(DICTIONARIES[self.dictionary])
        return cv2.aruco.CharucoBoard(self.squares, self.square, self.marker, words)

    def image(self, pixels_per_metre: float) -> NDArray[np.uint8]:
        """The board drawn at about ``pixels_per_metre`` (grey, white squares 255, no margin), a
        whole number of pixels to a square."""
        check_range("pixels_per_metre", as_float("pixels_per_metre", pixels_per_metre), low=1000.0, high=1e5)
        n = max(round(self.square * pixels_per_metre), 8)  # whole pixels a square: corners on pixel edges
        size = (self.squares[0] * n, self.squares[1] * n)
        return np.asarray(self.cv().generateImage(size, marginSize=0, borderBits=1), np.uint8)

    def plate_from_board(self, pose: ArrayLike | None = None) -> tuple[FloatArray, FloatArray]:
        """Rotation ``(3, 3)`` and translation ``(3,)`` [m] taking board coordinates (OpenCV's:
        origin at the first square's outer corner) to the plate frame. ``pose``: ``(rx, ry, rz,
        x, y, z)``, a rotation vector [rad] and a place [m] of the board's centre in the plate
        frame (default: lying flat at :attr:`center`)."""
        if pose is None:
            p = np.array([0.0, 0.0, 0.0, *self.center, 0.0])
        else:
            p = as_float("pose", pose)
            if p.shape != (6,) or not np.all(np.isfinite(p)):
                raise ParameterError(
                    f"pose must be 6 finite numbers (rx, ry, rz [rad], x, y, z [m]); got {pose!r}"
                )
        turn, _ = cv2.Rodrigues(p[:3].reshape(3, 1))
        rotation = np.asarray(turn, dtype=np.float64) @ _FLIP
        mid = np.array([self.size[0] / 2, self.size[1] / 2, 0.0])
        return rotation, p[3:] - rotation @ mid

    def corners_on_plate(self) -> FloatArray:
        """The chessboard's inner corners ``(N, 2)`` on the plate [m] when the board lies flat,
        in the order of their ids."""
        r, t = self.plate_from_board()
        pts = np.asarray(self.cv().getChessboardCorners(), dtype=np.float64)
        return np.asarray((pts @ r.T + t)[:, :2], dtype=np.float64)

    def save(self, path: str | Path, dpi: int = 300) -> Path:
        """Write the board at true scale: a PDF (vector page size = the board plus a 10 mm margin)
        or a PNG carrying its ``dpi`` (print it at 100 %; check a square with a ruler)."""
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        out = Path(path)
        if out.suffix.lower() not in (".pdf", ".png"):
            raise ParameterError(f"path must end in .pdf or .png; got {str(path)!r}")
        if not (isinstance(dpi, int) and 72 <= dpi <= 1200):
            raise ParameterError(f"dpi must be an integer in [72, 1200]; got {dpi!r}")
        margin = 0.01
        w, h = self.size
        inch = 0.0254
        fig = plt.figure(figsize=((w + 2 * margin) / inch, (h + 2 * margin) / inch), dpi=dpi)
        ax = fig.add_axes((margin / (w + 2 * margin), margin / (h + 2 * margin), w / (w + 2 * margin),
                           h / (h + 2 * margin)))  # fmt: skip
        ax.imshow(self.image(max(dpi / inch, 4000.0)), cmap="gray", vmin=0, vmax=255, interpolation="nearest")
        ax.set_axis_off()
        fig.text(0.5, margin / 4 / (h + 2 * margin), f"upm ChArUco {self.squares[0]}x{self.squares[1]}, "
                 f"square {1000 * self.square:g} mm, marker {1000 * self.marker:g} mm, {self.dictionary}",
                 ha="center", va="bottom", fontsize=6)  # fmt: skip
        out.parent.mkdir(parents=True, exist_ok=True)
        fig.savefig(out, dpi=dpi)
        plt.close(fig)
        return out


def find_board(frame: ArrayLike, board: CharucoBoard) -> tuple[FloatArray, FloatArray] | None:
    """The board's corners in a frame: ``(object_points (N, 3) [m], image_points (N, 2) [px])``
    matched by id, or None when fewer than 6 are found (``cv2.aruco.CharucoDetector``)."""
    grey = grey_of(check_frame(frame))
    cv_board = board.cv()
    detector = cv2.aruco.CharucoDetector(cv_board)
    corners, ids, _, _ = detector.detectBoard(grey)
    if ids is None or len(ids) < 6:
        return None
    obj, img = cv_board.matchImagePoints(corners, ids)
    return np.asarray(obj, np.float64).reshape(-1, 3), np.asarray(img, np.float64).reshape(-1, 2)


@dataclass(frozen=True)
class Calibration:
    """A calibrated camera over the plate.

    Attributes
    ----------
    camera_matrix : (3, 3) ndarray
        Intrinsics [px]: focal lengths and principal point.
    distortion : (5,) ndarray
        Lens distortion ``(k1, k2, p1, p2, k3)`` (OpenCV's model).
    rotation, translation : (3, 3) ndarray, (3,) ndarray
        The plate's pose in the camera: ``camera = rotation @ plate + translation`` [m].
    image_size : (int, int)
        Width and height of the frames [px].
    rms : float
        RMS reprojection error of the board's corners over all frames [px].
    frames : int
        Frames the board was found in.
    """

    camera_matrix: FloatArray
    distortion: FloatArray
    rotation: FloatArray
    translation: FloatArray
    image_size: tuple[int, int]
    rms: float
    frames: int

    def to_camera(self, points: ArrayLike) -> FloatArray:
        """Plate coordinates ``(..., 2)`` [m] to camera pixels, through the lens."""
        p = np.asarray(points, dtype=np.float64)
        flat = np.column_stack([p.reshape(-1, 2), np.zeros(p.size // 2)])
        rvec, _ = cv2.Rodrigues(self.rotation)
        px, _ = cv2.projectPoints(flat, rvec, self.translation, self.camera_matrix, self.distortion)
        return np.asarray(px, dtype=np.float64).reshape(p.shape)

    def to_plate(self, pixels: ArrayLike) -> FloatArray:
        """Camera pixels ``(..., 2)`` to plate coordinates [m]: the lens undone, then each pixel's
        ray met with the plate's plane."""
        q = np.asarray(pixels, dtype=np.float64)
        if q.size == 0:
            return np.zeros(q.shape)
        criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-12)
        ideal = cv2.undistortPoints(
            q.reshape(-1, 1, 2), self.camera_matrix, self.distortion, criteria=criteria
        )
        rays = np.column_stack([np.asarray(ideal, np.float64).reshape(-1, 2), np.ones(q.size // 2)])
        back = rays @ self.rotation  # each ray in plate axes (rotation.T @ ray)
        origin = -self.rotation.T @ self.translation  # the camera's centre on the plate's frame
        s = -origin[2] / back[:, 2]
        return np.asarray((origin + s[:, None] * back)[:, :2], dtype=np.float64).reshape(q.shape)

    def table(self, plate_size: float | tuple[float, float] = PLATE_SIZE) -> Table:
        """The plate as this camera sees it, mapped through the lens (for the loop and the desk)."""
        straight = Table.from_corners(self.to_camera(plate_corners(plate_size)), plate_size, self.image_size)
        return dataclasses.replace(straight, residual=self.rms, lens=self)

    def save(self, path: str | Path) -> Path:
        """Write the calibration as JSON (:meth:`load` reads it)."""
        out = Path(path)
        out.parent.mkdir(parents=True, exist_ok=True)
        data = {
            "format": "upm-calibration-1",
            "camera_matrix": self.camera_matrix.tolist(),
            "distortion": self.distortion.tolist(),
            "rotation": self.rotation.tolist(),
            "translation": self.translation.tolist(),
            "image_size": list(self.image_size),
            "rms": self.rms,
            "frames": self.frames,
        }
        out.write_text(json.dumps(data, indent=1))
        return out

    @classmethod
    def load(cls, path: str | Path) -> Calibration:
        """Read a calibration written by :meth:`save`; :class:`upm.ParameterError` naming the file
        when it is not one."""
        try:
            data = json.loads(Path(path).read_text())
            if data.get("format") != "upm-calibration-1":
                raise ValueError("no upm-calibration-1 format tag")
            k = np.array(data["camera_matrix"], dtype=np.float64).reshape(3, 3)
            d = np.array(data["distortion"], dtype=np.float64).ravel()
            r = np.array(data["rotation"], dtype=np.float64).reshape(3, 3)
            t = np.array(data["translation"], dtype=np.float64).reshape(3)
            w, h = (int(v) for v in data["image_size"])
            rms, frames = float(data["rms"]), int(data["frames"])
        except (OSError, ValueError, KeyError, TypeError, AttributeError) as error:
            raise ParameterError(
                f"path: {str(path)!r} is not a calibration written by upm calibrate ({error})"
            ) from None
        if not all(np.all(np.isfinite(a)) for a in (k, d, r, t)) or abs(np.linalg.det(r) - 1) > 1e-6:
            raise ParameterError(
                f"path: {str(path)!r} holds a broken calibration (non-finite or not a rotation)"
            )
        return cls(k, d, r, t, (w, h), rms, frames)


def table_of(table: object, plate_size: float | tuple[float, float] = PLATE_SIZE) -> Table | None:
    """The plate in the camera from what a user passes as ``table``: a :class:`Table`, a
    :class:`Calibration`, the path of one saved by ``upm calibrate``, or None (find the plate from
    its outline in the first frame)."""
    if table is None or isinstance(table, Table):
        return table
    if isinstance(table, Calibration):
        return table.table(plate_size)
    if isinstance(table, (str, Path)):
        return Calibration.load(table).table(plate_size)
    raise ParameterError(
        f"table must be a Table, a Calibration, the path of a calibration (upm calibrate) or None; "
        f"got {type(table).__name__}"
    )


def calibrate(
    frames: Sequence[ArrayLike],
    board: CharucoBoard | None = None,
    *,
    on_plate: int = -1,
    fix_aspect: bool = True,
) -> Calibration:
    """Calibrate the camera from frames of a ChArUco ``board``.

    Parameters
    ----------
    frames : sequence of (H, W) or (H, W, 3) uint8 arrays
        Frames of the board, all of one size: held at several slants over the view (at least 3
        such frames for the lens; 10 or more is better) and, at ``on_plate``, one of it lying flat
        on the plate at :attr:`CharucoBoard.center`.
    board : CharucoBoard
        The board printed (default :class:`CharucoBoard()`).
    on_plate : int
        Index in ``frames`` of the frame with the board flat on the plate (default the last).
    fix_aspect : bool
        Square pixels (one focal length): true of nearly every camera; steadier from few frames.

    Raises
    ------
    VisionError
        When the board is not found in the ``on_plate`` frame, or in fewer than 4 frames.
    """
    board = CharucoBoard() if board is None else board
    if not isinstance(board, CharucoBoard):
        raise ParameterError(f"board must be a upm.vision.CharucoBoard; got {type(board).__name__}")
    images = [check_frame(f, f"frames[{i}]") for i, f in enumerate(frames)]
    if len(images) < 4:
        raise ParameterError(f"frames must hold at least 4 frames of the board; got {len(images)}")
    if (
        isinstance(on_plate, bool)
        or not isinstance(on_plate, int)
        or not -len(images) <= on_plate < len(images)
    ):
        raise ParameterError(
            f"on_plate must be a frame's index in [-{len(images)}, {len(images)}); got {on_plate!r}"
        )
    size = (images[0].shape[1], images[0].shape[0])
    for i, img in enumerate(images):
        if (img.shape[1], img.shape[0]) != size:
            raise ParameterError(
                f"frames[{i}] is {img.shape[1]} x {img.shape[0]} px; frames[0] is {size[0]} x {size[1]}"
            )
    plate_index = on_plate % len(images)
    found = [find_board(img, board) for img in images]
    if found[plate_index] is None:
        raise VisionError(
            f"the board lying on the plate (frames[{plate_index}]) was not found: need 6 corners"
        )
    used = [i for i, f in enumerate(found) if f is not None]
    if len(used) < 4:
        raise VisionError(f"the board was found in {len(used)} of {len(images)} frames; calibration needs 4")
    object_points = [found[i][0].astype(np.float32) for i in used]  # type: ignore[index]
    image_points = [found[i][1].astype(np.float32) for i in used]  # type: ignore[index]
    flags = cv2.CALIB_FIX_K3 | (cv2.CALIB_FIX_ASPECT_RATIO if fix_aspect else 0)
    guess = np.array([[1.0, 0, size[0] / 2], [0, 1.0, size[1] / 2], [0, 0, 1]]) * [
        [max(size), 1, 1],
        [1, max(size), 1],
        [1, 1, 1],
    ]
    criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 200, 1e-12)
    rms, k, dist, rvecs, tvecs = cv2.calibrateCamera(
        object_points, image_points, size, guess, np.zeros(5), flags=flags, criteria=criteria
    )
    if not math.isfinite(rms):
        raise VisionError("calibration did not converge: give frames of the board at more slants")
    at = used.index(plate_index)
    board_in_camera, _ = cv2.Rodrigues(rvecs[at])
    r_pb, t_pb = board.plate_from_board()
    # camera = R_cb board + t_cb, board = R_pb^T (plate - t_pb)
    rotation = np.asarray(board_in_camera, np.float64) @ r_pb.T
    translation = np.asarray(tvecs[at], np.float64).ravel() - rotation @ t_pb
    return Calibration(np.asarray(k, np.float64), np.asarray(dist, np.float64).ravel()[:5], rotation,
                       translation, size, float(rms), len(used))  # fmt: skip
