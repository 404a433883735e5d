"""Given poses refined on the images (``Params.pose_refinement``).

Odometry or a loosely synchronised IMU gives every frame's pose with an error of its own (tenths
of a degree); the images give the motion between consecutive frames ten times more precisely,
but nothing absolute. :class:`PoseRefiner` keeps both for what each is good at:

- a **chain** of relative motions: each step's rotation and direction of travel from the images
  (:class:`~fisheyemotion.egomotion.PoseTracker`) where they disagree with the given step by more
  than the tolerance (``auto``) or always (``on``); the given step where they agree; no motion
  where the images see the camera standing still. The step's length: where the camera's height
  above the road is known (``camera_height``, or the given poses' median height over the last
  :data:`ANCHOR_FRAMES` frames above a given ``road``), from the road the images show, as the
  pose tracker measures it for a stream without poses (the median of its last few steps); else,
  and until the road has been measured, the given step's length. Given positions a few per cent
  of a step off put each step's length that far off, and the next pair's prior reuses scene
  points triangulated over a baseline with another error; the road measures each step within
  about 1 % (docs/evaluation.md, noisy poses);
- an **anchor** ``world_from_chain``, the chain's frame in the user's world: the rotation mean
  of ``R_given R_chain^T`` over the last :data:`ANCHOR_FRAMES` frames (each given pose's own
  error averages out, and the chain's drift is followed) and the translation that maps the
  chain's positions' centroid onto the given ones'.

The detector runs a frame pair with *one* anchor for both of its poses, so the pair's relative
pose is the chain's, untouched by the anchor's changes, while the road given in the world
(and everything else absolute) sees the camera within the averaged error: about
``sigma / sqrt(n)`` after ``n`` frames for given orientations off by ``sigma`` each
(docs/evaluation.md, noisy poses).
"""

from __future__ import annotations

from collections import deque

import numpy as np
from numpy.typing import NDArray

from .calib.base import CameraModel
from .calib.transforms import make_transform, mean_rotation, rotation_angle, vector_angle
from .egomotion import PoseTracker
from .road import Road

__all__ = ["ANCHOR_FRAMES", "DIRECTION_TOLERANCE", "PoseRefiner"]

#: ``auto`` also refines where the given direction of travel is off the images' by this many
#: times the rotation tolerance (the direction is measured less precisely).
DIRECTION_TOLERANCE = 5.0
#: Frames over which the given poses' absolute pose is averaged into the anchor.
ANCHOR_FRAMES = 30


class PoseRefiner:
    """Refine a stream's given poses frame by frame (see the module doc).

    Parameters
    ----------
    camera : CameraModel
    mode : {'on', 'auto'}
        ``on``: every step's rotation and direction from the images; ``auto``: where they
        disagree with the given step by more than ``tolerance`` degrees (rotation) or
        ``DIRECTION_TOLERANCE`` times that (direction).
    tolerance : float
        Degrees.
    mask : ndarray of bool, shape (H, W), optional
        Pixels to track corners in.
    camera_height : float, optional
        Metres above the road: each step's length from the road the images show (module doc).
        Without it, a ``road`` given to :meth:`step` gives the height.
    """

    def __init__(self, camera: CameraModel, *, mode: str, tolerance: float,
                 mask: NDArray[np.bool_] | None = None,
                 camera_height: float | None = None) -> None:
        self.mode, self.tolerance = mode, tolerance
        # Validated here; the height the tracker measures with is set at every step.
        self._tracker = PoseTracker(camera, mask=mask, camera_height=camera_height)
        self.camera_height = camera_height
        self._given: NDArray[np.float64] | None = None
        self._chain: NDArray[np.float64] | None = None
        self._window: deque[tuple[NDArray, NDArray]] = deque(maxlen=ANCHOR_FRAMES)
        #: The last step's anchor, ``world_from_chain`` (4x4).
        self.anchor = np.eye(4)

    def step(self, gray: NDArray[np.uint8], pose: NDArray[np.float64],
             exclude: NDArray[np.bool_] | None = None, *,
             road: Road | None = None) -> NDArray[np.float64]:
        """The chain's pose ``(4, 4)`` at this frame, given its pose in the world and the frame
        (``exclude``: pixels the detector found moving; ``road``: the road in the world, when
        known); :attr:`anchor` maps it to the world."""
        self._tracker.camera_height = self._height(pose, road)
        estimate = self._tracker.step(gray, exclude)
        given_before, chain_before = self._given, self._chain
        if chain_before is None:
            chain = pose.copy()
        else:
            # cam_now_from_cam_before of the given poses.
            given = np.linalg.inv(pose) @ given_before
            relative = given
            if estimate is not None:
                angle = np.degrees(rotation_angle(given[:3, :3].T @ estimate[:3, :3]))
                # The camera's displacement in the previous camera's frame, given and imaged.
                step_given = -given[:3, :3].T @ given[:3, 3]
                step_images = -estimate[:3, :3].T @ estimate[:3, 3]
                length = float(np.linalg.norm(step_given))
                off_course = (np.degrees(vector_angle(step_given, step_images))
                              if length > 1e-9 else 0.0)
                if self.mode == "on" or angle > self.tolerance \
                        or off_course > DIRECTION_TOLERANCE * self.tolerance:
                    r = estimate[:3, :3]
                    scale = self._tracker.scale  # the road's length (module doc), if measured
                    length = length if scale is None else scale
                    relative = make_transform(r, -r @ (step_images * length))
            elif self._tracker.still:
                # The images say the camera stood still: it did, whatever the given poses say.
                relative = np.eye(4)
            chain = chain_before @ np.linalg.inv(relative)
        self._given, self._chain = pose, chain
        self._window.append((pose, chain))
        given_all = np.stack([g for g, _ in self._window])
        chain_all = np.stack([c for _, c in self._window])
        rotation = mean_rotation(given_all[:, :3, :3] @ chain_all[:, :3, :3].transpose(0, 2, 1))
        self.anchor = make_transform(rotation, given_all[:, :3, 3].mean(axis=0)
                                     - rotation @ chain_all[:, :3, 3].mean(axis=0))
        return chain

    def _height(self, pose: NDArray[np.float64], road: Road | None) -> float | None:
        """The camera's height above the road for this step: ``camera_height``, or the median of
        the given poses' heights above ``road`` over the window and this frame (None where
        neither is known or the given poses are not above the road)."""
        if self.camera_height is not None:
            return self.camera_height
        if road is None or not road.known:
            return None
        positions = np.stack([pose[:3, 3], *(g[:3, 3] for g, _ in self._window)])
        height = float(np.median(road.height(positions)))
        return height if np.isfinite(height) and height > 0 else None
