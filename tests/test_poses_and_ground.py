"""Pose sources (formats, interpolation, matching) and the road estimated in any world frame."""

from __future__ import annotations

import numpy as np
import pytest
from fisheyemotion.calib.transforms import make_transform, matrix_to_quat, rotate
from hypothesis import given, settings
from hypothesis import strategies as st

import fisheyemotion as fm
from fisheyemotion import synth
from fisheyemotion.ground import GroundEstimator, check_road
from fisheyemotion.poses import POSE_FORMATS, PoseMatcher, Trajectory, read_poses, write_tum

from .cameras import tumvi_kb
from .scenes import random_rotation

RNG = np.random.default_rng(3)
POSES = np.array([make_transform(random_rotation(RNG), RNG.normal(size=3)) for _ in range(5)])
STAMPS = np.array([0.0, 0.1, 0.2, 0.3, 0.4]) + 1000.0


def test_every_format_reads_the_same_poses(tmp_path):
    write_tum(tmp_path / "a.txt", STAMPS, POSES)
    (tmp_path / "a.kitti").write_text("\n".join(" ".join(map(repr, p[:3].ravel().tolist())) for p in POSES))
    lines = ["#timestamp [ns], p_RS_R_x [m], p_RS_R_y [m], p_RS_R_z [m], q_RS_w [], q_RS_x [], "
             "q_RS_y [], q_RS_z []"]
    for t, p in zip(STAMPS, POSES, strict=True):
        x, y, z, w = (float(v) for v in matrix_to_quat(p[:3, :3]))
        lines.append(",".join(map(repr, [int(round(t * 1e9)), *p[:3, 3].tolist(), w, x, y, z])))
    (tmp_path / "a.csv").write_text("\n".join(lines))
    np.save(tmp_path / "a.npy", POSES)
    np.savez(tmp_path / "a.npz", poses=POSES, timestamps=STAMPS, names=np.array(list("abcde")))
    for name in ("a.txt", "a.kitti", "a.csv", "a.npy", "a.npz"):
        traj = read_poses(tmp_path / name)
        np.testing.assert_allclose(traj.poses, POSES, atol=1e-9, err_msg=name)
    assert read_poses(tmp_path / "a.npz").names == tuple("abcde")
    np.testing.assert_allclose(read_poses(tmp_path / "a.csv").stamps, STAMPS, atol=1e-9)


def test_aria_pose_csv_is_named_by_frame():
    traj = read_poses("data/real/aria_gen2_office/slam-side-left/poses_T_odometry_camera.csv")
    assert len(traj) == 9 and traj.names[0] == "000000.png"
    pose_time, pose = PoseMatcher(traj)(3, "000003.png", None)
    np.testing.assert_array_equal(pose, traj.poses[3])


def _rotation_deg(a, b):
    """Angle (degrees) between two rotation matrices, stable near 0."""
    return float(np.degrees(2 * np.arcsin(min(1.0, np.linalg.norm(a - b, "fro") / np.sqrt(8)))))


@pytest.mark.parametrize("camera", ["slam-side-left", "slam-side-right"])
def test_an_aria_vio_export_with_the_factory_extrinsic_gives_the_per_frame_camera_poses(camera):
    """The Gen2 clip's 800 Hz VIO export (device poses, columns found by name) composed with the
    factory calibration's T_device_camera and interpolated at the frames' times is the
    recording's own per-frame camera pose file (written from the same trajectory by other
    code) to a micrometre."""
    clip = "data/real/aria_gen2_office"
    vio = read_poses(f"{clip}/poses_vio_high_frequency.csv")
    assert len(vio) == 237 and np.all(np.diff(vio.stamps) > 0)
    extrinsic = fm.calib.load_rig(f"{clip}/device_calibration_full.json").extrinsic(camera)
    frames = read_poses(f"{clip}/{camera}/poses_T_odometry_camera.csv")
    got = vio.compose(extrinsic).at(frames.stamps, max_gap=0.01)
    np.testing.assert_allclose(got[:, :3, 3], frames.poses[:, :3, 3], atol=5e-6)
    assert max(_rotation_deg(a[:3, :3], b[:3, :3]) for a, b in zip(got, frames.poses,
                                                                      strict=True)) < 1e-4
    # Without the extrinsic they are the device's poses, not the camera's: centimetres apart.
    assert np.abs(vio.at(frames.stamps, max_gap=0.01)[:, :3, 3]
                  - frames.poses[:, :3, 3]).max() > 1e-3


