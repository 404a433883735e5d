"""Detection on the real fisheye clips in ``data/real`` (Project Aria): no ground truth masks, so
the report shows the annotated frames and measures what can be measured without them.

Each clip folder holds ``device_calibration_full.json`` and camera folders with frames and,
where the recording has them, a ``poses*.csv``. The clips are head-mounted and indoors: there
is no road (``Road.unknown()``: the epipolar and positive-depth constraints only), and they are
10-30 Hz clips of 3-9 frames, so consecutive frames are compared (``frame_gap=1``); the rest
are the defaults, scaled to each camera's resolution.

The moving object of the office clip is the wearer's arm, one region: the share of valid pixels
flagged *outside the largest region* bounds the static background flagged. Where a clip has
ground-truth masks (``ground_truth/moving/<camera>/<frame>.png``, written from the Aria Digital
Twin's instance segmentation by the script beside them: 255 on objects that move, 128 in the
wearer's 2-D box, 0 static), the static background flagged is measured on them: the flagged share
of the valid static pixels outside the wearer's box and more than :data:`TOLERANCE_PX` from a
moving object. Each clip runs twice:
with its VIO poses, and with none (estimated from the images, :mod:`fisheyemotion.egomotion`),
where the estimated rotations are compared with the VIO's; a clip without poses (the AEA
bedroom) runs without only. Where two cameras of one rig saw the same instants, their estimated
rotations are compared with each other through the factory extrinsics
(:func:`~fisheyemotion.eval.pose_sources.rig_disagreement`): an error bound without ground
truth.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
import pandas as pd
from matplotlib.figure import Figure
from skimage.measure import label

from fisheyemotion import calib, draw
from fisheyemotion.detector import MotionDetector
from fisheyemotion.frames import to_gray
from fisheyemotion.inputs import ImageFolder
from fisheyemotion.params import Params
from fisheyemotion.poses import PoseMatcher, read_poses
from fisheyemotion.road import Road

from .pose_sources import pose_errors, rig_disagreement

__all__ = ["PAIRS", "RealClip", "TOLERANCE_PX", "find_clips", "run_pairs", "run_real",
           "static_flagged"]

#: Boundary tolerance of the ground-truth measure: pixels this close to a moving object are not
#: scored (a dense flow's 15-px window and one 6-px grid cell cannot place a boundary closer).
TOLERANCE_PX = 16


@dataclass(frozen=True)
class RealClip:
    name: str
    camera: str
    folder: Path
    calibration: Path
    poses: Path | None


#: The uncalibrated circular fisheye frame pairs (``data/real/fisheye_mc_pairs/<scene>/``, two
#: frames each), run with a nominal camera from their image circle.
PAIRS = "fisheye_mc_pairs"
#: Grey levels by which a still camera's two frames (smoothed 5x5) differ where something moved.
CHANGED_LEVELS = 20


#: Seconds within which two cameras' frames are taken to be of one instant.
SAME_INSTANT = 1e-3


def find_clips(data: Path) -> list[RealClip]:
    """Camera folders of ``data/real`` with a calibration, frames and one pose file or none
    (``poses`` None)."""
    clips = []
    for cal in sorted((data / "real").glob("*/device_calibration_full.json")):
        rig = calib.load_rig(cal)
        for folder in sorted(p for p in cal.parent.iterdir() if p.is_dir()):
            poses = sorted(folder.glob("poses*.csv"))
            if folder.name in rig.names and len(poses) <= 1 and any(folder.glob("*.png")):
                clips.append(RealClip(cal.parent.name, folder.name, folder, cal,
                                      poses[0] if poses else None))
    return clips


def static_flagged(mask: np.ndarray, truth: np.ndarray, valid: np.ndarray,
                   tolerance: int = TOLERANCE_PX) -> tuple[float, float]:
    """Static background flagged and moving-object pixels flagged, against a ground-truth mask.

    Parameters
    ----------
    mask : (H, W) bool
        The detection.
    truth : (H, W) uint8
        255 on moving objects, 128 where moving and static cannot be told apart (the wearer's
        box), 0 static.
    valid : (H, W) bool
        The camera's valid pixels.
    tolerance : int
        Pixels within this distance of a moving object are not scored as static.

    Returns
    -------
    static_share, moving_share : float
        The flagged fraction of the scored static pixels and of the moving objects' pixels
        (NaN where there are none).
    """
    moving = truth == 255
    size = 2 * tolerance + 1
    band = cv2.dilate(moving.astype(np.uint8),
                      cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (size, size))) > 0
    static = valid & (truth == 0) & ~band
    share = float(mask[static].mean()) if static.any() else np.nan
    found = float(mask[moving].mean()) if moving.any() else np.nan
    return share, found


def run_real(data: Path, params: Params | None = None) -> tuple[pd.DataFrame, Figure | None]:
    """Detect on every clip; a table (one row per clip camera) and a figure of the last
    annotated frame of each."""
    params = Params(frame_gap=1) if params is None else params
    rows, shown = [], []
    # Without poses, per (clip, camera): the frames' stamps, the poses used, the extrinsic.
    estimates: dict[tuple[str, str], tuple[list, list, np.ndarray | None]] = {}
    for clip in find_clips(data):
        rig = calib.load_rig(clip.calibration)
        cam = rig[clip.camera]
        matcher = None if clip.poses is None else PoseMatcher(read_poses(clip.poses))
        valid = cam.valid_pixel_mask()
        frames = ImageFolder(clip.folder)
        row = {"clip": clip.name, "camera": clip.camera, "model": cam.name,
               "size": f"{cam.width}x{cam.height}", "frames": len(frames)}
        last = None
        # The clip's VIO poses, then none (estimated); a clip without poses runs without only.
        for given in (True, False) if matcher is not None else (False,):
            det = MotionDetector(cam, Road.unknown(), params.for_camera(cam))
            flagged, outside, regions, used, vio, truth, stamps = [], [], [], [], [], [], []
            for f in frames:
                pose = None if matcher is None else matcher(f.index, f.name, f.stamp)[1]
                result = det.apply(f.image, pose if given else None)
                used.append(det.last_pose)
                vio.append(pose)
                stamps.append(f.stamp)
                if result is None:
                    continue
                mask = (result.mask > 0) & valid
                labels = label(mask)
                biggest = np.bincount(labels.ravel())[1:].max() if labels.max() else 0
                flagged.append(mask.sum() / valid.sum())
                outside.append((mask.sum() - biggest) / valid.sum())
                regions.append(len(result.regions))
                gt = clip.folder.parent / "ground_truth" / "moving" / clip.camera / f.name
                if gt.is_file():
                    truth.append(static_flagged(mask, cv2.imread(str(gt), cv2.IMREAD_GRAYSCALE),
                                                valid))
                if given or matcher is None:  # shown: with its own poses where it has them
                    last = (f.image, result, f"{clip.name} / {clip.camera} #{f.index}"
                            + ("" if given else ", no poses"))
            if given:
                row.update({"detections": len(flagged),
                            "flagged %": _percent(flagged),
                            "outside the largest region %": _percent(outside),
                            "regions per frame": float(np.mean(regions)) if regions else np.nan,
                            "ground truth: static flagged %": _percent([t[0] for t in truth]),
                            "ground truth: moving objects' pixels flagged %":
                            _percent([t[1] for t in truth])})
            else:
                errors = (pose_errors(np.array(used), np.array(vio), 1).rotation_error_deg
                          if matcher is not None else None)
                row.update({"no poses: flagged %": _percent(flagged),
                            "no poses: outside the largest region %": _percent(outside),
                            "no poses: rotation error vs VIO, median / max (deg)":
                            "–" if errors is None else
                            f"{errors.median():.2f} / {errors.max():.2f}",
                            "no poses, ground truth: static flagged %":
                            _percent([t[0] for t in truth])})
                estimates[clip.name, clip.camera] = (stamps, used, rig.extrinsic(clip.camera))
        if last is not None:
            shown.append(last)
        rows.append(row)
    table = pd.DataFrame(rows)
    if len(table):
        table["no poses: rotation vs the rig's other camera, median / max (deg)"] = [
            _rig_agreement(estimates, clip, camera)
            for clip, camera in zip(table["clip"], table["camera"], strict=True)]
    fig = _annotated_figure(shown, "Real fisheye clips (Project Aria): detected regions in "
                            "green, no road (indoors, head-mounted)", (3.4, 3.6))
    return table, fig


def _rig_agreement(estimates: dict, clip: str, camera: str) -> str:
    """The rotations estimated without poses for ``camera`` of ``clip`` against those of the
    clip's next camera (in the order run, cyclic) at the instants both saw, through the rig's
    extrinsics (:func:`~fisheyemotion.eval.pose_sources.rig_disagreement`): ``"median / max"``
    degrees, or "–" (one camera, no extrinsics, or fewer than two shared instants)."""
    cameras = [name for c, name in estimates if c == clip]
    if len(cameras) < 2:
        return "–"
    other = cameras[(cameras.index(camera) + 1) % len(cameras)]
    (stamps_a, poses_a, ext_a), (stamps_b, poses_b, ext_b) = (estimates[clip, camera],
                                                              estimates[clip, other])
    shared = [(i, j) for i, a in enumerate(stamps_a) for j, b in enumerate(stamps_b)
              if a is not None and b is not None and abs(a - b) <= SAME_INSTANT]
    if len(shared) < 2 or ext_a is None or ext_b is None:
        return "–"
    degrees = rig_disagreement(np.array([poses_a[i] for i, _ in shared]), ext_a,
                               np.array([poses_b[j] for _, j in shared]), ext_b)
    return f"{np.median(degrees):.2f} / {degrees.max():.2f}"


def _annotated_figure(shown: list[tuple[np.ndarray, object, str]], title: str,
                      size: tuple[float, float]) -> Figure | None:
    """One panel per ``(frame, result, caption)`` of ``shown``: the frame annotated with the
    result's regions; ``size`` (inches) per panel. None for nothing shown."""
    if not shown:
        return None
    fig = Figure(figsize=(size[0] * len(shown), size[1]), layout="constrained")
    for ax, (image, result, caption) in zip(np.atleast_1d(fig.subplots(1, len(shown))), shown,
                                            strict=True):
        ax.imshow(draw.annotate(image, result)[..., ::-1])
        ax.set_title(caption, fontsize=8)
        ax.set_axis_off()
    fig.suptitle(title, fontsize=9)
    return fig


