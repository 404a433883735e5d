"""The cluttered-street capabilities: the static-scene model, results on the current frame,
the ground-contact test and deviations in units of the flow's error."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import fisheyemotion as fm
from fisheyemotion import synth
from fisheyemotion.flow import grid_average, grid_gather, grid_transfer
from fisheyemotion.ground_contact import contact_ratios, smooth_columns, standing_regions
from fisheyemotion.prior import EgoFlowPrior
from fisheyemotion.significance import cell_sigma, pixel_angle, pose_sigma
from fisheyemotion.static_scene import StaticScene, triangulate_range

from .cameras import ALL_CAMERAS, CAMERA_IDS, tumvi_kb
from .scenes import camera_pose, moved, random_rotation, rays_of

CAM = tumvi_kb(320, 240, 100.0)
WALL = synth.parse_scenario({
    "name": "wall", "frames": 4, "ego": {"speed_kmh": 25},
    "camera": {"position": [2, 0, 0.9], "pitch_deg": 10},
    "static": [{"id": 20, "kind": "wall", "center": [9, -4.0], "size": [14, 0.3, 3.0]},
               {"id": 21, "kind": "parked_car", "center": [8, 3.0]}]})


# ---- triangulation and the static-scene model ----------------------------------------------

@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**31 - 1))
def test_triangulated_range_is_the_distance_to_the_point(seed):
    rng = np.random.default_rng(seed)
    pose0 = camera_pose(rng, height=1.0)
    pose1 = moved(pose0, [rng.uniform(0.3, 2.0), rng.uniform(-0.3, 0.3), 0.0],
                  yaw_deg=rng.uniform(-5, 5))
    points = pose0[:3, 3] + rng.uniform([3, -8, -0.9], [30, 8, 5], size=(50, 3))
    lam, ok = triangulate_range(rays_of(points, pose0), rays_of(points, pose1), pose0, pose1,
                                far=1e4, min_parallax=np.radians(0.05))
    truth = np.linalg.norm(points - pose0[:3, 3], axis=-1)
    assert ok.mean() > 0.9
    np.testing.assert_allclose(lam[ok], truth[ok], rtol=1e-8)
    # The parallax it returns is the sine of the rays' angle, |p x p'| in the world frame.
    r0, r1 = rays_of(points, pose0), rays_of(points, pose1)
    _, _, parallax = triangulate_range(r0, r1, pose0, pose1, far=1e4, with_parallax=True)
    cross = np.linalg.norm(np.cross(r0 @ pose0[:3, :3].T, r1 @ pose1[:3, :3].T), axis=-1)
    np.testing.assert_allclose(parallax, cross, rtol=1e-7, atol=1e-12)


def test_triangulation_rejects_points_behind_and_without_parallax():
    pose0 = camera_pose(np.random.default_rng(0), height=1.0)
    pose1 = moved(pose0, [1.0, 0, 0])
    ahead = pose0[:3, 3] + np.array([[10.0, 3.0, 0.0]])
    r0 = rays_of(ahead, pose0)
    # The same ray in both views (no parallax) and a ray pair that meets behind the camera.
    lam, ok = triangulate_range(r0, rays_of(ahead, pose0), pose0, pose1, far=100,
                                min_parallax=np.radians(0.5))
    assert not ok[0] and np.isnan(lam[0])
    # The second ray meets the first one's line 5 m behind the first camera.
    behind = pose0[:3, 3] - 5.0 * (r0 @ pose0[:3, :3].T)
    lam, ok = triangulate_range(r0, rays_of(behind, pose1), pose0, pose1, far=100)
    assert not ok[0]
    lam, ok = triangulate_range(r0, rays_of(ahead, pose1), pose0, pose1, far=100)
    assert ok[0] and lam[0] == pytest.approx(np.hypot(10.0, 3.0))


def test_scene_ranges_return_the_stored_points_along_other_rays():
    rng = np.random.default_rng(1)
    pose0 = camera_pose(rng, height=1.0)
    pose1 = moved(pose0, [1.0, 0.0, 0.0])
    prior = EgoFlowPrior(CAM, step=8)
    # A wall 6 m to the left seen on a dense grid of the first camera.
    u = np.stack(np.meshgrid(np.arange(0, 320, 2.0), np.arange(0, 240, 2.0)), axis=-1)
    rays, ok = CAM.unproject(u)
    dirs = rays @ pose0[:3, :3].T
    with np.errstate(divide="ignore", invalid="ignore"):
        lam = np.where(dirs[..., 1] > 0.05, 6.0 / dirs[..., 1], np.nan)
    scene = StaticScene(CAM)
    assert scene.add(rays, lam, pose0, ok & np.isfinite(lam)) > 1000
    # Seen from the second camera: ranges along its rays are the distances to the wall.
    got = scene.ranges(pose1, prior.step, prior._rays.shape[:2])
    d1 = prior._rays @ pose1[:3, :3].T
    with np.errstate(divide="ignore", invalid="ignore"):
        truth = (6.0 - pose1[1, 3] + pose0[1, 3]) / d1[..., 1]
    inner = np.isfinite(got) & (d1[..., 1] > 0.3)
    assert inner.sum() > 50
    np.testing.assert_allclose(got[inner], truth[inner], rtol=0.05)
    scene.clear()
    assert len(scene) == 0 and np.isnan(scene.ranges(pose1, 8, (30, 40))).all()


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), rows=st.integers(1, 9), cols=st.integers(1, 9),
       points=st.integers(0, 120))
def test_sample_medians_match_a_per_sample_median(seed, rows, cols, points):
    """The scene model's kernel against numpy sample by sample: the upper median of each
    sample's values, empty samples the smallest median among their eight neighbours, NaN
    where none (including points outside, cell -1)."""
    from fisheyemotion._grid_kernels import sample_medians

    rng = np.random.default_rng(seed)
    n = rows * cols
    cell = rng.integers(-1, n, points)
    values = np.round(rng.uniform(1, 50, points), 1)  # ties too
    out = np.empty((rows, cols))
    sample_medians(cell, values, np.zeros(n + 1, np.intp), np.empty(n, np.intp),
                   np.empty(points), np.empty(n), out)
    med = np.full((rows, cols), np.inf)
    for k in range(n):
        v = np.sort(values[cell == k])
        if len(v):
            med.flat[k] = v[len(v) // 2]
    want = med.copy()
    for r in range(rows):
        for c in range(cols):
            if not np.isfinite(med[r, c]):
                want[r, c] = med[max(r - 1, 0):r + 2, max(c - 1, 0):c + 2].min()
    want[~np.isfinite(want)] = np.nan
    np.testing.assert_array_equal(out, want)


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), rows=st.integers(1, 12), cols=st.integers(1, 12),
       grid=st.integers(1, 7), gap=st.integers(1, 4))
def test_temporal_accumulation_matches_numpy_to_the_bit(seed, rows, cols, grid, gap):
    """The temporal filter's kernel against the same step written with numpy arrays: each cell
    reads the previous map where its (source's) flow says it came from."""
    from fisheyemotion._grid_kernels import accumulate
    from fisheyemotion.flow import grid_centres

    rng = np.random.default_rng(seed)
    n = rows * cols
    source = rng.integers(-1, n, (rows, cols)).astype(np.intp)
    likelihood = np.where(rng.random((rows, cols)) < 0.2, np.nan, rng.random((rows, cols)) / 50)
    carrier = (rng.normal(size=(rows, cols, 2)) * 4 * grid).astype(np.float32)
    carrier[rng.random((rows, cols)) < 0.1] = np.nan
    acc_before, age_before = rng.random((rows, cols)) / 50, rng.integers(0, 5, (rows, cols))
    decay, threshold = 0.3, 0.004
    acc, age = np.empty((rows, cols)), np.empty((rows, cols), np.int64)
    accumulate(source, likelihood, carrier, acc_before, age_before, decay, threshold, gap, grid,
               acc, age)
    moved = carrier.reshape(n, 2)[np.maximum(source, 0)]
    moved[source < 0] = np.nan
    moved = np.nan_to_num(moved, nan=0.0)
    back = grid_centres(cols * grid, rows * grid, grid) - moved / gap
    c = np.clip(np.rint((back[..., 0] - (grid - 1) / 2) / grid), 0, cols - 1).astype(np.intp)
    r = np.clip(np.rint((back[..., 1] - (grid - 1) / 2) / grid), 0, rows - 1).astype(np.intp)
    want = (1 - decay) * np.nan_to_num(likelihood, nan=0.0) + decay * acc_before[r, c]
    np.testing.assert_array_equal(acc, want)
    np.testing.assert_array_equal(age, np.where(want > threshold, age_before[r, c] + 1, 0))


def test_scene_prior_predicts_the_flow_of_structure_beside_the_road():
    r = synth.Renderer(CAM, WALL, supersample=1)
    f = [r.render(k) for k in range(4)]
    det = fm.MotionDetector(CAM, roi=r.roi(), params=fm.Params(frame_gap=1))
    prior = EgoFlowPrior(CAM, step=4)
    structure = (f[2].ids >= 20) & (f[2].ids < 65535) & np.isfinite(f[3].flow).all(axis=-1)
    road_only, _ = prior(f[2].pose, f[3].pose, fm.Road())
    # The stream measures the scene with the exact flow, then predicts the next pair.
    for k in (1, 2):
        det.detect_flow(np.nan_to_num(f[k].flow), f[k - 1].pose, f[k].pose, stream=True)
    with_scene, _ = prior(f[2].pose, f[3].pose, fm.Road(), scene=det.scene)
    err_road_only = np.linalg.norm(road_only - f[3].flow, axis=-1)[structure]
    err_scene = np.linalg.norm(with_scene - f[3].flow, axis=-1)[structure]
    assert np.median(err_road_only) > 2.0
    assert np.median(err_scene) < 0.25 * np.median(err_road_only)


def test_prior_flow_is_continued_where_the_static_point_leaves_the_domain():
    # A double sphere whose domain ends inside the image: the road below the camera leaves it.
    ds = fm.calib.DoubleSphere(fx=80, fy=80, cx=159.5, cy=119.5, xi=-0.2, alpha=0.6,
                               width=320, height=240)
    pose0 = camera_pose(np.random.default_rng(0), height=0.9, pitch_deg=15)
    pose1 = moved(pose0, [1.5, 0, 0])
    flow, _ = EgoFlowPrior(ds, step=8)(pose0, pose1, fm.Road())
    valid = ds.valid_pixel_mask()
    bottom = valid.copy()
    bottom[:200] = False
    assert bottom.any()
    assert np.all(np.linalg.norm(flow[bottom], axis=-1) > 1.0)


# ---- results on the current frame ----------------------------------------------------------

def test_grid_transfer_moves_cells_by_their_flow_and_fills_gaps():
    rows, cols, g = 20, 30, 5
    values = np.zeros((rows, cols))
    values[5:8, 10:13] = 1.0
    flow = np.zeros((rows, cols, 2), np.float32)
    flow[5:8, 10:13] = (11.0, 5.0)  # two cells right, one down
    src = grid_transfer(flow, values, g)
    out = grid_gather(values, src)
    assert np.array_equal(np.argwhere(out > 0.5).min(axis=0), [6, 12])
    assert np.array_equal(np.argwhere(out > 0.5).max(axis=0), [8, 14])
    # Expansion: cells spread apart leave gaps that take a neighbour.
    spread = np.zeros((rows, cols, 2), np.float32)
    spread[..., 0] = (np.arange(cols) - cols / 2) * 2.0
    src = grid_transfer(spread, np.ones((rows, cols)), g)
    assert (src[:, 3:-3] >= 0).all()
    assert (grid_gather(np.ones((rows, cols)), src)[:, 3:-3] == 1).all()


def _crossing_car(*, frames: int, ego_kmh: float, start: list, kmh: float):
    """An empty road and one car crossing it at ``kmh``."""
    return synth.parse_scenario({
        "name": "crosser", "frames": frames, "ego": {"speed_kmh": ego_kmh},
        "camera": {"position": [2, 0, 1.0], "pitch_deg": 15},
        "objects": [{"id": 1, "kind": "car", "category": "crossing", "start": start,
                     "heading_deg": 90, "speed_kmh": kmh}]})


def test_masks_are_on_the_current_frame():
    scenario = _crossing_car(frames=2, ego_kmh=5, start=[8, -3], kmh=40)
    cam = tumvi_kb(640, 480, 200.0)
    f0, f1 = synth.render_frames(cam, scenario)
    det = fm.MotionDetector(cam).detect_flow(np.nan_to_num(f1.flow), f0.pose, f1.pose)
    now, before = f1.moving > 0, f0.moving > 0
    ahead, behind = (det.mask[now & ~before] > 0).mean(), (det.mask[before & ~now] > 0).mean()
    # Where the car is now, and much less where it was (cells straddling its trailing edge
    # carry it a cell or two behind).
    assert ahead > 0.7 and behind < 0.6 and behind < ahead - 0.3


# ---- ground contact ----------------------------------------------------------------------

def _column_scene(below_ratio: float):
    """One region 3 cells tall over 3 columns at range 10 m, with ``below_ratio`` x 10 m below."""
    pose = camera_pose(np.random.default_rng(0), height=1.0, pitch_deg=0)
    rows, cols, g = 48, 64, 5
    centres = np.stack(np.meshgrid(np.arange(cols) * g + 2.0, np.arange(rows) * g + 2.0),
                       axis=-1)
    rays, _ = CAM.unproject(centres)
    ranges = np.full((rows, cols), 10.0)
    labels = np.zeros((rows, cols), np.intp)
    labels[20:23, 30:33] = 1
    ranges[23:30, 30:33] = 10.0 * below_ratio
    return labels, ranges, rays, pose, g


@pytest.mark.parametrize("below, stands", [(0.8, True), (1.0, True), (1.5, False)])
def test_ground_contact_tells_standing_from_floating(below, stands):
    labels, ranges, rays, pose, g = _column_scene(below)
    ratios = contact_ratios(labels, ranges, rays, pose, CAM, fm.Road(), g)
    assert np.allclose(ratios[1, 30:33], below)
    share = np.where(labels > 0, 0.9, 0.0)
    got = standing_regions(labels > 0, share, ranges, rays, pose, CAM, fm.Road(), g, ratio=1.05)
    assert got[labels > 0].all() == stands and not got[labels == 0].any()


def test_a_column_whose_walk_meets_a_flow_error_takes_its_neighbours_ratio():
    # A region 7 columns wide standing on the road, but one column's walk below the edge met a
    # far reading (a smeared boundary): alone it floats; with its neighbours' median it stands.
    labels, ranges, rays, pose, g = _column_scene(1.0)
    labels[20:23, 28:35] = 1
    ranges[23:30, 28:35] = 10.0
    ranges[23:30, 31] = 15.0
    share = np.where(labels > 0, 0.9, 0.0)
    args = (labels > 0, share, ranges, rays, pose, CAM, fm.Road(), g)
    alone = standing_regions(*args, ratio=1.05, columns=0)
    assert alone[labels > 0].mean() < 1 and not alone[20:23, 31].any()
    assert standing_regions(*args, ratio=1.05, columns=2)[labels > 0].all()
    # A region floating in most of its columns still floats.
    ranges[23:30, 28:35] = 15.0
    ranges[23:30, 31] = 10.0
    assert not standing_regions(*args, ratio=1.05, columns=2).any()


@settings(max_examples=50, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), columns=st.integers(0, 5))
def test_smooth_columns_is_the_median_of_the_finite_neighbours(seed, columns):
    rng = np.random.default_rng(seed)
    ratios = np.where(rng.random((4, 20)) < 0.4, np.nan, rng.uniform(0.5, 2.0, (4, 20)))
    got = smooth_columns(ratios, columns)
    for i, c in np.ndindex(ratios.shape):
        if np.isnan(ratios[i, c]):
            assert np.isnan(got[i, c])
        else:
            window = ratios[i, max(0, c - columns):c + columns + 1]
            assert got[i, c] == pytest.approx(np.nanmedian(window), rel=1e-12)