OPEN_LOOP_HEADER = ("tracking_timestamp_us,utc_timestamp_ns,session_uid,tx_odometry_device,"
                    "ty_odometry_device,tz_odometry_device,qx_odometry_device,qy_odometry_device,"
                    "qz_odometry_device,qw_odometry_device,device_linear_velocity_x_odometry,"
                    "device_linear_velocity_y_odometry,device_linear_velocity_z_odometry,"
                    "angular_velocity_x_device,angular_velocity_y_device,"
                    "angular_velocity_z_device,gravity_x_odometry,gravity_y_odometry,"
                    "gravity_z_odometry,quality_score")


def _open_loop(sessions):
    rows = [OPEN_LOOP_HEADER]
    for t, p, uid in zip(STAMPS, POSES, sessions, strict=True):
        q = [float(v) for v in matrix_to_quat(p[:3, :3])]
        rows.append(",".join([str(int(round(t * 1e6))), "-1", uid, *map(repr, p[:3, 3].tolist()),
                              *map(repr, q), *["0.0"] * 9, "1.0"]))
    return "\n".join(rows)


def test_an_mps_open_loop_trajectory_is_read_by_its_column_names(tmp_path):
    """Aria MPS's open_loop_trajectory.csv (projectaria_tools' 20 columns): the device poses
    in the odometry frame at the tracking timestamps (microseconds), not the UTC ones."""
    (tmp_path / "open_loop_trajectory.csv").write_text(_open_loop(["s0"] * len(POSES)))
    traj = read_poses(tmp_path / "open_loop_trajectory.csv")
    np.testing.assert_allclose(traj.poses, POSES, atol=1e-12)
    np.testing.assert_allclose(traj.stamps, STAMPS, atol=1e-9)
    # A new VIO session is another odometry frame: named, not interpolated across.
    (tmp_path / "two.csv").write_text(_open_loop(["s0", "s0", "s1", "s1", "s1"]))
    with pytest.raises(ValueError, match=r"two.csv: line 4: session_uid changes"):
        read_poses(tmp_path / "two.csv")


def test_an_mps_closed_loop_trajectory_in_two_worlds_is_refused(tmp_path):
    rows = ["graph_uid,tracking_timestamp_us,utc_timestamp_ns,tx_world_device,ty_world_device,"
            "tz_world_device,qx_world_device,qy_world_device,qz_world_device,qw_world_device"]
    for k, graph in enumerate(["g0", "g0", "g0", "g1"]):
        rows.append(f"{graph},{k * 1000},-1,{k}.0,0,0,0,0,0,1")
    (tmp_path / "closed_loop_trajectory.csv").write_text("\n".join(rows))
    with pytest.raises(ValueError, match=r"line 5: graph_uid changes"):
        read_poses(tmp_path / "closed_loop_trajectory.csv")
    (tmp_path / "one.csv").write_text("\n".join(rows[:4]))
    np.testing.assert_allclose(read_poses(tmp_path / "one.csv").poses[:, 0, 3], [0, 1, 2])


@pytest.mark.parametrize("unit, scale", [("ns", 1e9), ("us", 1e6), ("ms", 1e3), ("s", 1.0)])
def test_a_csv_naming_its_columns_is_read_in_the_unit_its_timestamp_names(tmp_path, unit, scale):
    head = f"qw,qx,qy,qz,time_{unit},tx,ty,tz,extra"  # any order, other columns ignored
    rows = [head]
    for t, p in zip(STAMPS, POSES, strict=True):
        x, y, z, w = (float(v) for v in matrix_to_quat(p[:3, :3]))
        rows.append(",".join(map(repr, [w, x, y, z, float(t * scale), *p[:3, 3].tolist(), 7.0])))
    (tmp_path / "log.csv").write_text("\n".join(rows))
    traj = read_poses(tmp_path / "log.csv")
    np.testing.assert_allclose(traj.poses, POSES, atol=1e-9)
    np.testing.assert_allclose(traj.stamps, STAMPS, rtol=1e-12)


@pytest.mark.parametrize("head, match", [
    ("timestamp,tx,ty,tz,qx,qy,qz,qw", r"'timestamp' does not say its unit"),
    ("t_ns,tx,tx_b,ty,tz,qx,qy,qz,qw", r"one 'tx' column .*\['tx', 'tx_b'\]"),
    ("a_ns,tx,ty,tz,qx,qy,qz,qw", r"one timestamp column, got none"),
    ("start_time_s,end_time_s,tx,ty,tz,qx,qy,qz,qw", r"one timestamp column, got \['start"),
])
def test_a_csv_naming_its_columns_names_what_it_lacks(tmp_path, head, match):
    (tmp_path / "p.csv").write_text(head + "\n" + ",".join(["1"] * len(head.split(","))))
    with pytest.raises(ValueError, match=match):
        read_poses(tmp_path / "p.csv")


