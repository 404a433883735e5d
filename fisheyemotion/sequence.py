"""The on-disk sequence format that ``synth`` writes and ``detect``/``eval`` read.

A folder per sequence::

    frames/NNNNNN.png     images (BGR)
    masks/NNNNNN.png      moving-object mask (uint8 0/255)
    ids/NNNNNN.png        object ids (uint16 PNG; 0 = road, sky, outside the camera)
    flow/NNNNNN.npz       optional: ``flow`` (H, W, 2) from frame N-1 to N, ``range`` (H, W)
    poses.txt             TUM format, world_from_cam, timestamp = frame / fps
    calib.yaml            OpenCV FileStorage (readable by fisheyemotion.calib.load)
    roi.png               optional: 255 where the camera sees the scene, 0 on the vehicle's body
    objects.csv           frame, id, kind, category, moving, distance, visible_pixels
    scenario.yaml         the spec the sequence was rendered from
"""

from __future__ import annotations

import os
from functools import cached_property
from pathlib import Path

import cv2
import numpy as np
import pandas as pd
import yaml
from numpy.typing import NDArray

from . import calib
from .calib.base import CameraModel
from .poses import read_tum

OBJECT_COLUMNS = ("frame", "id", "kind", "category", "moving", "distance", "visible_pixels")


def frame_name(index: int) -> str:
    return f"{index:06d}.png"


class Sequence:
    """Read access to a sequence folder (see the module docstring).

    Parameters
    ----------
    path : str or path-like
    """

    def __init__(self, path: str | os.PathLike) -> None:
        self.path = Path(path)
        if not (self.path / "frames").is_dir():
            raise ValueError(f"{self.path}: not a sequence folder (no frames/)")
        self.frame_paths = sorted((self.path / "frames").glob("*.png"))
        for sub in ("masks", "ids"):
            if (self.path / "objects.csv").exists() and not (self.path / sub).is_dir():
                raise ValueError(f"{self.path / sub}: missing (the sequence's ground truth)")
        if len(self.frame_paths) < 2:
            raise ValueError(f"{self.path}: frames/: expected at least 2 frames")

    def __len__(self) -> int:
        return len(self.frame_paths)

    @property
    def name(self) -> str:
        return self.path.name

    @cached_property
    def camera(self) -> CameraModel:
        return calib.load(self.path / "calib.yaml")

    @cached_property
    def _poses(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        stamps, poses = read_tum(self.path / "poses.txt")
        if len(poses) != len(self):
            raise ValueError(f"{self.path / 'poses.txt'}: expected {len(self)} poses (one per "
                             f"frame), got {len(poses)}")
        return stamps, poses

    @property
    def timestamps(self) -> NDArray[np.float64]:
        return self._poses[0]

    @property
    def poses(self) -> NDArray[np.float64]:
        return self._poses[1]

    @cached_property
    def scenario(self) -> dict:
        p = self.path / "scenario.yaml"
        if not p.exists():
            return {}
        try:
            return yaml.safe_load(p.read_text(encoding="utf-8")) or {}
        except (yaml.YAMLError, UnicodeDecodeError, RecursionError) as exc:
            raise ValueError(f"{p}: cannot be read as YAML: {str(exc)[:200]}") from None

    @cached_property
    def objects(self) -> pd.DataFrame:
        p = self.path / "objects.csv"
        if not p.exists():
            return pd.DataFrame(columns=list(OBJECT_COLUMNS))
        try:
            table = pd.read_csv(p)
        except (ValueError, UnicodeDecodeError, pd.errors.ParserError) as exc:
            raise ValueError(f"{p}: cannot be read as CSV: {str(exc)[:200]}") from None
        missing = [c for c in OBJECT_COLUMNS if c not in table.columns]
        if missing:
            raise ValueError(f"{p}: missing column(s) {missing}")
        for col in ("frame", "id", "distance", "visible_pixels"):
            if not pd.api.types.is_numeric_dtype(table[col]):
                raise ValueError(f"{p}: {col}: expected numbers")
        if table["moving"].dtype != bool:
            try:
                table["moving"] = table["moving"].map(
                    {True: True, False: False, "True": True, "False": False}).astype(bool)
            except (TypeError, ValueError):
                raise ValueError(f"{p}: moving: expected True or False") from None
        return table

    def frame(self, index: int) -> NDArray[np.uint8]:
        img = cv2.imread(str(self.frame_paths[index]), cv2.IMREAD_COLOR)
        if img is None:
            raise ValueError(f"{self.frame_paths[index]}: cannot be read as an image")
        return img

    def _png(self, folder: str, index: int, flags: int, dtypes: tuple) -> NDArray:
        """A ground-truth image of frame ``index``: present, readable, of the frame's size."""
        p = self.path / folder / self.frame_paths[index].name
        if not p.is_file():
            raise ValueError(f"{p}: missing (the ground truth of {self.frame_paths[index].name})")
        img = cv2.imread(str(p), flags)
        if img is None or img.ndim != 2 or img.dtype not in dtypes:
            raise ValueError(f"{p}: cannot be read as a single-channel "
                             f"{'/'.join(np.dtype(d).name for d in dtypes)} image")
        return self._of_camera_size(p, img)

    def _of_camera_size(self, p: Path, img: NDArray) -> NDArray:
        """``img`` read from ``p``, or a ValueError naming it when its size is not the camera's."""
        if img.shape[:2] != (self.camera.height, self.camera.width):
            raise ValueError(f"{p}: expected {self.camera.width}x{self.camera.height} (the "
                             f"camera's size), got {img.shape[1]}x{img.shape[0]}")
        return img

    def mask(self, index: int) -> NDArray[np.uint8]:
        return self._png("masks", index, cv2.IMREAD_GRAYSCALE, (np.uint8,))

    def ids(self, index: int) -> NDArray[np.uint16]:
        return self._png("ids", index, cv2.IMREAD_UNCHANGED, (np.uint8, np.uint16))

    def roi(self) -> NDArray[np.uint8] | None:
        p = self.path / "roi.png"
        if not p.exists():
            return None
        roi = cv2.imread(str(p), cv2.IMREAD_GRAYSCALE)
        if roi is None:
            raise ValueError(f"{p}: cannot be read as an image")
        return self._of_camera_size(p, roi)

    def flow(self, index: int) -> dict[str, NDArray] | None:
        p = self.path / "flow" / self.frame_paths[index].name.replace(".png", ".npz")
        if not p.exists():
            return None
        with np.load(p) as z:
            return {k: z[k] for k in z.files}
