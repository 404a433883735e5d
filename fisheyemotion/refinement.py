"""Given poses refined on the images (``Params.pose_refinement``).

Odometry or a loosely synchronised IMU gives every frame's pose with an error of its own (tenths
of a degree); the images give the motion between consecutive frames ten times more precisely,
but nothing absolute. :class:`PoseRefiner` keeps both for what each is good at:

- a **chain** of relative motions: each step's rotation and direction of travel from the images
  (:class:`~fisheyemotion.egomotion.PoseTracker`) where they disagree with the given step by more
  than the tolerance (``auto``) or always (``on``), the step's length from the given poses (the
  images have no scale); the given step where they agree; no motion where the images see the
  camera standing still;
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
    """

    def __init__(self, camera: CameraModel, *, mode: str, tolerance: float,
                 mask: NDArray[np.bool_] | None = None) -> None:
        self.mode, self.tolerance = mode, tolerance
        self._tracker = PoseTracker(camera, mask=mask)
        self._given: NDArray[np.float64] | None = None
        self._chain: NDArray[np.float64] | None = None
        self._window: deque[tuple[NDArray, NDArray]] = deque(maxlen=ANCHOR_FRAMES)
        #: The last step's anchor, ``world_from_chain`` (4x4).
        self.anchor = np.eye(4)

    def step(self, gray: NDArray[np.uint8], pose: NDArray[np.float64],
             exclude: NDArray[np.bool_] | None = None) -> NDArray[np.float64]:
        """The chain's pose ``(4, 4)`` at this frame, given its pose in the world and the frame
        (``exclude``: pixels the detector found moving); :attr:`anchor` maps it to the world."""
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