@settings(max_examples=30, deadline=None)
@given(w=st.floats(0.0, 1.0))
def test_interpolation_is_linear_in_translation_and_slerp_in_rotation(w):
    traj = Trajectory(POSES[:2], STAMPS[:2])
    got = traj.at(STAMPS[0] + w * 0.1, max_gap=0.2)[0]
    np.testing.assert_allclose(got[:3, 3], (1 - w) * POSES[0, :3, 3] + w * POSES[1, :3, 3])
    # Equal angles from both ends, in proportion.
    rel = POSES[0, :3, :3].T @ POSES[1, :3, :3]
    total = np.arccos(np.clip((np.trace(rel) - 1) / 2, -1, 1))
    part = np.arccos(np.clip((np.trace(POSES[0, :3, :3].T @ got[:3, :3]) - 1) / 2, -1, 1))
    assert part == pytest.approx(w * total, abs=1e-7)


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), shape=st.sampled_from([(3,), (7, 3), (4, 5, 3)]))
def test_rotate_is_the_rotation_of_every_vector_whatever_the_rotations_layout(seed, shape):
    """``rotate(v, R)`` is ``R @ v`` per vector, for R given as a pose's 3x3 block or as its
    transposed view (the layouts the engine passes), NaN vectors staying NaN."""
    rng = np.random.default_rng(seed)
    pose = make_transform(random_rotation(rng), rng.normal(size=3))
    vectors = rng.normal(size=shape) * 10.0 ** rng.uniform(-3, 3)
    with_nan = vectors.ndim > 1  # one NaN vector beside finite ones
    if with_nan:
        vectors.reshape(-1, 3)[0] = np.nan
    for r in (pose[:3, :3], pose[:3, :3].T, np.ascontiguousarray(pose[:3, :3])):
        expected = np.einsum("ij,...j->...i", r, vectors)
        got = rotate(vectors, r)
        assert got.shape == vectors.shape
        np.testing.assert_allclose(got, expected, rtol=1e-12, atol=1e-12 * np.nanmax(
            np.abs(vectors)))
        assert np.isnan(got.reshape(-1, 3)[0]).all() == with_nan


def test_frames_without_a_pose_are_errors_naming_the_frame():
    traj = Trajectory(POSES, STAMPS)
    with pytest.raises(ValueError, match=r"frame 7 .*t=1000.9.*outside"):
        PoseMatcher(traj, "timestamp", max_gap=0.05)(7, None, 1000.9)
    gappy = Trajectory(POSES[[0, 3]], STAMPS[[0, 3]])
    with pytest.raises(ValueError, match="gap"):
        PoseMatcher(gappy, "timestamp", max_gap=0.05)(1, None, 1000.1)
    with pytest.raises(ValueError, match="5 poses for 6 frames"):
        PoseMatcher(traj, "index", frames=6)
    # By frame number: a missing frame does not shift the others.
    m = PoseMatcher(Trajectory(POSES))
    np.testing.assert_array_equal(m(2, "000003.png", None)[1], POSES[3])
    with pytest.raises(ValueError, match=r"frame 4 \(000009.png\).*no pose 9"):
        m(4, "000009.png", None)


@pytest.mark.parametrize("bad, match", [
    ("1 2 3\n", "cannot tell the pose format"),
    ("0 0 0 0 0 0 0 2\n", "line 1"),
    ("0 0 0 0 0 0 0 1\n0 0 0 0 0 0 0 1\n", "timestamps must increase"),
    ("0 nan 0 0 0 0 0 1\n", "finite"),
])
def test_bad_pose_files_name_the_line(tmp_path, bad, match):
    (tmp_path / "p.txt").write_text(bad)
    with pytest.raises(ValueError, match=match):
        read_poses(tmp_path / "p.txt")


@pytest.mark.parametrize("fmt", [None, *POSE_FORMATS])
@pytest.mark.parametrize("content", ["", "\n\n"])
def test_an_empty_pose_file_is_a_value_error_in_every_format(tmp_path, fmt, content):
    (tmp_path / "p.csv").write_text(content)
    with pytest.raises(ValueError, match="p.csv"):
        read_poses(tmp_path / "p.csv", format=fmt)


def test_binary_garbage_is_a_value_error(tmp_path):
    (tmp_path / "p.txt").write_bytes(b"\xff\xfe\x00\x01")
    with pytest.raises(ValueError, match="UTF-8"):
        read_poses(tmp_path / "p.txt")


