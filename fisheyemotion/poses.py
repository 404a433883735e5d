"""Pose sources: trajectory files, extrinsics, interpolation at frame times, frame matching.

A :class:`Trajectory` is a time series of 4x4 rigid ``world_from_X`` poses, ``X`` being the
camera or a body (IMU, device, vehicle) that a calibration's extrinsics relate to the camera.

Formats read by :func:`read_poses` (detected from the name and the content)
-------------------------------------------------------------------------
=========  ============================================================================
``tum``    ``timestamp tx ty tz qx qy qz qw`` per line, seconds (``#`` comments)
``kitti``  12 numbers per line: the top 3x4 of the pose, row by row; no timestamps
``euroc``  EuRoC/ASL ground-truth CSV: ``#timestamp [ns], p_RS_R_x, ..., q_RS_w, q_RS_x,
           ...`` (quaternion w first), nanoseconds
``aria``   Project Aria per-frame CSV: ``file,timestamp_ns,tx,ty,tz,qx,qy,qz,qw,...``
           (poses named by their frame file)
``mps``    Project Aria MPS trajectory CSV (``closed_loop_trajectory.csv``,
           ``aria_trajectory.csv``): ``tracking_timestamp_us``, ``tx_world_device`` ...
           ``qw_world_device``: *device* poses (compose with ``T_Device_Camera``)
``csv``    any CSV whose header names the pose's columns ``tx ty tz qx qy qz qw``, each alone
           or as a prefix (``tx_odometry_device``), and a timestamp column whose name says its
           unit (``_ns``, ``_us``, ``_ms``, ``_s``; the ``tracking_`` one where there are
           several): Project Aria MPS open-loop trajectories (``open_loop_trajectory.csv``,
           *device* poses in the VIO's odometry frame; a ``session_uid`` column must hold one
           session, whose frame it names), on-device VIO exports, a tool's own pose logs
``npy``    ``.npy`` array ``(N, 4, 4)``; ``.npz`` with ``poses`` ``(N, 4, 4)`` and optional
           ``timestamps`` ``(N,)`` seconds and ``names`` ``(N,)``
=========  ============================================================================

Every malformed file raises ValueError naming the file and the line or field.

Frames are matched to poses by :class:`PoseMatcher`: by timestamp (interpolated: linear
translation, slerp rotation, within ``max_gap`` seconds of a pose on each side), by frame name,
or by index when the counts agree. A frame without a pose is an error naming the frame; poses are
never shifted onto other frames.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from .calib.transforms import (
    check_rigid,
    interpolate_transform,
    make_transform,
    matrix_to_quat,
    quat_to_matrix,
)

__all__ = ["POSE_FORMATS", "PoseMatcher", "Trajectory", "read_poses", "read_tum", "write_tum"]

POSE_FORMATS = ("tum", "kitti", "euroc", "aria", "mps", "csv", "npy")


@dataclass(frozen=True, eq=False)
class Trajectory:
    """Poses ``(N, 4, 4)`` ``world_from_X`` with optional timestamps (seconds, increasing) and
    names (e.g. the frame files they belong to)."""

    poses: NDArray[np.float64]
    stamps: NDArray[np.float64] | None = None
    names: tuple[str, ...] | None = None
    source: str = "<poses>"

    def __post_init__(self) -> None:
        poses = np.asarray(self.poses, dtype=np.float64)
        if poses.ndim != 3 or poses.shape[1:] != (4, 4) or len(poses) == 0:
            raise ValueError(f"{self.source}: expected poses of shape (N, 4, 4), N >= 1, got "
                             f"{poses.shape}")
        for i, pose in enumerate(poses):
            try:
                check_rigid(pose, "pose")
            except ValueError as exc:
                raise ValueError(f"{self.source}: pose {i}: {exc}") from None
        object.__setattr__(self, "poses", poses)
        if self.stamps is not None:
            stamps = np.asarray(self.stamps, dtype=np.float64)
            if stamps.shape != (len(poses),) or not np.isfinite(stamps).all():
                raise ValueError(f"{self.source}: expected {len(poses)} finite timestamps, got "
                                 f"shape {stamps.shape}")
            steps = np.diff(stamps)
            if (steps <= 0).any():
                i = int(np.argmax(steps <= 0)) + 1
                raise ValueError(f"{self.source}: timestamps must increase; pose {i} "
                                 f"(t={stamps[i]!r}) does not follow t={stamps[i - 1]!r}")
            object.__setattr__(self, "stamps", stamps)
        if self.names is not None:
            names = tuple(str(n) for n in self.names)
            if len(names) != len(poses) or len(set(names)) != len(names):
                raise ValueError(f"{self.source}: expected {len(poses)} distinct names")
            object.__setattr__(self, "names", names)

    def __len__(self) -> int:
        return len(self.poses)

    def compose(self, x_from_cam: NDArray) -> Trajectory:
        """The camera's trajectory from a body's: ``world_from_cam = world_from_X @ X_from_cam``
        (``X_from_cam``: the calibration's extrinsic of the camera, e.g. Basalt's ``T_imu_cam``,
        the inverse of Kalibr's ``T_cam_imu``, WoodScape's vehicle extrinsic, Aria's
        ``T_Device_Camera``)."""
        extrinsic = check_rigid(x_from_cam, "x_from_cam")
        return Trajectory(self.poses @ extrinsic, self.stamps, self.names, self.source)

    def at(self, times: NDArray | float, *, max_gap: float) -> NDArray[np.float64]:
        """Poses interpolated at ``times`` (seconds): translation linearly, rotation by slerp.

        A time must have a pose within ``max_gap`` seconds on each side (or coincide with one,
        or lie within ``max_gap`` beyond either end, which takes the end pose); anything else
        raises ValueError naming the time.
        """
        if self.stamps is None:
            raise ValueError(f"{self.source}: has no timestamps to interpolate at")
        if not isinstance(max_gap, int | float) or not math.isfinite(max_gap) or max_gap < 0:
            raise ValueError(f"max_gap: expected a finite number of seconds >= 0, got {max_gap!r}")
        s, eps = self.stamps, 1e-9
        t = np.atleast_1d(np.asarray(times, dtype=np.float64))
        out = np.empty((len(t), 4, 4))
        for k, tk in enumerate(t):
            if not math.isfinite(tk):
                raise ValueError(f"{self.source}: time {tk!r} is not finite")
            hi = int(np.searchsorted(s, tk))
            if hi < len(s) and s[hi] - tk <= eps:
                out[k] = self.poses[hi]
            elif hi > 0 and tk - s[hi - 1] <= eps:
                out[k] = self.poses[hi - 1]
            elif hi == 0 or hi == len(s):
                end = 0 if hi == 0 else len(s) - 1
                if abs(s[end] - tk) > max_gap:
                    raise ValueError(f"{self.source}: t={tk!r} is outside the poses' time span "
                                     f"[{s[0]!r}, {s[-1]!r}] by more than {max_gap} s")
                out[k] = self.poses[end]
            else:
                lo = hi - 1
                if tk - s[lo] > max_gap or s[hi] - tk > max_gap:
                    raise ValueError(f"{self.source}: t={tk!r} falls in a gap of "
                                     f"{s[hi] - s[lo]:.4g} s between poses (more than {max_gap} s "
                                     "to one of them)")
                w = (tk - s[lo]) / (s[hi] - s[lo])
                out[k] = interpolate_transform(self.poses[lo], self.poses[hi], w)
        return out


# ---- readers --------------------------------------------------------------------------------

#: Seconds per unit of a timestamp column, by the unit its name carries.
_TIME_UNITS = {"ns": 1e-9, "us": 1e-6, "ms": 1e-3, "s": 1.0, "sec": 1.0}
_POSE_COLUMNS = ("tx", "ty", "tz", "qx", "qy", "qz", "qw")


def _header(line: str) -> list[str]:
    return [h.strip() for h in line.split(",")]


#: Columns naming the frame a row's pose is in: Aria MPS's open-loop ``session_uid`` (one
#: odometry frame per session) and closed-loop ``graph_uid`` (one world per graph).
_FRAME_IDS = ("session_uid", "graph_uid")


def _text(p: Path) -> str:
    try:
        return p.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ValueError(f"{p}: no such pose file") from None
    except UnicodeDecodeError:
        raise ValueError(f"{p}: not a text pose file (UTF-8); .npy/.npz arrays need their "
                         "suffix") from None
    except OSError as exc:
        raise ValueError(f"{p}: cannot be read: {exc}") from None


def _numbers(parts: list[str], p: Path, lineno: int) -> list[float]:
    try:
        v = [float(x) for x in parts]
    except ValueError:
        raise ValueError(f"{p}: line {lineno}: expected numbers, got {' '.join(parts)[:80]!r}") from None
    if not all(math.isfinite(x) for x in v):
        raise ValueError(f"{p}: line {lineno}: expected finite numbers")
    return v


def _pose(q_xyzw, t, p: Path, lineno: int) -> NDArray[np.float64]:
    try:
        return make_transform(quat_to_matrix(q_xyzw), t)
    except ValueError as exc:
        raise ValueError(f"{p}: line {lineno}: {exc}") from None


def _rows(text: str) -> list[tuple[int, list[str]]]:
    rows = []
    for lineno, line in enumerate(text.splitlines(), start=1):
        s = line.strip()
        if s and not s.startswith("#"):
            rows.append((lineno, s.replace(",", " ").split()))
    return rows


def read_tum(path: str | os.PathLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Timestamps ``(N,)`` and poses ``(N, 4, 4)`` of a TUM file (``read_poses`` for more)."""
    traj = read_poses(path, format="tum")
    return traj.stamps, traj.poses


