"""Rigid transforms: quaternions (x, y, z, w as in TUM, ROS and Basalt) and 4x4 matrices.

The one implementation used by the readers, the engine and the pose files.
"""

from __future__ import annotations

import math

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

#: Tolerance on ``R^T R - I`` and on a quaternion's norm for a transform to count as rigid.
RIGID_TOL = 1e-6
QUAT_NORM_TOL = 1e-3


def quat_to_matrix(q: ArrayLike) -> NDArray[np.float64]:
    """Rotation matrix of a quaternion ``(qx, qy, qz, qw)``, normalised first.

    Raises
    ------
    ValueError
        If ``q`` is not 4 finite numbers whose norm is within ``QUAT_NORM_TOL`` of 1.
    """
    q = np.asarray(q, dtype=np.float64)
    if q.shape != (4,) or not np.isfinite(q).all():
        raise ValueError(f"quaternion: expected 4 finite numbers (qx, qy, qz, qw), got {q!r}")
    n = np.linalg.norm(q)
    if abs(n - 1.0) > QUAT_NORM_TOL:
        raise ValueError(f"quaternion: expected unit norm (rigid rotation), got norm {n:.6g}")
    x, y, z, w = q / n
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


def matrix_to_quat(rotation: ArrayLike) -> NDArray[np.float64]:
    """Quaternion ``(qx, qy, qz, qw)`` with ``qw >= 0`` of a rotation matrix."""
    m = np.asarray(rotation, dtype=np.float64)
    tr = np.trace(m)
    if tr > 0:
        s = 2.0 * np.sqrt(tr + 1.0)
        q = [(m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s, s / 4]
    elif m[0, 0] > m[1, 1] and m[0, 0] > m[2, 2]:
        s = 2.0 * np.sqrt(1.0 + m[0, 0] - m[1, 1] - m[2, 2])
        q = [s / 4, (m[0, 1] + m[1, 0]) / s, (m[0, 2] + m[2, 0]) / s, (m[2, 1] - m[1, 2]) / s]
    elif m[1, 1] > m[2, 2]:
        s = 2.0 * np.sqrt(1.0 + m[1, 1] - m[0, 0] - m[2, 2])
        q = [(m[0, 1] + m[1, 0]) / s, s / 4, (m[1, 2] + m[2, 1]) / s, (m[0, 2] - m[2, 0]) / s]
    else:
        s = 2.0 * np.sqrt(1.0 + m[2, 2] - m[0, 0] - m[1, 1])
        q = [(m[0, 2] + m[2, 0]) / s, (m[1, 2] + m[2, 1]) / s, s / 4, (m[1, 0] - m[0, 1]) / s]
    q = np.asarray(q)
    q /= np.linalg.norm(q)
    return -q if q[3] < 0 else q

def rotation_angle(rotation: ArrayLike) -> float:
    """Angle (radians, 0 to pi) of a rotation matrix, precise near 0 (``atan2`` of its sine and
    cosine rather than ``acos`` of the trace)."""
    r = np.asarray(rotation, dtype=np.float64)
    sine = 0.5 * math.hypot(r[2, 1] - r[1, 2], r[0, 2] - r[2, 0], r[1, 0] - r[0, 1])
    return math.atan2(sine, 0.5 * (float(np.trace(r)) - 1.0))


def vector_angle(a: ArrayLike, b: ArrayLike) -> float:
    """Angle (radians, 0 to pi) between two 3-vectors of any length, precise near 0 and pi."""
    u, v = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    return math.atan2(float(np.linalg.norm(np.cross(u, v))), float(u @ v))


_LAST_ROW = np.array([0.0, 0.0, 0.0, 1.0])
_EYE3 = np.eye(3)


def rotate(vectors: NDArray, rotation: NDArray) -> NDArray[np.float64]:
    """``rotation @ v`` for every vector ``v`` of ``vectors`` (..., 3); ``rotation`` (3, 3).

    numpy's matmul takes a generic loop, 3-4x slower, when its 3x3 operand is a transposed
    view (``vectors @ R.T``); with a contiguous copy it gives the same bits through BLAS.
    """
    return vectors @ np.ascontiguousarray(np.asarray(rotation).T)


def make_transform(rotation: ArrayLike, translation: ArrayLike) -> NDArray[np.float64]:
    """4x4 matrix ``[[R, t], [0, 1]]``."""
    out = np.eye(4)
    out[:3, :3] = rotation
    out[:3, 3] = translation
    return out


def invert_transform(transform: ArrayLike) -> NDArray[np.float64]:
    """Inverse of a rigid 4x4 transform."""
    t = np.asarray(transform, dtype=np.float64)
    r = t[:3, :3]
    return make_transform(r.T, -r.T @ t[:3, 3])


def mean_rotation(rotations: NDArray) -> NDArray[np.float64]:
    """The chordal L2 mean of rotations ``(N, 3, 3)``: the rotation nearest (Frobenius) to their
    arithmetic mean, by SVD. Within a few degrees of each other it is their geodesic mean to
    second order."""
    u, _, vt = np.linalg.svd(np.mean(rotations, axis=0))
    d = np.sign(np.linalg.det(u @ vt))
    return u @ np.diag([1.0, 1.0, d]) @ vt


def interpolate_transform(a: ArrayLike, b: ArrayLike, weight: float) -> NDArray[np.float64]:
    """The rigid transform ``weight`` of the way from ``a`` to ``b`` (4x4 each).

    Rotation by slerp, ``R_a exp(weight log(R_a^T R_b))`` (the geodesic on SO(3), so 0 gives
    ``a``'s rotation and 1 ``b``'s); translation linearly. Undefined (any of the two geodesics)
    where the two rotations are half a turn apart.
    """
    ta, tb = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    relative = ta[:3, :3].T @ tb[:3, :3]
    axis_angle = cv2.Rodrigues(relative)[0]
    rotation = ta[:3, :3] @ cv2.Rodrigues(weight * axis_angle)[0]
    return make_transform(rotation, (1.0 - weight) * ta[:3, 3] + weight * tb[:3, 3])


#: Metres: larger translations are not poses (products of such numbers overflow).
MAX_TRANSLATION = 1e9


def check_rigid(transform: ArrayLike, name: str) -> NDArray[np.float64]:
    """Return ``transform`` as a float64 4x4 rigid transform or raise ValueError naming ``name``.

    Rigid: finite, last row ``(0, 0, 0, 1)``, ``R^T R = I`` within ``RIGID_TOL`` and ``det R > 0``.
    """
    try:
        t = np.array(transform, dtype=np.float64)  # a copy: callers may reuse their array
    except (TypeError, ValueError, OverflowError):
        raise ValueError(f"{name}: expected a 4x4 rigid transform of numbers") from None
    if t.shape != (4, 4):
        raise ValueError(f"{name}: expected a 4x4 rigid transform, got shape {t.shape}")
    if not np.isfinite(t).all():
        raise ValueError(f"{name}: expected finite values in the 4x4 transform")
    if np.abs(t[:3, 3]).max() > MAX_TRANSLATION:
        raise ValueError(f"{name}: translation {t[:3, 3].tolist()} is beyond "
                         f"{MAX_TRANSLATION:g} m (not a pose in metres)")
    if np.abs(t[3] - _LAST_ROW).max() > RIGID_TOL:
        raise ValueError(f"{name}: expected last row (0, 0, 0, 1), got {t[3].tolist()}")
    r = t[:3, :3]
    err = np.abs(r.T @ r - _EYE3).max()
    (a, b, c), (d, e, f), (g, h, i) = r.tolist()  # det by cofactors: np.linalg.det costs 10x more
    if err > RIGID_TOL or a * (e * i - f * h) - b * (d * i - f * g) + c * (d * h - e * g) <= 0:
        raise ValueError(
            f"{name}: expected a rotation (R^T R = I, det R = +1), off by {err:.3g}; "
            "the transform is not rigid"
        )
    return t
