"""Poses (x, y, theta) of polygon parts from synthetic frames with exact ground truth (random
cameras, noise, blur, lighting), symmetry handled: a square's angle modulo 90°."""

from __future__ import annotations

import numpy as np
import pytest

import upm
from upm.vision import find_poses, find_table
from upm.vision.poses import angle_error, outline_moments
from upm.vision.synthetic import Camera, render

PENTAGON = np.array([[0.0, 0.0], [0.030, -0.004], [0.041, 0.016], [0.022, 0.031], [-0.006, 0.019]])
SHAPES = {
    "square": upm.Polygon.rectangle(0.025, 0.025),
    "rectangle 2:1": upm.Polygon.rectangle(0.04, 0.02),
    "triangle": upm.Polygon.regular(3, 0.016),
    "irregular pentagon": upm.Polygon(PENTAGON),  # its frame's origin is not its centroid
}


def test_symmetry_orders_and_angle_errors():
    assert [p.symmetry for p in SHAPES.values()] == [4, 2, 3, 1]
    assert upm.Polygon.regular(6, 0.01).symmetry == 6
    assert angle_error(np.radians(89.0), 0.0, 4) == pytest.approx(-1.0)
    assert angle_error(np.radians(181.0), 0.0, 2) == pytest.approx(1.0)
    assert angle_error(np.radians(-179.0), np.radians(179.0), 1) == pytest.approx(2.0)


def test_outline_moments_match_a_fine_grid():
    part = SHAPES["irregular pentagon"]
    v = part.vertices - part.centroid
    h = 5e-5
    xs = np.arange(v[:, 0].min(), v[:, 0].max(), h) + h / 2
    ys = np.arange(v[:, 1].min(), v[:, 1].max(), h) + h / 2
    x, y = np.meshgrid(xs, ys)
    inside = np.ones_like(x, bool)
    for a, b in zip(v, np.roll(v, -1, axis=0), strict=True):
        inside &= (b[0] - a[0]) * (y - a[1]) - (b[1] - a[1]) * (x - a[0]) >= 0
    z = (x + 1j * y)[inside]
    for j, t in zip(range(2, 13), outline_moments(part), strict=True):
        assert abs((z**j).sum() * h * h - t) < 2e-3 * part.radius**j * part.area


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_poses_of_four_shapes_within_a_degree_and_half_a_millimetre(seed):
    rng = np.random.default_rng(seed)
    cam = Camera(tilt=float(rng.uniform(-0.2, 0.2)), yaw=float(rng.uniform(-0.15, 0.15)))
    errors, offsets = [], []
    for part in SHAPES.values():
        centroids = np.array([[x, y] for x in (-0.12, 0.0, 0.12) for y in (-0.1, 0.1)]) + rng.uniform(
            -0.01, 0.01, 2
        )
        angles = rng.uniform(0, 2 * np.pi, len(centroids))
        frame = render(
            cam, centroids, "red", shapes={"red": part.vertices - part.centroid}, angles=angles, rng=seed
        )
        poses = find_poses(frame.image, find_table(frame.image), part)
        assert len(poses) == len(centroids)
        j = [int(np.argmin(np.hypot(*(poses.centroids - p).T))) for p in centroids]
        k = part.symmetry
        errors.append(angle_error(poses.angles[j], angles, k))
        assert ((poses.angles >= 0) & (poses.angles < 2 * np.pi / k)).all()
        # the pose redraws the part: its frame's origin where the truth puts it
        c, s = np.cos(angles), np.sin(angles)
        origin = centroids - np.stack([c * part.centroid[0] - s * part.centroid[1],
                                       s * part.centroid[0] + c * part.centroid[1]], -1)  # fmt: skip
        offsets.append(np.hypot(*(poses.positions[j] - origin).T))
    err, off = np.abs(np.concatenate(errors)), np.concatenate(offsets)
    assert np.median(err) < 0.5 and err.max() < 1.5, np.round(err, 2)
    assert off.max() < 5e-4, off


def test_bad_input():
    frame = render(Camera(), np.zeros((1, 2)), "red", shapes={"red": SHAPES["square"].vertices}, rng=0)
    table = find_table(frame.image)
    with pytest.raises(upm.ParameterError, match=r"part must be a upm\.Polygon"):
        find_poses(frame.image, table, np.zeros((4, 2)))
    with pytest.raises(upm.ParameterError, match="min_contrast"):
        find_poses(frame.image, table, SHAPES["square"], min_contrast=-1)
    with pytest.raises(upm.VisionError, match="frame is"):
        find_poses(frame.image[:100], table, SHAPES["square"])


