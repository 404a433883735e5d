"""Ego-motion from the images: relative poses against the rendered truth, streams and the CLI
without poses."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import fisheyemotion as fm
from fisheyemotion import synth
from fisheyemotion.cli import main
from fisheyemotion.egomotion import PoseTracker, relative_pose, sampson_errors

from .cameras import tumvi_kb
from .scenes import camera_pose, moved, random_rotation, rays_of

CAM = tumvi_kb(480, 360, 150.0)
SCENE = synth.parse_scenario({
    "name": "ego", "frames": 6, "ego": {"speed_kmh": 25, "yaw_rate_deg_s": 8},
    "camera": {"position": [2, 0, 1.0], "pitch_deg": 12},
    "static": [{"id": 20, "kind": "building", "center": [18, 9], "size": [20, 6, 8]},
               {"id": 21, "kind": "building", "center": [20, -10], "size": [20, 6, 8],
                "texture": "camera"}],
    "objects": [{"id": 1, "kind": "car", "category": "crossing", "start": [9, -4],
                 "heading_deg": 90, "speed_kmh": 15}]})


def _angle(r):
    return np.degrees(np.arccos(np.clip((np.trace(r) - 1) / 2, -1, 1)))


def test_relative_pose_of_exact_rays_is_exact():
    rng = np.random.default_rng(2)
    pose0 = camera_pose(rng, height=1.0)
    pose1 = moved(pose0, [0.8, 0.1, 0.0], yaw_deg=3.0)
    points = pose0[:3, 3] + rng.uniform([2, -8, -0.9], [20, 8, 4], size=(200, 3))
    transform, inliers = relative_pose(rays_of(points, pose0), rays_of(points, pose1))
    truth = np.linalg.inv(pose1) @ pose0
    assert inliers.mean() > 0.5
    assert _angle(truth[:3, :3].T @ transform[:3, :3]) < 1e-4
    t = truth[:3, 3] / np.linalg.norm(truth[:3, 3])
    assert np.degrees(np.arccos(np.clip(t @ transform[:3, 3], -1, 1))) < 1e-3


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**31 - 1))
def test_sampson_errors_are_opencvs_sampson_distance(seed):
    """The epipolar error the guessed pose is judged by is OpenCV's Sampson distance (which
    returns its square) for E = [t]x R, and 0 for a static point's exact correspondence."""
    rng = np.random.default_rng(seed)
    r = random_rotation(rng) if seed % 2 else np.eye(3)
    t = rng.normal(size=3)
    transform = np.eye(4)
    transform[:3, :3], transform[:3, 3] = r, t / np.linalg.norm(t)
    x0, x1 = rng.uniform(-1, 1, size=(2, 20, 2))
    tx = np.array([[0, -t[2], t[1]], [t[2], 0, -t[0]], [-t[1], t[0], 0]]) / np.linalg.norm(t)
    essential = tx @ r
    expected = [np.sqrt(cv2.sampsonDistance(np.append(a, 1.0)[:, None], np.append(b, 1.0)[:, None],
                                            essential)) for a, b in zip(x0, x1, strict=True)]
    np.testing.assert_allclose(sampson_errors(x0, x1, transform), expected, rtol=1e-9, atol=1e-12)
    points = np.column_stack([x0, np.ones(20)]) * rng.uniform(2, 30, size=(20, 1))
    seen = points @ r.T + transform[:3, 3]
    exact = seen[:, :2] / seen[:, 2:]
    np.testing.assert_allclose(sampson_errors(x0, exact, transform), 0.0, atol=1e-12)


