"""Unprojection of every 640x480 pixel: our models vs cv2.fisheye.undistortPoints.

Run with ``make bench``; ``benchmarks/report.py`` turns the JSON into the ratios in
docs/performance.md. Accuracy (max angular error vs our ray) is recorded in ``extra_info``.
"""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from fisheyemotion import calib

KB = calib.KannalaBrandt(fx=238.7, fy=238.7, cx=319.5, cy=239.5, k1=0.0034823894022493434,
                         k2=0.0007150348452162257, k3=-0.0020532361418706202,
                         k4=0.00020293673591811182, width=640, height=480)
DS = calib.DoubleSphere(fx=197.86, fy=197.84, cx=319.5, cy=239.5, xi=-0.17213086034353243,
                        alpha=0.5931177593944744, width=640, height=480)
EUCM = calib.EnhancedUnified(fx=238.9, fy=238.9, cx=319.5, cy=239.5, alpha=0.6291060881178562,
                             beta=1.0418067381860868, width=640, height=480)
PIXELS = calib.pixel_grid(640, 480).reshape(-1, 2)
K = np.array([[KB.fx, 0, KB.cx], [0, KB.fy, KB.cy], [0, 0, 1.0]])
D = np.array([KB.k1, KB.k2, KB.k3, KB.k4])


def cv2_rays(pixels: np.ndarray) -> np.ndarray:
    """cv2's normalised coordinates made unit rays, leanly: (x, y, 1) / sqrt(x^2 + y^2 + 1)."""
    xy = cv2.fisheye.undistortPoints(pixels.reshape(-1, 1, 2), K, D).reshape(-1, 2)
    rays = np.empty((len(xy), 3))
    inv = 1.0 / np.sqrt(np.einsum("ij,ij->i", xy, xy) + 1.0)
    np.multiply(xy, inv[:, None], out=rays[:, :2])
    rays[:, 2] = inv
    return rays


def _angle(a, b):
    return np.degrees(np.arctan2(np.linalg.norm(np.cross(a, b), axis=-1), np.sum(a * b, axis=-1)))


@pytest.mark.benchmark(group="unproject-640x480")
def test_cv2_fisheye_undistortPoints_bare(benchmark):
    """The peer: what a cv2 user runs, normalised coordinates (x/z, y/z), not rays."""
    obj = PIXELS.reshape(-1, 1, 2)
    benchmark(cv2.fisheye.undistortPoints, obj, K, D)
    benchmark.extra_info["pixels"] = len(PIXELS)


@pytest.mark.benchmark(group="unproject-640x480")
def test_cv2_fisheye_undistortPoints_to_rays(benchmark):
    rays = benchmark(cv2_rays, PIXELS)
    ours, _ = KB.unproject(PIXELS)
    theta = np.degrees(np.arccos(ours[:, 2]))
    err = _angle(rays, ours)
    benchmark.extra_info["pixels"] = len(PIXELS)
    benchmark.extra_info["max_err_deg_below_90"] = float(err[theta < 90].max())
    benchmark.extra_info["max_err_deg_beyond_90"] = float(err[theta >= 90].max())
    benchmark.extra_info["pixels_beyond_90"] = int((theta >= 90).sum())


@pytest.mark.benchmark(group="unproject-640x480")
@pytest.mark.parametrize("cam", [KB, DS, EUCM], ids=["kannala_brandt", "double_sphere",
                                                     "enhanced_unified"])
def test_fisheyemotion_unproject(benchmark, cam):
    rays, valid = benchmark(cam.unproject, PIXELS)
    back, _ = cam.project(rays[valid])
    benchmark.extra_info["pixels"] = len(PIXELS)
    benchmark.extra_info["max_pixel_round_trip_error"] = float(np.abs(back - PIXELS[valid]).max())


RAYS, _RAYS_VALID = KB.unproject(PIXELS)
RAYS_FRONT = RAYS[_RAYS_VALID & (RAYS[:, 2] > 0)]  # cv2.fisheye projects the front hemisphere


@pytest.mark.benchmark(group="project-640x480")
def test_cv2_fisheye_projectPoints(benchmark):
    obj = RAYS_FRONT.reshape(-1, 1, 3)
    out = benchmark(cv2.fisheye.projectPoints, obj, np.zeros(3), np.zeros(3), K, D)[0]
    ours, _ = KB.project(RAYS_FRONT)
    benchmark.extra_info["rays"] = len(RAYS_FRONT)
    benchmark.extra_info["max_px_diff"] = float(np.abs(out.reshape(-1, 2) - ours).max())


@pytest.mark.benchmark(group="project-640x480")
@pytest.mark.parametrize("cam", [KB, DS, EUCM], ids=["kannala_brandt", "double_sphere",
                                                     "enhanced_unified"])
def test_fisheyemotion_project(benchmark, cam):
    pixels, valid = benchmark(cam.project, RAYS_FRONT)
    benchmark.extra_info["rays"] = len(RAYS_FRONT)
