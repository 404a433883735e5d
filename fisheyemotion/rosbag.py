"""ROS 1 and ROS 2 bags (the ``rosbags`` package): images, the calibration and poses.

- Images: ``sensor_msgs/Image`` or ``sensor_msgs/CompressedImage`` on ``image_topic`` (decoded by
  ``rosbags-image``), timed by their header stamps.
- Calibration: ``sensor_msgs/CameraInfo`` on ``info_topic`` (default: the image topic's
  ``camera_info`` sibling): ``equidistant`` (or the old ``fisheye``) distortion is
  Kannala-Brandt, ``plumb_bob``/``rational_polynomial`` with zero distortion a pinhole.
- Poses: ``geometry_msgs/PoseStamped`` or ``nav_msgs/Odometry`` on ``pose_topic``, or the
  ``/tf`` + ``/tf_static`` tree from ``world_frame`` to ``pose_frame`` (each moving link
  interpolated at the image times). The poses are of ``pose_frame``; when that is not the camera
  (an IMU, a base link), give the camera's extrinsic (``--poses-of rig`` with a calibration
  file that has one).

Without the ``ros`` extra (``pip install 'fisheyemotion[ros]'``) opening a bag is a ValueError
saying so.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from .calib.transforms import make_transform, quat_to_matrix
from .inputs import Frame, FrameSource
from .poses import Trajectory

__all__ = ["BagSource", "is_bag"]

IMAGE_TYPES = ("sensor_msgs/msg/Image", "sensor_msgs/msg/CompressedImage")
POSE_TYPES = ("geometry_msgs/msg/PoseStamped", "nav_msgs/msg/Odometry")
TF_TYPE = "tf2_msgs/msg/TFMessage"


def is_bag(path: Path) -> bool:
    return (path.is_file() and path.suffix == ".bag") or (
        path.is_dir() and (path / "metadata.yaml").is_file())


def _reader(path: Path):
    try:
        from rosbags.highlevel import AnyReader
    except ImportError:
        raise ValueError(f"{path}: reading ROS bags needs the 'ros' extra: "
                         "pip install 'fisheyemotion[ros]'") from None
    return AnyReader([path])


def _stamp(header) -> float:
    return header.stamp.sec + header.stamp.nanosec * 1e-9


def _pose_of(p) -> np.ndarray:
    q = p.orientation
    return make_transform(quat_to_matrix([q.x, q.y, q.z, q.w]), [p.position.x, p.position.y,
                                                                  p.position.z])


class BagSource(FrameSource):
    """Frames of one image topic of a bag, with the bag's calibration and poses on demand.

    Parameters
    ----------
    path : Path
        A ROS 1 ``.bag`` file or a ROS 2 bag folder.
    image_topic : str, optional
        Default: the only image topic of the bag (an error lists them when there are several).
    """

    def __init__(self, path: Path, *, image_topic: str | None = None) -> None:
        self.path = path
        with _reader(path) as reader:
            images = sorted({c.topic for c in reader.connections if c.msgtype in IMAGE_TYPES})
            if not images:
                raise ValueError(f"{path}: no image topic (sensor_msgs/Image or CompressedImage)")
            if image_topic is None:
                if len(images) > 1:
                    raise ValueError(f"--image-topic: the bag has several image topics: {images}")
                image_topic = images[0]
            if image_topic not in images:
                raise ValueError(f"--image-topic: no image topic {image_topic!r} in {path}; "
                                 f"it has {images}")
            self.topics = {c.topic: c.msgtype for c in reader.connections}
            self.count = sum(c.msgcount for c in reader.connections if c.topic == image_topic)
        self.image_topic = image_topic
        self.fps = None

    def __len__(self) -> int:
        return self.count

    def __iter__(self) -> Iterator[Frame]:
        from rosbags.image import message_to_cvimage

        with _reader(self.path) as reader:
            conns = [c for c in reader.connections if c.topic == self.image_topic]
            for i, (conn, _, raw) in enumerate(reader.messages(connections=conns)):
                msg = reader.deserialize(raw, conn.msgtype)
                try:
                    img = _decode(msg, message_to_cvimage)
                except Exception as exc:  # noqa: BLE001 - a bad message names the frame
                    raise ValueError(f"{self.path}: {self.image_topic} message {i}: cannot "
                                     f"decode the image: {exc}") from None
                img = np.ascontiguousarray(img)
                if img.dtype != np.uint8:
                    raise ValueError(f"{self.path}: {self.image_topic} message {i}: expected "
                                     f"8-bit images, got {img.dtype}")
                yield Frame(i, None, _stamp(msg.header), img)

    # ---- calibration ------------------------------------------------------------------------
    def camera(self, info_topic: str | None = None):
        """The camera model of the first ``sensor_msgs/CameraInfo`` message."""
        from . import calib

        topic = info_topic or self.image_topic.rsplit("/", 1)[0] + "/camera_info"
        if self.topics.get(topic) != "sensor_msgs/msg/CameraInfo":
            infos = [t for t, m in self.topics.items() if m == "sensor_msgs/msg/CameraInfo"]
            raise ValueError(f"--info-topic: no CameraInfo on {topic!r} in {self.path}; "
                             f"CameraInfo topics: {infos}")
        with _reader(self.path) as reader:
            conns = [c for c in reader.connections if c.topic == topic]
            for conn, _, raw in reader.messages(connections=conns):
                msg = reader.deserialize(raw, conn.msgtype)
                break
        # ROS 2 names the matrices k, d; ROS 1 K, D.
        k = np.asarray(getattr(msg, "k", None) if hasattr(msg, "k") else msg.K,
                       dtype=np.float64).reshape(3, 3)
        d = np.asarray(getattr(msg, "d", None) if hasattr(msg, "d") else msg.D, dtype=np.float64)
        field = f"{self.path}: {topic}"
        model = msg.distortion_model
        size = {"width": int(msg.width), "height": int(msg.height)}
        try:
            if model in ("equidistant", "fisheye"):
                if len(d) < 4:
                    raise ValueError(f"d: expected 4 equidistant coefficients, got {len(d)}")
                return calib.KannalaBrandt(fx=k[0, 0], fy=k[1, 1], cx=k[0, 2], cy=k[1, 2],
                                           k1=d[0], k2=d[1], k3=d[2], k4=d[3], **size)
            if model in ("plumb_bob", "rational_polynomial", "") and not np.any(d):
                return calib.Pinhole(fx=k[0, 0], fy=k[1, 1], cx=k[0, 2], cy=k[1, 2], **size)
        except ValueError as exc:
            raise ValueError(f"{field}: {exc}") from None
        raise ValueError(f"{field}: distortion_model {model!r} with coefficients {d.tolist()} "
                         "is not supported; expected equidistant (fisheye) or no distortion")

    # ---- poses ------------------------------------------------------------------------------
    def trajectory(self, *, pose_topic: str | None = None, pose_frame: str | None = None,
                   world_frame: str | None = None, times: np.ndarray | None = None) -> Trajectory:
        """Poses from a PoseStamped/Odometry topic, or ``world_frame`` -> ``pose_frame`` from
        ``/tf`` and ``/tf_static`` evaluated at ``times`` (the image times, seconds)."""
        source = f"{self.path}"
        if pose_topic:
            kind = self.topics.get(pose_topic)
            if kind not in POSE_TYPES:
                raise ValueError(f"--pose-topic: {pose_topic!r} in {self.path} is "
                                 f"{kind or 'missing'}; expected one of {POSE_TYPES}")
            stamps, poses = [], []
            with _reader(self.path) as reader:
                conns = [c for c in reader.connections if c.topic == pose_topic]
                for conn, _, raw in reader.messages(connections=conns):
                    msg = reader.deserialize(raw, conn.msgtype)
                    p = msg.pose.pose if kind.endswith("Odometry") else msg.pose
                    stamps.append(_stamp(msg.header))
                    poses.append(_pose_of(p))
            order = np.argsort(stamps, kind="stable")
            return Trajectory(np.array(poses)[order], np.array(stamps)[order],
                              source=f"{source}: {pose_topic}")
        if not pose_frame:
            raise ValueError("--pose-topic or --pose-frame: the bag's poses are needed")
        return self._tf_trajectory(pose_frame, world_frame, times)

    def _tf_trajectory(self, child: str, world: str | None, times) -> Trajectory:
        edges: dict[str, tuple[str, list[float], list[np.ndarray], bool]] = {}
        with _reader(self.path) as reader:
            conns = [c for c in reader.connections if c.msgtype == TF_TYPE]
            if not conns:
                raise ValueError(f"{self.path}: no /tf or /tf_static (tf2_msgs/TFMessage)")
            for conn, _, raw in reader.messages(connections=conns):
                msg = reader.deserialize(raw, conn.msgtype)
                static = conn.topic.endswith("tf_static")
                for tr in msg.transforms:
                    t, q = tr.transform.translation, tr.transform.rotation
                    pose = make_transform(quat_to_matrix([q.x, q.y, q.z, q.w]), [t.x, t.y, t.z])
                    entry = edges.setdefault(tr.child_frame_id,
                                             (tr.header.frame_id, [], [], static))
                    entry[1].append(_stamp(tr.header))
                    entry[2].append(pose)
        if child not in edges:
            raise ValueError(f"--pose-frame: no tf frame {child!r}; frames: {sorted(edges)}")
        chain, frame = [], child
        while frame in edges and frame != world:
            chain.append(frame)
            frame = edges[frame][0]
        if world is not None and frame != world:
            raise ValueError(f"--world-frame: {world!r} is not an ancestor of {child!r} in the "
                             f"tf tree (its root is {frame!r})")
        if times is None or len(times) == 0:
            raise ValueError(f"{self.path}: no image times to evaluate the tf tree at")
        times = np.asarray(times, dtype=np.float64)
        total = np.repeat(np.eye(4)[None], len(times), axis=0)
        for name in chain:  # child first: world_from_child = ... parent_from_child
            parent, stamps, poses, static = edges[name]
            if static:
                link = np.repeat(poses[-1][None], len(times), axis=0)
            else:
                order = np.argsort(stamps, kind="stable")
                s, p = np.array(stamps)[order], np.array(poses)[order]
                keep = np.r_[True, np.diff(s) > 0]
                link = Trajectory(p[keep], s[keep], source=f"{self.path}: tf {parent}->{name}"
                                  ).at(times, max_gap=max(0.25, 3 * _median_step(s[keep])))
            total = link @ total
        return Trajectory(total, times, source=f"{self.path}: tf {frame}->{child}")


def _median_step(s: np.ndarray) -> float:
    return float(np.median(np.diff(s))) if len(s) > 1 else math.inf


def _decode(msg, message_to_cvimage) -> np.ndarray:
    """BGR or grey uint8, as cv2 gives images."""
    encoding = getattr(msg, "encoding", None)
    if encoding is None:  # CompressedImage: decoded by OpenCV, BGR or grey already
        return message_to_cvimage(msg)
    if encoding in ("mono8", "bgr8", "8UC1", "8UC3"):
        return message_to_cvimage(msg)
    return message_to_cvimage(msg, "bgr8")
