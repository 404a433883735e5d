"""ROS 1 and ROS 2 bags written with ``rosbags`` itself, run through ``fisheyemotion detect``."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from fisheyemotion.calib.transforms import matrix_to_quat
from rosbags.typesys import Stores, get_typestore

from fisheyemotion import synth
from fisheyemotion.cli import main

from .cameras import tumvi_kb

CAM = tumvi_kb(400, 300, 120.0)
SCENE = synth.parse_scenario({
    "name": "bag", "frames": 4, "ego": {"speed_kmh": 10},
    "camera": {"position": [2, 0, 1.0], "pitch_deg": 15},
    "objects": [{"id": 1, "kind": "car", "category": "crossing", "start": [8, -4],
                 "heading_deg": 90, "speed_kmh": 15}]})
T0 = 1_700_000_000


@pytest.fixture(scope="module")
def frames():
    return synth.render_frames(CAM, SCENE)


def _write_bag(path, frames, ros1: bool, *, tf: bool):
    store = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
    if "tf2_msgs/msg/TFMessage" not in store.types:  # the ROS 1 store lacks it
        from rosbags.typesys import get_types_from_msg

        store.register(get_types_from_msg("geometry_msgs/TransformStamped[] transforms",
                                          "tf2_msgs/msg/TFMessage"))
    T = store.types
    Time, Header = T["builtin_interfaces/msg/Time"], T["std_msgs/msg/Header"]
    serialize = store.serialize_ros1 if ros1 else store.serialize_cdr
    if ros1:
        from rosbags.rosbag1 import Writer

        writer = Writer(path)
    else:
        from rosbags.rosbag2 import Writer

        writer = Writer(path, version=9)

    def header(k, frame_id="camera"):
        stamp = Time(sec=T0 + k // 15, nanosec=int((k % 15) / 15 * 1e9))
        return Header(seq=k, stamp=stamp, frame_id=frame_id) if ros1 else Header(
            stamp=stamp, frame_id=frame_id)

    def ns(k):
        return (T0 + k // 15) * 10**9 + int((k % 15) / 15 * 1e9)

    with writer:
        img_c = writer.add_connection("/cam/image_raw", "sensor_msgs/msg/Image", typestore=store)
        info_c = writer.add_connection("/cam/camera_info", "sensor_msgs/msg/CameraInfo",
                                       typestore=store)
        pose_c = writer.add_connection("/cam/pose", "geometry_msgs/msg/PoseStamped",
                                       typestore=store)
        tf_c = writer.add_connection("/tf", "tf2_msgs/msg/TFMessage", typestore=store)
        Image, Info = T["sensor_msgs/msg/Image"], T["sensor_msgs/msg/CameraInfo"]
        Roi = T["sensor_msgs/msg/RegionOfInterest"]
        Pose, PoseStamped = T["geometry_msgs/msg/Pose"], T["geometry_msgs/msg/PoseStamped"]
        Point, Quat = T["geometry_msgs/msg/Point"], T["geometry_msgs/msg/Quaternion"]
        Vec, Tr = T["geometry_msgs/msg/Vector3"], T["geometry_msgs/msg/Transform"]
        TrS, TF = T["geometry_msgs/msg/TransformStamped"], T["tf2_msgs/msg/TFMessage"]
        k = [CAM.fx, 0, CAM.cx, 0, CAM.fy, CAM.cy, 0, 0, 1]
        mats = dict(D=np.array([CAM.k1, CAM.k2, CAM.k3, CAM.k4]), K=np.array(k, float),
                    R=np.eye(3).ravel(), P=np.array([*k[:3], 0, *k[3:6], 0, *k[6:], 0], float))
        if not ros1:
            mats = {key.lower(): v for key, v in mats.items()}
        info = Info(header=header(0), height=CAM.height, width=CAM.width,
                    distortion_model="equidistant", **mats, binning_x=0, binning_y=0,
                    roi=Roi(x_offset=0, y_offset=0, height=0, width=0, do_rectify=False))
        writer.write(info_c, ns(0), serialize(info, Info.__msgtype__))
        for i, f in enumerate(frames):
            img = Image(header=header(i), height=CAM.height, width=CAM.width, encoding="bgr8",
                        is_bigendian=0, step=CAM.width * 3,
                        data=np.frombuffer(f.image.tobytes(), np.uint8))
            writer.write(img_c, ns(i), serialize(img, Image.__msgtype__))
            x, y, z, w = (float(v) for v in matrix_to_quat(f.pose[:3, :3]))
            t = f.pose[:3, 3]
            pose = PoseStamped(header=header(i, "map"), pose=Pose(
                position=Point(x=t[0], y=t[1], z=t[2]), orientation=Quat(x=x, y=y, z=z, w=w)))
            writer.write(pose_c, ns(i), serialize(pose, PoseStamped.__msgtype__))
            if tf:
                tr = TrS(header=header(i, "map"), child_frame_id="camera", transform=Tr(
                    translation=Vec(x=t[0], y=t[1], z=t[2]),
                    rotation=Quat(x=x, y=y, z=z, w=w)))
                writer.write(tf_c, ns(i), serialize(TF(transforms=[tr]), TF.__msgtype__))


@pytest.mark.parametrize("ros1", [True, False], ids=["ros1", "ros2"])
@pytest.mark.parametrize("poses", ["topic", "tf"])
def test_a_bag_runs_through_detect(tmp_path, frames, ros1, poses):
    bag = tmp_path / ("run.bag" if ros1 else "run")
    _write_bag(bag, frames, ros1, tf=poses == "tf")
    (tmp_path / "p.yaml").write_text("frame_gap: 1\n")
    args = ["detect", str(bag), "--out", str(tmp_path / "out"), "--quiet", "--road", "z0",
            "--params", str(tmp_path / "p.yaml")]
    args += ["--pose-topic", "/cam/pose"] if poses == "topic" else ["--pose-frame", "camera"]
    assert main(args) == 0
    regions = pd.read_csv(tmp_path / "out" / "regions.csv")
    assert len(regions) and regions.timestamp.min() >= T0
    assert len(list((tmp_path / "out" / "likelihood").glob("*.npz"))) == len(frames)
    # The bag's CameraInfo is the camera.
    from fisheyemotion.rosbag import BagSource

    src = BagSource(bag)
    assert src.camera() == CAM
    assert len(src) == len(frames)


def test_bag_errors_name_the_topic(tmp_path, frames):
    bag = tmp_path / "run.bag"
    _write_bag(bag, frames, True, tf=False)
    code = main(["detect", str(bag), "--out", str(tmp_path / "o"), "--image-topic", "/nope"])
    assert code == 2
    code = main(["detect", str(bag), "--out", str(tmp_path / "o"), "--pose-frame", "imu"])
    assert code == 2