def run_pairs(data: Path, params: Params | None = None, *, fov_deg: float = 180.0
              ) -> tuple[pd.DataFrame, Figure] | None:
    """Detect on each uncalibrated frame pair of ``data/real/fisheye_mc_pairs`` (None if there
    are none): a nominal equidistant camera from the first frame's image circle
    (:mod:`fisheyemotion.calib.circle`, ``fov_deg`` across), the poses from the images, the
    consecutive frames compared, no road. Where the camera stands still, the frames' difference
    (more than ``CHANGED_LEVELS`` grey levels, smoothed 5x5) is what moved: the table gives the
    share of it the detection covers and the share of the detection within 15 px of it. Returns
    the table (one row per pair) and a figure of each pair's annotated second frame."""
    root = data / "real" / PAIRS
    if not root.is_dir():
        return None
    params = Params(frame_gap=1) if params is None else params
    rows, shown = [], []
    for scene in sorted(p for p in root.iterdir() if p.is_dir()):
        frames = [f.image for f in ImageFolder(scene)]
        if len(frames) != 2:
            continue
        prev, curr = (to_gray(f, "frame") for f in frames)
        circle = calib.find_image_circle(prev)
        cam = calib.nominal_camera(circle, prev.shape[1], prev.shape[0], fov_deg=fov_deg)
        inside = circle.mask(cam.width, cam.height)
        det = MotionDetector(cam, Road.unknown(), params.for_camera(cam), roi=inside)
        det.apply(prev)
        result = det.apply(curr)
        inside = inside > 0
        flagged = (result.mask > 0) & inside
        still = result.static_camera  # the poses from the images stood still
        row = {"pair": scene.name, "size": f"{cam.width}x{cam.height}",
               "image circle (cx, cy, radius px)":
               f"{circle.cx:.1f}, {circle.cy:.1f}, {circle.radius:.1f}",
               "camera (estimated)": "still" if still else "moving",
               "flagged %": 100 * float(flagged[inside].mean()),
               "regions": len(result.regions)}
        if still:
            changed = (cv2.absdiff(cv2.GaussianBlur(prev, (5, 5), 0), cv2.GaussianBlur(
                curr, (5, 5), 0)) > CHANGED_LEVELS) & inside
            near = cv2.dilate(changed.astype(np.uint8), np.ones((31, 31), np.uint8)) > 0
            row["changed pixels flagged %"] = 100 * float(flagged[changed].mean())
            row["flagged within 15 px of a change %"] = (
                100 * float(near[flagged].mean()) if flagged.any() else np.nan)
        rows.append(row)
        shown.append((curr, result, f"{scene.name}: camera {row['camera (estimated)']}"))
    if not rows:
        return None
    return pd.DataFrame(rows), _annotated_figure(
        shown, "Real frame pairs without a calibration: a nominal camera from the image circle, "
        "poses from the images; detected regions in green", (3.0, 3.3))


def _percent(shares: list[float]) -> float:
    """The mean of ``shares`` in percent (NaN for none)."""
    return 100 * float(np.mean(shares)) if shares else np.nan