def read_poses(path: str | os.PathLike, *, format: str | None = None) -> Trajectory:
    """Read a trajectory file (:data:`POSE_FORMATS`; detected when ``format`` is None)."""
    p = Path(path)
    if format is not None and format not in POSE_FORMATS:
        raise ValueError(f"format: expected one of {', '.join(POSE_FORMATS)}, got {format!r}")
    if format == "npy" or (format is None and p.suffix.lower() in (".npy", ".npz")):
        return _read_array(p)
    text = _text(p)
    first = next((line.strip() for line in text.splitlines() if line.strip()), "")
    header = first.lower().replace(" ", "")
    if format == "aria" or (format is None and header.startswith("file,timestamp_ns")):
        return _read_aria(p, text)
    if format == "mps" or (format is None and "tx_world_device" in header):
        return _read_mps(p, text)
    if format == "euroc" or (format is None and ("p_rs_r_x" in header or "q_rs_w" in header)):
        return _read_euroc(p, text)
    if format == "csv" or (format is None and _named_columns(first)):
        return _read_named_csv(p, text)
    rows = _rows(text)
    if not rows:
        raise ValueError(f"{p}: no poses")
    width = len(rows[0][1])
    if format == "kitti" or (format is None and width == 12):
        return _read_kitti(p, rows)
    if format == "tum" or (format is None and width == 8):
        return _read_tum(p, rows)
    raise ValueError(f"{p}: line {rows[0][0]}: cannot tell the pose format from {width} "
                     f"columns; expected TUM (8), KITTI (12), EuRoC CSV, Aria CSV, a CSV whose "
                     f"header names tx ... qw and a timestamp, or .npy/.npz")


