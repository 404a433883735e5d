"""Ego-motion from the fisheye images themselves, for users without poses.

Corners are tracked between consecutive frames (:mod:`fisheyemotion.tracks`), unprojected to
rays with the camera model, and the relative pose is estimated by PoseLib (RANSAC over the
5-point minimal solver, then non-linear refinement). PoseLib takes image points of its own
camera models; rays within ``max_angle`` of the optical axis are given to it as points of the
unit pinhole camera ``(x/z, y/z)``, so any of this package's models (wider than 180 degrees
included) works, at the cost of the rays beyond that angle.

Each pair is first estimated fast (``FAST_*``): 300 corners found at half resolution and spread
over the image, tracked from where the last step and the road below predict them (constant
velocity: few are lost on the road near a fast vehicle, where the pyramid does not reach), ten
Lucas-Kanade iterations and no backward check; the last step, refined on the correspondences near
it (PoseLib's non-linear refinement), is the estimate when most of them are its inliers, else
PoseLib's RANSAC stopping once confident. A pair that this does not
settle (a rival motion, too few tracks, no road scale yet) is estimated again carefully: 800
full-resolution corners, PoseLib's default iterations.

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

__all__ = ["PoseTracker", "dominant_background_pose", "relative_pose", "road_depth",
           "road_scale"]

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


#: The fast estimate (measured on five demo scenes, 75 consecutive pairs in streams): 4.4-4.7 ms
#: a pair instead of 30 ms (the careful one), the rotation's error 0.018-0.026 deg median
#: (0.08 deg at most) instead of 0.011-0.018, the direction of travel's about twice the careful
#: one's. ``FAST_CORNERS`` corners found at half resolution, Lucas-Kanade's iterations capped at
#: ``FAST_LK_ITERATIONS``, PoseLib's RANSAC at ``FAST_THRESHOLD`` (unit pinhole image units, about
#: radians) for at most ``FAST_ITERATIONS`` iterations.
FAST_CORNERS, FAST_LK_ITERATIONS = 300, 10
FAST_THRESHOLD, FAST_ITERATIONS = 2e-3, 500
#: The fast estimate's tracks are not checked by tracking them back (``track_corners``'s
#: ``backward``): RANSAC and the refinement's robust loss leave out the few bad ones, and the
#: backward pass was a third of the step (measured over the demo scenes, 0.8.4: rotation error
#: 0.0309 -> 0.0308 deg median, direction 0.074 -> 0.076 deg, 1 ms a pair less).
FAST_BACKWARD = False
#: The last step as the guess of the next (``relative_pose``'s ``guess``): refined on the
#: correspondences within ``GUESS_TOLERANCE`` thresholds of it for ``GUESS_REFINE_ITERATIONS``
#: iterations, with a Cauchy loss at ``GUESS_LOSS`` thresholds, and kept if ``GUESS_SHARE`` of
#: the usable correspondences are its inliers. A vehicle's motion changes little in one frame;
#: measured over the demo scenes (0.8.4), with the backward pass dropped too: rotation error
#: 0.031 -> 0.030 deg median (0.154 -> 0.108 deg at most), direction 0.074 -> 0.064 deg, the
#: step 9.3 -> 5.7 ms. A second refinement on the first one's inliers alone removes the pull of
#: outliers within the tolerance (0.003 deg with a fifth of the correspondences wrong) but
#: measured worse on the demo scenes (direction 0.071 deg), as did loss scales of 0.25 and 2.
GUESS_TOLERANCE, GUESS_SHARE, GUESS_REFINE_ITERATIONS, GUESS_LOSS = 3.0, 0.6, 5, 0.5
#: ... and at least this many (PoseLib's default, 1000, is 10 ms a pair); the second hypothesis
#: (on the first one's outliers) at most ``SECOND_ITERATIONS``: a rival motion worth the name is
#: a large share of them, found in a few iterations, and on a street there is usually none, for
#: which RANSAC would run to its cap.
MIN_ITERATIONS = 30
SECOND_ITERATIONS = 100
#: The fast estimate is kept unless a second motion rivals it (a hypothesis fitted to the first
#: one's outliers with at least ``RIVAL_SHARE`` of its inliers: a large moving object such as the
#: Aria wearer's arm, 0.4-1.0 there, 0-0.3 on the demo scenes), fewer than ``FAST_MIN_TRACKS``
#: tracks support it (the Aria office's right camera with the arm left out: 47-77 tracks, up to
#: 1.4 deg off), or there is none. Then the pair is estimated again with the careful settings:
#: 800 full-resolution corners, 20 iterations, PoseLib at 1e-3 with its default iterations.
RIVAL_SHARE = 0.35
FAST_MIN_TRACKS = 100


def _pinhole_points(rays0: NDArray[np.float64], rays1: NDArray[np.float64], max_angle: float
                    ) -> tuple[NDArray[np.bool_], NDArray[np.float64], NDArray[np.float64]]:
    """The correspondences within ``max_angle`` of the optical axis in both views, as points
    ``(x/z, y/z)`` of the unit pinhole camera: ``(used, x0, x1)``."""
    with np.errstate(invalid="ignore"):
        use = (rays0[:, 2] > math.cos(max_angle)) & (rays1[:, 2] > math.cos(max_angle))
    return use, rays0[use, :2] / rays0[use, 2:], rays1[use, :2] / rays1[use, 2:]


_UNIT_PINHOLE = {"model": "PINHOLE", "width": 2, "height": 2, "params": [1.0, 1.0, 0.0, 0.0]}


def _transform(pose) -> NDArray[np.float64] | None:
    """A PoseLib pose as ``cam1_from_cam0`` with a unit translation (None if it has none)."""
    t = np.asarray(pose.t, dtype=np.float64)
    norm = np.linalg.norm(t)
    if not np.isfinite(norm) or norm == 0:
        return None
    return make_transform(np.asarray(pose.R, dtype=np.float64), t / norm)


def essential_matrix(cam1_from_cam0: NDArray[np.float64]) -> NDArray[np.float64]:
    """``E = [t]x R`` of ``cam1_from_cam0`` (3x3): ``p1 . E p0 = 0`` for corresponding rays (or
    homogeneous points) of a static point; ``E p0`` is the normal of their epipolar plane in
    camera 1."""
    r, t = cam1_from_cam0[:3, :3], cam1_from_cam0[:3, 3]
    return np.array([[0.0, -t[2], t[1]], [t[2], 0.0, -t[0]], [-t[1], t[0], 0.0]]) @ r


def sampson_errors(x0: NDArray[np.float64], x1: NDArray[np.float64],
                   cam1_from_cam0: NDArray[np.float64]) -> NDArray[np.float64]:
    """Sampson's first-order distance of unit-pinhole correspondences ``(N, 2)`` to the epipolar
    geometry of ``cam1_from_cam0`` (``E = [t]x R``), in the points' units: the error PoseLib's
    ``max_epipolar_error`` bounds."""
    e = essential_matrix(cam1_from_cam0)
    ex0 = x0 @ e[:, :2].T + e[:, 2]  # E (x0, 1)
    etx1 = x1 @ e[:2, :] + e[2, :]  # E^T (x1, 1)
    num = x1[:, 0] * ex0[:, 0] + x1[:, 1] * ex0[:, 1] + ex0[:, 2]
    den = ex0[:, 0] ** 2 + ex0[:, 1] ** 2 + etx1[:, 0] ** 2 + etx1[:, 1] ** 2
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.abs(num) / np.sqrt(den)


def _refined_guess(x0: NDArray[np.float64], x1: NDArray[np.float64], guess: NDArray[np.float64],
                   threshold: float) -> tuple[NDArray[np.float64] | None, NDArray[np.bool_]]:
    """``guess`` refined on the unit-pinhole correspondences within ``GUESS_TOLERANCE``
    thresholds of it (Cauchy loss at ``GUESS_LOSS`` thresholds), and its inliers; None if fewer
    than ``GUESS_SHARE`` of the correspondences are near it or inliers of the result."""
    import poselib

    least = max(8, GUESS_SHARE * len(x0))
    near = sampson_errors(x0, x1, guess) < GUESS_TOLERANCE * threshold
    if near.sum() < least:
        return None, near
    start = poselib.CameraPose()
    start.R, start.t = guess[:3, :3], guess[:3, 3]
    pose, _ = poselib.refine_relative_pose(
        x0[near], x1[near], start, _UNIT_PINHOLE, _UNIT_PINHOLE,
        {"loss_type": "CAUCHY", "loss_scale": GUESS_LOSS * threshold,
         "max_iterations": GUESS_REFINE_ITERATIONS})
    transform = _transform(pose)
    if transform is None:
        return None, near
    inliers = sampson_errors(x0, x1, transform) < threshold
    return (transform if inliers.sum() >= least else None), inliers


def relative_pose(rays0: NDArray[np.float64], rays1: NDArray[np.float64], *,
                  max_angle: float = math.radians(75.0), threshold: float = 1e-3,
                  max_iterations: int = 100000, min_iterations: int = 1000,
                  seed: int = 0, guess: NDArray[np.float64] | None = None,
                  ) -> tuple[NDArray[np.float64] | None, NDArray[np.bool_]]:
    """``cam1_from_cam0`` (4x4, unit translation) from ray correspondences ``(N, 3)``.

    Parameters
    ----------
    max_angle : float
        Radians off the optical axis in both views for a correspondence to be used.
    threshold : float
        RANSAC inlier threshold in the unit pinhole's image units (about radians).
    max_iterations, min_iterations : int
        RANSAC's iterations at most and at least (PoseLib's defaults); it stops in between once
        it is confident it has the best model.
    guess : ndarray, shape (4, 4), optional
        A motion expected to be close (a stream's last step): it is refined on the
        correspondences within ``GUESS_TOLERANCE`` thresholds of it (PoseLib's non-linear
        refinement, no sampling), and kept if at least ``GUESS_SHARE`` of them are inliers of
        the result; else RANSAC runs as without it.

    Returns
    -------
    transform : ndarray, shape (4, 4), or None
        None when fewer than 8 usable correspondences or PoseLib finds no model.
    inliers : ndarray of bool, shape (N,)
    """
    import poselib

    inliers = np.zeros(len(rays0), dtype=bool)
    use, x0, x1 = _pinhole_points(rays0, rays1, max_angle)
    if use.sum() < 8:
        return None, inliers
    if guess is not None:
        transform, mask = _refined_guess(x0, x1, guess, threshold)
        if transform is not None:
            inliers[np.flatnonzero(use)[mask]] = True
            return transform, inliers
    pose, info = poselib.estimate_relative_pose(
        x0, x1, _UNIT_PINHOLE, _UNIT_PINHOLE,
        {"max_epipolar_error": threshold, "seed": seed, "max_iterations": int(max_iterations),
         "min_iterations": min(int(max_iterations), int(min_iterations))}, {})
    mask = np.asarray(info.get("inliers", []), dtype=bool)
    if mask.sum() < 8:
        return None, inliers
    inliers[np.flatnonzero(use)[mask]] = True
    return _transform(pose), inliers


def road_scale(rays0: NDArray[np.float64], rays1: NDArray[np.float64],
               cam1_from_cam0: NDArray[np.float64], camera_height: float, *,
               tolerance: float = math.radians(0.3)) -> float | None:
    """Metres per unit of ``cam1_from_cam0``'s translation: ``camera_height`` over
    :func:`road_depth` (None where that is None)."""
    depth = road_depth(rays0, rays1, cam1_from_cam0, tolerance=tolerance)
    return None if depth is None else camera_height / depth


def road_depth(rays0: NDArray[np.float64], rays1: NDArray[np.float64],
               cam1_from_cam0: NDArray[np.float64], *,
               tolerance: float = math.radians(0.3)) -> float | None:
    """The road's depth below the first camera in units of ``cam1_from_cam0``'s translation,
    from the road seen in both views.

    Parameters
    ----------
    rays0, rays1 : ndarray, shape (N, 3)
        Corresponding rays, each in its camera's frame; those more than ``tolerance`` off
        their epipolar plane are left out (the pose's RANSAC inliers are too few here: its
        threshold is in pinhole units, which magnify the errors of wide rays).
    cam1_from_cam0 : ndarray, shape (4, 4)
        The relative pose, translation of any length.
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
    normal = rays0 @ essential_matrix(cam1_from_cam0).T  # each pair's epipolar plane, camera 1
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
    return float(np.exp(np.median(logs[near])))


def _still(moved: NDArray[np.float64]) -> bool:
    """Whether tracks that moved by ``moved`` pixels (at least 8) say the camera stood still."""
    return len(moved) >= 8 and bool(np.median(moved) <= STILL_PIXELS)


def _spread(pixels: NDArray[np.float64], shape: tuple[int, ...]) -> int:
    """Cells of a ``SPREAD_CELLS`` x ``SPREAD_CELLS`` grid over the image that ``pixels`` occupy."""
    h, w = shape[:2]
    c = np.clip((pixels[:, 0] * SPREAD_CELLS / w).astype(int), 0, SPREAD_CELLS - 1)
    r = np.clip((pixels[:, 1] * SPREAD_CELLS / h).astype(int), 0, SPREAD_CELLS - 1)
    return len(np.unique(r * SPREAD_CELLS + c))


def dominant_background_pose(rays0: NDArray[np.float64], rays1: NDArray[np.float64],
                             pixels0: NDArray[np.float64], shape: tuple[int, ...], **ransac
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
    **ransac
        ``threshold``, ``max_iterations`` of :func:`relative_pose`.
    """
    return _background(*_two_hypotheses(rays0, rays1, **ransac), pixels0, shape)


def _background(first, inliers, second, others, pixels0, shape):
    """Of two hypotheses (:func:`_two_hypotheses`), the one whose inliers cover more of the
    image: ``(pose, inliers)``."""
    if second is not None and _spread(pixels0[others], shape) > _spread(pixels0[inliers], shape):
        return second, others
    return first, inliers


def rival_iterations(inliers: int, rest: int, *, confidence: float = 0.99) -> int:
    """RANSAC iterations that find, with ``confidence``, a rival motion among ``rest`` outliers
    of a first hypothesis with ``inliers`` inliers: a rival has at least ``RIVAL_SHARE`` of
    ``inliers`` among them, so at least that inlier ratio ``w``, and a minimal sample of 5 is
    all its own with probability ``w^5`` (at least ``MIN_ITERATIONS``)."""
    w = min(1.0, RIVAL_SHARE * inliers / max(rest, 1))
    if w >= 1.0:
        return MIN_ITERATIONS
    return max(MIN_ITERATIONS, math.ceil(math.log(1 - confidence) / math.log(1 - w ** 5)))


def _two_hypotheses(rays0, rays1, second_iterations=None, **ransac):
    """:func:`relative_pose`, and again on its outliers (at most ``second_iterations``):
    ``(first, inliers, second, others)`` (``second`` None, ``others`` all False, where there is
    no second)."""
    first, inliers = relative_pose(rays0, rays1, **ransac)
    ransac.pop("guess", None)  # the rival is any other motion
    others = np.zeros_like(inliers)
    rest = ~inliers
    if first is None or rest.sum() < MIN_SECOND_HYPOTHESIS:
        return first, inliers, None, others
    if second_iterations is not None:
        ransac = {**ransac, "max_iterations": min(second_iterations,
                                                  rival_iterations(inliers.sum(), rest.sum()))}
    second, inliers2 = relative_pose(rays0[rest], rays1[rest], **ransac)
    if second is not None:
        others[np.flatnonzero(rest)[inliers2]] = True
    return first, inliers, second, others


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
        # The last step (cam_now_from_cam_before, unit translation) and the road's depth below
        # the camera in units of that step: the next pair's corners start where they predict.
        self._motion: NDArray[np.float64] | None = None
        self._depths: list[float] = []
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

    @property
    def scale(self) -> float | None:
        """Metres per unit of :meth:`step`'s translation (the median of the last
        ``SCALE_MEMORY`` road measurements), or None before the first."""
        return float(np.median(self._scales)) if self._scales else None

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
        transform, inliers, r0, r1, moved, contested = self._estimate(last, gray, mask, fast=True)
        careful = not _still(moved) and (transform is None or contested
                                         or len(moved) < FAST_MIN_TRACKS)
        depth = None
        if not careful and transform is not None:
            depth = self._road_depth(r0, r1, transform)
            # A scale wanted, none measured yet, and too few road tracks for one: look harder.
            careful = self.camera_height is not None and depth is None and not self._scales
        if careful:
            transform, inliers, r0, r1, moved, _ = self._estimate(last, gray, mask, fast=False)
            depth = None if transform is None else self._road_depth(r0, r1, transform)
        self.still = _still(moved)
        if len(moved) < 8 or self.still:  # a still camera has no baseline
            return None
        self.inlier_ratio = float(inliers.mean())
        self._motion = None if transform is None else transform.copy()
        if depth is not None:
            self._depths = (self._depths + [depth])[-SCALE_MEMORY:]
            if self.camera_height is not None:
                self._scales = (self._scales + [self.camera_height / depth])[-SCALE_MEMORY:]
        return transform

    def _predictor(self):
        """Where the last step and the road below would take a pixel of the previous frame
        (constant velocity), or None before there is one."""
        if self._motion is None or not self._depths:
            return None
        from .ground import PREDICTION_DISTANCE, provisional_road
        from .prior import static_scene_targets

        pose0, pose1 = np.eye(4), np.linalg.inv(self._motion)
        road = provisional_road(pose0, pose1, float(np.median(self._depths)))

        def predict(pixels):
            rays, _ = self.camera.unproject(pixels)
            return static_scene_targets(self.camera, rays, pose0, pose1, road,
                                        PREDICTION_DISTANCE)[0]
        return predict

    def _road_depth(self, r0, r1, transform) -> float | None:
        return road_depth(r0, r1, transform, tolerance=EPIPOLAR_PIXELS * self._pixel_angle)

    def _estimate(self, last, gray, mask, *, fast: bool):
        """Track and estimate one pair: ``(transform, inliers, rays0, rays1, displacements,
        contested)`` over the tracks with rays in both frames (``contested``: a second motion
        rivals the first, ``RIVAL_SHARE``)."""
        if fast:
            # Corners spread over the image (at most one per ~spacing^2 pixels): the strongest
            # few hundred crowd onto a high-contrast object (a car), whose motion is not ours.
            spacing = int(0.6 * math.sqrt(gray.shape[0] * gray.shape[1] / FAST_CORNERS))
            u0, u1 = track_corners(last, gray, mask=mask, corners=FAST_CORNERS, detect_scale=2,
                                   iterations=FAST_LK_ITERATIONS, fb_tolerance=1.0,
                                   min_distance=spacing, predict=self._predictor(),
                                   backward=FAST_BACKWARD)
            ransac = {"threshold": FAST_THRESHOLD, "max_iterations": FAST_ITERATIONS,
                      "min_iterations": MIN_ITERATIONS, "second_iterations": SECOND_ITERATIONS,
                      "guess": self._motion}
        else:
            u0, u1 = track_corners(last, gray, mask=mask, corners=800)
            ransac = {}
        r0, ok0 = self.camera.unproject(u0)
        r1, ok1 = self.camera.unproject(u1)
        ok = ok0 & ok1
        r0, r1, u0 = r0[ok], r1[ok], u0[ok]
        moved = np.linalg.norm(u1[ok] - u0, axis=-1)
        if len(moved) < 8 or _still(moved):
            return None, np.zeros(len(moved), bool), r0, r1, moved, False
        first, inliers, second, others = _two_hypotheses(r0, r1, **ransac)
        contested = second is not None and others.sum() >= RIVAL_SHARE * inliers.sum()
        transform, inliers = _background(first, inliers, second, others, u0, gray.shape)
        return transform, inliers, r0, r1, moved, contested

    def __call__(self, gray: NDArray[np.uint8],
                 exclude: NDArray[np.bool_] | None = None) -> NDArray[np.float64]:
        """The pose of this frame (see :meth:`step`; no usable motion: the camera is taken to
        stand still)."""
        transform = self.step(gray, exclude)
        if transform is not None:
            scale = self.scale
            transform[:3, 3] *= self.step_length if scale is None else scale
            self.pose = self.pose @ np.linalg.inv(transform)
        return self.pose.copy()