@pytest.mark.parametrize("guess_off_deg", [0.0, 0.3, 40.0])
def test_a_guessed_motion_is_refined_to_the_images_or_left_for_ransac(guess_off_deg, monkeypatch):
    """A stream's last step as the guess: near the truth (0.3 deg off, a turn's change over one
    frame) it is refined to the motion (to within the 0.003 deg that the outliers within its
    tolerance pull the robust loss); far off (40 deg) too few correspondences are its inliers
    and RANSAC finds the motion as without a guess. A fifth of the correspondences are outliers
    either way."""
    rng = np.random.default_rng(7)
    pose0 = camera_pose(rng, height=1.0)
    pose1 = moved(pose0, [0.8, 0.1, 0.0], yaw_deg=3.0)
    points = pose0[:3, 3] + rng.uniform([2, -8, -0.9], [20, 8, 4], size=(250, 3))
    rays0, rays1 = rays_of(points, pose0), rays_of(points, pose1)
    wrong = rng.random(250) < 0.2
    rays1[wrong] = rays_of(points[wrong] + rng.normal(scale=0.8, size=(wrong.sum(), 3)), pose1)
    truth = np.linalg.inv(pose1) @ pose0
    guess = truth.copy()
    turn = cv2.Rodrigues(np.radians(guess_off_deg) * np.array([0.0, 1.0, 0.0]))[0]
    guess[:3, :3] = turn @ truth[:3, :3]
    guess[:3, 3] /= np.linalg.norm(guess[:3, 3])
    import poselib

    sampled = []
    estimate = poselib.estimate_relative_pose
    monkeypatch.setattr(poselib, "estimate_relative_pose",
                        lambda *a, **k: sampled.append(1) or estimate(*a, **k))
    transform, inliers = relative_pose(rays0, rays1, threshold=2e-3, guess=guess,
                                       max_iterations=500, min_iterations=30)
    assert bool(sampled) == (guess_off_deg > 1)  # RANSAC only where the guess is far off
    assert _angle(truth[:3, :3].T @ transform[:3, :3]) < 5e-3
    t = truth[:3, 3] / np.linalg.norm(truth[:3, 3])
    assert np.degrees(np.arccos(np.clip(t @ transform[:3, 3], -1, 1))) < 0.05
    assert inliers[~wrong].mean() > 0.95 and inliers[wrong].mean() < 0.2


def test_rays_beyond_the_pinhole_range_are_left_out_not_wrong():
    rng = np.random.default_rng(3)
    r = random_rotation(rng)
    rays = rng.normal(size=(50, 3))
    rays[:, 2] = -np.abs(rays[:, 2])  # all behind the camera
    rays /= np.linalg.norm(rays, axis=-1, keepdims=True)
    transform, inliers = relative_pose(rays, rays @ r.T)
    assert transform is None and not inliers.any()


@pytest.mark.parametrize("seed", range(6))
def test_a_rival_motion_is_found_by_the_capped_second_ransac(seed):
    """The fast estimate's second hypothesis runs only the iterations that find a rival motion
    holding RIVAL_SHARE of the first one's inliers among its outliers (``rival_iterations``):
    a rival just above that share, among random outliers, is found and contests the first."""
    from fisheyemotion import egomotion

    rng = np.random.default_rng(seed)
    pose0 = camera_pose(rng, height=1.0)
    pose1 = moved(pose0, [0.8, 0.05, 0.0], yaw_deg=2.0)
    background = pose0[:3, 3] + rng.uniform([4, -10, -0.9], [25, 10, 5], size=(150, 3))
    n = int(np.ceil(egomotion.RIVAL_SHARE * 150)) + 8  # an object moving its own way
    thing = pose0[:3, 3] + rng.uniform([5, -1, -0.5], [7, 1, 0.5], size=(n, 3))
    r0 = np.concatenate([rays_of(background, pose0), rays_of(thing, pose0)])
    r1 = np.concatenate([rays_of(background, pose1),
                         rays_of(thing + [0.0, 1.2, 0.0], pose1)])
    junk = rng.normal(size=(25, 2, 3))  # outliers of both
    junk[..., 2] = np.abs(junk[..., 2]) + 1.0
    junk /= np.linalg.norm(junk, axis=-1, keepdims=True)
    r0, r1 = np.concatenate([r0, junk[:, 0]]), np.concatenate([r1, junk[:, 1]])
    first, inliers, second, others = egomotion._two_hypotheses(
        r0, r1, threshold=egomotion.FAST_THRESHOLD, max_iterations=egomotion.FAST_ITERATIONS,
        min_iterations=egomotion.MIN_ITERATIONS, second_iterations=egomotion.SECOND_ITERATIONS)
    assert inliers[:150].mean() > 0.95 and second is not None
    assert others[150:150 + n].mean() > 0.9
    assert others.sum() >= egomotion.RIVAL_SHARE * inliers.sum()  # contested