def _read_tum(p: Path, rows) -> Trajectory:
    stamps, poses = [], []
    for lineno, parts in rows:
        if len(parts) != 8:
            raise ValueError(f"{p}: line {lineno}: expected 8 numbers "
                             f"'timestamp tx ty tz qx qy qz qw', got {len(parts)}")
        v = _numbers(parts, p, lineno)
        stamps.append(v[0])
        poses.append(_pose(v[4:8], v[1:4], p, lineno))
    return Trajectory(np.array(poses), np.array(stamps), source=str(p))


def _read_kitti(p: Path, rows) -> Trajectory:
    poses = []
    for lineno, parts in rows:
        if len(parts) != 12:
            raise ValueError(f"{p}: line {lineno}: expected 12 numbers (a 3x4 pose), got {len(parts)}")
        m = np.eye(4)
        m[:3] = np.array(_numbers(parts, p, lineno)).reshape(3, 4)
        try:
            check_rigid(m, "pose")
        except ValueError as exc:
            raise ValueError(f"{p}: line {lineno}: {exc}") from None
        poses.append(m)
    return Trajectory(np.array(poses), source=str(p))


def _read_euroc(p: Path, text: str) -> Trajectory:
    stamps, poses = [], []
    for lineno, parts in _rows(text):
        if len(parts) < 8:
            raise ValueError(f"{p}: line {lineno}: expected 'timestamp [ns], p x y z, q w x y z, "
                             f"...', got {len(parts)} columns")
        v = _numbers(parts[:8], p, lineno)
        stamps.append(v[0] * 1e-9)
        poses.append(_pose([v[5], v[6], v[7], v[4]], v[1:4], p, lineno))
    if not poses:
        raise ValueError(f"{p}: no poses")
    return Trajectory(np.array(poses), np.array(stamps), source=str(p))


def _lines(p: Path, text: str) -> list[str]:
    """The non-empty lines of a CSV (its header first), or a ValueError when there are none."""
    lines = [line for line in text.splitlines() if line.strip()]
    if not lines:
        raise ValueError(f"{p}: no poses")
    return lines


