"""Sparse corner tracks between two frames (OpenCV's Shi-Tomasi corners and pyramidal
Lucas-Kanade, forward-backward checked): correspondences that need no prior, for the road
estimate and the ego-motion estimate."""

from __future__ import annotations

import cv2
import numpy as np
from numpy.typing import NDArray

__all__ = ["track_corners"]

_LK = {"winSize": (21, 21), "maxLevel": 6,
       "criteria": (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 40, 0.01)}


def track_corners(gray0: NDArray[np.uint8], gray1: NDArray[np.uint8], *,
                  mask: NDArray | None = None, corners: int = 600,
                  min_distance: int = 7, fb_tolerance: float = 0.5
                  ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Corners of ``gray0`` (where ``mask`` is non-zero) and where they are in ``gray1``.

    Returns
    -------
    u0, u1 : ndarray, shape (N, 2)
        Pixels of the tracks that came back within ``fb_tolerance`` pixels when tracked from
        ``gray1`` to ``gray0``.
    """
    m = None if mask is None else np.where(mask, 255, 0).astype(np.uint8)
    found = cv2.goodFeaturesToTrack(gray0, maxCorners=corners, qualityLevel=0.005,
                                    minDistance=min_distance, mask=m)
    if found is None or len(found) < 8:
        return np.empty((0, 2)), np.empty((0, 2))
    fwd, ok1, _ = cv2.calcOpticalFlowPyrLK(gray0, gray1, found, None, **_LK)
    back, ok2, _ = cv2.calcOpticalFlowPyrLK(gray1, gray0, fwd, None, **_LK)
    good = (ok1[:, 0] == 1) & (ok2[:, 0] == 1) & (
        np.linalg.norm(back - found, axis=-1)[:, 0] < fb_tolerance)
    return found[good, 0].astype(np.float64), fwd[good, 0].astype(np.float64)
