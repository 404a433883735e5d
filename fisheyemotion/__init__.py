"""fisheyemotion: moving-object detection for moving fisheye cameras from spherical constraints.

>>> import fisheyemotion as fm
>>> likelihood, mask = fm.detect(prev, curr, pose0, pose1, camera=cam)
"""

from . import calib
from .constraints import ConstraintResult, constraints
from .params import Params
from .road import Road

__all__ = ["ConstraintResult", "Params", "Road", "calib", "constraints"]
__version__ = "0.1.0"
