"""Vision: the plate, the parts, their labels and their tracks, checked against the exact ground
truth of synthetic frames (640 x 480, noise sigma 5 grey levels, lighting gradient, blur)."""

from __future__ import annotations

import importlib.metadata
from pathlib import Path

import cv2
import numpy as np
import pytest

import upm
from upm.plate.plant import SimulatedUPM
from upm.vision import THESIS_PALETTE, Palette, Table, Tracker, find_parts, find_table
from upm.vision.synthetic import COLORS, RADII, Camera, VirtualCamera, render

HALF = 0.4064 / 2
CHIP = RADII["red"]
PENNY = RADII["penny"]


def random_camera(rng: np.random.Generator) -> Camera:
    return Camera(
        tilt=float(rng.uniform(-0.2, 0.2)),
        yaw=float(rng.uniform(-0.15, 0.15)),
        shift=(float(rng.uniform(-20, 20)), float(rng.uniform(-20, 20))),
    )


def layout(n: int, r: float, rng: np.random.Generator, touching: int = 0, gap: float = 0.002) -> np.ndarray:
    """``n`` non-overlapping parts on the plate; the first ``2 * touching`` come in touching pairs."""
    while True:
        pts: list[np.ndarray] = []
        while len(pts) < n:
            p = rng.uniform(-HALF + r + 0.01, HALF - r - 0.01, 2)
            if all(np.linalg.norm(p - q) > 2 * r + gap for q in pts):
                pts.append(p)
        for i in range(touching):
            a = rng.uniform(0, 2 * np.pi)
            pts[2 * i + 1] = pts[2 * i] + (2 * r + 0.0002) * np.array([np.cos(a), np.sin(a)])
        p = np.array(pts)
        dist = np.linalg.norm(p[:, None] - p[None], axis=2) + np.eye(n)
        if dist.min() > 2 * r and np.abs(p).max() < HALF - r - 0.002:
            return p


def match(found: np.ndarray, truth: np.ndarray) -> np.ndarray:
    """Index of the nearest truth for every found point; all distinct, or the test fails."""
    d = np.linalg.norm(found[:, None] - truth[None], axis=2)
    j = np.argmin(d, axis=1)
    assert len(set(j.tolist())) == len(j), "two detections on one part"
    return j


# -- the plate ------------------------------------------------------------------------------


def test_table_corners_within_one_pixel(rng: np.random.Generator) -> None:
    errors = []
    for k in range(12):
        cam = random_camera(rng)
        frame = render(cam, layout(8, CHIP, rng), ["red", "blue"] * 4, rng=k)
        table = find_table(frame.image, cam.plate_size)
        errors.append(np.linalg.norm(table.corners - frame.truth.corners, axis=1))  # same order
        assert table.residual < 0.3
    errors = np.array(errors)
    assert errors.max() < 1.0  # the bound; measured about 0.15 px
    assert np.sqrt(np.mean(errors**2)) < 0.3


def test_table_maps_between_frames(rng: np.random.Generator) -> None:
    cam = random_camera(rng)
    frame = render(cam, np.zeros((0, 2)), [], rng=1)
    table = find_table(frame.image)
    corners = upm.vision.plate_corners(table.plate_size)
    np.testing.assert_allclose(table.to_plate(table.corners), corners, atol=1e-12)
    pts = rng.uniform(-0.2, 0.2, (20, 2))
    np.testing.assert_allclose(table.to_plate(table.to_camera(pts)), pts, atol=1e-12)
    # against the camera's exact homography: well under a pixel everywhere on the plate
    true_px = upm.vision.table.project(cam.camera_from_plate, pts)
    assert np.abs(table.to_camera(pts) - true_px).max() < 0.3
    assert table.pixels_per_metre == pytest.approx(0.8 * 480 / 0.4064, rel=0.15)


# -- the parts ------------------------------------------------------------------------------


