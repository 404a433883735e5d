"""A nominal camera from a circular fisheye's image circle (``fisheyemotion.calib.circle``): the
circle found on drawn frames whose circle is known, on the real frame pairs of
``data/real/fisheye_mc_pairs`` (no calibration), and detection and the CLI with it."""

from __future__ import annotations

import math
from pathlib import Path

import cv2
import numpy as np
import pytest

import fisheyemotion as fm
from fisheyemotion.cli import main

PAIRS = Path(__file__).resolve().parents[1] / "data" / "real" / "fisheye_mc_pairs"
SCENES = ("object_forward", "object_lateral", "camera_forward", "camera_lateral")


def drawn_frame(width, height, cx, cy, radius, *, seed=0, dark_sector=False, halo=True):
    """A circular fisheye frame: a textured disc (its rim softened as a lens's vignetting
    softens it), the dark ring beyond, a dim halo of stray light, sensor noise."""
    rng = np.random.default_rng(seed)
    texture = cv2.GaussianBlur(rng.uniform(60, 230, (height, width)), (0, 0), 2.0)
    v, u = np.mgrid[:height, :width]
    d = np.hypot(u - cx, v - cy)
    disc = np.clip(radius + 0.5 - d, 0, 1)  # anti-aliased edge
    image = texture * disc * np.clip(1.2 - 0.4 * (d / radius) ** 4, 0, 1)
    if dark_sector:  # shadowed content reaching the rim over 60 degrees
        angle = np.degrees(np.arctan2(v - cy, u - cx))
        image = np.where((angle > 100) & (angle < 160) & (d < radius), 6.0, image)
    if halo:
        image += 35.0 * np.exp(-np.clip(d - radius - 6, 0, None) / 8.0) * (d > radius + 3)
    image += rng.normal(0, 2.0, image.shape)
    return np.clip(image, 0, 255).astype(np.uint8)


@pytest.mark.parametrize("case", [
    dict(width=640, height=480, cx=318.3, cy=241.6, radius=200.4),
    dict(width=640, height=480, cx=300.7, cy=250.2, radius=228.9, dark_sector=True),
    dict(width=800, height=480, cx=402.1, cy=238.4, radius=290.0),  # cropped top and bottom
    dict(width=512, height=512, cx=260.5, cy=250.5, radius=240.0, halo=False, seed=3),
], ids=["centred", "dark sector", "cropped", "no halo"])
def test_the_image_circle_of_a_drawn_frame_is_found(case):
    circle = fm.calib.find_image_circle(drawn_frame(**case))
    assert abs(circle.cx - case["cx"]) < 0.7 and abs(circle.cy - case["cy"]) < 0.7
    assert abs(circle.radius - case["radius"]) < 1.0
    assert 0.25 <= circle.support <= 1.0


def test_a_bgr_frame_gives_the_grey_frames_circle():
    grey = drawn_frame(640, 480, 320.2, 240.9, 210.0)
    bgr = cv2.cvtColor(grey, cv2.COLOR_GRAY2BGR)
    assert fm.calib.find_image_circle(bgr) == fm.calib.find_image_circle(grey)


@pytest.mark.parametrize("image, match", [
    (np.random.default_rng(0).integers(40, 220, (480, 640)).astype(np.uint8), "corners"),
    (np.zeros((480, 640), np.uint8), "image: no image circle"),
    (np.zeros((480, 640), np.float32), "image: expected a uint8 image"),
    (np.zeros((480, 640, 2), np.uint8), "image: expected shape"),
    (np.zeros((0, 0), np.uint8), "image: expected a frame of at least 16x16"),
    (cv2.rectangle(np.zeros((480, 640), np.uint8), (100, 50), (500, 400), 200, -1), "circular"),
    (np.hstack([drawn_frame(480, 480, 240.2, 239.7, 225.0), drawn_frame(480, 480, 239.6, 240.3,
                                                                         225.0, seed=1)]),
     "two image circles"),
], ids=["full frame", "black", "float", "two channels", "empty", "a lit square", "dual fisheye"])
def test_no_image_circle_is_a_value_error_naming_the_image(image, match):
    with pytest.raises(ValueError, match=match):
        fm.calib.find_image_circle(image)


@pytest.mark.parametrize("fov", [150.0, 180.0, 195.0, 235.0])
def test_the_nominal_cameras_rim_is_the_circle_at_half_the_field_of_view(fov):
    circle = fm.calib.ImageCircle(317.4, 236.2, 211.3)
    cam = fm.calib.nominal_camera(circle, 640, 480, fov_deg=fov)
    azimuth = np.linspace(0, 2 * np.pi, 17)
    half = math.radians(fov / 2)
    rays = np.stack([np.sin(half) * np.cos(azimuth), np.sin(half) * np.sin(azimuth),
                     np.full_like(azimuth, math.cos(half))], axis=-1)
    pixels, valid = cam.project(rays)
    assert valid.all()
    np.testing.assert_allclose(np.hypot(pixels[:, 0] - circle.cx, pixels[:, 1] - circle.cy),
                               circle.radius, rtol=0, atol=1e-9)
    axis, ok = cam.unproject(np.array([[circle.cx, circle.cy]]))
    assert ok.all() and np.allclose(axis, [[0, 0, 1]], atol=1e-12)
    inside = circle.mask(640, 480) > 0
    assert inside[236, 317] and not inside[0, 0] and inside.sum() == pytest.approx(
        math.pi * (circle.radius - 2) ** 2, rel=0.01)


@pytest.mark.parametrize("fov", [0, -10, 360, float("nan"), "180"])
def test_a_nominal_camera_needs_a_field_of_view_in_degrees(fov):
    with pytest.raises(ValueError, match="fov_deg"):
        fm.calib.nominal_camera(fm.calib.ImageCircle(320, 240, 200), 640, 480, fov_deg=fov)