def test_rival_iterations_reach_their_confidence():
    from fisheyemotion.egomotion import MIN_ITERATIONS, RIVAL_SHARE, rival_iterations

    for inliers, rest in ((150, 60), (100, 100), (100, 300), (40, 12), (200, 500)):
        n = rival_iterations(inliers, rest)
        w = min(1.0, RIVAL_SHARE * inliers / rest)
        assert n >= MIN_ITERATIONS and (1 - w ** 5) ** n <= 0.01
        if n > MIN_ITERATIONS:  # no more than needed
            assert (1 - w ** 5) ** (n - 1) > 0.01


@pytest.fixture(scope="module")
def frames():
    return synth.render_frames(CAM, SCENE, supersample=1)


def test_tracked_poses_match_the_rendered_trajectory(frames):
    roi = synth.Renderer(CAM, SCENE, supersample=1).roi() > 0
    tracker = PoseTracker(CAM, mask=roi)
    est = [tracker(np.ascontiguousarray(f.image[..., 1])) for f in frames]
    rot, direction = [], []
    for k in range(1, len(frames)):
        true = np.linalg.inv(frames[k].pose) @ frames[k - 1].pose
        got = np.linalg.inv(est[k]) @ est[k - 1]
        rot.append(_angle(true[:3, :3].T @ got[:3, :3]))
        t, g = true[:3, 3] / np.linalg.norm(true[:3, 3]), got[:3, 3]
        direction.append(np.degrees(np.arccos(np.clip(t @ g, -1, 1))))
    # Turning at 8 deg/s with a car crossing: rotation within a tenth of a degree, the direction
    # of travel within a couple of degrees.
    assert np.median(rot) < 0.08 and max(rot) < 0.2
    assert np.median(direction) < 2.5 and max(direction) < 4.0


def test_a_stream_without_poses_does_as_well_as_with_the_true_ones(frames):
    roi = synth.Renderer(CAM, SCENE, supersample=1).roi()
    truth, static = frames[-1].moving > 0, (frames[-1].moving == 0) & (roi > 0)
    scores = {}
    for mode in ("true", "estimated"):
        det = fm.MotionDetector(CAM, fm.Road.unknown(), fm.Params(frame_gap=1), roi=roi)
        results = [det.apply(f.image, f.pose if mode == "true" else None) for f in frames]
        assert results[0] is None and det.last_pose is not None
        last = results[-1]
        scores[mode] = ((last.mask[truth] > 0).mean(), (last.mask[static] > 0).mean())
    assert scores["estimated"][0] > 0.3  # the crossing car
    assert scores["estimated"][0] > scores["true"][0] - 0.1
    assert scores["estimated"][1] < scores["true"][1] + 0.03
    with pytest.raises(ValueError, match="estimates its poses"):
        det.apply(frames[0].image, frames[0].pose)


