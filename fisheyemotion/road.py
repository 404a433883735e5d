"""The road plane, in the world frame."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .calib.transforms import check_rigid


@dataclass(frozen=True)
class Road:
    """The plane ``{x : normal . x = offset}`` in the world frame, ``normal`` pointing up.

    Parameters
    ----------
    normal : array_like, shape (3,)
        Up direction (normalised on construction).
    offset : float
        Signed distance of the plane from the world origin along ``normal`` (metres).
    known : bool
        False for :meth:`unknown`: no road is known (indoors, a head-mounted camera, or before
        :class:`fisheyemotion.ground.GroundEstimator` has found one). The positive-height and
        anti-parallel constraints and the ground-contact test then do not apply, and the ego
        prior uses the far field (and the scene model) only.
    """

    normal: tuple[float, float, float] = (0.0, 0.0, 1.0)
    offset: float = 0.0
    known: bool = True

    @classmethod
    def unknown(cls) -> Road:
        """No road: only the epipolar and positive-depth constraints apply."""
        return cls(known=False)

    def __post_init__(self) -> None:
        try:
            n = np.asarray(self.normal, dtype=np.float64)
        except (TypeError, ValueError):
            raise ValueError(f"normal: expected 3 finite numbers, got {self.normal!r}") from None
        with np.errstate(over="ignore", invalid="ignore"):
            norm = np.linalg.norm(n / np.abs(n).max()) if n.shape == (3,) and np.isfinite(n).all() \
                and np.abs(n).max() > 0 else 0.0
        if n.shape != (3,) or not np.isfinite(n).all() or not norm > 1e-12:
            raise ValueError(f"normal: expected 3 finite numbers, not all zero, got {self.normal!r}")
        if isinstance(self.offset, bool) or not isinstance(self.offset, int | float | np.number) \
                or not np.isfinite(self.offset):
            raise ValueError(f"offset: expected a finite number, got {self.offset!r}")
        if not isinstance(self.known, bool):
            raise ValueError(f"known: expected a bool, got {self.known!r}")
        n = n / np.abs(n).max()  # no overflow for normals like (1e300, 1e300, 1e300)
        object.__setattr__(self, "normal", tuple(float(v) for v in n / np.linalg.norm(n)))
        object.__setattr__(self, "offset", float(self.offset))

    @property
    def up(self) -> NDArray[np.float64]:
        """Unit normal (up), shape (3,)."""
        return np.array(self.normal)

    def height(self, points: ArrayLike) -> NDArray[np.float64]:
        """Signed height above the road of world points ``(..., 3)``."""
        return np.asarray(points, dtype=np.float64) @ self.up - self.offset

    def ray_range(self, origin: ArrayLike, dirs: ArrayLike, *,
                  min_down: float = 0.0) -> NDArray[np.float64]:
        """Metres along unit world directions ``dirs`` (..., 3) from ``origin`` (3,) to the
        plane; ``inf`` for rays that do not point down by more than ``min_down`` (the sine of
        their angle below the plane), for an origin not above the plane and for an unknown
        road."""
        dirs = np.asarray(dirs, dtype=np.float64)
        height = float(self.height(origin)) if self.known else 0.0
        down = dirs @ -self.up
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.where((down > min_down) & (height > 0), height / down, np.inf)

    def transformed(self, transform: ArrayLike) -> Road:
        """The same physical plane after the world frame is moved by ``transform``
        (``new_from_old``, 4x4 rigid)."""
        t = check_rigid(transform, "transform")
        n = t[:3, :3] @ self.up
        return Road(normal=tuple(n), offset=self.offset + float(n @ t[:3, 3]), known=self.known)

    @classmethod
    def from_camera(cls, *, height: float, cam_from_road: ArrayLike,
                    world_from_cam: ArrayLike) -> Road:
        """The paper's inputs: camera height ``eta_C`` above the road and the rotation ``R_C``
        (``cam_from_road``, so that ``h = R_C (0, 0, -1)`` is 'down' in the camera), at the
        camera pose ``world_from_cam``."""
        pose = check_rigid(world_from_cam, "world_from_cam")
        r_c = np.asarray(cam_from_road, dtype=np.float64)
        if r_c.shape != (3, 3) or not np.allclose(r_c.T @ r_c, np.eye(3), atol=1e-6):
            raise ValueError("cam_from_road: expected a 3x3 rotation matrix")
        if not np.isfinite(height) or height <= 0:
            raise ValueError(f"height: expected a positive camera height, got {height!r}")
        down_cam = r_c @ np.array([0.0, 0.0, -1.0])
        up = -(pose[:3, :3] @ down_cam)
        return cls(normal=tuple(up), offset=float(up @ pose[:3, 3]) - float(height))

    @classmethod
    def from_vehicle(cls, world_from_vehicle: ArrayLike) -> Road:
        """The ground plane ``z = 0`` of a vehicle frame (ISO 8855: origin on the ground, z up)
        at the vehicle pose ``world_from_vehicle``."""
        pose = check_rigid(world_from_vehicle, "world_from_vehicle")
        up = pose[:3, 2]
        return cls(normal=tuple(up), offset=float(up @ pose[:3, 3]))