@pytest.mark.parametrize("sigmas, contact_epipolar, explained",
                         [(1.5, True, True), (3.0, True, False), (1.5, False, False)])
def test_a_standing_cells_epipolar_deviation_counts_in_sigmas_only(sigmas, contact_epipolar,
                                                                   explained):
    """A parked car's cell that stands on the road, 1.5 flow-error sigmas off its arc: its raw
    angle alone (0.015 rad, 1.6 times the threshold at weight 1 / 2.4) is the flow's error, and
    it is static; 3 sigmas off it is not explained, nor is any without ``contact_epipolar``."""
    from fisheyemotion.constraints import ConstraintResult

    labels, ranges, rays, pose, g = _column_scene(1.0)
    det = fm.MotionDetector(CAM, params=fm.Params(contact_epipolar=contact_epipolar))
    region = labels > 0
    sigma = np.full(labels.shape, 0.01)
    zero = np.zeros(labels.shape)
    epipolar = np.where(region, sigmas * 0.01, 0.0)
    antiparallel = np.where(region, 0.3, 0.0)  # leads: 0.025 of the weighted mean
    res = ConstraintResult(epipolar, zero, zero, antiparallel,
                           (epipolar + 0.2 * antiparallel) / 2.4, np.ones(labels.shape, bool),
                           False)
    likelihood = det._with_significance(res, sigma, res.likelihood)
    assert (likelihood[region] > 0.004).all()
    out, _, _ = det._explain_standing(res, likelihood, res.valid, ranges, zero, sigma, pose)
    assert (out[region] < 0.004).all() == explained
    assert (out[region] > 0.004).all() == (not explained)
    np.testing.assert_array_equal(out[~region], likelihood[~region])


def test_regions_not_led_by_the_antiparallel_term_are_never_explained():
    labels, ranges, rays, pose, g = _column_scene(0.8)
    share = np.where(labels > 0, 0.3, 0.0)
    assert not standing_regions(labels > 0, share, ranges, rays, pose, CAM, fm.Road(), g,
                                ratio=1.05).any()


STEP_OUT = synth.parse_scenario({
    "name": "step_out", "frames": 16, "ego": {"speed_kmh": 22, "start": [0, -1.75]},
    "camera": {"position": [2.0, 0.0, 0.9], "pitch_deg": 15},
    "static": [{"id": 24, "kind": "parked_car", "center": [6.5, -4.6]},
               {"id": 25, "kind": "parked_car", "center": [13.5, -4.6], "texture": "coffee"},
               {"id": 26, "kind": "parked_car", "center": [18.5, -4.6]}],
    "objects": [{"id": 1, "kind": "pedestrian", "category": "crossing", "start": [10.5, -6.0],
                 "heading_deg": 90, "speed_kmh": 4}]})


def _exact_flow_run(tmp_path, camera, scenario, params, frames):
    from fisheyemotion.eval.evaluate import evaluate_sequence

    seq = synth.write_sequence(tmp_path / scenario.name, camera, scenario, frames=frames,
                               flow=False, progress=False, supersample=1)
    return evaluate_sequence(seq, params, exact_flow=True, ablation=False)


def test_parked_cars_on_their_arc_are_explained_with_the_exact_flow(tmp_path):
    """With perfect correspondences a parked car that stands on the road and is seen on its
    epipolar arc is static, whatever the scene model's 8-px median mixed it with. Without the
    road-spill trim, which drops some of the same false regions by what the road leaves of
    them."""
    world = synth.load_scenario("static_world")
    cam = tumvi_kb(320, 240, 100.0)
    params = fm.Params(road_spill=0.0)
    veto_only = _exact_flow_run(tmp_path / "a", cam, world, params.replace(contact_arc=0.0), 12)
    with_arc = _exact_flow_run(tmp_path / "b", cam, world, params, 12)
    assert veto_only.frames.fp_frame.sum() >= 3
    assert with_arc.frames.fp_frame.sum() == 0


