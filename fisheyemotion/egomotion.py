"""Ego-motion from the fisheye images themselves, for users without poses.

Corners are tracked between consecutive frames (:mod:`fisheyemotion.tracks`), unprojected to
rays with the camera model, and the relative pose is estimated by PoseLib (RANSAC over the
5-point minimal solver, then non-linear refinement). PoseLib takes image points of its own
camera models; rays within ``max_angle`` of the optical axis are given to it as points of the
unit pinhole camera ``(x/z, y/z)``, so any of this package's models (wider than 180 degrees
included) works, at the cost of the rays beyond that angle.

Scale: two views fix the translation's direction only. With the camera's height above the road
known (``camera_height``), each step's length comes from the road: the correspondences well
below the horizon (more than ``ROAD_ELEVATION`` down, where a vehicle camera sees its road) are
triangulated with a unit baseline, their most common depth below the camera along the level
"up" (the camera's up with the direction of travel projected out,
:func:`fisheyemotion.ground.level_up`; :func:`road_scale`) is the camera height in those units,
and the step is ``camera_height`` over it (the median of the last ``SCALE_MEMORY`` steps'
estimates, which steadies it). Otherwise the trajectory is chained with
a translation of ``step`` (default 1, arbitrary units) per frame: enough for the epipolar and
positive-depth constraints, which do not depend on scale, but the road terms need metres, so the
detector then runs with ``Road.unknown()``.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from .calib.base import CameraModel
from .calib.transforms import make_transform
from .tracks import track_corners

__all__ = ["PoseTracker", "dominant_background_pose", "relative_pose", "road_scale"]

#: Degrees below the level horizon from which correspondences are taken to lie on the road.
ROAD_ELEVATION = 20.0
#: Steps whose scale estimates are combined (median).
SCALE_MEMORY = 5
#: Pixels (their angle at the image centre) a road correspondence may lie off its epipolar plane.
EPIPOLAR_PIXELS = 1.5
#: Degrees of parallax a road correspondence needs (its range error is about the flow error
#: over this).
MIN_PARALLAX = 1.0
#: Median corner displacement (pixels) at or below which the camera is taken to stand still.
STILL_PIXELS = 0.3
#: Grid (per side) over which the spread of a pose hypothesis' inliers is counted.
SPREAD_CELLS = 8
#: Fewest outliers of the first hypothesis to fit a second one to.
MIN_SECOND_HYPOTHESIS = 30
#: Fewest road correspondences for a scale estimate.
MIN_ROAD_POINTS = 15


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


def road_scale(rays0: NDArray[np.float64], rays1: NDArray[np.float64],
               cam1_from_cam0: NDArray[np.float64], camera_height: float, *,
               tolerance: float = math.radians(0.3)) -> float | None:
    """Metres per unit of ``cam1_from_cam0``'s translation, from the road seen in both views.

    Parameters
    ----------
    rays0, rays1 : ndarray, shape (N, 3)
        Corresponding rays, each in its camera's frame; those more than ``tolerance`` off
        their epipolar plane are left out (the pose's RANSAC inliers are too few here: its
        threshold is in pinhole units, which magnify the errors of wide rays).
    cam1_from_cam0 : ndarray, shape (4, 4)
        The relative pose, translation of any length.
    camera_height : float
        Metres above the road.
    tolerance : float
        Radians off the epipolar plane (:class:`PoseTracker` uses ``EPIPOLAR_PIXELS`` pixels'
        angle at the image centre).

    Returns
    -------
    float or None
        None when fewer than ``MIN_ROAD_POINTS`` correspondences lie well below the horizon
        and triangulate.
    """
    from .ground import level_up
    from .static_scene import triangulate_range

    pose0, pose1 = np.eye(4), np.linalg.inv(cam1_from_cam0)
    up = level_up(pose0, pose1)
    rotation, t = cam1_from_cam0[:3, :3], cam1_from_cam0[:3, 3]
    normal = np.cross(t, rays0 @ rotation.T)  # the epipolar plane of each pair, camera 1
    with np.errstate(invalid="ignore", divide="ignore"):
        off_plane = np.abs(np.einsum("ij,ij->i", normal, rays1)) / np.linalg.norm(normal, axis=-1)
        low = (-(rays0 @ up) > math.sin(math.radians(ROAD_ELEVATION))) & (
            off_plane < math.sin(tolerance))
    if low.sum() < MIN_ROAD_POINTS:
        return None
    lam, ok = triangulate_range(rays0[low], rays1[low], pose0, pose1, far=1e6,
                                min_parallax=math.radians(MIN_PARALLAX))
    if ok.sum() < MIN_ROAD_POINTS:
        return None
    depth_below = -(lam[ok, None] * rays0[low][ok]) @ up
    depth_below = depth_below[depth_below > 0]
    if len(depth_below) < MIN_ROAD_POINTS:
        return None
    # The road is the most common depth below the camera (the mode, in 2 % bins of its
    # logarithm, smoothed over three): obstacles read shallower, objects moving along the
    # direction of travel (epipolar-consistent) deeper, and either can outnumber the half.
    logs = np.log(depth_below)
    counts, edges = np.histogram(logs, bins=np.arange(logs.min() - 0.02, logs.max() + 0.04, 0.02))
    smooth = np.convolve(counts, np.ones(3), mode="same")
    k = int(np.argmax(smooth))
    near = np.abs(logs - 0.5 * (edges[k] + edges[k + 1])) <= 0.03
    height = float(np.exp(np.median(logs[near])))
    return camera_height / height


def _spread(pixels: NDArray[np.float64], shape: tuple[int, ...]) -> int:
    """Cells of a ``SPREAD_CELLS`` x ``SPREAD_CELLS`` grid over the image that ``pixels`` occupy."""
    h, w = shape[:2]
    c = np.clip((pixels[:, 0] * SPREAD_CELLS / w).astype(int), 0, SPREAD_CELLS - 1)
    r = np.clip((pixels[:, 1] * SPREAD_CELLS / h).astype(int), 0, SPREAD_CELLS - 1)
    return len(np.unique(r * SPREAD_CELLS + c))


def dominant_background_pose(rays0: NDArray[np.float64], rays1: NDArray[np.float64],
                             pixels0: NDArray[np.float64], shape: tuple[int, ...]
                             ) -> tuple[NDArray[np.float64] | None, NDArray[np.bool_]]:
    """:func:`relative_pose`, checked against a second hypothesis fitted to its outliers: the one
    whose inliers cover more of the image wins. The static background spans the view; a moving
    object close to the camera (a wearer's arm, a passing bus) can hold more tracked corners, but
    in a compact part of the image.

    Parameters
    ----------
    rays0, rays1 : ndarray, shape (N, 3)
    pixels0 : ndarray, shape (N, 2)
        The corners' pixels in the first frame.
    shape : tuple
        The image's shape.
    """
    first, inliers = relative_pose(rays0, rays1)
    if first is None:
        return first, inliers
    rest = ~inliers
    if rest.sum() < MIN_SECOND_HYPOTHESIS:
        return first, inliers
    second, inliers2 = relative_pose(rays0[rest], rays1[rest])
    if second is None:
        return first, inliers
    others = np.zeros_like(inliers)
    others[np.flatnonzero(rest)[inliers2]] = True
    if _spread(pixels0[others], shape) > _spread(pixels0[inliers], shape):
        return second, others
    return first, inliers


class PoseTracker:
    """``world_from_cam`` for each frame of a stream, the world being the first camera's frame.

    Parameters
    ----------
    camera : CameraModel
    step : float
        Translation per frame (the scale the images cannot give).
    mask : ndarray of bool, shape (H, W), optional
        Pixels to track corners in (e.g. without the vehicle's own body).
    camera_height : float, optional
        Metres above the road: each step's length from the road (module docstring); ``step``
        until the first estimate.
    """

    def __init__(self, camera: CameraModel, *, step: float = 1.0,
                 mask: NDArray | None = None, camera_height: float | None = None) -> None:
        if camera_height is not None and not (math.isfinite(camera_height) and camera_height > 0):
            raise ValueError(f"camera_height: expected a positive number of metres, got "
                             f"{camera_height!r}")
        self.camera, self.step_length, self.mask = camera, float(step), mask
        self.camera_height = camera_height
        self._last: NDArray[np.uint8] | None = None
        self._scales: list[float] = []
        if camera_height is not None:
            from .significance import pixel_angle

            centre = np.array([[(camera.width - 1) / 2, (camera.height - 1) / 2]])
            self._pixel_angle = float(pixel_angle(camera, centre)[0])
        self.pose = np.eye(4)
        self.inlier_ratio = math.nan
        #: Whether the last :meth:`step` found the camera standing still (its corners moved
        #: ``STILL_PIXELS`` or less, median).
        self.still = False

    @property
    def metric(self) -> bool:
        """Whether the steps are in metres (a road scale has been measured)."""
        return bool(self._scales)

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
        self.still = ok.sum() >= 8 and np.median(moved[ok]) <= STILL_PIXELS
        if ok.sum() < 8 or self.still:  # a still camera has no baseline
            return None
        transform, inliers = dominant_background_pose(r0[ok], r1[ok], u0[ok], gray.shape)
        self.inlier_ratio = float(inliers.mean())
        if transform is not None and self.camera_height is not None:
            scale = road_scale(r0[ok], r1[ok], transform, self.camera_height,
                               tolerance=EPIPOLAR_PIXELS * self._pixel_angle)
            if scale is not None:
                self._scales = (self._scales + [scale])[-SCALE_MEMORY:]
        return transform

    def __call__(self, gray: NDArray[np.uint8],
                 exclude: NDArray[np.bool_] | None = None) -> NDArray[np.float64]:
        """The pose of this frame (see :meth:`step`; no usable motion: the camera is taken to
        stand still)."""
        transform = self.step(gray, exclude)
        if transform is not None:
            transform[:3, 3] *= float(np.median(self._scales)) if self._scales else self.step_length
            self.pose = self.pose @ np.linalg.inv(transform)
        return self.pose.copy()
