"""ChArUco calibration on synthetic frames (issue 60): a camera tilted 15 degrees with 2 % radial
distortion, the board held at slants and then laid flat on the plate. The references are the
synthetic camera's own model (its pinhole homography and its lens), independent of OpenCV's
calibration."""

from __future__ import annotations

import json
import math

import cv2
import numpy as np
import pytest

import upm
from upm.cli import main
from upm.control import Loop
from upm.vision import Calibration, CharucoBoard, calibrate, find_board, find_parts, find_table
from upm.vision.synthetic import Camera, render, render_board
from upm.vision.table import project

CAMERA = Camera(size=(1280, 960), tilt=math.radians(15), yaw=0.03, distortion=-0.02, fill=0.7)
BOARD = CharucoBoard()


def held_poses(seed: int, n: int = 9) -> list[tuple[float, ...]]:
    """The board held over the plate at ``n`` slants (up to about 29 degrees), heights and places."""
    rng = np.random.default_rng(seed)
    return [(*rng.uniform(-0.5, 0.5, 2), rng.uniform(-0.3, 0.3), *rng.uniform(-0.12, 0.12, 2),
             rng.uniform(0.02, 0.3)) for _ in range(n)]  # fmt: skip


@pytest.fixture(scope="module")
def frames() -> list[np.ndarray]:
    held = [render_board(CAMERA, BOARD, pose, rng=100 + i) for i, pose in enumerate(held_poses(1))]
    return [*held, render_board(CAMERA, BOARD, None, rng=1)]


def plate_grid() -> np.ndarray:
    g = np.linspace(-0.19, 0.19, 21)
    return np.stack(np.meshgrid(g, g), axis=-1).reshape(-1, 2)


def test_the_lens_the_model_says():
    # 2 % at the image's corner, and the inverse map used to render undoes it
    w, h = CAMERA.size
    k = CAMERA.intrinsics
    corner = np.array([[w - 0.5, h - 0.5]])
    ideal = k[:2, 2] + (corner - k[:2, 2]) / 0.98  # where a pinhole would put what is seen there
    seen = CAMERA.distort(ideal)
    assert np.linalg.norm(seen - k[:2, 2]) == pytest.approx(np.linalg.norm(ideal - k[:2, 2]) * 0.98, rel=2e-3)
    assert np.array_equal(Camera().distort(corner), corner)


def test_calibration_maps_pixels_to_the_plate_within_a_tenth_of_a_millimetre(frames):
    cal = calibrate(frames, BOARD)
    assert cal.frames == 10 and cal.rms < 0.2
    g = plate_grid()
    pixels = CAMERA.distort(project(CAMERA.camera_from_plate, g))  # the camera's own model
    err = 1000 * np.hypot(*(cal.to_plate(pixels) - g).T)
    assert np.sqrt(np.mean(err**2)) <= 0.1 and err.max() <= 0.3, (np.sqrt(np.mean(err**2)), err.max())
    assert np.abs(cal.to_camera(g) - pixels).max() < 0.3  # and back [px]
    # the straight table found from the outline bends with the lens (0.4 mm here, inside the plate)
    outline = find_table(render(CAMERA, np.zeros((0, 2))).image)
    assert 1000 * np.hypot(*(outline.to_plate(pixels) - g).T).max() > 2 * err.max()


def test_the_flat_board_gives_the_plate_where_it_lies(frames):
    shifted = CharucoBoard(center=(0.05, -0.02))
    moved = [*frames[:-1], render_board(CAMERA, shifted, None, rng=3)]
    cal = calibrate(moved, shifted)
    obj, img = find_board(moved[-1], shifted)
    on_plate = shifted.corners_on_plate()
    assert len(obj) == len(on_plate)
    # each corner seen maps back to its place on the plate (corners sorted by id in both)
    ids = [
        int(np.argmin(np.abs(BOARD.cv().getChessboardCorners() - o.astype(np.float32)).sum(1))) for o in obj
    ]
    assert 1000 * np.abs(cal.to_plate(img) - on_plate[ids]).max() < 0.3