def test_a_pedestrian_stepping_out_between_parked_cars_keeps_the_scene_models_veto(tmp_path,
                                                                                  monkeypatch):
    """The arc test removes the parked cars' false regions and keeps the pedestrian, which
    stands on the road beside them but moves off its arc; without the scene model's veto the
    pedestrian is lost."""
    import importlib

    cam = tumvi_kb(640, 480, 200.0)
    # What the constraints flag, not grown (on the image or by the flow) nor trimmed: a false
    # region beside the pedestrian grown onto it would count as finding it. Each pair's own
    # evidence, unconfirmed and without the three views.
    flagged = fm.Params(extent_reach=0.0, grow=0, road_spill=0.0, confirm_reach=0,
                        range_consistency=0.0)
    veto_only = _exact_flow_run(tmp_path / "a", cam, STEP_OUT, flagged.replace(contact_arc=0.0),
                                16)
    with_arc = _exact_flow_run(tmp_path / "b", cam, STEP_OUT, flagged, 16)
    monkeypatch.setattr(importlib.import_module("fisheyemotion.detector"), "SCENE_AGREEMENT",
                        np.inf)  # no range ever disagrees: no veto
    no_veto = _exact_flow_run(tmp_path / "c", cam, STEP_OUT, flagged.replace(contact_arc=0.0), 16)
    found = {name: int(r.objects.detected.sum())
             for name, r in (("veto", veto_only), ("arc", with_arc), ("none", no_veto))}
    assert veto_only.frames.fp_frame.sum() > 0 and with_arc.frames.fp_frame.sum() == 0
    assert found["arc"] >= found["veto"] >= 3 > found["none"]


# ---- significance ------------------------------------------------------------------------

def test_pixel_angle_is_one_over_the_focal_length_at_the_centre():
    a = pixel_angle(CAM, np.array([[159.5, 119.5]]))
    assert a[0] == pytest.approx(1 / 100.0, rel=1e-3)


def test_cell_sigma_grows_with_discordant_flow():
    flow = np.zeros((20, 20, 2), np.float32)
    flow[:10] = 100.0  # large but uniform: no extra error
    flow[10:, :, 0] = np.tile([0.0, 4.0], (10, 10))  # discordant pixels
    angle = np.full((4, 4), 0.01)
    s = cell_sigma(flow, 5, angle, floor=0.25)
    np.testing.assert_allclose(s[:2], 0.25 * 0.01, rtol=1e-6)
    assert (s[2:] > 5 * 0.25 * 0.01).all()


@given(st.integers(0, 2**32 - 1))
@settings(max_examples=25, deadline=None)
def test_pose_sigma_is_the_arc_deviation_a_turned_direction_of_travel_gives(seed):
    """Static points seen with the second position off by ``delta * b`` across the direction of
    travel: each deviates from its epipolar arc by pose_sigma times the share of the offset
    along its epipolar plane's normal (first order), never more."""
    rng = np.random.default_rng(seed)
    b, delta = 0.003, 1e-4
    r0, r1 = random_rotation(rng), random_rotation(rng)
    c0 = rng.normal(size=3)
    travel = rng.normal(size=3)
    travel /= np.linalg.norm(travel)
    points = rng.normal(size=(200, 3))
    points /= np.linalg.norm(points, axis=1, keepdims=True)
    points = points[np.abs(points @ travel) < np.cos(np.radians(15))]  # off the epipoles
    world = c0 + points * rng.uniform(0.3, 3.0, size=(len(points), 1))
    rays0 = (world - c0) @ r0
    rays1 = (world - c0 - b * travel) @ r1
    rays0 /= np.linalg.norm(rays0, axis=1, keepdims=True)
    rays1 /= np.linalg.norm(rays1, axis=1, keepdims=True)
    across = np.cross(travel, rng.normal(size=3))
    across /= np.linalg.norm(across)
    pose0, pose1 = np.eye(4), np.eye(4)
    pose0[:3, :3], pose0[:3, 3] = r0, c0
    pose1[:3, :3], pose1[:3, 3] = r1, c0 + b * (travel + delta * across)  # the given, off
    xi = fm.constraints(rays0, rays1, pose0, pose1).epipolar
    parallax = triangulate_range(rays0, rays1, pose0, pose1, far=1e6, with_parallax=True)[2]
    sigma = pose_sigma(rays0, parallax, pose0, pose1, delta * b)
    normals = np.cross(travel, points)
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    np.testing.assert_allclose(xi, sigma * np.abs(normals @ across), rtol=0.02, atol=1e-12)
    assert (xi <= 1.02 * sigma).all()
    assert (pose_sigma(rays0, parallax, pose0, pose1, 0.0) == 0).all()
    assert (pose_sigma(rays0, parallax, pose0, pose1, 1.0) >= pose_sigma(
        rays0, parallax, pose0, pose1, 0.5 * b)).all()  # at most a right angle's turn


def test_the_poses_error_keeps_a_millimetre_baseline_from_flagging_near_static_cells():
    """A head-mounted camera's 3 mm between frames, a table 0.5 m away, the direction of travel
    given 20 deg off (0.8 mm from the images' view): with the flow's error alone the table's
    arc deviations are many sigmas, with the poses' 2 mm they are not."""
    rng = np.random.default_rng(3)
    travel = np.array([1.0, 0.0, 0.0])
    given = np.array([np.cos(np.radians(20)), np.sin(np.radians(20)), 0.0])
    rays0 = rng.normal(size=(500, 3)) + [0.0, 0.0, 2.0]
    rays0 /= np.linalg.norm(rays0, axis=1, keepdims=True)
    world = 0.5 * rays0
    rays1 = world - 0.003 * travel
    rays1 /= np.linalg.norm(rays1, axis=1, keepdims=True)
    pose0, pose1 = np.eye(4), np.eye(4)
    pose1[:3, 3] = 0.003 * given
    xi = fm.constraints(rays0, rays1, pose0, pose1).epipolar
    flow_only = 0.25 * 0.003  # a quarter pixel at 3 mrad per pixel
    parallax = triangulate_range(rays0, rays1, pose0, pose1, far=1e6, with_parallax=True)[2]
    sigma = np.hypot(flow_only, pose_sigma(rays0, parallax, pose0, pose1, 0.002))
    assert np.percentile(xi / flow_only, 90) > 2
    assert (xi / sigma < 2).all()


@pytest.mark.parametrize("k", [1.0, 2.0, 3.5])
def test_epipolar_deviation_reaches_the_threshold_at_its_significance(k):
    from types import SimpleNamespace

    det = fm.MotionDetector(CAM, params=fm.Params(epipolar_significance=k, significance=0.0))
    sigma = np.array([0.001, 0.002, 0.004, np.nan])
    epipolar = k * sigma * np.array([0.5, 1.0, 2.0, 1.0])
    zero = np.zeros(4)
    res = SimpleNamespace(epipolar=epipolar, height=zero, depth=zero)
    raised = det._with_significance(res, sigma, zero)
    t = det.params.threshold
    np.testing.assert_allclose(raised, [0.5 * t, t, 2 * t, 0.0])  # unknown sigma: unchanged
    off = fm.MotionDetector(CAM, params=fm.Params(epipolar_significance=0.0, significance=0.0))
    np.testing.assert_array_equal(off._with_significance(res, sigma, zero), zero)


def test_epipolar_significance_finds_a_slow_distant_pedestrian():
    """A pedestrian 12 m ahead walking at 1.5 km/h deviates from its epipolar arc by less than
    the raw threshold, but by several of its (exact) flow's sigmas."""
    scenario = synth.parse_scenario({
        "name": "walker", "frames": 4, "ego": {"speed_kmh": 25},
        "camera": {"position": [2, 0, 1.0], "pitch_deg": 15},
        "objects": [{"id": 1, "kind": "pedestrian", "category": "crossing", "start": [12, -2],
                     "heading_deg": 90, "speed_kmh": 1.5}]})
    cam = tumvi_kb(640, 480, 200.0)
    renderer = synth.Renderer(cam, scenario)
    f0, f3 = renderer.render(0), renderer.render(3)
    flow = np.nan_to_num(renderer.flow(3, gap=3))
    obj = f3.moving > 0
    masks = {k: fm.MotionDetector(cam, params=fm.Params(epipolar_significance=k),
                                  roi=renderer.roi()).detect_flow(flow, f0.pose, f3.pose).mask > 0
             for k in (0.0, 2.0)}
    assert not masks[0.0].any()                  # raw angles: not found
    assert masks[2.0][obj].mean() > 0.3          # measured 0.55
    assert not (masks[2.0] & ~obj).any()


def test_regions_grow_over_their_objects_residual_and_stop_at_its_boundary():
    from fisheyemotion.grow import grow_regions

    residual = np.zeros((30, 40, 2))
    residual[10:20, 10:25] = (6.0, 1.0)       # the object's own motion
    residual[10:20, 25:30] = (-4.0, 0.0)      # another object beside it
    moving = np.zeros((30, 40), bool)
    moving[12:14, 12:15] = True               # only a few cells were flagged
    valid = np.ones((30, 40), bool)
    grown = grow_regions(moving, residual, valid, steps=20)
    assert grown[10:20, 10:25].all()          # the whole object ...
    assert not grown[:, 25:].any() and not grown[:10].any() and not grown[20:].any()  # ... only
    few = grow_regions(moving, residual, valid, steps=1)
    assert few.sum() == (moving | ndimage_dilate(moving)).sum()
    assert not grow_regions(moving, residual, moving, steps=5)[~moving].any()  # only valid cells


def ndimage_dilate(mask):
    from scipy import ndimage

    return ndimage.binary_dilation(mask, structure=np.ones((3, 3), bool))