def test_the_cli_without_poses_estimates_and_writes_them(tmp_path, frames):
    import cv2

    folder = tmp_path / "frames"
    folder.mkdir()
    for k, f in enumerate(frames):
        cv2.imwrite(str(folder / f"{k:06d}.png"), f.image)
    fm.calib.save_opencv(CAM, tmp_path / "calib.yaml")
    (tmp_path / "p.yaml").write_text("frame_gap: 1\n")
    assert main(["detect", str(folder), "--calib", str(tmp_path / "calib.yaml"), "--out",
                 str(tmp_path / "out"), "--quiet", "--params", str(tmp_path / "p.yaml")]) == 0
    poses = fm.poses.read_poses(tmp_path / "out" / "poses.txt").poses
    assert len(poses) == len(frames)
    np.testing.assert_allclose(poses[0], np.eye(4))
    # With the camera's height the estimated steps are metres.
    assert main(["detect", str(folder), "--calib", str(tmp_path / "calib.yaml"), "--out",
                 str(tmp_path / "out2"), "--quiet", "--params", str(tmp_path / "p.yaml"),
                 "--camera-height", "1.0"]) == 0
    poses = fm.poses.read_poses(tmp_path / "out2" / "poses.txt").poses
    true_steps = np.linalg.norm(np.diff([f.pose[:3, 3] for f in frames], axis=0), axis=-1)
    np.testing.assert_allclose(np.linalg.norm(np.diff(poses[:, :3, 3], axis=0), axis=-1),
                               true_steps, rtol=0.06)


def test_a_stream_without_poses_but_with_the_camera_height_keeps_its_road_terms(frames):
    import warnings

    roi = synth.Renderer(CAM, SCENE, supersample=1).roi()
    det = fm.MotionDetector(CAM, "auto", fm.Params(frame_gap=1), roi=roi, camera_height=1.0)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no "road terms are off" warning
        for f in frames:
            det.apply(f.image)
    assert det.ground is not None and det._tracker.metric


# The unrefined noisy poses flood the image on purpose (the warning says so).
@pytest.mark.filterwarnings("ignore:detection. more than:UserWarning")
def test_pose_refinement_repairs_noisy_rotations(frames):
    from .scenes import rotation

    roi = synth.Renderer(CAM, SCENE, supersample=1).roi()
    static = (frames[-1].moving == 0) & (roi > 0)
    rng = np.random.default_rng(5)
    noisy = []
    for f in frames:  # 0.6 deg of rotation error per frame, as from a loose IMU
        p = f.pose.copy()
        p[:3, :3] = p[:3, :3] @ rotation(rng.normal(size=3), np.radians(0.6))
        noisy.append(p)
    flagged = {}
    for name, mode, poses in (("true", "off", [f.pose for f in frames]),
                              ("noisy", "off", noisy), ("refined", "auto", noisy)):
        det = fm.MotionDetector(CAM, fm.Road(), fm.Params(frame_gap=1, pose_refinement=mode),
                                roi=roi)
        for f, p in zip(frames, poses, strict=True):
            last = det.apply(f.image, p)
        flagged[name] = (last.mask[static] > 0).mean()
    # Measured: 1.4 % of static pixels flagged with the true poses, 6.3 % with the noisy ones,
    # 1.9 % with the noisy ones refined.
    assert flagged["noisy"] > flagged["true"] + 0.03  # the noise costs false alarms ...
    assert flagged["refined"] < flagged["true"] + 0.01  # ... which the refinement removes


