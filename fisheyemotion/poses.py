"""Pose files in TUM format: ``timestamp tx ty tz qx qy qz qw`` per line, ``world_from_cam``."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from .calib.transforms import make_transform, matrix_to_quat, quat_to_matrix


def read_tum(path: str | os.PathLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Timestamps ``(N,)`` and poses ``(N, 4, 4)`` (``world_from_cam``) of a TUM file.

    Lines starting with ``#`` and blank lines are skipped. Raises ValueError naming the file and
    line for anything else that is not 8 finite numbers with a unit quaternion.
    """
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ValueError(f"{p}: no such pose file") from None
    stamps, poses = [], []
    for lineno, line in enumerate(text.splitlines(), start=1):
        s = line.strip()
        if not s or s.startswith("#"):
            continue
        parts = s.replace(",", " ").split()
        if len(parts) != 8:
            raise ValueError(f"{p}: line {lineno}: expected 8 numbers "
                             f"'timestamp tx ty tz qx qy qz qw', got {len(parts)}")
        try:
            v = [float(x) for x in parts]
        except ValueError:
            raise ValueError(f"{p}: line {lineno}: expected numbers, got {s!r}") from None
        if not np.isfinite(v).all():
            raise ValueError(f"{p}: line {lineno}: expected finite numbers")
        try:
            r = quat_to_matrix(v[4:8])
        except ValueError as exc:
            raise ValueError(f"{p}: line {lineno}: {exc}") from None
        stamps.append(v[0])
        poses.append(make_transform(r, v[1:4]))
    if not poses:
        raise ValueError(f"{p}: no poses")
    return np.array(stamps), np.array(poses)


def write_tum(path: str | os.PathLike, timestamps, poses) -> None:
    """Write ``world_from_cam`` poses ``(N, 4, 4)`` with their timestamps in TUM format."""
    lines = ["# timestamp tx ty tz qx qy qz qw (world_from_cam)"]
    for t, pose in zip(timestamps, poses, strict=True):
        q = matrix_to_quat(pose[:3, :3])
        vals = [t, *pose[:3, 3], *q]
        lines.append(" ".join(repr(float(x)) for x in vals))
    Path(path).write_text("\n".join(lines) + "\n", encoding="utf-8")