def _read_csv_columns(p: Path, lines: list[str], need: tuple[str, ...], name: str | None,
                      time_scale: float) -> Trajectory:
    """A CSV with a header (``lines``: :func:`_lines`): ``need`` = (time, tx, ty, tz, qx, qy,
    qz, qw) column names. A :data:`_FRAME_IDS` column whose value changes is a ValueError
    naming the line: poses in different frames cannot be interpolated into one trajectory."""
    head = _header(lines[0])
    wanted = need + ((name,) if name else ())
    missing = [n for n in wanted if n not in head]
    if missing:
        raise ValueError(f"{p}: header: missing column(s) {missing}")
    col = {n: head.index(n) for n in wanted}
    frame_ids = [head.index(n) for n in _FRAME_IDS if n in head]
    first_ids = None
    names, stamps, poses = [], [], []
    for lineno, line in enumerate(lines[1:], start=2):
        parts = [x.strip() for x in line.split(",")]
        if len(parts) != len(head):
            raise ValueError(f"{p}: line {lineno}: expected {len(head)} columns, got {len(parts)}")
        ids = [parts[c] for c in frame_ids]
        first_ids = ids if first_ids is None else first_ids
        if ids != first_ids:
            changed = next(head[c] for c, a, b in zip(frame_ids, ids, first_ids, strict=True)
                           if a != b)
            raise ValueError(f"{p}: line {lineno}: {changed} changes: the poses after it are in "
                             "another frame; give the poses of one")
        v = _numbers([parts[col[n]] for n in need], p, lineno)
        if name:
            names.append(parts[col[name]])
        stamps.append(v[0] * time_scale)
        poses.append(_pose(v[4:8], v[1:4], p, lineno))
    if not poses:
        raise ValueError(f"{p}: no poses")
    return Trajectory(np.array(poses), np.array(stamps), tuple(names) if name else None,
                      source=str(p))


def _read_aria(p: Path, text: str) -> Trajectory:
    return _read_csv_columns(p, _lines(p, text), ("timestamp_ns", *_POSE_COLUMNS), "file", 1e-9)


def _read_mps(p: Path, text: str) -> Trajectory:
    cols = tuple(f"{c}_world_device" for c in _POSE_COLUMNS)
    return _read_csv_columns(p, _lines(p, text), ("tracking_timestamp_us", *cols), None, 1e-6)


def _named_columns(first: str) -> bool:
    """Whether a first line is a CSV header naming the pose's columns (the ``csv`` format)."""
    head = _header(first.lstrip("#"))
    return len(head) > 1 and all(any(h == c or h.startswith(c + "_") for h in head)
                                 for c in _POSE_COLUMNS)


def _read_named_csv(p: Path, text: str) -> Trajectory:
    """The ``csv`` format: columns found by name (module doc)."""
    lines = _lines(p, text)
    head = _header(lines[0].lstrip("#"))
    need = []
    for c in _POSE_COLUMNS:
        found = [h for h in head if h == c or h.startswith(c + "_")]
        if len(found) != 1:
            raise ValueError(f"{p}: header: expected one {c!r} column (named {c} or {c}_...), "
                             f"got {found or 'none'}")
        need.append(found[0])
    times = [h for h in head if {"timestamp", "time", "t"} & set(h.lower().split("_"))]
    if len(times) > 1:
        times = [h for h in times if h.lower().startswith("tracking")] or times
    if len(times) != 1:
        raise ValueError(f"{p}: header: expected one timestamp column, got {times or 'none'}")
    units = [_TIME_UNITS[t] for t in times[0].lower().split("_") if t in _TIME_UNITS]
    if len(units) != 1:
        raise ValueError(f"{p}: header: the timestamp column {times[0]!r} does not say its unit "
                         "(_ns, _us, _ms or _s in its name)")
    return _read_csv_columns(p, [",".join(head), *lines[1:]], (times[0], *need), None,
                             units[0])


def _read_array(p: Path) -> Trajectory:
    try:
        data = np.load(p, allow_pickle=False)
    except FileNotFoundError:
        raise ValueError(f"{p}: no such pose file") from None
    except (OSError, ValueError, EOFError) as exc:
        raise ValueError(f"{p}: cannot be read as a numpy array: {exc or 'empty'}") from None
    if isinstance(data, np.ndarray):
        poses, stamps, names = data, None, None
    else:
        with data:
            if "poses" not in data.files:
                raise ValueError(f"{p}: poses: missing (arrays: {data.files})")
            poses = data["poses"]
            stamps = data["timestamps"] if "timestamps" in data.files else None
            names = tuple(data["names"].tolist()) if "names" in data.files else None
    if poses.dtype.kind not in "fiu":
        raise ValueError(f"{p}: poses: expected numbers, got dtype {poses.dtype}")
    return Trajectory(poses, stamps, names, source=str(p))


