"""Ego-motion-guided flow: the flow a static scene would have, as the flow method's start.

Every pixel's ray is followed to the road plane (below the horizon) or to a point at
``distance`` metres (above it, and where the road is farther than that); the point is projected
into the current camera. Large road displacements near the bottom of a fisheye image are then
found by Farneback or DIS, which otherwise underestimate them and make the static road look like
it sinks below the road plane (the positive-height term firing on static ground).
"""

from __future__ import annotations

from functools import cached_property

import cv2
import numpy as np
from numpy.typing import NDArray

from .calib.base import CameraModel, pixel_grid
from .road import Road

#: Rays closer than this to the horizon (sine) use the fixed distance.
_HORIZON_SIN = 0.02


def static_scene_targets(camera: CameraModel, rays: NDArray[np.float64], pose0: NDArray,
                         pose1: NDArray, road: Road, distance: float
                         ) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
    """Where the static scene seen along ``rays`` of the ``pose0`` camera is seen from ``pose1``.

    The scene point is the road point of the ray (below the horizon, closer than ``distance``)
    or the point at ``distance`` metres.

    Parameters
    ----------
    rays : ndarray, shape (..., 3)
        Camera-frame rays of the ``pose0`` camera (NaN where invalid).

    Returns
    -------
    pixels : ndarray, shape (..., 2)
        In the ``pose1`` image; NaN where the point leaves the camera's domain.
    valid : ndarray of bool, shape (...)
    """
    dirs = rays @ pose0[:3, :3].T
    centre0 = pose0[:3, 3]
    height = float(road.height(centre0))
    down = dirs @ -road.up
    with np.errstate(invalid="ignore", divide="ignore"):
        to_road = np.where((down > _HORIZON_SIN) & (height > 0), height / down, np.inf)
    depth = np.minimum(to_road, distance)
    points = centre0 + depth[..., None] * dirs
    return camera.project((points - pose1[:3, 3]) @ pose1[:3, :3])


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

    def __call__(self, pose0: NDArray, pose1: NDArray, road: Road, *,
                 view: NDArray[np.bool_] | None = None
                 ) -> tuple[NDArray[np.float32], NDArray[np.bool_]]:
        """The predicted flow from the ``pose0`` frame to the ``pose1`` frame, and where it is seen.

        Parameters
        ----------
        view : ndarray of bool, shape (H, W), optional
            Usable pixels of the ``pose1`` frame (default: the whole image).

        Returns
        -------
        flow : ndarray of float32, shape (H, W, 2)
            0 where the static point leaves the camera's domain.
        seen : ndarray of bool, shape (H, W)
            The predicted point lands on ``view`` (at the prediction grid's resolution).
        """
        pixels, ok = static_scene_targets(self.camera, self._rays, pose0, pose1, road,
                                          self.distance)
        ok &= self._valid
        h, w = self.camera.height, self.camera.width
        with np.errstate(invalid="ignore"):
            seen = ok & (pixels[..., 0] >= 0) & (pixels[..., 0] <= w - 1)
            seen &= (pixels[..., 1] >= 0) & (pixels[..., 1] <= h - 1)
        if view is not None:
            iu = np.rint(np.where(seen, pixels[..., 0], 0)).astype(np.intp)
            iv = np.rint(np.where(seen, pixels[..., 1], 0)).astype(np.intp)
            seen &= view[iv, iu]
        flow = np.where(ok[..., None], pixels - self._pixels, 0.0).astype(np.float32)
        return (cv2.remap(flow, *self._lookup, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE),
                cv2.remap(seen.astype(np.uint8), *self._lookup, cv2.INTER_NEAREST,
                          borderMode=cv2.BORDER_REPLICATE) > 0)

    @cached_property
    def _lookup(self) -> tuple[NDArray[np.float32], NDArray[np.float32]]:
        """Fractional coarse-grid coordinates of every pixel (sample j sits at pixel step * j)."""
        h, w = self.camera.height, self.camera.width
        xs = (np.arange(w, dtype=np.float32) / self.step)[None, :].repeat(h, 0)
        ys = (np.arange(h, dtype=np.float32) / self.step)[:, None].repeat(w, 1)
        return xs, ys
