"""The road plane in the user's world frame, estimated from the stream itself.

Users' poses come in their own world frame (a SLAM map, the first camera, an odometry frame): the
road is rarely ``z = 0``. :class:`GroundEstimator` tracks corners in the lower image between
consecutive frames (OpenCV's pyramidal Lucas-Kanade, forward-backward checked, against the second
frame warped back by the flow the road found so far, or a provisional one, predicts: the tracker
measures the residual from there, so a wrong prediction is corrected rather than followed, as a
dense flow's smoothing would), triangulates them with the poses, and fits a plane to the points
below the camera: RANSAC (scikit-image's) with a plane model, then a least-squares fit to the
inliers.

A fit is accepted when it is plausible:

- at least ``min_points`` candidate points and ``min_inlier_share`` of them on the plane
  (within ``tolerance`` metres per metre of range);
- the camera above it by ``min_height``..``max_height`` metres (``camera_height`` +-25 % when
  given);
- its normal within ``max_tilt`` (8 deg) of :func:`level_up`, the camera's up with its pitch
  removed by the direction of travel (a vehicle camera's road normal, up to its roll).

Before a plausible fit, the road is :meth:`fisheyemotion.Road.unknown`: the constraints that
need a road (height, anti-parallel, ground contact) are off, the others work.
"""

from __future__ import annotations

import warnings

import numpy as np
from numpy.typing import NDArray

from .road import Road
from .static_scene import TRIANGULATION_PARALLAX, triangulate_range, world_points
from .tracks import track_corners

#: Rounds of re-selecting the inliers of the least-squares plane and refitting.
REFINE_ROUNDS = 2
#: Metres to points whose ray does not meet the road, for the corners' predicted positions.
PREDICTION_DISTANCE = 1000.0

__all__ = ["GroundEstimator", "PlaneModel", "check_road"]


class PlaneModel:
    """``n . x = d`` with unit ``n``, for :func:`skimage.measure.ransac`. Residuals are distances
    to the plane divided by each point's range from the camera: triangulated depth errors grow
    with range, so a fixed tolerance would keep only the nearest points."""

    def __init__(self, normal: NDArray | None = None, offset: float = 0.0) -> None:
        self.normal, self.offset = normal, offset

    @classmethod
    def from_estimate(cls, points: NDArray[np.float64], ranges: NDArray | None = None
                      ) -> PlaneModel:
        centre = points.mean(axis=0)
        try:
            _, s, vt = np.linalg.svd(points - centre, full_matrices=False)
        except np.linalg.LinAlgError:
            return cls()
        if len(points) < 3 or s[1] < 1e-9:
            return cls()
        n = vt[-1]
        return cls(n, float(n @ centre))

    def __bool__(self) -> bool:
        return self.normal is not None

    def residuals(self, points: NDArray[np.float64], ranges: NDArray[np.float64]
                  ) -> NDArray[np.float64]:
        return np.abs(points @ self.normal - self.offset) / ranges


#: The road's corner tracking once a road is found (the next frame warped by it): Lucas-Kanade
#: from one pyramid level, 10 iterations a level. Measured (`docs/measurements.py
#: road_estimates`, the first 12 frames; tilt median / 90th percentile, tracking time a pair):
#: on its six scenes, OpenCV's four levels and 20 iterations 0.008 / 0.022 deg, 14.2 ms; one
#: level 0.005 / 0.013 deg, 6.9 ms; and 10 iterations 0.004 / 0.012 deg; on six other demo
#: scenes, 0.004 / 0.017 and 0.004 / 0.016 deg. Corners found at half resolution as well were
#: faster still (4 ms) but, on a 320x240 camera, tilted the road up to 0.12 deg; without the
#: backward check the road was 0.012 / 0.039 deg off.
ROAD_TRACKING = {"levels": 1, "iterations": 10}

#: Metres below the camera of the provisional road while none is known (and no height given).
PROVISIONAL_HEIGHT = 1.0


def provisional_road(pose: NDArray, pose_next: NDArray, height: float | None) -> Road:
    """A road guessed before one is found: ``height`` (or ``PROVISIONAL_HEIGHT``) below the
    camera, its normal :func:`level_up`. For predictions only (the prior's warp, where corners
    are looked for), never for the constraints."""
    up = level_up(pose, pose_next)
    return Road(normal=tuple(up), offset=float(up @ pose[:3, 3]) - (height or PROVISIONAL_HEIGHT))


def level_up(pose: NDArray, pose_next: NDArray) -> NDArray[np.float64]:
    """The camera's "up" with its pitch removed: minus its image-down axis, with the direction of
    travel (from ``pose`` to ``pose_next``) projected out. A vehicle moves parallel to its road,
    so for a vehicle camera this is the road's normal up to the camera's roll."""
    down = pose[:3, 1].copy()
    travel = pose_next[:3, 3] - pose[:3, 3]
    norm = np.linalg.norm(travel)
    if norm > 1e-6:
        t = travel / norm
        down -= (down @ t) * t
    return -down / np.linalg.norm(down)