def _pair(scene):
    return [cv2.imread(str(PAIRS / scene / name), cv2.IMREAD_GRAYSCALE)
            for name in ("000000_reference.png", "000001_current.png")]


@pytest.mark.parametrize("scene", SCENES)
def test_both_frames_of_a_real_pair_give_one_circle(scene):
    a, b = (fm.calib.find_image_circle(frame) for frame in _pair(scene))
    assert math.dist((a.cx, a.cy), (b.cx, b.cy)) < 1.0 and abs(a.radius - b.radius) < 1.0


def test_the_lab_scenes_camera_has_one_circle():
    """The three lab scenes are one camera (the fourth, outdoors, is mounted otherwise)."""
    circles = [fm.calib.find_image_circle(_pair(s)[0]) for s in SCENES if s != "object_lateral"]
    for c in circles[1:]:
        assert math.dist((c.cx, c.cy), (circles[0].cx, circles[0].cy)) < 2.5
        assert abs(c.radius - circles[0].radius) < 1.5


@pytest.fixture(scope="module")
def pairs_table():
    from fisheyemotion.eval.real import run_pairs

    table, figure = run_pairs(PAIRS.parents[1])
    assert len(figure.axes) == len(SCENES)
    return table.set_index("pair")


@pytest.mark.parametrize("scene", ["object_forward", "object_lateral"])
def test_a_still_real_camera_flags_what_moved(pairs_table, scene):
    """With the camera still, what the frames' difference shows is what moved: the detection
    (nominal camera, poses from the images) covers it and stays near it."""
    row = pairs_table.loc[scene]
    assert row["camera (estimated)"] == "still"
    assert row["changed pixels flagged %"] >= 80
    assert row["flagged within 15 px of a change %"] >= 70


def test_a_moving_real_camera_keeps_a_static_lab_quiet(pairs_table):
    assert set(pairs_table.index) == set(SCENES)
    row = pairs_table.loc["camera_forward"]
    assert row["camera (estimated)"] == "moving" and row["flagged %"] < 2


def test_cli_detects_on_a_frame_pair_with_a_nominal_camera(tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["detect", str(PAIRS / "object_forward"), "--calib", "circle:180", "--out",
                 str(out), "--quiet"]) == 0
    err = capsys.readouterr().err
    assert "a nominal equidistant camera" in err and "frame gap 1 instead of 3" in err
    cam = fm.calib.load(out / "calib.yaml")
    circle = fm.calib.find_image_circle(_pair("object_forward")[0])
    assert cam == fm.calib.nominal_camera(circle, 640, 640, fov_deg=180)
    assert (cv2.imread(str(out / "roi.png"), cv2.IMREAD_GRAYSCALE) == circle.mask(640, 640)).all()
    regions = (out / "regions.csv").read_text().splitlines()
    assert len(regions) > 1 and all(row.startswith("1,") for row in regions[1:])


@pytest.mark.parametrize("calib, match", [
    ("circle:400", "--calib: expected circle or circle:FOV"),
    ("circle:wide", "--calib: expected circle or circle:FOV"),
])
def test_cli_refuses_a_bad_field_of_view(tmp_path, capsys, calib, match):
    code = main(["detect", str(PAIRS / "object_forward"), "--calib", calib, "--out",
                 str(tmp_path / "o"), "--quiet"])
    assert code == 2 and match in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


def test_cli_on_frames_without_an_image_circle_says_so(tmp_path, capsys):
    frames = tmp_path / "frames"
    frames.mkdir()
    rng = np.random.default_rng(1)
    for k in range(2):
        cv2.imwrite(str(frames / f"{k:06d}.png"), rng.integers(40, 220, (240, 320), np.uint8))
    code = main(["detect", str(frames), "--calib", "circle", "--out", str(tmp_path / "o"),
                 "--quiet"])
    assert code == 2
    assert "--calib circle: frame 0: image: no image circle" in capsys.readouterr().err


def test_cli_intersects_a_given_roi_with_the_circle_and_checks_its_size(tmp_path, capsys):
    half = np.zeros((640, 640), np.uint8)
    half[:, :320] = 255
    cv2.imwrite(str(tmp_path / "left.png"), half)
    out = tmp_path / "out"
    assert main(["detect", str(PAIRS / "object_forward"), "--calib", "circle", "--roi",
                 str(tmp_path / "left.png"), "--out", str(out), "--quiet"]) == 0
    roi = cv2.imread(str(out / "roi.png"), cv2.IMREAD_GRAYSCALE)
    circle = fm.calib.find_image_circle(_pair("object_forward")[0])
    assert (roi == np.where(half > 0, circle.mask(640, 640), 0)).all() and roi[:, 320:].max() == 0
    cv2.imwrite(str(tmp_path / "small.png"), half[:480])
    code = main(["detect", str(PAIRS / "object_forward"), "--calib", "circle", "--roi",
                 str(tmp_path / "small.png"), "--out", str(tmp_path / "o2"), "--quiet"])
    assert code == 2 and "--roi: expected a 640x640 mask" in capsys.readouterr().err
    assert not (tmp_path / "o2").exists()


def test_cli_refuses_a_single_frame(tmp_path, capsys):
    frames = tmp_path / "frames"
    frames.mkdir()
    cv2.imwrite(str(frames / "000000.png"), _pair("object_forward")[0])
    code = main(["detect", str(frames), "--calib", "circle", "--out", str(tmp_path / "o"),
                 "--quiet"])
    assert code == 2 and "one frame; detection needs two or more" in capsys.readouterr().err