def test_body_poses_compose_with_the_extrinsic():
    body_from_cam = make_transform(random_rotation(RNG), [0.1, 0.2, 0.3])
    traj = Trajectory(POSES, STAMPS).compose(body_from_cam)
    np.testing.assert_allclose(traj.poses[2], POSES[2] @ body_from_cam)


# ---- the road in any world frame ------------------------------------------------------------

CAM = tumvi_kb(400, 300, 120.0)
ROAD_SCENE = synth.parse_scenario({"name": "road", "frames": 8, "ego": {"speed_kmh": 20},
                                   "camera": {"position": [2, 0, 1.1], "pitch_deg": 12}})


@pytest.fixture(scope="module")
def road_frames():
    return synth.render_frames(CAM, ROAD_SCENE)


def test_the_road_is_found_in_the_first_camera_frame(road_frames):
    new_from_scene = np.linalg.inv(road_frames[0].pose)
    truth = fm.Road().transformed(new_from_scene)
    det = fm.MotionDetector(CAM, "auto", fm.Params(frame_gap=1))
    assert not det.road.known
    tilts, offsets = [], []
    for f in road_frames:
        det.apply(f.image, new_from_scene @ f.pose)
        if det.road.known:
            tilts.append(np.degrees(np.arccos(np.clip(det.road.up @ truth.up, -1, 1))))
            offsets.append(abs(det.road.offset - truth.offset))
    # Found at the first pair; corners tracked against the next frame warped by the road's flow
    # (and the first pair again by the road it found): every estimate within 0.08 deg (up to
    # 0.11 deg when corners only started at their predicted places) and 5 mm.
    assert len(tilts) == len(road_frames) - 1
    assert max(tilts) < 0.08 and max(offsets) < 0.005


def test_camera_height_rejects_an_implausible_plane():
    est = GroundEstimator(camera_height=3.0)
    pts = np.random.default_rng(0).uniform([-3, -3, 0], [3, 3, 0], (500, 3))
    down = np.array([0.0, 0.0, -1.0])
    assert est.fit(pts, np.array([0.0, 0.0, 1.0]), down) is None  # 1 m is not 3 m +- 25 %
    road = GroundEstimator().fit(pts, np.array([0.0, 0.0, 1.0]), down)
    assert road is not None and road.height(np.array([0, 0, 1.0])) == pytest.approx(1.0)


def test_an_implausible_given_road_warns():
    poses = np.repeat(np.eye(4)[None], 3, axis=0)
    with pytest.warns(UserWarning, match="on or under the road"):
        assert check_road(fm.Road(normal=(0, 0, 1), offset=0.5), poses)
    assert check_road(fm.Road(normal=(0, 0, 1), offset=-1.2), poses) == []


# ---- any resolution --------------------------------------------------------------------------

@pytest.mark.parametrize("width, height", [(512, 512), (640, 480), (1280, 966), (1920, 1080)])
def test_defaults_scaled_to_the_camera_behave_alike_at_any_resolution(width, height):
    """The same 190-degree lens at four sensor sizes: the scaled defaults see the crossing car
    as one region of about the same angular size, and flag little else."""
    scale = width / 640
    cam = tumvi_kb(width, height, 200.0 * scale)
    scene = synth.parse_scenario({
        "name": "res", "frames": 2, "ego": {"speed_kmh": 5},
        "camera": {"position": [2, 0, 1.0], "pitch_deg": 15},
        "objects": [{"id": 1, "kind": "car", "category": "crossing", "start": [9, -5],
                     "heading_deg": 90, "speed_kmh": 15}]})
    f0, f1 = synth.render_frames(cam, scene, supersample=1)
    roi = synth.Renderer(cam, scene, supersample=1).roi()  # without the ego vehicle's body
    params = fm.Params(frame_gap=1).for_camera(cam)
    assert params.grid == max(3, round(5 * scale))
    det = fm.MotionDetector(cam, params=params, roi=roi).detect_flow(
        np.nan_to_num(f1.flow), f0.pose, f1.pose)
    moving = f1.moving > 0
    ys, xs = np.nonzero(moving)
    boxes = [r.bbox for r in det.regions
             if r.bbox[0] <= np.median(xs) <= r.bbox[0] + r.bbox[2]
             and r.bbox[1] <= np.median(ys) <= r.bbox[1] + r.bbox[3]]
    assert len(boxes) == 1  # the car is one region, not a dozen boxes
    assert (det.mask[moving] > 0).mean() > 0.6
    static = ~moving & (roi > 0)
    assert (det.mask[static] > 0).mean() < 0.03