class GroundEstimator:
    """Fits the road plane to static world points seen below the camera.

    Parameters
    ----------
    camera_height : float, optional
        Metres, when known: the fit must put the camera this high (+-25 %).
    min_points : int
    min_inlier_share : float
    tolerance : float
        RANSAC's inlier distance, metres per metre of range from the camera.
    min_height, max_height : float
        Metres: the plausible camera heights when ``camera_height`` is not given.
    seed : int
        RANSAC's random generator (reproducible runs).
    """

    def __init__(self, *, camera_height: float | None = None, min_points: int = 100,
                 min_inlier_share: float = 0.2, tolerance: float = 0.02,
                 min_height: float = 0.2, max_height: float = 5.0, seed: int = 0) -> None:
        if camera_height is not None and (not np.isfinite(camera_height) or camera_height <= 0):
            raise ValueError(f"camera_height: expected a positive number of metres, got "
                             f"{camera_height!r}")
        self.camera_height = camera_height
        self.min_points, self.min_inlier_share = int(min_points), float(min_inlier_share)
        self.tolerance, self.seed = float(tolerance), int(seed)
        lo, hi = (0.75 * camera_height, 1.25 * camera_height) if camera_height else (
            min_height, max_height)
        self.height_range = (float(lo), float(hi))
        self.road: Road | None = None
        self.inliers = 0
        self._points: list[NDArray[np.float64]] = []
        self._last: tuple[NDArray, NDArray] | None = None
        self._pairs = 0
        self.refit_every = 5
        self.max_tilt = 8.0
        self.early_pairs = 12
        # Once the road is found and the early pairs are in, corners are tracked on one pair in
        # this many (the tracking is the estimate's main cost: 15 ms a pair at 640x480, a fit 1 ms).
        self.settled_every = 3
        self._frames = 0
        # The road's predicted flow for the tracker's warp (per camera).
        self._prior = None

    def observe(self, camera, gray: NDArray[np.uint8], pose: NDArray, *,
                mask: NDArray | None = None) -> Road | None:
        """The next frame of the stream: track corners of the lower half of the previous frame
        observed into this one (consecutive frames keep the displacements small for the
        tracker), triangulate them with the poses, keep the points (the last few pairs) and try
        a fit (:meth:`fit`)."""
        if self._last is not None and np.array_equal(self._last[1], pose):
            return None  # this frame was observed already
        last, self._last = self._last, (gray.copy(), np.array(pose, dtype=np.float64))
        if last is None or np.linalg.norm(pose[:3, 3] - last[1][:3, 3]) < 1e-3:
            return None
        self._frames += 1
        if self.road is not None and self._pairs > self.early_pairs \
                and self._frames % self.settled_every:
            return None  # settled: track one consecutive pair in settled_every
        (gray0, pose0), gray1, pose1 = last, gray, pose

        h = gray0.shape[0]
        lower = np.zeros(gray0.shape, bool)
        lower[h // 2:] = True
        if mask is not None:
            lower &= np.asarray(mask, dtype=bool)
        # The road (or a provisional one) predicts where each road point goes: the tracker's
        # pyramid does not reach the road's displacements near a fast vehicle (60-100 px between
        # consecutive frames at the bottom of a fisheye image on a highway).
        found_before = self.road is not None
        road = self.road or provisional_road(pose0, pose1, self.camera_height)
        points = self._pair_points(camera, gray0, gray1, pose0, pose1, road, lower)
        if points is None:
            return None
        self._points = (self._points + [points])[-12:]
        self._pairs += 1
        # Refit with every pair while the point set is young, then now and then.
        if self.road is not None and self._pairs > self.early_pairs \
                and self._pairs % self.refit_every:
            return None
        fitted = self.fit(np.concatenate(self._points), pose0[:3, 3], pose0[:3, 1],
                          expected_up=level_up(pose0, pose1))
        if fitted is not None and not found_before:
            # The first road: track this pair again, warped by it rather than by the guess.
            again = self._pair_points(camera, gray0, gray1, pose0, pose1, fitted, lower)
            if again is not None:
                self._points[-1] = again
                fitted = self.fit(np.concatenate(self._points), pose0[:3, 3], pose0[:3, 1],
                                  expected_up=level_up(pose0, pose1)) or fitted
        return fitted

    def _pair_points(self, camera, gray0, gray1, pose0, pose1, road, lower):
        """World points of the corners tracked from ``gray0`` to ``gray1`` (:meth:`_warped_tracks`)
        and triangulated with the poses, or None when fewer than 10 are tracked."""
        u0, u1 = self._warped_tracks(camera, gray0, gray1, pose0, pose1, road, lower)
        if len(u0) < 10:
            return None
        r0, v0 = camera.unproject(u0)
        r1, v1 = camera.unproject(u1)
        lam, ok = triangulate_range(r0, r1, pose0, pose1, far=100.0,
                                    min_parallax=TRIANGULATION_PARALLAX)
        ok &= v0 & v1
        return world_points(r0[ok], lam[ok], pose0)

    def _warped_tracks(self, camera, gray0, gray1, pose0, pose1, road, lower):
        """Corners of ``gray0`` (in ``lower``) and where they are in ``gray1``: tracked against
        ``gray1`` warped back by the flow the road predicts (:class:`fisheyemotion.prior.
        EgoFlowPrior`, as the dense flow's warp), so that the tracker measures only a small
        residual, and the road's perspective and fisheye deformation between the frames, which
        biases a patch tracker, is undone (the road's tilt 0.016 deg median over the first 12
        frames of the demo scenes when corners started at their predicted positions instead,
        0.008 deg warped)."""
        import cv2

        from .flow import warp_by
        from .prior import EgoFlowPrior
        if self._prior is None or self._prior.camera is not camera:
            self._prior = EgoFlowPrior(camera, distance=PREDICTION_DISTANCE)
        prior, _ = self._prior(pose0, pose1, road)
        warped = warp_by(gray1, prior)
        # Warped by the road found, a road corner is within a pixel or two of its place: the
        # pyramid's coarse levels only lead patches away, and half the iterations do
        # (ROAD_TRACKING). Warped by the provisional road, whose height is a guess, the
        # displacements left can be tens of pixels near the camera: the full pyramid.
        settled = ROAD_TRACKING if self.road is not None else {}
        u0, r = track_corners(gray0, warped, mask=lower, **settled)
        if not len(u0):
            return u0, r
        at = r.astype(np.float32)
        # Channel by channel: one remap of the two-channel prior came out up to 0.4 px off a
        # bilinear interpolation on a rough field (each single-channel one within 1e-6).
        px = cv2.remap(prior[..., 0], at[:, 0:1], at[:, 1:2], cv2.INTER_LINEAR)[:, 0]
        py = cv2.remap(prior[..., 1], at[:, 0:1], at[:, 1:2], cv2.INTER_LINEAR)[:, 0]
        return u0, r + np.stack([px, py], axis=-1)

    def fit(self, points: NDArray[np.float64], centre: NDArray[np.float64],
            down: NDArray[np.float64], *, expected_up: NDArray | None = None) -> Road | None:
        """Fit to world ``points`` (N, 3) around the camera centre ``centre``; ``down`` is the
        camera's rough down direction (its image's y axis, in the world), used only to choose
        the candidates below it. Returns the road when the fit is plausible (also kept in
        :attr:`road`), else None."""
        rel = points - centre
        dist = np.linalg.norm(rel, axis=-1)
        with np.errstate(invalid="ignore", divide="ignore"):
            below = (rel @ down) / dist > 0.3  # at least ~17 deg below the camera's horizon
        from skimage.measure import ransac  # imports scipy.optimize: only when a road is fitted

        keep = below & (dist < 25.0) & np.isfinite(dist)
        cand, rng = points[keep], dist[keep]
        if len(cand) < self.min_points:
            return None
        model, inliers = ransac((cand, rng), PlaneModel, min_samples=3,
                                residual_threshold=self.tolerance, max_trials=200,
                                rng=np.random.default_rng(self.seed))
        if model is None or inliers is None or inliers.mean() < self.min_inlier_share:
            return None
        refined = PlaneModel.from_estimate(cand[inliers])
        for _ in range(REFINE_ROUNDS):  # the inliers of the least-squares plane, not RANSAC's
            if not refined:
                return None
            inliers = refined.residuals(cand, rng) < self.tolerance
            if inliers.sum() < 3:
                return None
            refined = PlaneModel.from_estimate(cand[inliers])
        if not refined:
            return None
        n, d = refined.normal, refined.offset
        height = float(n @ centre - d)
        if height < 0:
            n, d, height = -n, -d, -height
        lo, hi = self.height_range
        if not lo <= height <= hi:
            return None
        if expected_up is not None and n @ expected_up < np.cos(np.radians(self.max_tilt)):
            return None
        self.road, self.inliers = Road(normal=tuple(n), offset=float(d)), int(inliers.sum())
        return self.road


def check_road(road: Road, poses: NDArray[np.float64], source: str = "road", *,
               warn: bool = True) -> list[str]:
    """Warnings for a given road that is implausible for these camera poses (N, 4, 4): a camera
    on or under it, or far above it. Returns the messages (also issued as warnings unless
    ``warn`` is False, for callers that print them themselves)."""
    if not road.known:
        return []
    heights = road.height(poses[:, :3, 3])
    notes = []
    if (heights <= 0.05).any():
        i = int(np.argmin(heights))
        notes.append(f"{source}: the camera is on or under the road at pose {i} (height "
                     f"{heights[i]:.2f} m); is the road's normal pointing up in this world frame?")
    elif (heights > 10).all():
        notes.append(f"{source}: the camera is {np.median(heights):.1f} m above the road; is the "
                     "road in this world frame?")
    for note in notes if warn else ():
        warnings.warn(note, stacklevel=2)
    return notes