@pytest.mark.parametrize("road", [None, fm.Road()], ids=["no road", "road given"])
def test_pose_refinement_takes_the_direction_of_travel_from_the_images_and_the_length_from_the_road(
        frames, road):
    """Without a road the step's length is the given one; with the road given (the camera 1 m
    above it, read off the given poses), it is the road's as the images show it."""
    from fisheyemotion.refinement import PoseRefiner

    roi = synth.Renderer(CAM, SCENE, supersample=1).roi()
    rng = np.random.default_rng(6)
    noisy = []
    for f in frames:  # the positions 10 % of a step off, in a random direction
        p = f.pose.copy()
        p[:3, 3] += 0.10 * 0.46 * _unit(rng)
        noisy.append(p)
    refiner = PoseRefiner(CAM, mode="on", tolerance=0.1, mask=roi > 0)
    chain = [refiner.step(cv2.cvtColor(f.image, cv2.COLOR_BGR2GRAY), p, road=road)
             for f, p in zip(frames, noisy, strict=True)]
    given_off, refined_off = [], []
    for k in range(2, len(frames)):
        true_step = frames[k].pose[:3, 3] - frames[k - 1].pose[:3, 3]
        got_step = chain[k][:3, 3] - chain[k - 1][:3, 3]
        given_step = noisy[k][:3, 3] - noisy[k - 1][:3, 3]
        # Direction from the images (the true one within 1 deg, rotated into the chain's frame
        # whose orientation is the first noisy pose's).
        r = chain[k - 1][:3, :3] @ frames[k - 1].pose[:3, :3].T
        cos = (r @ true_step) @ got_step / (np.linalg.norm(true_step) * np.linalg.norm(got_step))
        assert np.degrees(np.arccos(min(1.0, cos))) < 1.0  # 3-7 deg unrefined
        if road is None:
            assert np.linalg.norm(got_step) == pytest.approx(np.linalg.norm(given_step),
                                                             rel=1e-9)
        given_off.append(abs(np.linalg.norm(given_step) / np.linalg.norm(true_step) - 1))
        refined_off.append(abs(np.linalg.norm(got_step) / np.linalg.norm(true_step) - 1))
    if road is not None:  # measured: given 1-13 % off, refined 0.2-0.5 %
        assert max(refined_off) < 0.02 and np.mean(refined_off) < np.mean(given_off) / 5
    with pytest.raises(ValueError, match="camera_height"):
        PoseRefiner(CAM, mode="on", tolerance=0.1, camera_height=0.0)


def test_refined_poses_average_the_given_orientations_errors_not_keep_the_first(frames):
    """The stream's refined pose (its anchor times its chain) is off the truth by about the
    mean of the given poses' errors so far, not by the first given pose's error."""
    from fisheyemotion.calib.transforms import mean_rotation

    from .scenes import rotation

    roi = synth.Renderer(CAM, SCENE, supersample=1).roi()
    rng = np.random.default_rng(8)
    errors = [rotation(rng.normal(size=3), np.radians(0.5)) for _ in frames]
    det = fm.MotionDetector(CAM, fm.Road(), fm.Params(frame_gap=1, pose_refinement="on"),
                            roi=roi)
    for k, f in enumerate(frames):
        p = f.pose.copy()
        p[:3, :3] = p[:3, :3] @ errors[k]
        det.apply(f.image, p)
        off = _angle(det.last_pose[:3, :3].T @ f.pose[:3, :3])
        # The mean of the errors so far, up to what the images' relative poses add (0.02 deg
        # a step, measured); the first given pose's error (0.5 deg) would fail from frame 1.
        expected = _angle(mean_rotation(np.stack(errors[:k + 1])))
        assert off == pytest.approx(expected, abs=0.03 * k + 1e-9)
    assert off < 0.3


def _unit(rng):
    v = rng.normal(size=3)
    return v / np.linalg.norm(v)


@pytest.fixture(scope="module")
def ego_sequence(tmp_path_factory):
    return synth.write_sequence(tmp_path_factory.mktemp("ego") / "ego", CAM, SCENE,
                                frames=6, flow=False, progress=False, supersample=1)