def _reference_growth(moving, residual, valid, steps, tolerance=2.0, relative=0.5):
    """The growth of fisheyemotion.grow's module doc written with scikit-image's labelling and
    scipy's grey dilation over the whole grid (the implementation before 0.8.19)."""
    from scipy import ndimage
    from skimage.measure import label

    labels = label(moving, connectivity=2)
    n = int(labels.max())
    if n == 0 or steps <= 0:
        return moving.copy()
    res = np.nan_to_num(residual, nan=np.inf)
    flat = labels.ravel()
    count = np.maximum(np.bincount(flat, minlength=n + 1), 1)
    finite = np.isfinite(res).all(axis=-1).ravel() & (flat > 0)
    mean = np.stack([np.bincount(flat[finite], weights=res.reshape(-1, 2)[finite, i],
                                 minlength=n + 1) / count for i in range(2)], axis=-1)
    norm = np.linalg.norm(mean, axis=-1)
    grown = labels.copy()
    open_ = valid & np.isfinite(res).all(axis=-1)
    for _ in range(steps):
        near = ndimage.grey_dilation(grown, size=(3, 3), mode="constant", cval=0)
        cand = (grown == 0) & (near > 0) & open_
        lab = near[cand]
        r = res[cand]
        ok = (np.linalg.norm(r - mean[lab], axis=-1) <= tolerance + relative * norm[lab]) & (
            np.linalg.norm(r, axis=-1) >= 0.5 * norm[lab])
        rows, cols = np.nonzero(cand)
        grown[rows[ok], cols[ok]] = lab[ok]
    return grown > 0


def test_a_stream_grows_its_regions_over_the_pedestrians_own_motion():
    """The default growth (``grow=4``) covers more of the crossing pedestrians in a stream; the
    static background it reaches around them (the cells beside an object that move with it
    within the tolerance) stays below three times what it adds of them. A single pair, whose
    static prediction knows only the road and the far field, is not grown."""
    cam = tumvi_kb(640, 480, 200.0)
    renderer = synth.Renderer(cam, synth.load_scenario("crossing"))
    frames = [renderer.render(k) for k in range(14)]
    covered, static = {}, {}
    for steps in (0, 4):
        det = fm.MotionDetector(cam, params=fm.Params(grow=steps), roi=renderer.roi())
        results = [(det.apply(f.image, f.pose), f.moving > 0) for f in frames]
        covered[steps] = sum(((r.mask > 0) & obj).sum() for r, obj in results if r)
        static[steps] = sum(((r.mask > 0) & ~obj).sum() for r, obj in results if r)
    assert fm.Params().grow == 4
    assert covered[4] > 1.1 * covered[0]                       # measured 1.16
    assert static[4] - static[0] < 3 * (covered[4] - covered[0])  # measured 2.6 ×
    f0, f3 = frames[0], frames[3]
    pair = {steps: fm.detect(f0.image, f3.image, f0.pose, f3.pose, camera=cam,
                             params=fm.Params(grow=steps), roi=renderer.roi()).mask
            for steps in (0, 4)}
    np.testing.assert_array_equal(pair[0], pair[4])


@given(st.integers(1, 40), st.integers(1, 40), st.sampled_from([0.0, 0.01, 0.05, 0.3, 1.0]),
       st.integers(0, 6), st.floats(0.5, 4.0), st.integers(0, 2**31 - 1))
@settings(max_examples=300, deadline=None)
def test_growth_equals_the_scikit_image_and_scipy_reference(rows, cols, share, steps, tolerance,
                                                            seed):
    """OpenCV's labelling renumbered in raster order, its dilation and the bounding box give
    the reference's cells exactly, wherever regions compete for a cell (the later one wins)."""
    from fisheyemotion.grow import grow_regions

    rng = np.random.default_rng(seed)
    moving = rng.random((rows, cols)) < share
    residual = rng.normal(0, 3, (rows, cols, 2)) + rng.normal(0, 5, 2)
    residual[rng.random((rows, cols)) < 0.1] = np.nan
    valid = rng.random((rows, cols)) < 0.9
    got = grow_regions(moving, residual, valid, steps=steps, tolerance=tolerance)
    np.testing.assert_array_equal(
        got, _reference_growth(moving, residual, valid, steps, tolerance=tolerance))


@given(st.integers(1, 6), st.integers(1, 24), st.floats(0.0, 0.9), st.integers(0, 2**31 - 1))
@settings(max_examples=60)
def test_row_percentile_matches_numpy(rows, cols, missing, seed):
    import warnings

    from fisheyemotion.ground_contact import row_nanpercentile

    rng = np.random.default_rng(seed)
    a = rng.normal(size=(rows, cols))
    a[rng.random(a.shape) < missing] = np.nan
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN rows
        expected = np.nanpercentile(a, 75, axis=1)
    np.testing.assert_allclose(row_nanpercentile(a, 75.0), expected, rtol=1e-12, atol=1e-12)


# ---- extension ---------------------------------------------------------------------------

def test_extension_covers_more_of_a_detected_object_and_keeps_what_was_found():
    scenario = _crossing_car(frames=4, ego_kmh=30, start=[10, -4], kmh=8)
    cam = tumvi_kb(640, 480, 200.0)
    renderer = synth.Renderer(cam, scenario)
    f0, f3 = renderer.render(0), renderer.render(3)
    flow = np.nan_to_num(renderer.flow(3, gap=3))
    masks = {t: fm.MotionDetector(cam, params=fm.Params(extend_threshold=t, region_gap=0,
                                                        carry_share=0.0, receding=0.0),
                                  roi=renderer.roi())
             .detect_flow(flow, f0.pose, f3.pose).mask > 0 for t in (0.0, 0.002)}
    obj = f3.moving > 0
    plain, extended = (masks[t][obj].mean() for t in (0.0, 0.002))
    assert masks[0.002][masks[0.0]].all()        # nothing found is lost
    assert extended > plain + 0.08               # measured 0.61 -> 0.75
    assert (masks[0.002] & ~obj).sum() <= (masks[0.0] & ~obj).sum() + 0.02 * obj.sum()


# ---- regions closed over small gaps -------------------------------------------------------

def test_regions_closed_over_their_gaps_cover_more_of_the_pedestrian_than_they_add_around_it():
    """``Params.region_gap``: on a crossing pair whose pedestrian is found in pieces, the
    closing covers more of the pedestrian (measured 46 -> 59 %) than it adds of the static
    scene, joins pieces instead of adding regions, and the cell mask stays what the
    constraints flagged (the pose step leaves that out). Without the road-spill trim, which
    takes static pixels from either mask."""
    cam = tumvi_kb(640, 480, 200.0)
    renderer = synth.Renderer(cam, synth.load_scenario("crossing"))
    f0, f3 = renderer.render(12), renderer.render(15)
    out = {g: fm.MotionDetector(cam, params=fm.Params(region_gap=g, road_spill=0.0),
                                roi=renderer.roi())
           .detect(f0.image, f3.image, f0.pose, f3.pose) for g in (0, 1)}
    obj = f3.moving > 0
    plain, closed = (out[g].mask > 0 for g in (0, 1))
    assert closed[obj].mean() > plain[obj].mean() + 0.08
    added_object = (closed & obj).sum() - (plain & obj).sum()
    added_static = (closed & ~obj).sum() - (plain & ~obj).sum()
    assert 0 <= added_static < added_object
    assert len(out[1].regions) <= len(out[0].regions)
    np.testing.assert_array_equal(out[0].likelihood, out[1].likelihood)
    cells = out[1].cell_mask > 0
    assert cells.any() and closed[cells].all()
    assert (out[1].likelihood[cells] >= np.float32(fm.Params().threshold)).all()
    assert (closed & ~cells & (out[1].likelihood < fm.Params().threshold)).any()


def test_two_seeds_for_anti_parallel_led_regions_keep_a_crossing_pedestrian():
    """``Params.antiparallel_seeds``: the crossing pedestrian, led by the epipolar term, is
    found as with one seed; the anti-parallel share reaches the segmentation (a stricter count
    for every region drops it)."""
    cam = tumvi_kb(640, 480, 200.0)
    renderer = synth.Renderer(cam, synth.load_scenario("crossing"))
    f0, f3 = renderer.render(12), renderer.render(15)

    def mask(**kw):
        return fm.MotionDetector(cam, params=fm.Params(**kw), roi=renderer.roi()).detect(
            f0.image, f3.image, f0.pose, f3.pose).mask > 0

    one, two = mask(), mask(antiparallel_seeds=2)
    obj = f3.moving > 0
    assert one[obj].mean() > 0.3
    np.testing.assert_array_equal(two, one)
    # The same count for every region (the share's threshold at 0) drops this pedestrian's:
    from fisheyemotion import segment
    original = segment.LED
    try:
        segment.LED = 0.0
        strict = mask(antiparallel_seeds=10**6)
    finally:
        segment.LED = original
    assert not strict[obj].any()


# ---- the photometric check of the static hypothesis ---------------------------------------

def test_cell_residual_is_zero_for_the_true_shift_and_not_for_another():
    from fisheyemotion.photometric import cell_residual

    rng = np.random.default_rng(3)
    prev = cv2.GaussianBlur(rng.integers(0, 255, (60, 80), dtype=np.uint8), (5, 5), 1.0)
    curr = np.roll(prev, (2, 3), axis=(0, 1))            # content moved 3 right, 2 down
    true = np.zeros((60, 80, 2), np.float32)
    true[..., 0], true[..., 1] = 3, 2
    inner = (slice(1, -1), slice(1, -1))                  # cells clear of the wrapped border
    assert cell_residual(prev, curr, true, 5)[inner].max() == 0
    assert cell_residual(prev, curr, np.zeros_like(true), 5)[inner].min() > 2