def write_tum(path: str | os.PathLike, timestamps, poses) -> None:
    """Write ``world_from_cam`` poses ``(N, 4, 4)`` with their timestamps in TUM format."""
    lines = ["# timestamp tx ty tz qx qy qz qw (world_from_cam)"]
    for t, pose in zip(timestamps, poses, strict=True):
        q = matrix_to_quat(pose[:3, :3])
        vals = [t, *pose[:3, 3], *q]
        lines.append(" ".join(repr(float(x)) for x in vals))
    Path(path).write_text("\n".join(lines) + "\n", encoding="utf-8")


# ---- matching frames to poses ---------------------------------------------------------------

MATCHES = ("auto", "timestamp", "name", "index")


class PoseMatcher:
    """The pose of each frame of an input.

    Parameters
    ----------
    trajectory : Trajectory
        Camera poses (``world_from_cam``).
    match : {'auto', 'timestamp', 'name', 'index'}
        ``timestamp``: interpolated at the frame's time (see :meth:`Trajectory.at`); ``name``:
        the pose named like the frame file (or, for poses without names, the pose whose index
        is the frame's number, ``000012.png`` -> 12); ``index``: the k-th pose for the k-th
        frame, only when the input has exactly as many frames as there are poses (``frames``).
        ``auto``: by name when the poses are named, by timestamp when frames and poses both have
        times, else by the frame's number.
    max_gap : float
        Seconds (timestamp matching).
    frames : int, optional
        Number of frames of the input, when known (checked against the poses for ``index``).
    """

    def __init__(self, trajectory: Trajectory, match: str = "auto", *, max_gap: float = 0.05,
                 frames: int | None = None) -> None:
        if match not in MATCHES:
            raise ValueError(f"match: expected one of {', '.join(MATCHES)}, got {match!r}")
        if not isinstance(max_gap, int | float) or not math.isfinite(max_gap) or max_gap < 0:
            raise ValueError(f"max_dt: expected a finite number of seconds >= 0, got {max_gap!r}")
        self.trajectory, self.match, self.max_gap = trajectory, match, float(max_gap)
        src = trajectory.source
        if match == "index" and frames is not None and frames != len(trajectory):
            raise ValueError(f"{src}: {len(trajectory)} poses for {frames} frames; match by "
                             "timestamp or frame name instead of by index")
        if match == "timestamp" and trajectory.stamps is None:
            raise ValueError(f"{src}: has no timestamps; match by name or index")
        self._by_name = ({n: i for i, n in enumerate(trajectory.names)}
                         if trajectory.names is not None else None)

    def __call__(self, index: int, name: str | None, stamp: float | None
                 ) -> tuple[float | None, NDArray[np.float64]]:
        """``(time, world_from_cam)`` of frame ``index`` (file ``name``, time ``stamp`` in
        seconds, each None when unknown)."""
        traj, where = self.trajectory, _frame_label(index, name, stamp)
        mode = self.match
        if mode == "auto":
            if self._by_name is not None and name is not None:
                mode = "name"
            elif traj.stamps is not None and stamp is not None:
                mode = "timestamp"
            else:
                mode = "name" if name is not None and _number(name) is not None else "index"
        if mode == "timestamp":
            if stamp is None:
                raise ValueError(f"{where}: has no timestamp to match poses by; its name is not "
                                 "a time (use --match name or index)")
            try:
                return stamp, traj.at(stamp, max_gap=self.max_gap)[0]
            except ValueError as exc:
                raise ValueError(f"{where}: {exc}") from None
        if mode == "name":
            if name is None:
                raise ValueError(f"{where}: has no name to match poses by")
            if self._by_name is not None:
                key = name if name in self._by_name else Path(name).name
                if key not in self._by_name:
                    raise ValueError(f"{where}: {traj.source} has no pose named {Path(name).name!r}")
                i = self._by_name[key]
            else:
                i = _number(name)
                if i is None or not 0 <= i < len(traj):
                    raise ValueError(f"{where}: no pose {i} in {traj.source} ({len(traj)} poses)")
            return (None if traj.stamps is None else float(traj.stamps[i])), traj.poses[i]
        if index >= len(traj):
            raise ValueError(f"{where}: {traj.source} has only {len(traj)} poses")
        return (None if traj.stamps is None else float(traj.stamps[index])), traj.poses[index]


def _number(name: str) -> int | None:
    stem = Path(name).stem
    return int(stem) if stem.isdigit() and len(stem) < 16 else None


def _frame_label(index: int, name: str | None, stamp: float | None) -> str:
    label = f"frame {index}"
    if name is not None:
        label += f" ({Path(name).name})"
    elif stamp is not None:
        label += f" (t={stamp!r})"
    return label