def test_eval_pose_sources_true_estimated_perturbed(ego_sequence):
    from fisheyemotion.eval.pose_sources import Perturbation, pose_errors, poses_for

    from fisheyemotion.sequence import Sequence

    seq = Sequence(ego_sequence)
    params = fm.Params(frame_gap=1)
    true = poses_for(seq, "true", params).poses
    assert np.array_equal(true, seq.poses)
    assert pose_errors(true, seq.poses, 1)[["rotation_error_deg", "direction_error_deg"]] \
        .abs().max().max() < 1e-6
    # From the images: every pair's rotation within 0.2 deg, direction within 3 deg.
    errors = pose_errors(poses_for(seq, "estimated", params).poses, seq.poses, 1)
    assert errors.rotation_error_deg.max() < 0.2 and errors.direction_error_deg.max() < 3.0
    # Noise of the stated size: each frame's orientation off by exactly rotation_deg.
    noisy = poses_for(seq, "perturbed", params, noise=Perturbation(rotation_deg=0.4,
                                                                   translation=0.0,
                                                                   time_offset_s=0.0)).poses
    for k in range(len(seq)):
        assert _angle(noisy[k, :3, :3].T @ seq.poses[k, :3, :3]) == pytest.approx(0.4, abs=1e-6)
    errs = pose_errors(noisy, seq.poses, 1).rotation_error_deg
    assert errs.max() <= 0.8 + 1e-6 and errs.median() > 0.1
    # Refinement brings the rotation back to what the images say.
    refined = pose_errors(poses_for(seq, "perturbed", params.replace(pose_refinement="on"),
                                    noise=Perturbation(rotation_deg=0.4, translation=0.0,
                                                       time_offset_s=0.0)).poses, seq.poses, 1)
    assert refined.rotation_error_deg.iloc[1:].median() < errs.iloc[1:].median() / 2
    with pytest.raises(ValueError, match="poses"):
        poses_for(seq, "odometry", params)


@pytest.mark.parametrize("seed", range(5))
def test_road_scale_of_exact_rays_is_the_baseline_in_metres(seed):
    from fisheyemotion.egomotion import road_scale

    rng = np.random.default_rng(seed)
    height = rng.uniform(0.5, 2.5)
    pose0 = camera_pose(rng, height=height)
    pose1 = moved(pose0, [rng.uniform(0.3, 1.5), 0.0, 0.0], yaw_deg=rng.uniform(-3, 3))
    # Road well below the horizon (within 2.5 camera heights ahead), and farther road.
    road = np.c_[pose0[:2, 3] + rng.uniform([0.6 * height, -2 * height], [2.5 * height, 2 * height],
                                            size=(150, 2)), np.zeros(150)]
    road = np.r_[road, np.c_[pose0[:2, 3] + rng.uniform([5, -6], [20, 6], size=(100, 2)),
                             np.zeros(100)]]
    wall = pose0[:3, 3] + np.c_[rng.uniform(3, 6, 60), rng.uniform(-2, 2, 60),
                                rng.uniform(-height + 0.2, 0.5, 60)]  # obstacles: shallower
    points = np.r_[road, wall]
    truth = np.linalg.inv(pose1) @ pose0
    unit = truth.copy()
    unit[:3, 3] /= np.linalg.norm(truth[:3, 3])
    scale = road_scale(rays_of(points, pose0), rays_of(points, pose1), unit, height)
    assert scale == pytest.approx(np.linalg.norm(truth[:3, 3]), rel=1e-6)


def test_a_tracker_given_the_camera_height_steps_in_metres(frames):
    roi = synth.Renderer(CAM, SCENE, supersample=1).roi() > 0
    tracker = PoseTracker(CAM, mask=roi, camera_height=1.0)
    est = np.stack([tracker(np.ascontiguousarray(f.image[..., 1])) for f in frames])
    true_steps = np.linalg.norm(np.diff([f.pose[:3, 3] for f in frames], axis=0), axis=-1)
    est_steps = np.linalg.norm(np.diff(est[:, :3, 3], axis=0), axis=-1)
    assert tracker.metric
    np.testing.assert_allclose(est_steps, true_steps, rtol=0.06)  # 4 % at 480x360, fx 150
    with pytest.raises(ValueError, match="camera_height"):
        PoseTracker(CAM, camera_height=-1.0)


