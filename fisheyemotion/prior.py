"""Ego-motion-guided flow: the flow a static scene would have, as the flow method's start.

Every pixel's ray is followed to the road plane (below the horizon) or to a point at
``distance`` metres (above it, and where the road is farther than that); the point is projected
into the current camera. Large road displacements near the bottom of a fisheye image are then
found by Farneback or DIS, which otherwise underestimate them and make the static road look like
it sinks below the road plane (the positive-height term firing on static ground).
"""

from __future__ import annotations

import cv2
import numpy as np
from numpy.typing import NDArray

from .calib.base import CameraModel, pixel_grid
from .road import Road

#: Rays closer than this to the horizon (sine) use the fixed distance.
_HORIZON_SIN = 0.02


class EgoFlowPrior:
    """Predicted static-scene flow for one camera, computed on a coarse grid and upsampled.

    Parameters
    ----------
    camera : CameraModel
    distance : float
        Metres along rays that do not meet the road within that distance.
    step : int
        Grid stride (pixels) of the prediction before bilinear upsampling.
    """

    def __init__(self, camera: CameraModel, *, distance: float = 15.0, step: int = 8) -> None:
        self.camera, self.distance, self.step = camera, float(distance), int(step)
        grid = pixel_grid(camera.width, camera.height)[::step, ::step]
        self._pixels = grid
        self._rays, self._valid = camera.unproject(grid)

    def __call__(self, pose0: NDArray, pose1: NDArray, road: Road) -> NDArray[np.float32]:
        """Flow ``(H, W, 2)`` float32 from the ``pose0`` frame to the ``pose1`` frame."""
        dirs = self._rays @ pose0[:3, :3].T
        centre0 = pose0[:3, 3]
        height = float(road.height(centre0))
        down = dirs @ -road.up
        with np.errstate(invalid="ignore", divide="ignore"):
            to_road = np.where((down > _HORIZON_SIN) & (height > 0), height / down, np.inf)
        depth = np.minimum(to_road, self.distance)
        points = centre0 + depth[..., None] * dirs
        seen = (points - pose1[:3, 3]) @ pose1[:3, :3]
        pixels, ok = self.camera.project(seen)
        flow = np.where((ok & self._valid)[..., None], pixels - self._pixels, 0.0).astype(np.float32)
        h, w = self.camera.height, self.camera.width
        # Coarse sample j sits at pixel step * j: look up fractional sample x / step.
        xs = (np.arange(w, dtype=np.float32) / self.step)[None, :].repeat(h, 0)
        ys = (np.arange(h, dtype=np.float32) / self.step)[:, None].repeat(w, 1)
        return cv2.remap(flow, xs, ys, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
