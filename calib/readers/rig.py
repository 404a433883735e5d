"""A set of cameras with their extrinsics, as multi-camera calibration files hold them."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from ..base import CameraModel


@dataclass(frozen=True, eq=False)
class Rig:
    """Cameras of one calibration file.

    Attributes
    ----------
    cameras : tuple of CameraModel
    names : tuple of str
        As the file names them (``cam0``, COLMAP's camera id, WoodScape's ``FV``...).
    extrinsics : tuple of (4, 4) ndarray or None
        ``reference_from_cam`` for each camera (X_ref = R X_cam + t); None when the file has none.
    reference : str
        The frame the extrinsics map into: ``imu`` (Basalt, Kalibr with T_cam_imu), ``cam0``
        (Kalibr with T_cn_cnm1 only), ``vehicle`` (WoodScape, ISO 8855), or ``none``.
    """

    cameras: tuple[CameraModel, ...]
    names: tuple[str, ...]
    extrinsics: tuple[NDArray[np.float64] | None, ...]
    reference: str = "none"
    #: Cameras the file names but no model here reads, with the error to raise when asked for.
    unsupported: dict = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.cameras)

    def index(self, camera: int | str) -> int:
        """Position of ``camera`` given by index or name; ValueError naming ``camera`` otherwise."""
        if isinstance(camera, bool):
            raise ValueError(f"camera: expected an index or a name, got {camera!r}")
        if isinstance(camera, int | np.integer):
            if not -len(self) <= camera < len(self):
                raise ValueError(
                    f"camera: index {camera} out of range; the file has {len(self)} camera(s)"
                )
            return int(camera) % len(self)
        if isinstance(camera, str) and camera in self.names:
            return self.names.index(camera)
        if str(camera) in self.unsupported:
            raise self.unsupported[str(camera)]
        raise ValueError(f"camera: no camera {camera!r}; the file has {list(self.names)}")

    def __getitem__(self, camera: int | str) -> CameraModel:
        return self.cameras[self.index(camera)]

    def extrinsic(self, camera: int | str) -> NDArray[np.float64] | None:
        """``reference_from_cam`` of one camera (a copy), or None."""
        t = self.extrinsics[self.index(camera)]
        return None if t is None else t.copy()