def test_a_close_moving_object_with_more_corners_does_not_win_the_pose():
    from fisheyemotion.egomotion import dominant_background_pose

    rng = np.random.default_rng(11)
    pose0 = camera_pose(rng, height=1.5)
    pose1 = moved(pose0, [0.3, 0.0, 0.0], yaw_deg=2.0)
    background = pose0[:3, 3] + rng.uniform([3, -10, -1.4], [20, 10, 5], size=(120, 3))
    # An arm: 300 corners in a compact patch 0.5 m ahead, moving on its own.
    arm = pose0[:3, 3] + np.array([0.6, 0.0, -0.2]) + rng.uniform(-0.08, 0.08, size=(300, 3))
    arm_pose1 = moved(pose1, [0.0, 0.05, 0.04], yaw_deg=-4.0)
    rays0 = np.r_[rays_of(background, pose0), rays_of(arm, pose0)]
    rays1 = np.r_[rays_of(background, pose1), rays_of(arm, arm_pose1)]
    pixels0, _ = CAM.project(rays0)
    transform, inliers = dominant_background_pose(rays0, rays1, pixels0, (CAM.height, CAM.width))
    truth = np.linalg.inv(pose1) @ pose0
    assert _angle(truth[:3, :3].T @ transform[:3, :3]) < 0.01
    assert inliers[:120].mean() > 0.9 and inliers[120:].mean() < 0.1


def test_eval_cli_draws_the_pose_noise_by_seed(ego_sequence, tmp_path, capsys):
    import pandas as pd

    (tmp_path / "p.yaml").write_text("frame_gap: 1\nflow: dis\ndis_preset: ultrafast\n")
    errors = {}
    for seed in (0, 0, 1):
        out = tmp_path / f"out{seed}{len(errors)}"
        assert main(["eval", str(ego_sequence), "--poses", "perturbed", "--noise-seed", str(seed),
                     "--params", str(tmp_path / "p.yaml"), "--workers", "1", "--quiet",
                     "--out", str(out)]) == 0
        frames = pd.read_csv(out / "frames.csv")
        errors.setdefault(seed, []).append(frames.rotation_error_deg.to_numpy())
    np.testing.assert_array_equal(*errors[0])              # a draw is reproducible
    assert not np.allclose(errors[0][0], errors[1][0])      # another seed, another draw
    with pytest.raises(SystemExit):
        main(["eval", str(ego_sequence), "--noise-seed", "-1", "--out", str(tmp_path / "x")])
    assert "integer >= 0" in capsys.readouterr().err


def test_eval_cli_sets_the_size_of_the_pose_noise(ego_sequence, tmp_path, capsys):
    import pandas as pd

    (tmp_path / "p.yaml").write_text("frame_gap: 1\nflow: dis\ndis_preset: ultrafast\n")
    out = tmp_path / "out"
    assert main(["eval", str(ego_sequence), "--poses", "perturbed", "--noise-rotation", "0.2",
                 "--noise-translation", "0", "--noise-time-offset", "0",
                 "--params", str(tmp_path / "p.yaml"), "--workers", "1", "--quiet",
                 "--out", str(out)]) == 0
    errors = pd.read_csv(out / "frames.csv").rotation_error_deg
    # Two frames' orientations each 0.2 deg off about random axes: 0.4 deg at most between them.
    assert 0.02 < errors.median() and errors.max() <= 0.4 + 1e-6
    for flag in ("--noise-rotation", "--noise-translation", "--noise-time-offset"):
        with pytest.raises(SystemExit):
            main(["eval", str(ego_sequence), flag, "nan", "--out", str(tmp_path / "x")])
        assert f"argument {flag}: expected a finite number >= 0" in capsys.readouterr().err


@pytest.mark.parametrize("field, value", [("rotation_deg", -0.1), ("translation", np.inf),
                                          ("time_offset_s", "5 ms"), ("seed", -1),
                                          ("seed", 1.5)])
def test_a_perturbation_names_the_field_it_refuses(field, value):
    from fisheyemotion.eval.pose_sources import Perturbation

    with pytest.raises(ValueError, match=f"^{field}: expected"):
        Perturbation(**{field: value})
