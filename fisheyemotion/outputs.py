"""Output folders written whole or not at all, and the region records of a detection."""

from __future__ import annotations

import math
import shutil
import tempfile
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from .calib.base import CameraModel
from .road import Road

__all__ = ["atomic_folder", "region_records"]


@contextmanager
def atomic_folder(out: Path, *, overwrite: bool = False):
    """Yield a temporary folder beside ``out`` that becomes ``out`` only when the block ends
    without an exception (Ctrl-C included): ``out`` never holds half old, half new files.

    A non-empty existing ``out`` is refused (ValueError) unless ``overwrite``; then it is
    replaced as a whole.
    """
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise ValueError(f"--out: {out} exists and is not a folder")
    if out.is_dir() and any(out.iterdir()) and not overwrite:
        raise ValueError(f"--out: {out} is not empty; give --overwrite to replace it")
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.partial-", dir=out.parent))
    try:
        yield tmp
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    old = None
    if out.exists():
        old = Path(tempfile.mkdtemp(prefix=f".{out.name}.old-", dir=out.parent))
        old.rmdir()
        out.rename(old)
    tmp.rename(out)
    if old is not None:
        shutil.rmtree(old, ignore_errors=True)


def region_records(regions, camera: CameraModel, pose: np.ndarray, road: Road) -> list[dict]:
    """One record per region: its box and likelihood, the bearing of its centroid (degrees,
    camera frame: azimuth right of the optical axis, elevation above it) and, where the ray
    through the bottom centre of its box meets the road within 200 m, the ground distance
    (metres, along the road from the point below the camera)."""
    rows = []
    for r in regions:
        x, y, w, h = r.bbox
        ray, ok = camera.unproject(np.array(r.centroid, dtype=np.float64))
        az = el = math.nan
        if ok:
            az = math.degrees(math.atan2(ray[0], ray[2]))
            el = math.degrees(math.atan2(-ray[1], math.hypot(ray[0], ray[2])))
        distance = math.nan
        if road.known:
            foot, ok = camera.unproject(np.array([x + (w - 1) / 2, y + h - 1], dtype=np.float64))
            if ok:
                d = pose[:3, :3] @ foot
                reach = float(road.ray_range(pose[:3, 3], d, min_down=1e-6))
                if reach < 200:
                    below = pose[:3, 3] - float(road.height(pose[:3, 3])) * road.up
                    distance = float(np.linalg.norm(pose[:3, 3] + reach * d - below))
        rows.append({"label": r.label, "x": x, "y": y, "w": w, "h": h, "area": r.area,
                     "mean_likelihood": r.mean_likelihood, "u": r.centroid[0],
                     "v": r.centroid[1], "azimuth_deg": az, "elevation_deg": el,
                     "ground_distance_m": distance})
    return rows
