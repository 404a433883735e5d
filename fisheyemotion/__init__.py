"""fisheyemotion: moving-object detection for moving fisheye cameras from spherical constraints."""

from . import calib

__all__ = ["calib"]
__version__ = "0.1.0"
