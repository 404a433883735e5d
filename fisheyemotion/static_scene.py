"""The static-scene model of a stream: world points already judged static, carried to the next pair.

The ego prior (:mod:`fisheyemotion.prior`) predicts the flow a static scene would have. With only
the road plane and a far field to go on, that prediction is right on the road and the sky but
off by 10-70 px on buildings, walls, parked cars and poles close to the road, and the flow method
does not recover so large a residual. A stream has already measured those surfaces: every cell
it scored as static gives, by triangulation, a world point. This module keeps the points of the
last few detections and gives, for the rays of the next pair's first camera, the range of the
nearest such point, which the prior then uses instead of the road/far-field guess.

Triangulation
-------------
Rays ``p`` (from the previous centre ``C``) and ``p'`` (from the current centre ``C'``), in the
world frame, unit length; ``d = C' - C``, ``a = p . p'``. The range along ``p`` of the point
nearest to both rays (midpoint method) is::

    lambda = (d . p - a (d . p')) / (1 - a^2)

Valid where ``lambda > 0`` and the rays' angle (the parallax) is at least ``min_parallax``: below
it the range is mostly flow noise, and the prediction hardly depends on it anyway. Ranges beyond
``far`` metres are clipped to ``far`` (the rotation alone then explains the flow).

Splatting
---------
Stored points are projected into the camera whose rays are asked for and binned to the prior's
coarse samples (``step`` pixels); each sample takes the median range of its points (robust to the
odd wrong flow, which a nearest-point z-buffer would keep). Samples with no point but a neighbour
that has one take the nearest neighbouring range; the rest stay NaN, and the prior uses the road
plane or the far field there. The prior uses a stored range only where it is clearly nearer than
the road or the far field (``prior.OCCLUDER_RATIO``): on the road itself, the plane is better
than any triangulation.

Moving objects are excluded by the detector (only cells below its threshold are added); a cell
misjudged static adds a wrong point that leaves the memory after ``memory`` detections. The
prior only steers the flow method: the flow it returns still measures the real displacement.
"""

from __future__ import annotations

from collections import deque

import numpy as np
from numpy.typing import NDArray

from .calib.base import CameraModel
from .calib.transforms import rotate

__all__ = ["StaticScene", "TRIANGULATION_PARALLAX", "triangulate_range", "world_points"]

_DEGENERATE = 1e-9

#: Radians: correspondences with less parallax are not triangulated by the detector.
TRIANGULATION_PARALLAX = float(np.radians(0.5))


def triangulate_range(rays0: NDArray[np.float64], rays1: NDArray[np.float64], pose0: NDArray,
                      pose1: NDArray, *, far: float, min_parallax: float = 0.0,
                      with_parallax: bool = False) -> tuple[NDArray, ...]:
    """Range along ``rays0`` of the point seen along ``rays0`` from ``pose0`` and ``rays1`` from
    ``pose1`` (midpoint method).

    Parameters
    ----------
    rays0, rays1 : ndarray, shape (..., 3)
        Unit rays, each in its own camera frame (NaN where invalid).
    pose0, pose1 : ndarray, shape (4, 4)
        ``world_from_cam``.
    far : float
        Ranges beyond this (and parallel rays) are clipped to it.
    min_parallax : float
        Radians; rays closer in angle than this are not valid.
    with_parallax : bool
        Also return the sine of the rays' angle, ``sqrt(1 - (p . p')^2)`` (``|p x p'|``), which
        the triangulation computes anyway.

    Returns
    -------
    range : ndarray, shape (...)
        Metres from ``pose0``'s centre; NaN where not valid.
    valid : ndarray of bool, shape (...)
        Finite rays at least ``min_parallax`` apart triangulating in front of the first camera
        (or parallel, when ``min_parallax`` is 0: ``far``).
    parallax : ndarray, shape (...)
        With ``with_parallax``: the sine of the angle between the rays (NaN where not finite).
    """
    p = rotate(rays0, pose0[:3, :3])
    q = rotate(rays1, pose1[:3, :3])
    d = pose1[:3, 3] - pose0[:3, 3]
    a = np.einsum("...i,...i->...", p, q)
    dp, dq = p @ d, q @ d
    den = 1.0 - a * a
    with np.errstate(invalid="ignore", divide="ignore"):
        lam = np.where(den > _DEGENERATE, (dp - a * dq) / den, np.inf)
        valid = np.isfinite(a) & (lam > 0) & (den >= np.sin(min_parallax) ** 2)
        lam = np.where(valid, np.minimum(lam, far), np.nan)
    if with_parallax:
        return lam, valid, np.sqrt(np.maximum(den, 0.0))
    return lam, valid


