"""Random camera motions and world points for geometric tests (seeded, no rendering)."""

from __future__ import annotations

import numpy as np
from fisheyemotion.calib.transforms import make_transform


def rotation(axis: np.ndarray, angle: float) -> np.ndarray:
    """Rodrigues' formula."""
    a = np.asarray(axis, float)
    a = a / np.linalg.norm(a)
    k = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * (k @ k)


def random_rotation(rng: np.random.Generator) -> np.ndarray:
    q = rng.normal(size=4)
    q /= np.linalg.norm(q)
    x, y, z, w = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


# A front camera looking along world +x, tilted down: camera z -> world x, camera y -> world -z.
CAM_TO_VEHICLE = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])


def camera_pose(rng: np.random.Generator, *, height: float, pitch_deg: float = 10.0,
                yaw_deg: float = 0.0, roll_deg: float = 0.0, position_xy=(0.0, 0.0)) -> np.ndarray:
    """world_from_cam of a road camera at ``height`` metres, looking roughly along the heading."""
    r = (rotation([0, 0, 1], np.radians(yaw_deg)) @ rotation([0, 1, 0], np.radians(pitch_deg))
         @ rotation([1, 0, 0], np.radians(roll_deg)) @ CAM_TO_VEHICLE)
    return make_transform(r, [position_xy[0], position_xy[1], height])


def rays_of(points: np.ndarray, pose: np.ndarray) -> np.ndarray:
    """Unit rays, in the camera frame, towards world points."""
    d = (points - pose[:3, 3]) @ pose[:3, :3]
    return d / np.linalg.norm(d, axis=-1, keepdims=True)


def moved(pose: np.ndarray, translation, yaw_deg: float = 0.0) -> np.ndarray:
    """The pose after the vehicle moves by ``translation`` (world) and turns by ``yaw_deg``."""
    out = pose.copy()
    out[:3, :3] = rotation([0, 0, 1], np.radians(yaw_deg)) @ pose[:3, :3]
    out[:3, 3] = pose[:3, 3] + np.asarray(translation, float)
    return out
