"""Checks on frames as callers hand them over (cv2 images)."""

from __future__ import annotations

import cv2
import numpy as np
from numpy.typing import NDArray


def to_gray(frame: object, name: str, *, size: tuple[int, int] | None = None) -> NDArray[np.uint8]:
    """A uint8 gray image from a cv2 frame (gray ``(H, W)``, BGR ``(H, W, 3)`` or BGRA).

    Parameters
    ----------
    frame : ndarray
    name : str
        Argument name for errors.
    size : (width, height), optional
        Required size.
    """
    if not isinstance(frame, np.ndarray):
        raise ValueError(f"{name}: expected a numpy uint8 image, got {type(frame).__name__}")
    if frame.dtype != np.uint8:
        raise ValueError(f"{name}: expected dtype uint8 (as cv2 reads frames), got {frame.dtype}")
    if frame.ndim == 3 and frame.shape[2] in (3, 4):
        code = cv2.COLOR_BGR2GRAY if frame.shape[2] == 3 else cv2.COLOR_BGRA2GRAY
        gray = cv2.cvtColor(frame, code)
    elif frame.ndim == 2:
        gray = frame
    elif frame.ndim == 3 and frame.shape[2] == 1:
        gray = frame[..., 0]
    else:
        raise ValueError(f"{name}: expected shape (H, W) or (H, W, 3), got {frame.shape}")
    if size is not None and (gray.shape[1], gray.shape[0]) != tuple(size):
        raise ValueError(
            f"{name}: expected a {size[0]}x{size[1]} frame (the camera's size), "
            f"got {gray.shape[1]}x{gray.shape[0]}"
        )
    # Never the caller's memory: streams keep frames, and a caller reusing its buffer must not
    # change them (cvtColor already made a new array).
    return np.array(gray, order="C", copy=True) if gray.base is not None or gray is frame \
        else gray
