"""fisheyemotion: moving-object detection for moving fisheye cameras from spherical constraints.

>>> import fisheyemotion as fm
>>> likelihood, mask = fm.detect(prev, curr, pose0, pose1, camera=cam)
"""

from . import calib, draw, poses
from .constraints import ConstraintResult, constraints
from .detect import detect
from .detection import Detection, Grid
from .detector import MotionDetector
from .params import Params
from .road import Road
from .segment import Region

__all__ = [
    "draw", "poses",
    "ConstraintResult", "Detection", "Grid", "MotionDetector", "Params", "Region", "Road",
    "calib", "constraints", "detect",
]
__version__ = "0.8.24"
