"""The poses the detector is given in an evaluation: the true ones, estimated from the images,
or the true ones with realistic noise; optionally refined on the images first.

- ``true``: the rendered sequence's poses.
- ``estimated``: every consecutive frame pair's rotation and translation direction from the
  images, and the step's length from the road and the camera's true height
  (:class:`fisheyemotion.egomotion.PoseTracker` with ``camera_height``, what a stream without
  poses runs), chained from the first true pose.
- ``perturbed``: the true poses with independent noise on every frame (:class:`Perturbation`:
  rotation, translation relative to the frame-to-frame step, and a time offset).

Refinement (``Params.pose_refinement`` ``on`` or ``auto``) runs the detector's own refinement
(:meth:`fisheyemotion.MotionDetector.apply` does it per frame) over the frames first.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
import pandas as pd
from fisheyemotion.calib.transforms import rotation_angle, vector_angle
from numpy.typing import NDArray

from fisheyemotion.egomotion import PoseTracker
from fisheyemotion.frames import to_gray
from fisheyemotion.params import Params
from fisheyemotion.poses import Trajectory
from fisheyemotion.refinement import PoseRefiner
from fisheyemotion.road import Road
from fisheyemotion.sequence import Sequence

__all__ = ["POSE_SOURCES", "GivenPoses", "Perturbation", "pose_errors", "poses_for"]

POSE_SOURCES = ("true", "estimated", "perturbed")


@dataclass(frozen=True, kw_only=True)
class Perturbation:
    """Noise of the ``perturbed`` poses, as odometry or a loosely synchronised IMU gives it.

    Attributes
    ----------
    rotation_deg : float
        Angle of a rotation about a random axis applied to every frame's orientation.
    translation : float
        Position error per frame, as a share of the frame-to-frame step, random direction.
    time_offset_s : float
        The poses are those of this many seconds later (interpolated).
    seed : int
    """

    rotation_deg: float = 0.3
    translation: float = 0.03
    time_offset_s: float = 0.005
    seed: int = 0

    def __post_init__(self) -> None:
        for name in ("rotation_deg", "translation", "time_offset_s"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int | float) \
                    or not math.isfinite(value) or value < 0:
                raise ValueError(f"{name}: expected a finite number >= 0, got {value!r}")
        if isinstance(self.seed, bool) or not isinstance(self.seed, int | np.integer) \
                or self.seed < 0:
            raise ValueError(f"seed: expected an integer >= 0, got {self.seed!r}")


def _rotation(axis: NDArray, angle: float) -> NDArray[np.float64]:
    import cv2

    return cv2.Rodrigues(np.asarray(axis, np.float64) / np.linalg.norm(axis) * angle)[0]


def _unit(rng: np.random.Generator) -> NDArray[np.float64]:
    v = rng.normal(size=3)
    return v / np.linalg.norm(v)


def perturbed(seq: Sequence, noise: Perturbation) -> NDArray[np.float64]:
    """The true poses with ``noise`` (see :class:`Perturbation`)."""
    truth = seq.poses
    stamps = seq.timestamps
    if noise.time_offset_s:
        late = Trajectory(truth, stamps=stamps).at(stamps + noise.time_offset_s,
                                                   max_gap=float(np.max(np.diff(stamps))))
    else:
        late = truth.copy()
    steps = np.linalg.norm(np.diff(truth[:, :3, 3], axis=0), axis=-1)
    step = np.r_[steps[:1], steps] if len(steps) else np.zeros(1)
    rng = np.random.default_rng(noise.seed)
    out = late.copy()
    for k in range(len(out)):
        out[k, :3, :3] = out[k, :3, :3] @ _rotation(_unit(rng), math.radians(noise.rotation_deg))
        out[k, :3, 3] += noise.translation * step[k] * _unit(rng)
    return out


def estimated(seq: Sequence, mask: NDArray | None) -> NDArray[np.float64]:
    """Poses from the images, each step's length from the road and the true camera height
    (see module doc), chained from the first true pose."""
    truth = seq.poses
    height = float(Road().height(truth[0, :3, 3]))  # the scenes' road is z = 0
    tracker = PoseTracker(seq.camera, mask=mask, camera_height=height)
    chained = [tracker(to_gray(seq.frame(k), "frame")) for k in range(len(seq))]
    return np.stack([truth[0] @ pose for pose in chained])


class GivenPoses(NamedTuple):
    """What the detector is given: ``poses`` ``(N, 4, 4)`` and the ``anchors`` ``(N, 4, 4)``
    that place them in the world. A pair ``(k - gap, k)`` runs with ``anchors[k] @ poses[k -
    gap]`` and ``anchors[k] @ poses[k]``, as :meth:`fisheyemotion.MotionDetector.apply` does:
    refined poses are a chain of relative motions whose anchor follows the given poses
    (:mod:`fisheyemotion.refinement`); otherwise the anchors are the identity."""

    poses: NDArray[np.float64]
    anchors: NDArray[np.float64]

    def pair(self, k: int, gap: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The world poses of frames ``k - gap`` and ``k`` as the pair ending at ``k`` uses
        them."""
        return self.anchors[k] @ self.poses[k - gap], self.anchors[k] @ self.poses[k]


