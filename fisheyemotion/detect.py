"""``detect()`` for one frame pair, in the style of cv2: the thin front of the engine.

>>> likelihood, mask = fisheyemotion.detect(prev, curr, pose0, pose1, camera=cam)

A stream keeps a :class:`~fisheyemotion.detector.MotionDetector` (:mod:`fisheyemotion.detector`);
``detect`` keeps one per camera and settings for the caller.
"""

from __future__ import annotations

import json
import threading
from collections import OrderedDict

import numpy as np
from numpy.typing import NDArray

from .calib.base import CameraModel
from .detection import CONSTRAINT_NAMES, Detection, Grid
from .detector import MotionDetector
from .params import Params
from .road import Road

__all__ = ["CONSTRAINT_NAMES", "Detection", "Grid", "MotionDetector", "detect"]


#: ``detect()``'s detectors (their grid rays and OpenCV flow objects) are cached per thread:
#: an OpenCV DIS object must not be used from two threads at once.
_CACHE = threading.local()
_CACHE_SIZE = 4


def _detectors() -> OrderedDict[tuple, MotionDetector]:
    if not hasattr(_CACHE, "detectors"):
        _CACHE.detectors = OrderedDict()
    return _CACHE.detectors


def detect(prev: NDArray[np.uint8], curr: NDArray[np.uint8], pose0: NDArray, pose1: NDArray, *,
           camera: CameraModel, road: Road | None = None, params: Params | None = None,
           roi: NDArray | None = None) -> Detection:
    """Moving objects between two frames of a moving fisheye camera.

    Parameters
    ----------
    prev, curr : ndarray of uint8, shape (H, W) or (H, W, 3)
        Gray or BGR frames, as cv2 gives them, of the camera's size.
    pose0, pose1 : ndarray, shape (4, 4)
        ``world_from_cam`` at ``prev`` and at ``curr``.
    camera : CameraModel
    road : Road, optional
        Default: the plane ``z = 0`` of the world frame.
    params : Params, optional
    roi : ndarray, shape (H, W), optional
        Pixels to use (non-zero); default all pixels with a ray.

    Returns
    -------
    Detection
        Unpacks as ``likelihood, mask`` (``(H, W)`` float32 and uint8 0/255).

    Notes
    -----
    The grid rays of a camera are computed once and kept (for the last few cameras used, in
    each thread), as a :class:`MotionDetector` keeps them. ``detect`` may be called from several
    threads at once; a :class:`MotionDetector` belongs to one thread at a time.
    """
    road = Road() if road is None else road
    params = Params() if params is None else params
    if not isinstance(params, Params):
        raise ValueError(f"params: expected a fisheyemotion.Params, got {type(params).__name__}")
    roi_key = None if roi is None else hash(np.asarray(roi).tobytes())
    key = (camera, road, json.dumps(params.to_dict(), sort_keys=True), roi_key)
    try:
        detector = _detectors().pop(key)
    except (KeyError, TypeError):
        detector = MotionDetector(camera, road, params, roi=roi)
    cache = _detectors()
    cache[key] = detector
    while len(cache) > _CACHE_SIZE:
        cache.popitem(last=False)
    return detector.detect(prev, curr, pose0, pose1)