def world_points(rays: NDArray[np.float64], ranges: NDArray[np.float64],
                 pose: NDArray) -> NDArray[np.float64]:
    """World points ``(..., 3)`` at ``ranges`` (...) along camera-frame ``rays`` (..., 3) of the
    camera at ``pose`` (``world_from_cam``)."""
    return pose[:3, 3] + ranges[..., None] * rotate(rays, pose[:3, :3])


class StaticScene:
    """World points a stream has judged static, kept for the next frame pairs.

    Parameters
    ----------
    camera : CameraModel
    memory : int
        Detections whose points are kept (newest first).
    """

    def __init__(self, camera: CameraModel, *, memory: int = 3) -> None:
        self.camera = camera
        self._version = 0
        self._cached: tuple | None = None
        self._sets: deque[NDArray[np.float64]] = deque(maxlen=int(memory))

    def __len__(self) -> int:
        """Stored points."""
        return sum(len(s) for s in self._sets)

    def points(self) -> NDArray[np.float64]:
        """All stored world points ``(N, 3)``, newest first."""
        return np.concatenate(list(self._sets)) if self._sets else np.empty((0, 3))

    def clear(self) -> None:
        self._sets.clear()
        self._version += 1

    def add(self, rays: NDArray[np.float64], ranges: NDArray[np.float64], pose: NDArray,
            static: NDArray[np.bool_]) -> int:
        """Keep the world points of the correspondences marked ``static``.

        Parameters
        ----------
        rays : ndarray, shape (..., 3)
            Rays of the previous frame, camera frame.
        ranges : ndarray, shape (...)
            Their triangulated ranges (:func:`triangulate_range`; NaN where not valid).
        pose : ndarray, shape (4, 4)
            ``world_from_cam`` of the previous frame.
        static : ndarray of bool, shape (...)
            Correspondences judged static (valid and below the detection threshold).

        Returns
        -------
        int
            Points added.
        """
        ok = static & np.isfinite(ranges)
        points = world_points(rays[ok], ranges[ok], pose)
        self._sets.appendleft(points)
        self._version += 1
        return len(points)

    def ranges(self, pose: NDArray, step: int, shape: tuple[int, int]) -> NDArray[np.float64]:
        """Median range of the stored points seen in each ``step x step`` cell of a camera.

        Parameters
        ----------
        pose : ndarray, shape (4, 4)
            ``world_from_cam`` of the camera.
        step : int
            Cell size, pixels: cell ``(r, c)`` holds pixels ``[step r, step (r + 1))`` down and
            ``[step c, step (c + 1))`` across.
        shape : (rows, cols)

        Returns
        -------
        ndarray, shape (rows, cols)
            Metres; NaN where no stored point falls in or next to the cell. The last result is
            kept: asking again for the same pose and cells before the next :meth:`add` is free.
        """
        key = (pose.tobytes(), step, tuple(shape), self._version)
        if self._cached is not None and self._cached[0] == key:
            return self._cached[1]
        out = self._ranges(pose, step, *shape)
        self._cached = (key, out)
        return out

    def _ranges(self, pose: NDArray, step: int, rows: int, cols: int) -> NDArray[np.float64]:
        from ._grid_kernels import sample_medians  # numba on first use: a light import

        out = np.empty((rows, cols))
        if not len(self):
            out[:] = np.nan
            return out
        points = np.concatenate(list(self._sets))
        local = (points - pose[:3, 3]) @ pose[:3, :3]
        pix, ok = self.camera.project(local)
        with np.errstate(invalid="ignore"):
            c = np.floor(pix[:, 0] / step)
            r = np.floor(pix[:, 1] / step)
            inside = ok & (c >= 0) & (c < cols) & (r >= 0) & (r < rows)
        cell = np.where(inside, r * cols + c, -1).astype(np.intp)
        x, y, z = local.T  # np.linalg.norm(local, axis=-1), same sums, a sixth of its time
        rng = np.sqrt(x * x + y * y + z * z)
        n = rows * cols
        sample_medians(cell, rng, np.zeros(n + 1, np.intp), np.empty(n, np.intp),
                       np.empty(len(rng)), np.empty(n), out)
        return out