def refined(seq: Sequence, poses: NDArray, params: Params, mask: NDArray | None, *,
            road: Road | None = None, camera_height: float | None = None) -> GivenPoses:
    """``poses`` refined on the images by the detector's own refinement, frame by frame, as
    :meth:`fisheyemotion.MotionDetector.apply` runs it with ``road`` (the scene's frame) or
    ``camera_height`` known."""
    refiner = PoseRefiner(seq.camera, mode=params.pose_refinement,
                          tolerance=params.refine_tolerance,
                          mask=seq.camera.valid_pixel_mask() & (True if mask is None else mask > 0),
                          camera_height=camera_height)
    chain, anchors = [], []
    for k in range(len(seq)):
        chain.append(refiner.step(to_gray(seq.frame(k), "frame"), poses[k], road=road))
        anchors.append(refiner.anchor)
    return GivenPoses(np.stack(chain), np.stack(anchors))


def poses_for(seq: Sequence, source: str, params: Params, *, noise: Perturbation | None = None,
              roi: NDArray | None = None, road: Road | None = None,
              camera_height: float | None = None) -> GivenPoses:
    """The poses (scene frame) the detector is given for ``source``, refined when
    ``params.pose_refinement`` says so (with the ``road`` in the scene's frame or the
    ``camera_height``, where the detector knows them)."""
    if source not in POSE_SOURCES:
        raise ValueError(f"poses: expected one of {', '.join(POSE_SOURCES)}, got {source!r}")
    if source == "true":
        poses = seq.poses
    elif source == "estimated":
        poses = estimated(seq, None if roi is None else roi > 0)
    else:
        poses = perturbed(seq, noise or Perturbation())
    if params.pose_refinement != "off":
        return refined(seq, poses, params, roi, road=road, camera_height=camera_height)
    return GivenPoses(poses, np.broadcast_to(np.eye(4), poses.shape))


def pose_errors(poses: NDArray, truth: NDArray, gap: int) -> pd.DataFrame:
    """Errors of the relative pose of every detected pair ``(k - gap, k)``: rotation (degrees)
    and translation direction (degrees; NaN where the true camera stood still)."""
    rows = []
    for k in range(gap, len(truth)):
        est = np.linalg.inv(poses[k]) @ poses[k - gap]
        tru = np.linalg.inv(truth[k]) @ truth[k - gap]
        t_est, t_tru = est[:3, 3], tru[:3, 3]
        direction = (math.degrees(vector_angle(t_est, t_tru))
                     if np.linalg.norm(t_est) > 1e-9 and np.linalg.norm(t_tru) > 1e-6
                     else math.nan)
        rows.append({"frame": k,
                     "rotation_error_deg": math.degrees(rotation_angle(est[:3, :3].T
                                                                       @ tru[:3, :3])),
                     "direction_error_deg": direction})
    return pd.DataFrame(rows)


def rig_disagreement(poses_a: NDArray, reference_from_a: NDArray, poses_b: NDArray,
                     reference_from_b: NDArray) -> NDArray[np.float64]:
    """How far two rigidly mounted cameras' pose estimates disagree on the rig's rotation
    (degrees, one value per consecutive pair of frames): each camera's motion between frames
    ``k`` and ``k + 1`` (``poses_*``: ``(N, 4, 4)`` ``world_from_cam`` at the same instants,
    each in a world frame of its own) expressed in the rig's reference frame
    (``reference_from_*``, the calibration's extrinsics) is the rig's motion, the same for
    both; the angle between the two is an error bound that needs no ground truth (about
    sqrt(2) times each camera's own rotation error, if the errors are independent)."""
    out = []
    for k in range(min(len(poses_a), len(poses_b)) - 1):
        motions = []
        for poses, extrinsics in ((poses_a, reference_from_a), (poses_b, reference_from_b)):
            r = extrinsics[:3, :3]
            step = np.linalg.inv(poses[k]) @ poses[k + 1]  # cam_k from cam_k+1
            motions.append(r @ step[:3, :3] @ r.T)
        out.append(math.degrees(rotation_angle(motions[0].T @ motions[1])))
    return np.asarray(out)