@pytest.mark.parametrize(("kind", "radius"), [("penny", PENNY), ("chips", CHIP)])
def test_part_centres_subpixel_and_labels_exact(kind: str, radius: float, rng: np.random.Generator) -> None:
    errors, mm = [], []
    for k in range(10):
        cam = random_camera(rng)
        labels = ["penny"] * 10 if kind == "penny" else ["red", "blue"] * 5
        pos = layout(10, radius, rng, touching=2)
        frame = render(cam, pos, labels, rng=k)
        table = find_table(frame.image)
        parts = find_parts(frame.image, table, radius)
        assert len(parts) == 10
        j = match(parts.pixels, frame.truth.centers)
        assert [labels[i] for i in j] == list(parts.labels)  # every label right
        errors.append(parts.pixels - frame.truth.centers[j])
        mm.append(np.linalg.norm(parts.positions - pos[j], axis=1) * 1e3)
        np.testing.assert_allclose(parts.area, 1.0, atol=0.06)
    err = np.concatenate(errors)
    rms = float(np.sqrt(np.mean(np.sum(err**2, axis=1))))
    assert rms < 0.5  # px, the bound; measured 0.04 (pennies) and 0.08 (chips)
    assert np.abs(err).max() < 0.5
    assert np.concatenate(mm).max() < 0.5  # mm on the plate


def test_chips_vanish_in_grey_but_not_in_colour(rng: np.random.Generator) -> None:
    # the chips are as bright as the plate in grey: a grey matched filter cannot see them
    grey = lambda bgr: 0.114 * bgr[0] + 0.587 * bgr[1] + 0.299 * bgr[2]  # noqa: E731
    for chip in ("red", "blue"):
        assert abs(grey(COLORS[chip]) - grey(COLORS["plate"])) < 3
    cam = random_camera(rng)
    pos = layout(6, CHIP, rng)
    frame = render(cam, pos, ["red", "blue"] * 3, rng=3)
    table = find_table(frame.image)
    assert len(find_parts(frame.image, table, CHIP)) == 6
    grey_frame = cv2.cvtColor(frame.image, cv2.COLOR_BGR2GRAY)
    assert len(find_parts(grey_frame, table, CHIP)) == 0
    # pennies are dark: found in grey frames too, without labels
    frame = render(cam, pos, "penny", rng=4, grey=True)
    parts = find_parts(frame.image, table, PENNY)
    assert len(parts) == 6 and set(parts.labels) == {""}
    j = match(parts.pixels, frame.truth.centers)
    assert np.abs(parts.pixels - frame.truth.centers[j]).max() < 0.5


def test_convex_shapes_found_at_their_centroid(rng: np.random.Generator) -> None:
    s = 0.012
    shapes = {
        "red": [[-s, -s], [s, -s], [s, s], [-s, s]],
        "blue": [[2 * s, 0], [-s, 1.7 * s], [-s, -1.7 * s]],
    }
    cam = random_camera(rng)
    pos = layout(6, 2.3 * s, rng)
    frame = render(cam, pos, ["red", "blue"] * 3, shapes=shapes, angles=rng.uniform(0, 6, 6), rng=5)
    parts = find_parts(frame.image, find_table(frame.image), 2 * s)
    assert len(parts) == 6
    j = match(parts.pixels, frame.truth.centers)
    assert np.abs(parts.pixels - frame.truth.centers[j]).max() < 0.5
    assert [["red", "blue"][i % 2] for i in j] == list(parts.labels)


def test_occluded_part_is_reported_partial_or_missing(rng: np.random.Generator) -> None:
    cam = Camera()
    pos = np.array([[-0.1, 0.1], [0.1, 0.1], [0.0, -0.1]])
    px = upm.vision.table.project(cam.camera_from_plate, pos)
    x, y = px[2]
    arm = [[x - 60, 480], [x - 60, y + 2], [x + 60, y - 6], [x + 60, 480]]  # covers the lower half
    frame = render(cam, pos, "penny", occluders=[arm], rng=6)
    assert frame.truth.visible[:2] == pytest.approx([1.0, 1.0], abs=0.02)
    assert 0.3 < frame.truth.visible[2] < 0.7
    parts = find_parts(frame.image, find_table(frame.image), PENNY)
    whole = parts.area > 0.9
    assert whole.sum() == 2
    j = match(parts.pixels[whole], frame.truth.centers)
    assert sorted(j.tolist()) == [0, 1]
    assert np.abs(parts.pixels[whole] - frame.truth.centers[j]).max() < 0.5


