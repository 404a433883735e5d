"""Kannala-Brandt against OpenCV's own cv2.fisheye, and where OpenCV is wrong (beyond 90 deg)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from fisheyemotion import calib

from .cameras import TUMVI_KB

CAM = calib.KannalaBrandt(**TUMVI_KB)
K = np.array([[CAM.fx, 0, CAM.cx], [0, CAM.fy, CAM.cy], [0, 0, 1.0]])
D = np.array([CAM.k1, CAM.k2, CAM.k3, CAM.k4])
CRITERIA = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-15)


def rays_at(theta_deg: np.ndarray, seed: int = 7) -> np.ndarray:
    rng = np.random.default_rng(seed)
    t = np.radians(theta_deg)
    phi = rng.uniform(0, 2 * np.pi, t.shape)
    return np.stack([np.sin(t) * np.cos(phi), np.sin(t) * np.sin(phi), np.cos(t)], -1)


def cv2_project(rays: np.ndarray) -> np.ndarray:
    out, _ = cv2.fisheye.projectPoints(rays.reshape(-1, 1, 3), np.zeros(3), np.zeros(3), K, D)
    return out.reshape(-1, 2)


def cv2_unproject(pixels: np.ndarray) -> np.ndarray:
    xy = cv2.fisheye.undistortPoints(pixels.reshape(-1, 1, 2), K, D, criteria=CRITERIA)
    xy = xy.reshape(-1, 2)
    rays = np.concatenate([xy, np.ones((len(xy), 1))], axis=1)
    return rays / np.linalg.norm(rays, axis=1, keepdims=True)


def angle(a, b):
    return np.arctan2(np.linalg.norm(np.cross(a, b), axis=-1), np.sum(a * b, axis=-1))


def test_projection_matches_cv2_below_90_degrees():
    rays = rays_at(np.random.default_rng(0).uniform(0, 89.5, 5000))
    ours, valid = CAM.project(rays)
    assert valid.all()
    np.testing.assert_allclose(ours, cv2_project(rays), atol=1e-9)


def test_unprojection_matches_cv2_below_90_degrees():
    theta = np.random.default_rng(1).uniform(0, 80, 5000)
    pixels, _ = CAM.project(rays_at(theta))
    ours, valid = CAM.unproject(pixels)
    assert valid.all()
    assert angle(ours, cv2_unproject(pixels)).max() < 1e-9


@pytest.mark.parametrize("theta_deg", [95.0, 100.0, 110.0, 115.0])
def test_beyond_90_degrees_cv2_is_wrong_and_we_are_right(theta_deg):
    ray = rays_at(np.array([theta_deg]))
    ours, valid = CAM.project(ray)
    assert valid.all()
    # cv2 divides by z: the ray behind the image plane lands on the mirrored side of the image.
    theirs = cv2_project(ray)
    centre = np.array([CAM.cx, CAM.cy])
    assert np.dot(ours[0] - centre, theirs[0] - centre) < 0
    # Our pixel comes back as our ray; cv2 returns a ray in the front hemisphere, far off.
    back, ok = CAM.unproject(ours)
    assert ok.all() and angle(back, ray)[0] < 1e-9
    wrong = cv2_unproject(ours)
    assert wrong[0, 2] > 0
    assert np.degrees(angle(wrong, ray)[0]) > 2 * (theta_deg - 90) - 1e-6


def test_tumvi_corner_is_115_degrees_off_axis_and_valid():
    rays, valid = CAM.unproject(np.array([[0.0, 0.0], [511.0, 511.0]]))
    assert valid.all()
    theta = np.degrees(np.arccos(rays[:, 2]))
    assert theta.min() > 114 and theta.max() < 116.5
