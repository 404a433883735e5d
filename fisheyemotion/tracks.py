"""Sparse corner tracks between two frames (OpenCV's Shi-Tomasi corners and pyramidal
Lucas-Kanade, forward-backward checked): correspondences that need no prior, for the road
estimate and the ego-motion estimate."""

from __future__ import annotations

from collections.abc import Callable

import cv2
import numpy as np
from numpy.typing import NDArray

__all__ = ["track_corners"]

#: Small windows: a fisheye's perspective deforms a patch between frames, and a 21-px window
#: straddling that deformation biased the tracks (measured on the demo scenes: the relative
#: rotation's error 0.04-0.14 deg with 21 px, 0.02-0.04 deg with 7 px; the road's tilt 0.07 deg
#: median, 0.40 deg 90th percentile, with 21 px; 0.016 and 0.038 deg with 7 px).
_LK = {"winSize": (7, 7), "maxLevel": 4}
_LK_GUESSED = {**_LK, "maxLevel": 1}


def _mask_u8(mask: NDArray) -> NDArray[np.uint8]:
    """``mask`` as OpenCV's 8-bit mask (non-zero: used); a contiguous boolean one is viewed as
    0/1 bytes, not copied."""
    mask = np.asarray(mask)
    if mask.dtype == np.bool_ and mask.flags.c_contiguous:
        return mask.view(np.uint8)
    return np.where(mask, 255, 0).astype(np.uint8)


def track_corners(gray0: NDArray[np.uint8], gray1: NDArray[np.uint8], *,
                  mask: NDArray | None = None, corners: int = 600,
                  min_distance: int = 7, fb_tolerance: float = 0.5,
                  predict: Callable[[NDArray[np.float64]], NDArray[np.float64]] | None = None,
                  detect_scale: int = 1, iterations: int = 20, backward: bool = True,
                  levels: int | None = None
                  ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Corners of ``gray0`` (where ``mask`` is non-zero) and where they are in ``gray1``.

    ``detect_scale`` > 1 looks for the corners in ``gray0`` shrunk by that factor (a quarter of
    the work at 2; the tracking is at full resolution); ``iterations`` caps Lucas-Kanade's
    iterations per pyramid level.

    ``predict`` maps corner pixels (N, 2) to where they are expected in ``gray1`` (NaN: no
    guess): the tracker starts there, so that large displacements the pyramid cannot reach (the
    road near a fast vehicle) are still tracked.

    ``backward``: each track is tracked back from ``gray1`` and kept only if it returns within
    ``fb_tolerance`` pixels of its corner (twice the work); without it, every track Lucas-Kanade
    reports found is kept.

    ``levels``: the pyramid levels above the full resolution that Lucas-Kanade starts from
    (default: 4 without ``predict``, 1 with it).

    Returns
    -------
    u0, u1 : ndarray, shape (N, 2)
        Pixels of the tracks kept in ``gray0`` and ``gray1``.
    """
    m = None if mask is None else _mask_u8(mask)
    if detect_scale > 1:
        f = 1.0 / detect_scale
        small = cv2.resize(gray0, None, fx=f, fy=f, interpolation=cv2.INTER_AREA)
        small_mask = None if m is None else cv2.resize(m, (small.shape[1], small.shape[0]),
                                                       interpolation=cv2.INTER_NEAREST)
        found = cv2.goodFeaturesToTrack(small, maxCorners=corners, qualityLevel=0.005,
                                        minDistance=max(1, min_distance // detect_scale),
                                        mask=small_mask)
        if found is not None:  # a shrunk pixel's centre in full-resolution pixels
            found = (found * detect_scale + 0.5 * (detect_scale - 1)).astype(np.float32)
    else:
        found = cv2.goodFeaturesToTrack(gray0, maxCorners=corners, qualityLevel=0.005,
                                        minDistance=min_distance, mask=m)
    if found is None or len(found) < 8:
        return np.empty((0, 2)), np.empty((0, 2))
    # From a guess only fine levels: a coarse level would lead a patch that the perspective
    # deforms (the road near the camera) away from it.
    lk = {**(_LK if predict is None else _LK_GUESSED),
          "criteria": (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, iterations, 0.01)}
    if levels is not None:
        lk["maxLevel"] = int(levels)
    if predict is None:
        fwd, ok1, _ = cv2.calcOpticalFlowPyrLK(gray0, gray1, found, None, **lk)
        back, ok2 = found, ok1
        if backward:
            back, ok2, _ = cv2.calcOpticalFlowPyrLK(gray1, gray0, fwd, None, **lk)
    else:
        guess = np.asarray(predict(found[:, 0].astype(np.float64)), dtype=np.float64)
        guess = np.where(np.isfinite(guess), guess, found[:, 0])
        guess = np.ascontiguousarray(guess.reshape(-1, 1, 2), dtype=np.float32)
        fwd, ok1, _ = cv2.calcOpticalFlowPyrLK(gray0, gray1, found, guess,
                                               flags=cv2.OPTFLOW_USE_INITIAL_FLOW, **lk)
        # Back with the predicted displacement reversed (not from the corners themselves).
        back, ok2 = found, ok1
        if backward:
            back_guess = np.ascontiguousarray(fwd - (guess - found), dtype=np.float32)
            back, ok2, _ = cv2.calcOpticalFlowPyrLK(gray1, gray0, fwd, back_guess,
                                                    flags=cv2.OPTFLOW_USE_INITIAL_FLOW, **lk)
    good = (ok1[:, 0] == 1) & (ok2[:, 0] == 1) & (
        np.linalg.norm(back - found, axis=-1)[:, 0] < fb_tolerance)
    return found[good, 0].astype(np.float64), fwd[good, 0].astype(np.float64)