def test_palette_labels_survive_a_lighting_change() -> None:
    ratios = np.array([np.asarray(THESIS_PALETTE.colors[k]) / 150.0 for k in ("penny", "red", "blue")])
    assert THESIS_PALETTE.classify(ratios) == ("penny", "red", "blue")
    assert THESIS_PALETTE.classify(ratios * 1.0) == THESIS_PALETTE.classify(ratios * 0.999)
    green = np.array([[0.5, 1.4, 0.5]])
    assert THESIS_PALETTE.classify(green) == ("unknown",)
    # darker light scales part and plate alike: the ratios, and so the labels, do not change
    cam = Camera()
    pos = np.array([[-0.1, 0.0], [0.0, 0.0], [0.1, 0.0]])
    dim = {k: tuple(0.6 * c for c in COLORS[k]) for k in ("plate", "penny", "red", "blue")}
    frame = render(cam, pos, ["penny", "red", "blue"], radius=CHIP, colors=dim, rng=7)
    parts = find_parts(frame.image, find_table(frame.image), CHIP, min_contrast=20)
    assert [parts.labels[i] for i in np.argsort(parts.positions[:, 0])] == ["penny", "red", "blue"]
    custom = Palette({"bolt": (80, 80, 80)}, plate=(150, 150, 150))
    assert custom.labels == ("bolt",)


# -- tracking -------------------------------------------------------------------------------


def sorting_run(frames: int, rng: np.random.Generator, r: float = CHIP) -> tuple[np.ndarray, list[str]]:
    """Ground truth of a sorting run: 5 red and 5 blue chips start packed (touching) and drift to
    opposite sides with a wobble; overlaps are pushed apart to touching, so parts keep touching."""
    labels = ["red", "blue"] * 5
    d = 2 * r + 0.0001
    grid = np.array(
        [[(c + 0.5 * (row % 2)) * d, row * d * np.sqrt(3) / 2] for row in range(4) for c in range(3)]
    )
    pos = grid[:10] - grid[:10].mean(axis=0)
    rng.shuffle(pos)
    phase = rng.uniform(0, 2 * np.pi, 10)
    side = np.array([-1.0 if lab == "red" else 1.0 for lab in labels])
    lim = HALF - r - 0.003
    out = [pos.copy()]
    for k in range(1, frames):
        p = out[-1] + np.column_stack([side * 0.00025, 0.0004 * np.sin(0.02 * k + phase)])
        p = np.clip(p, -lim, lim)
        for _ in range(20):
            diff = p[:, None] - p[None]
            dist = np.linalg.norm(diff, axis=2) + np.eye(10) * 1e9
            close = np.argwhere(np.triu(dist < d, 1))
            if not len(close):
                break
            for a, b in close:
                u = diff[a, b] / dist[a, b]
                push = (d - dist[a, b]) / 2 + 1e-7
                p[a] += u * push
                p[b] -= u * push
            p = np.clip(p, -lim, lim)
        out.append(p)
    return np.array(out), labels


@pytest.mark.slow
def test_tracker_keeps_ids_through_1000_frames_of_sorting(rng: np.random.Generator) -> None:
    truth, labels = sorting_run(1000, rng)
    gaps = [np.min(np.linalg.norm(t[:, None] - t[None], axis=2) + np.eye(10)) for t in truth]
    assert min(gaps) < 2 * CHIP * 1.01  # the parts really touch
    cam = Camera()
    first = render(cam, truth[0], labels, rng=0)
    tracker = Tracker(find_table(first.image), CHIP)
    tracks = tracker.update(first.image)
    assert len(tracks) == 10 and tracks.entered == tuple(range(10))
    owner = match(tracks.positions, truth[0])
    assert [labels[i] for i in owner] == list(tracks.labels)
    worst = 0.0
    for k in range(1, len(truth)):
        tracks = tracker.update(render(cam, truth[k], labels, rng=k).image)
        assert not tracks.lost.any() and tracks.ids.tolist() == list(range(10))
        worst = max(worst, float(np.abs(tracks.positions - truth[k][owner]).max()))
    assert worst < 0.0005  # m: no swap (a swap is at least a part diameter), and 0.5 px accuracy