@pytest.mark.parametrize("seed", range(3))
def test_cell_residual_of_chosen_cells_is_the_whole_images(seed):
    from fisheyemotion.photometric import cell_residual

    rng = np.random.default_rng(seed)
    prev = cv2.GaussianBlur(rng.integers(0, 255, (120, 160), dtype=np.uint8), (5, 5), 1.0)
    curr = np.roll(prev, 3, axis=1)
    flow = (rng.normal(size=(120, 160, 2)) * 4).astype(np.float32)
    flow[:5] += 50.0                                      # some samples far outside: replicated
    whole = cell_residual(prev, curr, flow, 5)
    cells = rng.random(whole.shape) < 0.3
    chosen = cell_residual(prev, curr, flow, 5, cells)
    np.testing.assert_allclose(chosen[cells], whole[cells], atol=1e-4)
    assert np.isnan(chosen[~cells]).all()
    assert np.isnan(cell_residual(prev, curr, flow, 5, np.zeros_like(cells))).all()


def test_cell_residual_matches_an_opencv_remap_of_the_whole_image():
    """Golden values from an independent implementation: cv2.remap (1/32-pixel weights,
    rounded to grey levels) then OpenCV's area resize, within half a grey level."""
    from fisheyemotion.flow import grid_average, warp_by
    from fisheyemotion.photometric import cell_residual

    rng = np.random.default_rng(7)
    prev = cv2.GaussianBlur(rng.integers(0, 255, (120, 160), dtype=np.uint8), (5, 5), 1.0)
    curr = np.roll(prev, (1, 3), axis=(0, 1))
    flow = (rng.normal(size=(120, 160, 2)) * 4).astype(np.float32)
    flow[:5] += 50.0                                      # far outside: the edge replicated
    opencv = grid_average(cv2.absdiff(prev, warp_by(curr, flow)).astype(np.float32), 5)
    np.testing.assert_allclose(cell_residual(prev, curr, flow, 5), opencv, atol=0.5)
    flow[7, 12, 0] = np.nan                               # a position that is not a number
    residual = cell_residual(prev, curr, flow, 5)
    assert np.isnan(residual[1, 2]) and np.isfinite(np.delete(residual.ravel(), 1 * 32 + 2)).all()


_FISHEYES = [(i, n, c) for i, (n, c) in zip(CAMERA_IDS, ALL_CAMERAS, strict=True) if n != "pinhole"]


@pytest.mark.parametrize("name,cam", [(n, c) for _, n, c in _FISHEYES],
                         ids=[i for i, _, _ in _FISHEYES])
def test_epipolar_directions_are_where_a_static_point_moves_with_its_range(name, cam):
    from fisheyemotion.photometric import epipolar_directions

    rng = np.random.default_rng(11)
    pose0 = camera_pose(rng, height=1.2, pitch_deg=5)
    pose1 = moved(pose0, [0.6, 0.1, 0.02], yaw_deg=2.0)
    pixels = np.stack([rng.uniform(0, cam.width - 1, 400), rng.uniform(0, cam.height - 1, 400)], -1)
    rays, ok = cam.unproject(pixels)
    points = pose0[:3, 3] + rng.uniform(2, 30, (400, 1)) * (rays @ pose0[:3, :3].T)
    seen, ok1 = cam.project((points - pose1[:3, 3]) @ pose1[:3, :3])
    # The same point a little nearer and a little farther along its ray from the first camera:
    # the image's tangent to the curve (central difference).
    nearer, ok2 = cam.project((pose0[:3, 3] + (1 - 1e-5) * (points - pose0[:3, 3]) - pose1[:3, 3])
                              @ pose1[:3, :3])
    farther, ok3 = cam.project((pose0[:3, 3] + (1 + 1e-5) * (points - pose0[:3, 3])
                                - pose1[:3, 3]) @ pose1[:3, :3])
    use = ok & ok1 & ok2 & ok3
    d = epipolar_directions(cam, seen[use], pose0, pose1)
    step = nearer[use] - farther[use]
    big = np.linalg.norm(step, axis=-1) > 1e-6           # the point moved in the image
    step = step[big] / np.linalg.norm(step[big], axis=-1, keepdims=True)
    d = d[big]
    fine = np.isfinite(d).all(axis=-1)
    assert fine.mean() > 0.95
    assert np.abs(step[fine, 0] * d[fine, 1] - step[fine, 1] * d[fine, 0]).max() < 1e-4
    np.testing.assert_allclose(np.linalg.norm(d[fine], axis=-1), 1.0, atol=1e-9)
    assert np.isnan(epipolar_directions(cam, seen[use][:3], pose0, pose0)).all()  # no motion


def test_the_tolerance_explains_a_prediction_off_along_its_epipolar_curve_only():
    from fisheyemotion.photometric import static_explained

    rng = np.random.default_rng(5)
    prev = cv2.GaussianBlur(rng.integers(0, 255, (60, 80), dtype=np.uint8), (3, 3), 0.7)
    curr = np.roll(prev, (2, 3), axis=(0, 1))
    flow = np.zeros((60, 80, 2), np.float32)
    flow[..., 0], flow[..., 1] = 3, 2                     # the measured flow: right
    cells = np.zeros((12, 16), bool)
    cells[2:-2, 2:-2] = True
    d = np.array([0.6, 0.8])                              # the curve's direction everywhere
    off = {"along": 0.25 * d, "across": 0.25 * np.array([-0.8, 0.6])}
    explained = {}
    for key, error in off.items():
        static = flow + error.astype(np.float32)          # the static scene, 0.25 px off
        for tolerance in (0.0, 0.25):
            explained[key, tolerance] = static_explained(
                prev, curr, flow, static, 5, 1.0, cells=cells, tolerance=tolerance,
                directions=lambda left: np.tile(d, (left.sum(), 1)))
    assert not explained["along", 0.0][cells].any()      # a sharp texture: 0.25 px is too much
    assert explained["along", 0.25][cells].all()          # ... unless it is along the curve
    assert not explained["across", 0.25][cells].any()     # across it, the tolerance does not help
    assert not explained["along", 0.25][~cells].any()     # untested cells stay unexplained


def test_the_reach_widens_the_tolerance_cell_by_cell_along_the_curve_only():
    from fisheyemotion.photometric import MIN_REACH, TOLERANCE_STEPS, static_explained

    rng = np.random.default_rng(6)
    prev = cv2.GaussianBlur(rng.integers(0, 255, (60, 80), dtype=np.uint8), (3, 3), 0.7)
    curr = np.roll(prev, (2, 3), axis=(0, 1))
    flow = np.zeros((60, 80, 2), np.float32)
    flow[..., 0], flow[..., 1] = 3, 2
    cells = np.zeros((12, 16), bool)
    cells[2:-2, 2:-2] = True
    near = np.zeros_like(cells)
    near[:, :8] = True                                    # structure close to the camera
    d = np.array([0.6, 0.8])
    seen = {}

    def reach(left):                                      # pixels, row-major over `left`
        return np.where(near[left], 1.3, 0.5)

    off = 0.75 * 1.3                                      # on one of the moves: 3/4 of the reach
    for key, error in {"along": off * d, "across": off * np.array([-0.8, 0.6])}.items():
        static = flow + error.astype(np.float32)          # the static scene ~1 px off
        for with_reach in (False, True):
            seen[key, with_reach] = static_explained(
                prev, curr, flow, static, 5, 1.0, cells=cells, tolerance=0.25,
                directions=lambda left: np.tile(d, (left.sum(), 1)),
                reach=reach if with_reach else None)
    assert not seen["along", False][cells].any()          # the fixed quarter pixel: too little
    assert seen["along", True][cells & near].all()        # 1.3 px of reach: found
    assert not seen["along", True][cells & ~near].any()   # 0.5 px of reach: still too little
    assert not seen["across", True][cells].any()          # across the curve no reach helps
    assert TOLERANCE_STEPS == 4                           # the moves were quarters of 1.3 px
    static = flow + (0.6 * d).astype(np.float32)          # 0.6 px off along the curve
    for wide, found in ((0.6, False), (MIN_REACH, True)):  # a small reach is not used
        assert static_explained(prev, curr, flow, static, 5, 1.0, cells=cells, tolerance=0.25,
                                directions=lambda left: np.tile(d, (left.sum(), 1)),
                                reach=lambda left, w=wide: np.full(left.sum(), w)
                                )[cells].all() == found


def _depth_edge(near_cols: int = 34):
    """Two textured surfaces side by side: the left one (columns below ``near_cols``, nearer)
    moves 4 px right, the right one 1 px, and the nearer one hides what the farther one moves
    under. Cell column 6 (pixels 30-34) holds both: four columns of the near surface, one of
    the far."""
    rng = np.random.default_rng(12)
    prev = cv2.GaussianBlur(rng.integers(0, 255, (60, 80), dtype=np.uint8), (3, 3), 0.7)
    curr = np.where(np.arange(80) < near_cols + 4, np.roll(prev, 4, axis=1),
                    np.roll(prev, 1, axis=1)).astype(np.uint8)
    motion = np.zeros((12, 16, 2))
    motion[:, :6, 0], motion[:, 6, 0], motion[:, 7:, 0] = 4.0, 2.5, 1.0  # 2.5: interpolated
    return prev, curr, motion


@pytest.mark.parametrize("ratio,explained", [(0.1, True), (0.5, True), (1.0, False)])
def test_a_cell_on_a_depth_edge_is_explained_by_its_nearer_neighbours_motion(ratio, explained):
    """Its own static prediction is interpolated across the edge and the measured flow is
    smoothed across it (2.5 px); moved as a whole with the near neighbour (parallax 4 against
    2.5: 60 % more) four fifths of it match."""
    from fisheyemotion.photometric import cell_residual, edge_explained

    prev, curr, motion = _depth_edge()
    parallax = np.linalg.norm(motion, axis=-1)
    smoothed = np.zeros((60, 80, 2), np.float32)
    smoothed[..., 0] = 2.5
    measured = cell_residual(prev, curr, smoothed, 5)
    cells = np.zeros((12, 16), bool)
    cells[2:-2, 6] = True
    out = edge_explained(prev, curr, 5, cells, measured, motion, parallax, ratio)
    assert out[cells].all() == explained and not out[~cells].any()
    if explained:  # the farther side is never tried: the same cell with the sides swapped
        swapped = parallax.copy()
        swapped[:, :6], swapped[:, 7:] = 1.0, 4.0
        assert not edge_explained(prev, curr, 5, cells, measured, motion, swapped, ratio)[cells].any()


