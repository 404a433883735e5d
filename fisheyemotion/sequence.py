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
        return yaml.safe_load(p.read_text()) if p.exists() else {}

    @cached_property
    def objects(self) -> pd.DataFrame:
        p = self.path / "objects.csv"
        if not p.exists():
            return pd.DataFrame(columns=list(OBJECT_COLUMNS))
        return pd.read_csv(p)

    def frame(self, index: int) -> NDArray[np.uint8]:
        img = cv2.imread(str(self.frame_paths[index]), cv2.IMREAD_COLOR)
        if img is None:
            raise ValueError(f"{self.frame_paths[index]}: cannot be read as an image")
        return img

    def _png(self, folder: str, index: int, flags: int) -> NDArray | None:
        p = self.path / folder / self.frame_paths[index].name
        return cv2.imread(str(p), flags) if p.exists() else None

    def mask(self, index: int) -> NDArray[np.uint8] | None:
        return self._png("masks", index, cv2.IMREAD_GRAYSCALE)

    def ids(self, index: int) -> NDArray[np.uint16] | None:
        return self._png("ids", index, cv2.IMREAD_UNCHANGED)

    def roi(self) -> NDArray[np.uint8] | None:
        p = self.path / "roi.png"
        return cv2.imread(str(p), cv2.IMREAD_GRAYSCALE) if p.exists() else None

    def flow(self, index: int) -> dict[str, NDArray] | None:
        p = self.path / "flow" / self.frame_paths[index].name.replace(".png", ".npz")
        if not p.exists():
            return None
        with np.load(p) as z:
            return {k: z[k] for k in z.files}