def test_tracker_reports_lost_parts_and_finds_them_again() -> None:
    cam = Camera()
    pos = np.array([[-0.1, 0.0], [0.0, 0.05], [0.1, -0.05]])
    table = find_table(render(cam, pos, "penny").image)
    tracker = Tracker(table, PENNY, detect_every=0, max_missed=5)
    first = tracker.update(render(cam, pos, "penny", rng=1).image)
    ids = {int(first.ids[i]): int(j) for i, j in enumerate(match(first.positions, pos))}  # id -> part
    picked = next(i for i, j in ids.items() if j == 1)
    # part 1 is picked up: lost (NaN), never guessed; the others stay tracked
    for k in range(3):
        t = tracker.update(render(cam, pos[[0, 2]], "penny", rng=2 + k).image)
        assert t.lost.tolist() == [i == picked for i in t.ids]
        assert np.isnan(t.position(picked)).all() and not np.isnan(t.positions[~t.lost]).any()
        assert t.redetected
    # put back 8 mm away: re-acquired under its old id
    back = pos.copy()
    back[1] += [0.008, 0.0]
    t = tracker.update(render(cam, back, "penny", rng=9).image)
    assert t.ids.tolist() == [0, 1, 2] and not t.lost.any() and t.entered == ()
    np.testing.assert_allclose(t.position(picked), back[1], atol=5e-4)
    # with detect_every=0 nobody looks for newcomers while every part is tracked ...
    more = np.vstack([back, [[0.1, 0.12]]])
    assert tracker.update(render(cam, more, "penny", rng=10).image).ids.tolist() == [0, 1, 2]
    # ... with periodic searches a new part gets a new id
    tracker.detect_every = 1
    t = tracker.update(render(cam, more, "penny", rng=11).image)
    assert t.entered == (3,) and t.ids.tolist() == [0, 1, 2, 3]
    np.testing.assert_allclose(t.position(3), more[3], atol=5e-4)
    # part 0 leaves for good: lost, then dropped after max_missed frames
    gone = next(i for i, j in ids.items() if j == 0)
    left: list[int] = []
    for k in range(8):
        t = tracker.update(render(cam, more[1:], "penny", rng=12 + k).image)
        left += t.left
    assert left == [gone] and gone not in t.ids.tolist() and len(t) == 3 and not t.lost.any()


def test_tracker_reads_an_opencv_video(tmp_path: Path, rng: np.random.Generator) -> None:
    truth, labels = sorting_run(40, rng)
    path = tmp_path / "run.avi"
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), 30.0, (640, 480))
    assert writer.isOpened()
    cam = Camera()
    for k, p in enumerate(truth):
        writer.write(render(cam, p, labels, rng=k).image)
    writer.release()
    capture = cv2.VideoCapture(str(path))
    ok, first = capture.read()
    assert ok
    tracker = Tracker(find_table(first), CHIP)
    tracks = [tracker.update(first), *tracker.run(capture)]
    capture.release()
    assert len(tracks) == 40
    owner = match(tracks[0].positions, truth[0])
    for k, t in enumerate(tracks):
        assert t.ids.tolist() == list(range(10)) and not t.lost.any()
        assert np.abs(t.positions - truth[k][owner]).max() < 0.001  # lossy JPEG frames: 1 mm


def test_virtual_camera_of_the_simulated_plate() -> None:
    plant = SimulatedUPM(parts=np.array([[-0.05, 0.02], [0.06, -0.03]]))
    camera = plant.camera(["red", "blue"], noise=3.0)
    assert isinstance(camera, VirtualCamera) and camera.isOpened()
    ok, frame = camera.read()
    assert ok and frame.shape == (480, 640, 3)
    tracker = Tracker(find_table(frame), CHIP)
    t = tracker.update(frame)
    assert sorted(t.labels) == ["blue", "red"]
    plant.move_parts(plant.parts + np.array([0.002, 0.001]))
    moved = next(tracker.run(camera, frames=1))
    by_label = dict(zip(moved.labels, moved.positions, strict=True))
    np.testing.assert_allclose(by_label["red"], plant.parts[0], atol=3e-4)
    np.testing.assert_allclose(by_label["blue"], plant.parts[1], atol=3e-4)


