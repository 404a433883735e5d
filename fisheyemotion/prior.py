"""Ego-motion-guided flow: the flow a static scene would have, and where that scene stays in view.

Every pixel's ray is followed to the road plane (below the horizon) or to a point at
``distance`` metres (above it, and where the road is farther than that); the point is projected
into the current camera. The detector warps the current frame back by this prediction so that
Farneback or DIS only measure the residual (they otherwise underestimate the large road
displacements near the bottom of a fisheye image and make the static road look like it sinks
below the road plane), keeps the previous frame where the predicted point leaves the view, and
does not score the cells whose point leaves it (``docs/geometry.md``).
"""

from __future__ import annotations

import cv2
import numpy as np
from numpy.typing import NDArray

from .calib.base import CameraModel
from .calib.transforms import rotate
from .flow import grid_upsample
from .road import Road
from .static_scene import StaticScene

#: Rays closer than this to the horizon (sine) use the fixed distance.
_HORIZON_SIN = 0.02

#: A range measured static replaces the road/far-field guess only where it is nearer than this
#: fraction of it (something stands in front of the road or the far field); on the road itself
#: the plane is better than any triangulation.
OCCLUDER_RATIO = 0.8


def static_scene_targets(camera: CameraModel, rays: NDArray[np.float64], pose0: NDArray,
                         pose1: NDArray, road: Road, distance: float,
                         ranges: NDArray[np.float64] | None = None
                         ) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
    """Where the static scene seen along ``rays`` of the ``pose0`` camera is seen from ``pose1``.

    The scene point is the road point of the ray (below the horizon, closer than ``distance``),
    else the point at ``distance`` metres, unless ``ranges`` knows a point clearly nearer
    (``OCCLUDER_RATIO``) along the ray: then that one.

    Parameters
    ----------
    rays : ndarray, shape (..., 3)
        Camera-frame rays of the ``pose0`` camera (NaN where invalid).
    ranges : ndarray, shape (...), optional
        Metres along each ray to a point measured static (NaN where unknown); see
        :class:`fisheyemotion.static_scene.StaticScene`.

    Returns
    -------
    pixels : ndarray, shape (..., 2)
        In the ``pose1`` image; NaN where the point leaves the camera's domain.
    valid : ndarray of bool, shape (...)
    """
    dirs = rotate(rays, pose0[:3, :3])
    centre0 = pose0[:3, 3]
    depth = np.minimum(road.ray_range(centre0, dirs, min_down=_HORIZON_SIN), distance)
    if ranges is not None:
        with np.errstate(invalid="ignore"):
            depth = np.where(ranges < OCCLUDER_RATIO * depth, ranges, depth)
    points = centre0 + depth[..., None] * dirs
    return camera.project((points - pose1[:3, 3]) @ pose1[:3, :3])


class EgoFlowPrior:
    """Predicted static-scene flow for one camera, computed on a coarse grid and upsampled.

    The coarse samples sit at pixels ``step * j + (step - 1) / 2``, where an area-aligned
    ``cv2.resize`` by ``step`` interpolates them bilinearly (edges replicated).

    Parameters
    ----------
    camera : CameraModel
    distance : float
        Metres along rays that do not meet the road within that distance.
    step : int
        Grid stride (pixels) of the prediction before bilinear upsampling.
    """

    def __init__(self, camera: CameraModel, *, distance: float = 1000.0, step: int = 8) -> None:
        self.camera, self.distance, self.step = camera, float(distance), int(step)
        w, h = camera.width, camera.height
        cols, rows = -(-w // step), -(-h // step)
        u = np.arange(cols) * step + (step - 1) / 2
        v = np.arange(rows) * step + (step - 1) / 2
        self._pixels = np.stack(np.meshgrid(u, v), axis=-1)
        self._rays, self._valid = camera.unproject(self._pixels)

    def _upsample(self, coarse: NDArray) -> NDArray:
        """The coarse samples interpolated bilinearly to every pixel (edges replicated)."""
        h, w = self.camera.height, self.camera.width
        rows, cols = coarse.shape[:2]
        full = cv2.resize(coarse, (cols * self.step, rows * self.step),
                          interpolation=cv2.INTER_LINEAR)
        return full[:h, :w]

    def __call__(self, pose0: NDArray, pose1: NDArray, road: Road, *,
                 view: NDArray[np.bool_] | None = None, scene: StaticScene | None = None
                 ) -> tuple[NDArray[np.float32], NDArray[np.bool_]]:
        """The predicted flow from the ``pose0`` frame to the ``pose1`` frame, and where it is seen.

        Parameters
        ----------
        view : ndarray of bool, shape (H, W), optional
            Usable pixels of the ``pose1`` frame (default: the whole image).
        scene : StaticScene, optional
            Points measured static so far: their ranges replace the road/far-field guess.

        Returns
        -------
        flow : ndarray of float32, shape (H, W, 2)
            Where the static point leaves the camera's domain (no target pixel), the flow of the
            nearest sample that has one: continued, never 0, so that the correspondence lands
            outside the image or the domain and the cell is not scored.
        seen : ndarray of bool, shape (H, W)
            The predicted point lands on ``view`` (at the prediction grid's resolution).
        """
        ranges = None if scene is None else scene.ranges(pose0, self.step, self._rays.shape[:2])
        pixels, ok = static_scene_targets(self.camera, self._rays, pose0, pose1, road,
                                          self.distance, ranges)
        ok &= self._valid
        flow = np.where(ok[..., None], pixels - self._pixels, 0.0).astype(np.float32)
        if ok.any() and not ok.all():
            from scipy import ndimage  # scikit-image/scipy on first use: `import fisheyemotion` stays light
            _, (r, c) = ndimage.distance_transform_edt(~ok, return_indices=True)
            flow = flow[r, c]
        seen = lands_on(pixels, ok, view, self.camera.width, self.camera.height)
        return (self._upsample(flow),
                grid_upsample(seen, self.step, self.camera.width, self.camera.height))


def lands_on(pixels: NDArray[np.float64], ok: NDArray[np.bool_], view: NDArray[np.bool_] | None,
             width: int, height: int) -> NDArray[np.bool_]:
    """Where ``pixels`` (..., 2), valid where ``ok``, fall inside the ``width x height`` image
    and, if given, on ``view`` (H, W) bool (nearest pixel)."""
    with np.errstate(invalid="ignore"):
        inside = ok & (pixels[..., 0] >= 0) & (pixels[..., 0] <= width - 1)
        inside &= (pixels[..., 1] >= 0) & (pixels[..., 1] <= height - 1)
    if view is None:
        return inside
    iu = np.rint(np.where(inside, pixels[..., 0], 0)).astype(np.intp)
    iv = np.rint(np.where(inside, pixels[..., 1], 0)).astype(np.intp)
    return inside & view[iv, iu]
