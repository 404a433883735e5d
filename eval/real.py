"""Detection on the real fisheye clips in ``data/real`` (Project Aria): no ground truth masks, so
the report shows the annotated frames and measures what can be measured without them.

Each clip folder holds ``device_calibration_full.json`` and camera folders with frames and a
``poses*.csv``. The clips are head-mounted and indoors: there is no road (``Road.unknown()``:
the epipolar and positive-depth constraints only), and they are 30 Hz clips of 3-9 frames, so
consecutive frames are compared (``frame_gap=1``); the rest are the defaults, scaled to each
camera's resolution.

The moving object of the office clip is the wearer's arm, one region: the share of valid pixels
flagged *outside the largest region* bounds the static background flagged. Each clip runs twice:
with its VIO poses, and with none (estimated from the images, :mod:`fisheyemotion.egomotion`),
where the estimated rotations are compared with the VIO's.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
from matplotlib.figure import Figure
from skimage.measure import label

from fisheyemotion import calib, draw
from fisheyemotion.detect import MotionDetector
from fisheyemotion.inputs import ImageFolder
from fisheyemotion.params import Params
from fisheyemotion.poses import PoseMatcher, read_poses
from fisheyemotion.road import Road

from .pose_sources import pose_errors

__all__ = ["RealClip", "find_clips", "run_real"]


@dataclass(frozen=True)
class RealClip:
    name: str
    camera: str
    folder: Path
    calibration: Path
    poses: Path


def find_clips(data: Path) -> list[RealClip]:
    """Camera folders of ``data/real`` with a calibration and a pose file."""
    clips = []
    for cal in sorted((data / "real").glob("*/device_calibration_full.json")):
        rig = calib.load_rig(cal)
        for folder in sorted(p for p in cal.parent.iterdir() if p.is_dir()):
            poses = sorted(folder.glob("poses*.csv"))
            if folder.name in rig.names and len(poses) == 1:
                clips.append(RealClip(cal.parent.name, folder.name, folder, cal, poses[0]))
    return clips


def run_real(data: Path, params: Params | None = None) -> tuple[pd.DataFrame, Figure | None]:
    """Detect on every clip; a table (one row per clip camera) and a figure of the last
    annotated frame of each."""
    params = Params(frame_gap=1) if params is None else params
    rows, shown = [], []
    for clip in find_clips(data):
        cam = calib.load(clip.calibration, clip.camera)
        matcher = PoseMatcher(read_poses(clip.poses))
        valid = cam.valid_pixel_mask()
        frames = ImageFolder(clip.folder)
        row = {"clip": clip.name, "camera": clip.camera, "model": cam.name,
               "size": f"{cam.width}x{cam.height}", "frames": len(frames)}
        last = None
        for given in (True, False):  # the clip's VIO poses, then none (estimated)
            det = MotionDetector(cam, Road.unknown(), params.for_camera(cam))
            flagged, outside, regions, used, vio = [], [], [], [], []
            for f in frames:
                pose = matcher(f.index, f.name, f.stamp)[1]
                result = det.apply(f.image, pose if given else None)
                used.append(det.last_pose)
                vio.append(pose)
                if result is None:
                    continue
                mask = (result.mask > 0) & valid
                labels = label(mask)
                biggest = np.bincount(labels.ravel())[1:].max() if labels.max() else 0
                flagged.append(mask.sum() / valid.sum())
                outside.append((mask.sum() - biggest) / valid.sum())
                regions.append(len(result.regions))
                if given:
                    last = (f.image, result, f"{clip.name} / {clip.camera} #{f.index}")
            if given:
                row.update({"detections": len(flagged),
                            "flagged %": 100 * float(np.mean(flagged)) if flagged else np.nan,
                            "outside the largest region %": 100 * float(np.mean(outside))
                            if outside else np.nan,
                            "regions per frame": float(np.mean(regions)) if regions else np.nan})
                if last is not None:
                    shown.append(last)
            else:
                errors = pose_errors(np.array(used), np.array(vio), 1).rotation_error_deg
                row.update({"no poses: outside the largest region %":
                            100 * float(np.mean(outside)) if outside else np.nan,
                            "no poses: rotation error vs VIO, median / max (deg)":
                            f"{errors.median():.2f} / {errors.max():.2f}"})
        rows.append(row)
    fig = None
    if shown:
        fig = Figure(figsize=(3.4 * len(shown), 3.6), layout="constrained")
        axes = np.atleast_1d(fig.subplots(1, len(shown)))
        for ax, (image, result, title) in zip(axes, shown, strict=True):
            ax.imshow(draw.annotate(image, result)[..., ::-1])
            ax.set_title(title, fontsize=8)
            ax.set_axis_off()
        fig.suptitle("Real fisheye clips (Project Aria): detected regions in green, no road "
                     "(indoors, head-mounted)", fontsize=9)
    return pd.DataFrame(rows), fig