# -- bad input ------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("frame", "message"),
    [
        (np.zeros((480, 640, 3), np.uint8), "blank"),
        (np.full((480, 640), 128, np.uint8), "blank"),
        (np.zeros((480, 640, 3), np.float32), "uint8"),
        (np.zeros((480, 640, 4), np.uint8), "shape"),
        (np.zeros((0, 0), np.uint8), "too small"),
        ([[1, 2], [3, 4]], "numpy array"),
    ],
)
def test_unusable_frames_raise_vision_error(frame: object, message: str) -> None:
    with pytest.raises(upm.VisionError, match=message):
        find_table(frame)  # type: ignore[arg-type]


def test_no_table_in_a_frame_of_noise_or_a_disk(rng: np.random.Generator) -> None:
    noise = rng.integers(0, 255, (480, 640, 3), dtype=np.uint8)
    disk = np.zeros((480, 640), np.uint8)
    cv2.circle(disk, (320, 240), 150, 200, -1)
    for frame in (noise, disk):
        with pytest.raises(upm.VisionError, match="no table found"):
            find_table(frame)


def test_bad_parts_arguments() -> None:
    cam = Camera()
    frame = render(cam, np.array([[0.0, 0.0]]), "penny")
    table = find_table(frame.image)
    assert isinstance(upm.VisionError("x"), upm.UpmError)
    with pytest.raises(upm.VisionError, match="640 x 480"):
        find_parts(frame.image[:240, :320], table, PENNY)
    with pytest.raises(upm.VisionError, match="at least 2 px"):
        find_parts(frame.image, table, 0.001)
    with pytest.raises(upm.ParameterError, match="part_radius"):
        find_parts(frame.image, table, -0.01)
    with pytest.raises(upm.VisionError, match="degenerate"):
        Table.from_corners([[0, 0], [1, 1], [2, 2], [3, 3]])
    with pytest.raises(upm.ParameterError, match="labels"):
        render(cam, np.zeros((2, 2)), ["penny", "nickel"])
    with pytest.raises(upm.ShapeError, match="positions"):
        render(cam, np.zeros((2, 3)))
    with pytest.raises(upm.VisionError, match="no part with id 7"):
        Tracker(table, PENNY).update(frame.image).position(7)


def test_exactly_one_opencv_package_installed() -> None:
    names = {
        (d.metadata["Name"] or "").lower()
        for d in importlib.metadata.distributions()
        if (d.metadata["Name"] or "").lower().startswith("opencv")
    }
    assert names == {"opencv-python-headless"}


def test_tracker_follows_a_long_step_where_it_is_told_to_expect_it() -> None:
    # Two pennies swap sides in one step, 12 cm each, far beyond the search radius: told where to
    # look (a planner's prediction, 2 mm off), the tracker keeps each id on its own penny; left to
    # its constant-velocity guess it re-acquires them swapped.
    cam = Camera()
    start = np.array([[-0.06, 0.0], [0.06, 0.02]])
    moved = start + np.array([[0.12, 0.0], [-0.12, 0.0]])
    table = find_table(render(cam, start, "penny").image)
    blind = Tracker(table, PENNY, detect_every=0, search=8.0)
    told = Tracker(table, PENNY, detect_every=0, search=8.0)
    first = told.update(render(cam, start, "penny", rng=1).image)
    blind.update(render(cam, start, "penny", rng=1).image)
    owner = np.argmin(np.linalg.norm(first.positions[:, None] - start[None], axis=2), axis=1)  # row -> penny
    told.expect(first.ids, moved[owner] + 0.0015)
    after = told.update(render(cam, moved, "penny", rng=2).image)
    assert not after.lost.any() and after.ids.tolist() == first.ids.tolist()
    assert np.abs(after.positions - moved[owner]).max() < 0.001
    lost = blind.update(render(cam, moved, "penny", rng=2).image)
    assert np.abs(lost.positions - moved[owner]).max() > 0.1  # swapped
    with pytest.raises(upm.ShapeError):
        told.expect([0, 1], [[0.0, 0.0]])