def test_a_moving_cell_beside_a_nearer_surface_is_not_explained_by_it():
    """The same edge, but cell column 6 holds something that moved 3 px left: neither
    neighbour's motion explains it as well as the measured flow, which follows it."""
    from fisheyemotion.photometric import cell_residual, edge_explained

    prev, curr, motion = _depth_edge()
    curr = curr.copy()
    curr[:, 27:32] = prev[:, 30:35]                       # the cell's content, 3 px left
    follows = np.zeros((60, 80, 2), np.float32)
    follows[:, 30:35, 0] = -3.0
    measured = cell_residual(prev, curr, follows, 5)
    cells = np.zeros((12, 16), bool)
    cells[2:-2, 6] = True
    parallax = np.linalg.norm(motion, axis=-1)
    assert not edge_explained(prev, curr, 5, cells, measured, motion, parallax, 0.1).any()


@pytest.mark.parametrize("near,lands,hidden", [(True, 1.0, True), (True, 4.0, False),
                                               (False, 1.0, False)])
def test_a_cell_is_hidden_where_a_nearer_neighbours_static_point_lands_on_its_own(near, lands,
                                                                                hidden):
    """The cell left of a cell moves 5 px right, onto it; the cell itself ``lands`` px right
    (its prediction lands ``lands`` px from the neighbour's: hidden within half a 5-px cell),
    and the neighbour is the nearer one or the farther."""
    from fisheyemotion.photometric import COVERS, hidden_cells

    assert COVERS * 5 > 1.0 and COVERS * 5 < 4.0
    motion = np.zeros((6, 8, 2))
    motion[3, 2, 0], motion[3, 3, 0] = 5.0, lands
    parallax = np.full((6, 8), 2.0)
    parallax[3, 2] = 4.0 if near else 1.0
    cells = np.zeros((6, 8), bool)
    cells[3, 3] = True
    out = hidden_cells(5, cells, motion, parallax, 0.1)
    assert out[3, 3] == hidden and not out[~cells].any()
    motion[3, 3] = np.nan                                  # no prediction: not hidden
    assert not hidden_cells(5, cells, motion, parallax, 0.1).any()


def test_the_parallax_is_the_distance_from_the_point_at_infinity():
    cam = tumvi_kb(640, 480, 200.0)
    det = fm.MotionDetector(cam, fm.Road(), params=fm.Params())
    rng = np.random.default_rng(8)
    pose0 = camera_pose(rng, height=1.2, pitch_deg=5)
    pose1 = moved(pose0, [0.0, 0.0, 0.0], yaw_deg=3.0)    # a pure rotation: no parallax
    at = det._at_infinity(pose0, pose1)
    r, c = np.nonzero(np.isfinite(at).all(axis=-1))
    rays = det._rays0[r, c]
    points = pose0[:3, 3] + 7.0 * (rays @ pose0[:3, :3].T)
    seen, ok = cam.project((points - pose1[:3, 3]) @ pose1[:3, :3])
    np.testing.assert_allclose(seen[ok], at[r, c][ok], atol=1e-6)
    pose2 = moved(pose0, [0.5, 0.0, 0.05], yaw_deg=3.0)   # and with a translation: ~1 / range
    shift = {}
    for rng_m in (5.0, 10.0, 1e6):
        points = pose0[:3, 3] + rng_m * (rays @ pose0[:3, :3].T)
        seen, ok = cam.project((points - pose2[:3, 3]) @ pose2[:3, :3])
        shift[rng_m] = np.linalg.norm(seen - det._at_infinity(pose0, pose2)[r, c], axis=-1)
    far = np.isfinite(shift[5.0]) & np.isfinite(shift[10.0]) & (shift[10.0] > 0.5)
    assert np.median(shift[5.0][far] / shift[10.0][far]) == pytest.approx(2.0, rel=0.1)
    assert np.nanmax(shift[1e6]) < 0.01


def _crossing_car_pair():
    """A car crossing the road ahead of a camera at 30 km/h, frames 0 and 3: the camera, its
    renderer, both frames, their grey images and the exact flow (0 where a point leaves the
    camera's domain)."""
    cam = tumvi_kb(640, 480, 200.0)
    renderer = synth.Renderer(cam, _crossing_car(frames=4, ego_kmh=30, start=[10, -4], kmh=20))
    f0, f3 = renderer.render(0), renderer.render(3)
    g0, g3 = (cv2.cvtColor(f.image, cv2.COLOR_BGR2GRAY) for f in (f0, f3))
    return cam, renderer, f0, f3, g0, g3, np.nan_to_num(renderer.flow(3, gap=3)).astype(np.float32)


def _masks_without_and_with(setting, flow, cam, renderer, f0, f3, g0, g3):
    """``{False: mask, True: mask}`` (bool, the current frame's) of one pair's ``flow`` with a
    boolean ``setting`` of the defaults off and on (no growth to the extent, and no trim of
    the road spill, which removes these false regions on the road too: tested below)."""
    masks = {}
    for on in (False, True):
        params = fm.Params(extent_reach=0, road_spill=0.0).replace(**{setting: on})
        det = fm.MotionDetector(cam, params=params, roi=renderer.roi())
        masks[on] = det.detect_flow(flow, f0.pose, f3.pose, prev=g0, curr=g3).mask > 0
    return masks


def test_photometric_check_removes_a_flow_error_on_static_structure_and_keeps_the_car():
    cam, renderer, f0, f3, g0, g3, true = _crossing_car_pair()
    # A flow error on the road ahead (a method that locked onto the wrong texture): 5 px down.
    bad = np.zeros(true.shape[:2], bool)
    bad[210:240, 200:250] = True
    assert not (f0.moving[bad] > 0).any()
    flow = true.copy()
    flow[bad, 1] += 5.0
    # Where that road is in the current frame, on which the masks are.
    v, u = np.nonzero(bad)
    now = np.zeros_like(bad)
    now[np.round(v + true[v, u, 1]).astype(int), np.round(u + true[v, u, 0]).astype(int)] = True
    masks = _masks_without_and_with("photometric_check", flow, cam, renderer, f0, f3, g0, g3)
    car = f3.moving > 0
    assert masks[False][now].mean() > 0.4          # measured 0.60: a false alarm without it
    assert masks[True][now].mean() < 0.05          # 0.0: the images say the road is static
    # The car's region has cells the static scene cannot explain: it stays, whole.
    assert masks[False][car].mean() > 0.5
    np.testing.assert_array_equal(masks[True] & car, masks[False] & car)


@pytest.mark.parametrize(("at", "measured", "testable"), [
    ((100.0, 100.0), 50.0, True),        # lands in view: the images test it, whatever it matched
    ((100.0, 100.0), np.nan, True),
    ((700.0, 100.0), 50.0, False),       # left the view: the border is no static prediction
    ((100.0, -3.0), 50.0, False),
    ((3.0, 100.0), 50.0, False),         # inside the image but not a whole cell from its edge
    ((np.nan, np.nan), 50.0, False),     # left the camera's domain
    ((700.0, 100.0), 4.0, True),         # left the view, but the measured flow matches: seen
    ((np.nan, np.nan), 9.9, True),       # where a static point would have left
    ((700.0, 100.0), 10.0, False),       # (below the margin, strictly)
    ((700.0, 100.0), np.nan, False),
])
def test_only_cells_whose_static_prediction_the_images_show_are_testable(at, measured,
                                                                         testable):
    from fisheyemotion.photometric import testable_cells

    view = np.zeros((240, 320), bool)
    view[5:-5, 5:-5] = True              # the usable pixels shrunk by a 5-px cell
    out = testable_cells(np.array([[at]]), view, np.array([[measured]]), 10.0)
    assert out.shape == (1, 1) and out[0, 0] == testable


def test_the_road_spill_trim_removes_a_flow_error_on_the_road_and_keeps_the_car():
    """The photometric check's case, nearer the camera and with that check off: the road-spill
    trim (:mod:`fisheyemotion.spill`) finds the false region explained by the road, pixel by
    pixel (measured: 62 -> 4 % of it flagged), and leaves the crossing car (95 -> 93 %: the
    road its mask took)."""
    cam, renderer, f0, f3, g0, g3, true = _crossing_car_pair()
    bad = np.zeros(true.shape[:2], bool)
    bad[280:300, 200:250] = True
    flow = true.copy()
    flow[bad, 1] += 5.0
    v, u = np.nonzero(bad)
    now = np.zeros_like(bad)
    now[np.round(v + true[v, u, 1]).astype(int), np.round(u + true[v, u, 0]).astype(int)] = True
    masks = {}
    for spill in (0.0, 15.0):
        params = fm.Params(extent_reach=0, photometric_check=False, road_spill=spill)
        det = fm.MotionDetector(cam, params=params, roi=renderer.roi())
        masks[spill] = det.detect_flow(flow, f0.pose, f3.pose, prev=g0, curr=g3).mask > 0
    car = f3.moving > 0
    assert masks[0.0][now].mean() > 0.4
    assert masks[15.0][now].mean() < 0.1
    assert masks[15.0][car].mean() > masks[0.0][car].mean() - 0.04
    assert not (masks[15.0] & ~masks[0.0]).any()


def test_a_flow_error_where_the_static_point_left_the_view_is_no_evidence():
    """The near road leaves the bottom of the view as the camera drives on: a flow that
    matched something else there (pointing back into the image) compared the static scene
    with the image's replicated border and became a false region; the images cannot test it,
    and the crossing car is found as before."""
    cam, renderer, f0, f3, g0, g3, true = _crossing_car_pair()
    bad = (slice(400, 440), slice(250, 350))
    v, u = np.mgrid[bad]
    assert not ((u + true[bad][..., 0] < 639) & (v + true[bad][..., 1] < 479)).any()  # left
    flow = true.copy()
    flow[bad] = (0.0, -20.0)             # into the image, onto other gravel
    now = np.zeros(true.shape[:2], bool)  # where the measured flow carries it
    now[380:420, 250:350] = True
    masks = _masks_without_and_with("photometric_view", flow, cam, renderer, f0, f3, g0, g3)
    car = f3.moving > 0
    assert masks[False][now].mean() > 0.8          # measured 0.97: a false region without it
    assert not masks[True][now].any()
    assert masks[True][car].mean() > 0.5
    np.testing.assert_array_equal(masks[True] & car, masks[False] & car)


