"""Frame sources for the command line: videos, image folders, sequence folders, ROS bags.

Every source yields :class:`Frame` records: the frame's position in the input, its name (file
name, or None for a video), its time in seconds (None when unknown) and the image (BGR or gray
uint8, as cv2 reads it). ``len()`` is the number of frames where the source knows it.
"""

from __future__ import annotations

import csv
import math
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
from numpy.typing import NDArray

IMAGE_SUFFIXES = {".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff"}

__all__ = ["Frame", "FrameSource", "ImageFolder", "VideoFile", "open_source"]


@dataclass(frozen=True)
class Frame:
    index: int
    name: str | None
    stamp: float | None
    image: NDArray[np.uint8]


class FrameSource:
    """Base: iterate for frames; ``fps`` is the source's frame rate (None when unknown)."""

    fps: float | None = None

    def __iter__(self) -> Iterator[Frame]:  # pragma: no cover - interface
        raise NotImplementedError

    def __len__(self) -> int:  # pragma: no cover - interface
        raise NotImplementedError


def _stamp_from_name(path: Path) -> float | None:
    """Seconds from a file stem that is a time: nanoseconds (16+ digits, EuRoC, TUM VI, Aria)
    or seconds with a fraction (``1403636579.763555.png``); None otherwise (``000012.png``)."""
    stem = path.stem
    digits = stem.split(".")[0]
    if not digits.isdigit():
        return None
    if len(digits) >= 16 and "." not in stem:
        return int(stem) * 1e-9
    if "." in stem:
        try:
            return float(stem)
        except ValueError:
            return None
    return None


class ImageFolder(FrameSource):
    """The images of a folder (or its ``frames/`` subfolder), sorted by name. Times come from
    a ``timestamps.csv`` beside them (``file`` and a column whose name starts with ``time`` or
    contains ``timestamp``, in ns when its name says so, else seconds) or from names that are
    times."""

    def __init__(self, folder: Path) -> None:
        self.folder = folder / "frames" if (folder / "frames").is_dir() else folder
        self.paths = sorted(p for p in self.folder.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES)
        if not self.paths:
            raise ValueError(f"{folder}: no images ({', '.join(sorted(IMAGE_SUFFIXES))})")
        self.stamps = self._read_stamps()
        known = [t for t in self.stamps.values() if t is not None]
        steps = np.diff(sorted(known)) if len(known) > 1 else np.array([])
        self.fps = float(1.0 / np.median(steps)) if len(steps) and np.median(steps) > 0 else None

    def _read_stamps(self) -> dict[str, float | None]:
        table = self.folder / "timestamps.csv"
        stamps = {p.name: _stamp_from_name(p) for p in self.paths}
        if not table.is_file():
            return stamps
        try:
            with table.open(newline="", encoding="utf-8") as fh:
                rows = list(csv.DictReader(fh))
        except (UnicodeDecodeError, csv.Error) as exc:
            raise ValueError(f"{table}: cannot be read as CSV: {exc}") from None
        if not rows or "file" not in rows[0]:
            raise ValueError(f"{table}: expected a header with 'file' and a timestamp column")
        cols = [c for c in rows[0] if c != "file" and ("timestamp" in c or c.startswith("time"))]
        if not cols:
            raise ValueError(f"{table}: no timestamp column (header: {list(rows[0])})")
        col = cols[0]
        scale = 1e-9 if "ns" in col else 1e-6 if "us" in col else 1.0
        for lineno, row in enumerate(rows, start=2):
            try:
                t = float(row[col]) * scale
            except (TypeError, ValueError):
                raise ValueError(f"{table}: line {lineno}: {col}: expected a number, got "
                                 f"{row[col]!r}") from None
            if not math.isfinite(t):
                raise ValueError(f"{table}: line {lineno}: {col}: expected a finite number")
            if row["file"] in stamps:
                stamps[row["file"]] = t
        return stamps

    def __len__(self) -> int:
        return len(self.paths)

    def __iter__(self) -> Iterator[Frame]:
        for i, p in enumerate(self.paths):
            img = cv2.imread(str(p), cv2.IMREAD_UNCHANGED)
            if img is None or img.dtype != np.uint8 or img.ndim not in (2, 3):
                raise ValueError(f"{p}: cannot be read as an 8-bit image")
            if img.ndim == 3 and img.shape[2] == 4:
                img = cv2.cvtColor(img, cv2.COLOR_BGRA2BGR)
            yield Frame(i, p.name, self.stamps[p.name], img)


class VideoFile(FrameSource):
    """A video file read with OpenCV; times from the container (seconds)."""

    def __init__(self, path: Path) -> None:
        cap = cv2.VideoCapture(str(path))
        if not cap.isOpened():
            raise ValueError(f"{path}: cannot be opened as a video")
        fps = cap.get(cv2.CAP_PROP_FPS)
        self.count = int(cap.get(cv2.CAP_PROP_FRAME_COUNT))
        cap.release()
        self.path = path
        self.fps = float(fps) if math.isfinite(fps) and fps > 0 else None

    def __len__(self) -> int:
        return max(self.count, 0)

    def __iter__(self) -> Iterator[Frame]:
        cap = cv2.VideoCapture(str(self.path))
        i = 0
        try:
            while True:
                ok, img = cap.read()
                if not ok:
                    break
                stamp = cap.get(cv2.CAP_PROP_POS_MSEC) / 1000.0
                if self.fps:
                    stamp = i / self.fps
                yield Frame(i, None, stamp, img)
                i += 1
        finally:
            cap.release()


def open_source(path: Path, **bag_options) -> FrameSource:
    """The frame source for ``path``: a folder of images (or a sequence folder), a ROS bag
    (``.bag``, or a ROS 2 bag folder with ``metadata.yaml``), or a video file."""
    if not path.exists():
        raise ValueError(f"{path}: no such file or folder")
    from . import rosbag

    if rosbag.is_bag(path):
        return rosbag.BagSource(path, **bag_options)
    if path.is_dir():
        return ImageFolder(path)
    return VideoFile(path)