def test_the_simulated_plant_moves_polygons_and_its_camera_shows_their_poses():
    from upm.plate.plant import SimulatedUPM

    part = SHAPES["irregular pentagon"]
    plant = SimulatedUPM(
        parts=[[-0.06, 0.02], [0.05, -0.03], [0.0, 0.08]], part_shape=part, angles=[0.0, 1.0, 2.0]
    )
    # the thesis's optimal two-harmonic drive as a rotation: parts near the centre turn with it
    spin = upm.PlateMotion.rotation(
        (0.0, 0.0), upm.TwoHarmonic(0.5, np.pi / 2, amplitude=2.0, frequency=20.0)
    )
    before = plant.angles.copy()
    plant.play(spin.for_duration(0.5))
    assert np.abs(plant.angles - before).max() > 0.01  # they turned
    camera = plant.camera("red")
    ok, image = camera.read()
    assert ok
    poses = find_poses(image, find_table(image), part)
    assert len(poses) == 3
    j = [int(np.argmin(np.hypot(*(poses.positions - p).T))) for p in plant.parts]
    assert np.abs(angle_error(poses.angles[j], plant.angles, 1)).max() < 1.5
    assert np.hypot(*(poses.positions[j] - plant.parts).T).max() < 5e-4
    with pytest.raises(upm.ParameterError, match="not both"):
        SimulatedUPM(part_radius=0.01, part_shape=part)
    with pytest.raises(upm.ShapeError, match="one angle per part"):
        plant.move_parts(plant.parts, angles=[0.0])


def test_the_board_emulator_process_carries_polygon_parts_its_camera_shows(tmp_path):
    import json
    import subprocess
    import sys

    from upm.board import Board
    from upm.control import BoardDevice
    from upm.vision import RemoteCamera

    part = SHAPES["rectangle 2:1"]
    scene = tmp_path / "scene.json"
    scene.write_text(json.dumps({"parts": [[0.06, 0.0], [-0.05, 0.04]], "part_shape": part.vertices.tolist(),
                                 "angles": [0.3, 1.2], "labels": "red"}))  # fmt: skip
    cmd = [sys.executable, "-m", "upm.board.emulator", "--scene", str(scene), "--camera-port", "0"]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, text=True)
    try:
        url = proc.stdout.readline().strip()
        camera_url = proc.stdout.readline().strip().split()[-1]
        with Board(url) as board, RemoteCamera(camera_url) as camera:
            before = camera.truth()
            BoardDevice(board, wait_rest=False).execute(
                [upm.Pulse.jet((0.0, 0.0), (1, 0), 0.05, 0.08, 35.0, 0.1, 0.3, 0.1)]
            )
            after = camera.truth()
            assert np.hypot(*(after - before).T).max() > 1e-3  # the pulse moved them
            ok, image = camera.read()
            assert ok and image is not None
            poses = find_poses(image, find_table(image), part)
            assert len(poses) == 2
            j = [int(np.argmin(np.hypot(*(poses.positions - p).T))) for p in after]
            assert np.hypot(*(poses.positions[j] - after).T).max() < 5e-4
    finally:
        proc.kill()
        proc.wait()


def test_parts_of_mixed_shapes_are_told_apart_and_posed():
    from upm.plate.plant import SimulatedUPM

    shapes = [SHAPES["rectangle 2:1"], SHAPES["irregular pentagon"], SHAPES["square"]]
    which = [1, 0, 2, 1, 0]
    plant = SimulatedUPM(
        parts=[[-0.08, 0.06], [0.0, 0.07], [0.08, 0.05], [-0.05, -0.06], [0.06, -0.05]],
        part_shape=[shapes[k] for k in which],
        angles=[0.3, 1.0, 2.0, 4.0, 5.5],
    )
    ok, image = plant.camera("red").read()
    assert ok
    poses = find_poses(image, find_table(image), shapes)
    assert len(poses) == 5
    j = [int(np.argmin(np.hypot(*(poses.centroids - c).T))) for c in plant.centroids()]
    assert poses.kinds[j].tolist() == which
    assert poses.symmetries[j].tolist() == [shapes[k].symmetry for k in which]
    for i, k in enumerate(which):
        assert abs(angle_error(poses.angles[j[i]], plant.angles[i], shapes[k].symmetry)) < 1.5
    assert np.hypot(*(poses.positions[j] - plant.parts).T).max() < 5e-4
    with pytest.raises(upm.ParameterError, match="non-empty list"):
        find_poses(image, find_table(image), [])


def test_render_takes_an_outline_per_part():
    sq = SHAPES["square"].vertices - SHAPES["square"].centroid
    frame = render(Camera(), [[0.0, 0.0], [0.05, 0.0]], "red", shapes=[sq, None], radius=0.01, noise=0.0)
    disks = render(Camera(), [[0.0, 0.0], [0.05, 0.0]], "red", radius=0.01, noise=0.0)
    assert (frame.truth.visible > 0.99).all()
    # the first part is drawn as the square (its corners outside the disk), the second as before
    changed = np.argwhere(np.any(frame.image != disks.image, axis=-1))
    centres = frame.truth.centers
    near = np.hypot(*(changed[:, ::-1] - centres[0]).T) < np.hypot(*(changed[:, ::-1] - centres[1]).T)
    assert len(changed) > 50 and near.all()
    with pytest.raises(upm.ShapeError, match="one outline"):
        render(Camera(), [[0.0, 0.0], [0.05, 0.0]], "red", shapes=[sq], radius=0.01)