def test_a_vehicle_seen_where_a_static_point_would_have_left_the_view_stays_a_seed(
        tmp_path, monkeypatch):
    """On the highway scene with the exact flow, an overtaking vehicle whose static prediction
    leaves the view is still found: its measured flow explains the frames. Without that
    exception (every such cell dropped) one of its frames is lost."""
    import importlib
    from pathlib import Path

    from fisheyemotion import photometric

    cam = fm.calib.load(Path(__file__).resolve().parents[1] / "data" / "calib"
                        / "front_kb_640x480.yaml")
    highway = synth.load_scenario("highway")

    def overtaking_found(name, params):
        result = _exact_flow_run(tmp_path / name, cam, highway, params, 16)
        return int(result.objects[result.objects.category == "overtaking"].detected.sum())

    on = overtaking_found("on", fm.Params())
    off = overtaking_found("off", fm.Params(photometric_view=False))
    monkeypatch.setattr(importlib.import_module("fisheyemotion.detector"), "testable_cells",
                        lambda at, view, measured, margin: photometric.testable_cells(
                            at, view, measured, -np.inf))
    strict = overtaking_found("strict", fm.Params())
    assert on == off > strict                      # measured 8, 8, 7 of 12


def test_the_off_arc_test_compares_with_the_best_static_correspondence_not_only_the_nearest():
    """A flow error along vertical stripes (photometrically free) whose nearest arc point is
    1.5 px off the true one in u: the nearest point explains the frames badly, so the deviation
    looks supported; among the candidates along the arc the true correspondence explains them
    as well as the measured flow, and the deviation is not supported."""
    from fisheyemotion.photometric import best_candidate, off_arc_supported

    rng = np.random.default_rng(3)
    stripes = np.tile(cv2.GaussianBlur(rng.integers(0, 255, (1, 120), dtype=np.uint8),
                                       (3, 1), 0.7), (90, 1))
    curr = np.roll(stripes, 3, axis=1)                     # the static truth: 3 px right
    flow = np.zeros((90, 120, 2), np.float32)
    flow[..., 0], flow[..., 1] = 3.0, 3.125                # measured: 3.125 px too far down
    cells = np.zeros((18, 24), bool)
    cells[4:-4, 4:-4] = True
    n = int(cells.sum())
    d = np.array([0.6, 0.8])                               # the arc's direction in the image
    nearest = np.array([3.0, 0.0]) + (np.array([0.0, 3.125]) @ d) * d   # truth + 2.5 d
    candidates = nearest + np.arange(-8, 9)[:, None] * 0.5 * d        # 4 px either way

    def to_shift(points):  # a point of the current image as a shift of the measured flow
        return np.broadcast_to(points - [3.0, 3.125], (n, 2))

    alone = off_arc_supported(stripes, curr, flow, 5, 10.0, cells, to_shift(nearest))
    searched = off_arc_supported(stripes, curr, flow, 5, 10.0, cells,
                                 np.stack([to_shift(c) for c in candidates]))
    assert alone[cells].all() and not searched.any()
    # The best candidate counts, wherever it is among them, and only finite ones are tried.
    some = np.stack([to_shift(candidates[0]), to_shift(candidates[-1])])
    assert off_arc_supported(stripes, curr, flow, 5, 10.0, cells, some)[cells].all()
    with_nan = np.stack([to_shift(candidates[3]), np.full((n, 2), np.nan)])  # 3: the truth
    assert not off_arc_supported(stripes, curr, flow, 5, 10.0, cells, with_nan).any()
    assert off_arc_supported(stripes, curr, flow, 5, 10.0, cells,
                             np.full((2, n, 2), np.nan))[cells].all()  # no arc: supported
    index, residual = best_candidate(stripes, curr, flow, 5, cells,
                                     np.stack([to_shift(c) for c in candidates]))
    assert (index == 3).all() and residual.max() < 1.0          # the truth, to its bilinear error
    index, residual = best_candidate(stripes, curr, flow, 5, cells, np.full((2, n, 2), np.nan))
    assert (index == -1).all() and np.isnan(residual).all()


def test_a_deviation_along_an_edge_is_not_supported_by_the_images_and_one_across_it_is():
    """The aperture problem: along vertical stripes a flow error in v changes nothing in the
    images, so moving it away (onto the arc) is not contradicted; a random texture contradicts."""
    from fisheyemotion.photometric import off_arc_supported

    rng = np.random.default_rng(9)
    stripes = np.tile(cv2.GaussianBlur(rng.integers(0, 255, (1, 80), dtype=np.uint8),
                                       (5, 1), 1.0), (60, 1))
    texture = cv2.GaussianBlur(rng.integers(0, 255, (60, 80), dtype=np.uint8), (3, 3), 0.7)
    cells = np.zeros((12, 16), bool)
    cells[3:-3, 3:-3] = True
    shift = np.tile([0.0, -2.0], (cells.sum(), 1))       # the flow's v error removed
    for image, supported in ((stripes, False), (texture, True)):
        curr = np.roll(image, 3, axis=1)                   # the content moved 3 px right
        flow = np.zeros((60, 80, 2), np.float32)
        flow[..., 0], flow[..., 1] = 3.0, 2.0              # measured: right, and 2 px down
        if supported:                                     # the texture really moved down too
            curr = np.roll(curr, 2, axis=0)
        out = off_arc_supported(image, curr, flow, 5, 10.0, cells, shift)
        assert out[cells].all() == supported and not out[~cells].any()
    nan_shift = shift.copy()
    nan_shift[0] = np.nan                                 # no arc there: counts as supported
    out = off_arc_supported(stripes, np.roll(stripes, 3, axis=1), flow, 5, 10.0, cells, nan_shift)
    assert out[3, 3] and not out[cells].all()


# ---- two spans (Params.photometric_span) --------------------------------------------------

def _two_spans(shift_curr: float, shift_before: float):
    """A textured frame, the next one moved ``shift_curr`` px right and the one before it moved
    ``shift_before`` px (a static point seen from three camera positions: one range, one shift
    either side, here of opposite signs)."""
    rng = np.random.default_rng(5)
    prev = cv2.GaussianBlur(rng.integers(0, 255, (60, 80), dtype=np.uint8), (3, 3), 0.7)
    def moved_by(shift):
        return cv2.warpAffine(prev, np.float32([[1, 0, shift], [0, 1, 0]]), (80, 60),
                              flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT)

    return prev, moved_by(shift_curr), moved_by(shift_before)


@pytest.mark.parametrize("before,explained", [(-2.0, True), (-3.0, False), (-1.0, False)])
def test_one_static_point_must_explain_both_spans(before, explained):
    """The frames show a point that moved 2 px right in the pair and 2 px the other way in the
    span before (the candidate's prediction): it is explained only where the frame before
    agrees with that same candidate; one span alone explains nothing."""
    from fisheyemotion.photometric import cell_residual, span_explained

    prev, curr, earlier = _two_spans(2.0, before)
    cells = np.zeros((12, 16), bool)
    cells[3:-3, 4:-4] = True
    n = int(cells.sum())
    flow = np.zeros((60, 80, 2), np.float32)
    flow[..., 0] = 2.0                                     # the measured flow follows the pair
    measured = cell_residual(prev, curr, flow, 5, cells)
    to_curr = np.tile([[2.0, 0.0]], (1, n, 1))              # one candidate: +2 px, then -2 px
    to_before = np.tile([[-2.0, 0.0]], (1, n, 1))
    out = span_explained(prev, curr, earlier, 5, cells, measured, to_curr, to_before)
    assert out[cells].all() == explained and not out[~cells].any()
    nan = np.full_like(to_before, np.nan)                  # no static point: nothing explained
    assert not span_explained(prev, curr, earlier, 5, cells, measured, to_curr, nan).any()


