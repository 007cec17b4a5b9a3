"""Vision for the closed loop (docs/spec.md §8, thesis 5.2.4): find the plate, find and label the parts,
track them; :mod:`upm.vision.synthetic` renders test frames with exact ground truth.

Needs OpenCV: ``pip install upm[vision]`` (``opencv-python-headless``).
"""

from __future__ import annotations

try:
    import cv2  # noqa: F401
except ImportError:  # tested with cv2 blocked in a subprocess
    from .._errors import MissingExtraError

    raise MissingExtraError(
        "upm.vision needs OpenCV (opencv-python-headless), which is not installed: pip install 'upm[vision]'"
    ) from None

from .._errors import VisionError
from .calibration import Calibration, CharucoBoard, calibrate, find_board
from .parts import THESIS_PALETTE, Palette, Parts, find_parts
from .poses import Poses, find_poses
from .remote import RemoteCamera
from .table import PLATE_SIZE, Table, find_table, plate_corners
from .tracker import Tracker, Tracks

__all__ = [
    "PLATE_SIZE",
    "THESIS_PALETTE",
    "Calibration",
    "CharucoBoard",
    "Palette",
    "Parts",
    "Poses",
    "RemoteCamera",
    "Table",
    "Tracker",
    "Tracks",
    "VisionError",
    "calibrate",
    "find_board",
    "find_parts",
    "find_poses",
    "find_table",
    "plate_corners",
]
