"""Camera models behind one interface, and readers/writers for the calibration files users have.

>>> from fisheyemotion import calib
>>> cam = calib.load("camchain.yaml", camera="cam0")
>>> rays, valid = cam.unproject(pixels)          # g(u): (..., 2) -> (..., 3) unit rays
"""

from .base import CameraModel, pixel_grid
from .circle import ImageCircle, find_image_circle, nominal_camera
from .errors import CalibrationError
from .models import DoubleSphere, EnhancedUnified, Fisheye624, KannalaBrandt, Pinhole, RadialPoly, Unified
from .readers import FORMATS, Rig, load, load_rig, parse, save_kalibr, save_opencv
from .registry import MODELS, create, model_class, register

__all__ = [
    "FORMATS",
    "MODELS",
    "Rig",
    "load",
    "load_rig",
    "parse",
    "save_kalibr",
    "save_opencv",
    "CalibrationError",
    "CameraModel",
    "DoubleSphere",
    "EnhancedUnified", "Fisheye624",
    "ImageCircle",
    "KannalaBrandt",
    "Pinhole",
    "RadialPoly",
    "Unified",
    "create",
    "find_image_circle",
    "model_class",
    "nominal_camera",
    "pixel_grid",
    "register",
]