def test_two_spans_explain_a_parked_car_a_wrong_range_away_not_a_pedestrian_walking_out():
    """On a rendered street (the demo's 640x480 fisheye, 22 km/h, frames 3, 6 and 9): most of
    the parked cars' cells, given a scene-model range 10 % too far, are explained by one of the
    candidate ranges over both spans; most of the pedestrian's stepping out towards the path,
    whose pair reads as a static point (the model holding that very reading, the worst case),
    are not: no one range fits it in both spans. Without the spread of ranges most car cells
    stay unexplained."""
    from types import SimpleNamespace

    from fisheyemotion.photometric import cell_residual

    cam = fm.calib.load(Path(__file__).resolve().parents[1] / "data" / "calib"
                        / "front_kb_640x480.yaml")
    street = synth.parse_scenario({
        "name": "step_out_in_view", "frames": 12, "ego": {"speed_kmh": 22, "start": [0, -1.75]},
        "camera": {"position": [2.0, 0.0, 0.9], "pitch_deg": 15},
        "static": [{"id": 25, "kind": "parked_car", "center": [13.5, -4.6], "texture": "coffee"},
                   {"id": 26, "kind": "parked_car", "center": [18.5, -4.6]}],
        "objects": [{"id": 1, "kind": "pedestrian", "category": "crossing", "start": [9.5, -5.2],
                     "heading_deg": 90, "speed_kmh": 4}]})  # 6.8, 5.7 and 4.5 m away
    renderer = synth.Renderer(cam, street, supersample=1)
    frames = {k: renderer.render(k) for k in (3, 6, 9)}
    gray = {k: cv2.cvtColor(f.image, cv2.COLOR_BGR2GRAY) for k, f in frames.items()}
    det = fm.MotionDetector(cam, params=fm.Params(), roi=renderer.roi())
    g = det.params.grid
    exact = np.nan_to_num(renderer.flow(9, gap=3), nan=1e5).astype(np.float32)
    centre = (slice(g // 2, None, g), slice(g // 2, None, g))
    rows, cols = det._centres.shape[:2]
    ids = frames[6].ids[centre][:rows, :cols]
    truth = frames[6].range[centre][:rows, :cols].astype(float)
    t0, t1 = frames[6].pose, frames[9].pose
    rays1, _ = cam.unproject(det._centres + grid_average(exact, g))
    reading, _ = triangulate_range(det._rays0, rays1, t0, t1, far=1e3)
    cars = np.isin(ids, (25, 26)) & np.isfinite(truth)
    walker = (ids == 1) & np.isfinite(reading)
    assert cars.sum() >= 20 and walker.sum() >= 10
    model = np.where(cars, 1.1 * truth, np.where(walker, reading, np.nan))
    # The pair's best rigid shift of each cell (the exact mean flow), as the candidates are
    # rigid shifts: what a flow method that found each cell's motion would leave.
    block = np.repeat(np.repeat(grid_average(exact, g), g, axis=0), g, axis=1)
    uniform = np.zeros_like(exact)
    uniform[:block.shape[0], :block.shape[1]] = block
    # ... give or take the 2 grey levels any flow method's own error adds.
    measured = cell_residual(gray[6], gray[9], uniform, g, cars | walker) + 2.0

    def explained(spread):
        m = SimpleNamespace(span_before=(frames[3].pose, gray[3]), scene_ranges=model,
                            along_travel=None, t0=t0, t1=t1, road=fm.Road(), gray=gray[6],
                            curr=gray[9])
        det.params = det.params.replace(photometric_span=spread)
        return det._span_explained(m, cars | walker, measured)

    out = explained(fm.Params().photometric_span)  # measured: 75 % of the cars' cells, 20 % of the walker's
    assert out[cars].mean() >= 0.65 and out[walker].mean() <= 0.25
    assert explained(0.001)[cars].mean() <= out[cars].mean() - 0.3  # 31 %: the range is off


# ---- swept scene ranges (Params.scene_sweep, opt-in) ---------------------------------------

#: A parked car and a wall with textures that do not repeat (a brick wall's period gives a sweep
#: along the arc several minima: ``docs/evaluation.md``, *Swept scene ranges*).
PLAIN = synth.parse_scenario({
    "name": "plain", "frames": 4, "ego": {"speed_kmh": 25},
    "camera": {"position": [2, 0, 0.9], "pitch_deg": 10},
    "static": [{"id": 20, "kind": "wall", "center": [9, -4.0], "size": [14, 0.3, 3.0],
                "texture": "coffee"},
               {"id": 21, "kind": "parked_car", "center": [8, 3.0], "texture": "camera"}]})


def _plain_pair():
    """Frames 0 and 3 of PLAIN (gray), their truths, and a flow that followed a wrong prior on
    the parked car: each of its pixels moved as the static point at ``0.6`` of its range would."""
    from fisheyemotion.calib.base import pixel_grid

    from fisheyemotion.prior import static_scene_targets

    r = synth.Renderer(CAM, PLAIN, supersample=1)
    f0, f1 = r.render(0), r.render(3)
    g0, g1 = (cv2.cvtColor(f.image, cv2.COLOR_BGR2GRAY) for f in (f0, f1))
    pixels = pixel_grid(CAM.width, CAM.height).astype(np.float64)
    rays, _ = CAM.unproject(pixels)
    car = f0.ids == 21
    near = np.where(car, 0.6 * f0.range, np.inf)
    target, ok = static_scene_targets(CAM, rays, f0.pose, f1.pose, fm.Road(), 1e3, near)
    exact = np.nan_to_num(r.flow(3, gap=3))
    flow = np.where((car & ok)[..., None], target - pixels, exact).astype(np.float32)
    return r, f0, f1, g0, g1, flow


def _car_cells(f0, grid):
    """The cells wholly on the parked car, their rays, centres and true ranges."""
    from fisheyemotion.flow import grid_average, grid_centres

    cells = grid_average((f0.ids == 21).astype(np.float32), grid) > 1 - 1e-6
    centres = grid_centres(CAM.width, CAM.height, grid)
    r, c = np.nonzero(cells)
    rays, _ = CAM.unproject(centres[r, c])
    at = np.rint(centres[r, c]).astype(int)
    return cells, r, c, rays, centres, f0.range[at[:, 1], at[:, 0]]


def test_sweep_ranges_finds_a_static_cells_range_from_a_wrong_flow():
    """From the flow of a car read at 0.6 of its range, the sweep along each cell's arc lands
    nearer its true range, in the candidates around it, and explains the frames better."""
    from fisheyemotion.flow import grid_average
    from fisheyemotion.photometric import cell_residual, sweep_ranges

    _, f0, f1, g0, g1, flow = _plain_pair()
    grid = 5
    cells, r, c, rays, centres, truth = _car_cells(f0, grid)
    assert len(r) >= 30
    at = centres[r, c] + grid_average(flow, grid)[r, c]
    swept, residual = sweep_ranges(CAM, g0, g1, flow, grid, cells, rays, at, f0.pose, f1.pose)
    error = np.abs(np.log(swept / truth))
    assert np.mean(error < abs(np.log(0.6))) > 0.8      # nearer than the flow's range
    assert np.mean(np.abs(swept / truth - 1) < 0.3) > 0.8
    before = cell_residual(g0, g1, flow, grid, cells)[r, c]
    assert np.median(residual) < 0.5 * np.median(before)


def test_scene_sweep_is_off_by_default_and_stores_the_swept_ranges_when_on(monkeypatch):
    from fisheyemotion.static_scene import StaticScene

    assert fm.Params().scene_sweep == 0.0 == fm.Params.paper().scene_sweep
    with pytest.raises(ValueError, match="scene_sweep"):
        fm.Params(scene_sweep=-1.0)
    r, f0, f1, g0, g1, flow = _plain_pair()
    stored = []
    original = StaticScene.add

    def add(self, rays, ranges, pose, static):
        stored.append((ranges.copy(), static.copy()))
        return original(self, rays, ranges, pose, static)

    monkeypatch.setattr(StaticScene, "add", add)
    errors = {}
    for sweep in (0.0, 10.0):
        det = fm.MotionDetector(CAM, roi=r.roi(), params=fm.Params(scene_sweep=sweep))
        stored.clear()
        det.detect_flow(flow, f0.pose, f1.pose, prev=g0, curr=g1, stream=True)
        ranges, static = stored[0]
        _, rr, cc, _, _, truth = _car_cells(f0, det.params.grid)
        kept = (static & np.isfinite(ranges))[rr, cc]
        assert kept.sum() >= 10
        errors[sweep] = np.abs(ranges[rr, cc][kept] / truth[kept] - 1)
    assert np.median(errors[0.0]) > 0.3      # the wrong flow's ranges, stored as measured
    assert np.median(errors[10.0]) < 0.2     # swept along the arc


# ---- the scene model's bootstrap (Params.scene_bootstrap) ---------------------------------

def test_a_streams_first_pair_is_warped_by_the_structure_its_frames_between_show():
    """With a frame gap of 3 the first pair's displacements on a wall and a parked car beside
    the road are too large for the road/far-field prior; bootstrapped from the consecutive
    pairs between its frames, the first pair's prior is within a fraction of that error, and
    the static structure is quieter."""
    r = synth.Renderer(CAM, PLAIN, supersample=1)
    frames = [r.render(k) for k in range(4)]
    exact = r.flow(3, gap=3)
    structure = ((frames[0].ids >= 20) & (frames[0].ids < 65535)
                 & np.isfinite(exact).all(axis=-1))
    errors, flagged = {}, {}
    for bootstrap in (False, True):
        det = fm.MotionDetector(CAM, roi=r.roi(), params=fm.Params(scene_bootstrap=bootstrap))
        assert det.params.frame_gap == 3
        priors = []
        static_prior = det._static_prior

        def recorded(a, b, static_prior=static_prior, priors=priors):
            out = static_prior(a, b)
            if a.tobytes() == frames[0].pose.tobytes() and b.tobytes() == frames[3].pose.tobytes():
                priors.append(out[0])
            return out
        det._static_prior = recorded
        results = [det.apply(f.image, f.pose) for f in frames]
        assert results[:3] == [None] * 3
        errors[bootstrap] = np.median(np.linalg.norm(priors[0] - exact, axis=-1)[structure])
        flagged[bootstrap] = (results[3].mask > 0)[(frames[3].ids >= 20)
                                                   & (frames[3].ids < 65535)].mean()
    assert errors[False] > 10.0              # the road/far-field prior: tens of pixels off
    assert errors[True] < 0.1 * errors[False]
    assert flagged[False] > 0.2 and flagged[True] < 0.05
    assert fm.Params().scene_bootstrap and not fm.Params.paper().scene_bootstrap


def test_the_bootstrap_runs_once_per_stream_and_again_after_reset(monkeypatch):
    """Three consecutive flows before the first pair's, none later; reset() starts over."""
    r = synth.Renderer(CAM, PLAIN, supersample=1)
    frames = [r.render(k) for k in range(4)]
    det = fm.MotionDetector(CAM, roi=r.roi())
    flows = []
    one_flow = det._one_flow

    def counted(a, b, pose_a, pose_b):
        flows.append((pose_a.tobytes(), pose_b.tobytes()))
        return one_flow(a, b, pose_a, pose_b)
    monkeypatch.setattr(det, "_one_flow", counted)
    poses = [f.pose.tobytes() for f in frames]
    for _ in range(2):
        flows.clear()
        for f in frames + frames[:1]:
            det.apply(f.image, f.pose)
        assert flows[:4] == [(poses[0], poses[1]), (poses[1], poses[2]), (poses[2], poses[3]),
                             (poses[0], poses[3])]
        assert flows[4:] == [(poses[1], poses[0])]  # frame 1 to the repeated frame 0: a pair
        det.reset()