def test_the_loop_sees_parts_through_a_calibrated_table(frames, tmp_path):
    cal = calibrate(frames, BOARD)
    path = cal.save(tmp_path / "calibration.json")
    loaded = Calibration.load(path)
    assert np.array_equal(loaded.camera_matrix, cal.camera_matrix) and loaded.rms == cal.rms
    parts = np.array([[-0.17, -0.17], [0.16, 0.17], [0.0, 0.02], [0.17, -0.15]])
    frame = render(CAMERA, parts, ["red", "blue", "red", "blue"], rng=4)
    seen = find_parts(frame.image, loaded.table(), 0.0195)
    order = [int(np.argmin(np.hypot(*(seen.positions - p).T))) for p in parts]
    assert 1000 * np.abs(seen.positions[order] - parts).max() < 1.0
    # Loop and the desk take the file
    limits = upm.drive.DriveLimits()
    plant = upm.plant.SimulatedUPM(plate=limits.plate, axes=limits.axes, stroke=limits.stroke, parts=parts)
    planner, task = upm.plan.PredictivePlanner(limits), upm.control.SortTask({"red": -1})
    loop = Loop(
        plant, plant.camera(["red"] * 4, camera=CAMERA), planner, task, part_radius=0.0195, table=path
    )
    assert loop.table is not None and loop.table.lens is not None
    log = loop.run(1)  # the tracker, through the lens, sees the parts where they started
    tracked = log.positions[0]
    assert max(1000 * np.hypot(*(tracked - p).T).min() for p in parts) < 1.0
    with pytest.raises(upm.ParameterError, match="table must be"):
        Loop(plant, plant.camera(["red"] * 4), planner, task, part_radius=0.0195, table=3)


@pytest.mark.slow
def test_upm_calibrate_prints_the_board_and_calibrates_from_files(frames, tmp_path, capsys):
    assert main(["calibrate", "--print-board", str(tmp_path / "board.png")]) == 0
    from PIL import Image

    printed = Image.open(tmp_path / "board.png")
    dpi = printed.info["dpi"][0]
    assert printed.size[0] / dpi * 25.4 == pytest.approx(270 + 20, abs=0.5)  # the board and its margins [mm]
    names = []
    for i, f in enumerate(frames):
        names.append(str(tmp_path / f"f{i}.png"))
        cv2.imwrite(names[-1], f)
    assert main(["calibrate", *names, "--out", str(tmp_path / "cal.json")]) == 0
    assert "reprojection error" in capsys.readouterr().out
    data = json.loads((tmp_path / "cal.json").read_text())
    assert data["frames"] == 10
    assert main(["calibrate", str(tmp_path / "nope.png")]) == 2
    assert "not an image" in capsys.readouterr().err
    assert main(["calibrate", "--squares", "9by6", "--print-board", str(tmp_path / "b.pdf")]) == 2


def test_bad_calibration_input_is_refused(frames, tmp_path):
    with pytest.raises(upm.ParameterError, match="marker must be smaller"):
        CharucoBoard(marker=0.03)
    with pytest.raises(upm.ParameterError, match="dictionary"):
        CharucoBoard(squares=(20, 20), dictionary="4x4_50")
    with pytest.raises(upm.ParameterError, match="squares"):
        CharucoBoard(squares=(2, 9))
    with pytest.raises(upm.ParameterError, match="frames must hold at least 4"):
        calibrate(frames[:3])
    with pytest.raises(upm.ParameterError, match="on_plate"):
        calibrate(frames, on_plate=10)
    with pytest.raises(upm.ParameterError, match=r"frames\[1\]"):
        calibrate([frames[0], frames[1][:100], *frames[2:]])
    blank = np.full_like(frames[0], 90)
    with pytest.raises(upm.VisionError, match="lying on the plate"):
        calibrate([*frames[:-1], blank])
    with pytest.raises(upm.VisionError, match="found in 2 of"):
        calibrate([blank, blank, blank, frames[0], blank, frames[-1]])
    (tmp_path / "bad.json").write_text("{not json")
    with pytest.raises(upm.ParameterError, match="not a calibration"):
        Calibration.load(tmp_path / "bad.json")
    with pytest.raises(upm.ParameterError, match="pose must be"):
        BOARD.plate_from_board([0, 0, 0])
    with pytest.raises(upm.ParameterError, match="distortion"):
        Camera(distortion=0.5)
