"""Ego-motion from the fisheye images themselves, for users without poses.

Corners are tracked between consecutive frames (:mod:`fisheyemotion.tracks`), unprojected to
rays with the camera model, and the relative pose is estimated by PoseLib (RANSAC over the
5-point minimal solver, then non-linear refinement). PoseLib takes image points of its own
camera models; rays within ``max_angle`` of the optical axis are given to it as points of the
unit pinhole camera ``(x/z, y/z)``, so any of this package's models (wider than 180 degrees
included) works, at the cost of the rays beyond that angle.

Scale: two views fix the translation's direction only. The trajectory is chained with a
translation of ``step`` (default 1, arbitrary units) per frame: enough for the epipolar and
positive-depth constraints, which do not depend on scale. The road terms need metres: without
poses the detector runs with ``Road.unknown()``.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from .calib.base import CameraModel
from .calib.transforms import make_transform
from .tracks import track_corners

__all__ = ["PoseTracker", "relative_pose"]


def relative_pose(rays0: NDArray[np.float64], rays1: NDArray[np.float64], *,
                  max_angle: float = math.radians(75.0), threshold: float = 1e-3,
                  seed: int = 0) -> tuple[NDArray[np.float64] | None, NDArray[np.bool_]]:
    """``cam1_from_cam0`` (4x4, unit translation) from ray correspondences ``(N, 3)``.

    Parameters
    ----------
    max_angle : float
        Radians off the optical axis in both views for a correspondence to be used.
    threshold : float
        RANSAC inlier threshold in the unit pinhole's image units (about radians).

    Returns
    -------
    transform : ndarray, shape (4, 4), or None
        None when fewer than 8 usable correspondences or PoseLib finds no model.
    inliers : ndarray of bool, shape (N,)
    """
    import poselib

    inliers = np.zeros(len(rays0), dtype=bool)
    with np.errstate(invalid="ignore"):
        use = (rays0[:, 2] > math.cos(max_angle)) & (rays1[:, 2] > math.cos(max_angle))
    if use.sum() < 8:
        return None, inliers
    x0 = rays0[use, :2] / rays0[use, 2:]
    x1 = rays1[use, :2] / rays1[use, 2:]
    cam = {"model": "PINHOLE", "width": 2, "height": 2, "params": [1.0, 1.0, 0.0, 0.0]}
    pose, info = poselib.estimate_relative_pose(
        x0, x1, cam, cam, {"max_epipolar_error": threshold, "seed": seed}, {})
    mask = np.asarray(info.get("inliers", []), dtype=bool)
    if mask.sum() < 8:
        return None, inliers
    inliers[np.flatnonzero(use)[mask]] = True
    t = np.asarray(pose.t, dtype=np.float64)
    norm = np.linalg.norm(t)
    if not np.isfinite(norm) or norm == 0:
        return None, inliers
    return make_transform(np.asarray(pose.R, dtype=np.float64), t / norm), inliers


class PoseTracker:
    """``world_from_cam`` for each frame of a stream, the world being the first camera's frame.

    Parameters
    ----------
    camera : CameraModel
    step : float
        Translation per frame (the scale the images cannot give).
    mask : ndarray of bool, shape (H, W), optional
        Pixels to track corners in (e.g. without the vehicle's own body).
    """

    def __init__(self, camera: CameraModel, *, step: float = 1.0,
                 mask: NDArray | None = None) -> None:
        self.camera, self.step_length, self.mask = camera, float(step), mask
        self._last: NDArray[np.uint8] | None = None
        self.pose = np.eye(4)
        self.inlier_ratio = math.nan

    def step(self, gray: NDArray[np.uint8], exclude: NDArray[np.bool_] | None = None
             ) -> NDArray[np.float64] | None:
        """``cam_now_from_cam_before`` (unit translation) between the previous frame and this
        one, or None (the first frame, too little motion, no model). ``exclude`` (H, W): pixels
        of the previous frame to leave out (what the detector found moving there)."""
        last, self._last = self._last, gray.copy()
        if last is None:
            return None
        mask = self.mask if exclude is None else (
            (np.ones(gray.shape, bool) if self.mask is None else self.mask) & ~exclude)
        u0, u1 = track_corners(last, gray, mask=mask, corners=800)
        r0, ok0 = self.camera.unproject(u0)
        r1, ok1 = self.camera.unproject(u1)
        ok = ok0 & ok1
        moved = np.linalg.norm(u1 - u0, axis=-1)
        if ok.sum() < 8 or np.median(moved[ok]) <= 0.3:  # a still camera has no baseline
            return None
        transform, inliers = relative_pose(r0[ok], r1[ok])
        self.inlier_ratio = float(inliers.mean())
        return transform

    def __call__(self, gray: NDArray[np.uint8],
                 exclude: NDArray[np.bool_] | None = None) -> NDArray[np.float64]:
        """The pose of this frame (see :meth:`step`; no usable motion: the camera is taken to
        stand still)."""
        transform = self.step(gray, exclude)
        if transform is not None:
            transform[:3, 3] *= self.step_length
            self.pose = self.pose @ np.linalg.inv(transform)
        return self.pose.copy()
