"""The constraint engine: every condition of the paper, proved on exact correspondences."""

from __future__ import annotations

import numpy as np
import pytest
from fisheyemotion.calib.transforms import make_transform
from hypothesis import given
from hypothesis import strategies as st

import fisheyemotion as fm

from .cameras import MODEL_SAMPLES
from .scenes import camera_pose, moved, random_rotation, rays_of

NO_DEAD_BAND = fm.Params(lambda_h=0.0, lambda_p=0.0)


@st.composite
def ego_motions(draw):
    """A road camera (height, pitch, yaw, roll) and a forward ego-motion with some yaw."""
    seed = draw(st.integers(0, 2**32 - 1))
    rng = np.random.default_rng(seed)
    height = draw(st.floats(0.5, 2.0))
    pose0 = camera_pose(rng, height=height, pitch_deg=draw(st.floats(-5, 30)),
                        yaw_deg=draw(st.floats(-180, 180)), roll_deg=draw(st.floats(-5, 5)),
                        position_xy=(draw(st.floats(-50, 50)), draw(st.floats(-50, 50))))
    heading = draw(st.floats(-np.pi, np.pi))
    step = draw(st.floats(0.05, 1.5))
    pose1 = moved(pose0, [step * np.cos(heading), step * np.sin(heading), 0.0],
                  yaw_deg=draw(st.floats(-3, 3)))
    return rng, pose0, pose1


def scene_points(rng, pose, n=400, *, on_road=False):
    """World points 2-30 m around the camera, above the road (or on it)."""
    c = pose[:3, 3]
    ang = rng.uniform(-np.pi, np.pi, n)
    dist = rng.uniform(2, 30, n)
    z = np.zeros(n) if on_road else rng.uniform(0.05, 4.0, n)
    return np.c_[c[0] + dist * np.cos(ang), c[1] + dist * np.sin(ang), z]


@given(ego_motions())
def test_static_points_satisfy_epipolar_depth_and_height(case):
    rng, pose0, pose1 = case
    x = scene_points(rng, pose0)
    r = fm.constraints(rays_of(x, pose0), rays_of(x, pose1), pose0, pose1)
    assert r.valid.mean() > 0.9
    v = r.valid
    assert np.abs(r.epipolar[v]).max() < 1e-9
    assert np.all(r.depth[v] == 0)
    assert np.all(r.height[v] == 0)


@given(ego_motions())
def test_static_road_points_have_zero_likelihood(case):
    rng, pose0, pose1 = case
    x = scene_points(rng, pose0, on_road=True)
    r = fm.constraints(rays_of(x, pose0), rays_of(x, pose1), pose0, pose1, params=NO_DEAD_BAND)
    v = r.valid
    assert np.abs(r.likelihood[v]).max() < 1e-9
    assert r.height[v].max() < 1e-9 and r.antiparallel[v].max() < 1e-9


@given(ego_motions())
def test_crossing_motion_fires_epipolar(case):
    rng, pose0, pose1 = case
    x = scene_points(rng, pose0)
    r0 = fm.constraints(rays_of(x, pose0), rays_of(x, pose1), pose0, pose1)
    # Move every point out of its own epipolar plane, by 0.2 m along the plane normal.
    c0, c1 = pose0[:3, 3], pose1[:3, 3]
    normal = np.cross(x - c0, c1 - c0)
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    r = fm.constraints(rays_of(x, pose0), rays_of(x + 0.2 * normal, pose1), pose0, pose1)
    v = r.valid & r0.valid
    assert (r.epipolar[v] > 1e-4).all()


def _translation(pose0, pose1):
    return pose1[:3, 3] - pose0[:3, 3]


@given(ego_motions(), st.floats(1.2, 4.0))
def test_faster_same_direction_fires_depth(case, factor):
    rng, pose0, pose1 = case
    x = scene_points(rng, pose0)
    x1 = x + factor * _translation(pose0, pose1)
    # Keep pure translation so that the motion stays in the epipolar plane.
    pose1 = make_transform(pose0[:3, :3], pose1[:3, 3])
    r = fm.constraints(rays_of(x, pose0), rays_of(x1, pose1), pose0, pose1)
    v = r.valid
    assert np.abs(r.epipolar[v]).max() < 1e-9
    assert (r.depth[v] > 0).all()


@given(ego_motions(), st.floats(0.1, 0.9))
def test_slower_same_direction_road_points_fire_height(case, factor):
    rng, pose0, pose1 = case
    x = scene_points(rng, pose0, on_road=True)
    x1 = x + factor * _translation(pose0, pose1)
    r = fm.constraints(rays_of(x, pose0), rays_of(x1, pose1), pose0, pose1, params=NO_DEAD_BAND)
    v = r.valid
    assert (r.height[v] > 0).all()
    assert np.all(r.depth[v] == 0) and np.all(r.antiparallel[v] == 0)


@given(ego_motions(), st.floats(0.2, 3.0))
def test_oncoming_road_points_fire_antiparallel(case, factor):
    rng, pose0, pose1 = case
    x = scene_points(rng, pose0, on_road=True)
    x1 = x - factor * _translation(pose0, pose1)
    r = fm.constraints(rays_of(x, pose0), rays_of(x1, pose1), pose0, pose1, params=NO_DEAD_BAND)
    v = r.valid
    assert (r.antiparallel[v] > 0).all()
    assert np.all(r.depth[v] == 0) and np.all(r.height[v] == 0)


@given(ego_motions(), st.integers(0, 2**32 - 1))
def test_rigid_change_of_world_frame_changes_nothing(case, seed):
    rng, pose0, pose1 = case
    x = scene_points(rng, pose0)
    x1 = x + rng.normal(0, 0.3, x.shape)  # arbitrary (moving) correspondences
    rays0, rays1 = rays_of(x, pose0), rays_of(x1, pose1)
    r = fm.constraints(rays0, rays1, pose0, pose1, params=fm.Params(lambda_p_mode="adaptive"))
    g = np.random.default_rng(seed)
    new_from_old = make_transform(random_rotation(g), g.uniform(-100, 100, 3))
    r2 = fm.constraints(rays0, rays1, new_from_old @ pose0, new_from_old @ pose1,
                        road=fm.Road().transformed(new_from_old),
                        params=fm.Params(lambda_p_mode="adaptive"))
    np.testing.assert_array_equal(r.valid, r2.valid)
    for name in ("epipolar", "depth", "height", "antiparallel", "likelihood"):
        np.testing.assert_allclose(getattr(r2, name), getattr(r, name), atol=1e-9, err_msg=name)


@pytest.mark.parametrize("seed", range(3))
def test_same_scene_through_kb_ds_eucm_gives_same_deviations(seed):
    rng = np.random.default_rng(seed)
    pose0 = camera_pose(rng, height=1.0)
    pose1 = moved(pose0, [0.3, 0.02, 0.0], yaw_deg=1.0)
    x = scene_points(rng, pose0, n=2000)
    x1 = x + rng.normal(0, 0.2, x.shape)
    results = []
    for name in ("kannala_brandt", "double_sphere", "enhanced_unified"):
        cam = MODEL_SAMPLES[name][0]
        px0, ok0 = cam.project(rays_of(x, pose0))
        px1, ok1 = cam.project(rays_of(x1, pose1))
        rays0, _ = cam.unproject(px0)
        rays1, _ = cam.unproject(px1)
        r = fm.constraints(rays0, rays1, pose0, pose1)
        results.append((r, ok0 & ok1))
    common = np.logical_and.reduce([ok & r.valid for r, ok in results])
    assert common.sum() > 500
    for r, _ in results[1:]:
        np.testing.assert_allclose(r.likelihood[common], results[0][0].likelihood[common], atol=1e-9)


def test_weighted_mean_uses_the_papers_weights():
    rng = np.random.default_rng(0)
    pose0 = camera_pose(rng, height=1.0)
    pose1 = moved(pose0, [0.3, 0, 0])
    x = scene_points(rng, pose0)
    r = fm.constraints(rays_of(x, pose0), rays_of(x + rng.normal(0, 0.3, x.shape), pose1), pose0, pose1)
    v = r.valid
    expected = (r.epipolar + r.depth + 0.2 * r.height + 0.2 * r.antiparallel) / 2.4
    np.testing.assert_allclose(r.likelihood[v], expected[v], rtol=1e-12)
    assert r.likelihood[v].max() > 0


def test_static_camera_uses_angle_between_rays():
    rng = np.random.default_rng(1)
    pose = camera_pose(rng, height=1.0)
    x = scene_points(rng, pose)
    rays0 = rays_of(x, pose)
    r = fm.constraints(rays0, rays0, pose, pose)
    assert r.static_camera and np.all(r.likelihood == 0)
    r = fm.constraints(rays0, rays_of(x + [0.1, 0.0, 0.0], pose), pose, pose)
    expected = np.linalg.norm(np.cross(rays_of(x + [0.1, 0, 0], pose), rays0), axis=1)
    np.testing.assert_allclose(r.likelihood, expected, rtol=1e-12)
    assert np.all(r.epipolar == 0) and np.all(r.depth == 0)


def test_rotation_only_is_a_static_camera_and_is_compensated():
    rng = np.random.default_rng(2)
    pose0 = camera_pose(rng, height=1.0)
    pose1 = moved(pose0, [0.0, 0.0, 0.0], yaw_deg=5.0)
    x = scene_points(rng, pose0)
    r = fm.constraints(rays_of(x, pose0), rays_of(x, pose1), pose0, pose1)
    assert r.static_camera and r.likelihood.max() < 1e-12


def test_near_epipole_rays_are_invalid_and_nan():
    rng = np.random.default_rng(3)
    pose0 = camera_pose(rng, height=1.0)
    pose1 = moved(pose0, [0.5, 0, 0])
    # Points straight ahead and straight behind along the motion line at camera height.
    x = np.array([[10.0, 0.0, 1.0], [-10.0, 0.0, 1.0], [10.0, 3.0, 1.0]])
    r = fm.constraints(rays_of(x, pose0), rays_of(x, pose1), pose0, pose1)
    assert list(r.valid) == [False, False, True]
    assert np.isnan(r.likelihood[:2]).all() and np.isnan(r.epipolar[:2]).all()


def test_non_finite_rays_are_invalid_not_errors():
    pose0 = np.eye(4)
    pose1 = make_transform(np.eye(3), [0, 0, 0.5])
    r = fm.constraints([[np.nan, 0, 1], [0.3, 0.1, 1]], [[0, 0, 1], [np.inf, 0, 1]], pose0, pose1)
    assert not r.valid.any()


def test_papers_n_dot_p_is_identically_zero():
    """The printed height/anti-parallel conditions use n'.p, which cannot discriminate."""
    rng = np.random.default_rng(4)
    p = rng.normal(size=(1000, 3))
    e = rng.normal(size=3)
    n = np.cross(p, e)
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    assert np.abs(np.einsum("ij,ij->i", n, p)).max() < 1e-12


def test_lambda_dead_bands_and_adaptive_mode():
    rng = np.random.default_rng(5)
    pose0 = camera_pose(rng, height=1.0)
    pose1 = moved(pose0, [0.3, 0, 0])
    x = scene_points(rng, pose0, on_road=True)
    rays0, rays1 = rays_of(x, pose0), rays_of(x - [0.3, 0, 0], pose1)
    free = fm.constraints(rays0, rays1, pose0, pose1, params=NO_DEAD_BAND)
    band = fm.constraints(rays0, rays1, pose0, pose1, params=fm.Params(lambda_p=0.01))
    v = free.valid
    np.testing.assert_allclose(band.antiparallel[v], np.maximum(free.antiparallel[v] - 0.01, 0))
    adaptive = fm.constraints(rays0, rays1, pose0, pose1,
                              params=fm.Params(lambda_p_mode="adaptive", lambda_p_ratio=0.5))
    # Oncoming at ego speed doubles the road displacement: deviation exceeds half of it.
    assert (adaptive.antiparallel[v] > 0).mean() > 0.9


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        (dict(rays0=np.zeros((3, 2))), "rays0"),
        (dict(rays1=np.zeros((4, 3))), "rays1"),
        (dict(pose0=np.eye(3)), "pose0"),
        (dict(pose1=np.diag([2.0, 1, 1, 1])), "pose1.*rigid"),
        (dict(pose1=np.full((4, 4), np.nan)), "pose1"),
        (dict(road="z=0"), "road"),
        (dict(params={"grid": 5}), "params"),
    ],
)
def test_bad_inputs_name_the_argument(kwargs, match):
    args = dict(rays0=np.ones((3, 3)), rays1=np.ones((3, 3)), pose0=np.eye(4), pose1=np.eye(4))
    extra = {k: kwargs.pop(k) for k in list(kwargs) if k in ("road", "params")}
    args.update(kwargs)
    with pytest.raises(ValueError, match=match):
        fm.constraints(args["rays0"], args["rays1"], args["pose0"], args["pose1"], **extra)


def test_depth_in_previous_view_is_an_option():
    """p'_Pi beyond e' (a > 0, c < 0) triangulates behind the previous camera."""
    rng = np.random.default_rng(6)
    pose0 = camera_pose(rng, height=1.0)
    pose1 = moved(pose0, [0.5, 0, 0])
    x = scene_points(rng, pose0)
    p = rays_of(x, pose0) @ pose0[:3, :3].T  # world
    e = (pose0[:3, 3] - pose1[:3, 3]) / 0.5
    q = e - 0.3 * p  # negative combination of p: beyond e' on the circle
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    rays1 = q @ pose1[:3, :3]
    both = fm.constraints(rays_of(x, pose0), rays1, pose0, pose1)
    paper = fm.constraints(rays_of(x, pose0), rays1, pose0, pose1,
                           params=fm.Params(depth_both_views=False))
    v = both.valid
    np.testing.assert_allclose(both.depth[v], np.linalg.norm(np.cross(q, e), axis=1)[v], rtol=1e-9)
    assert (both.depth[v] > 0).all() and np.all(paper.depth[v] == 0)


def test_road_from_the_papers_inputs_and_from_a_vehicle_pose():
    rng = np.random.default_rng(7)
    pose = camera_pose(rng, height=1.3, pitch_deg=12.0, yaw_deg=40.0)
    # The paper's inputs: camera height and R_C (cam_from_road) with h = R_C (0, 0, -1).
    cam_from_road = pose[:3, :3].T  # the world frame here is the road frame
    road = fm.Road.from_camera(height=1.3, cam_from_road=cam_from_road, world_from_cam=pose)
    np.testing.assert_allclose(road.up, [0, 0, 1], atol=1e-12)
    assert road.offset == pytest.approx(0.0, abs=1e-12)
    world_from_vehicle = make_transform(random_rotation(rng), [3.0, -2.0, 0.5])
    from_vehicle = fm.Road.from_vehicle(world_from_vehicle)
    ground = world_from_vehicle @ np.array([[5.0, 1.0, 0.0, 1.0], [-2.0, 3.0, 0.0, 1.0]]).T
    np.testing.assert_allclose(from_vehicle.height(ground[:3].T), 0.0, atol=1e-12)
    above = world_from_vehicle @ np.array([0.0, 0.0, 2.0, 1.0])
    assert from_vehicle.height(above[:3]) == pytest.approx(2.0)
    with pytest.raises(ValueError, match="height"):
        fm.Road.from_camera(height=-1.0, cam_from_road=np.eye(3), world_from_cam=np.eye(4))
    with pytest.raises(ValueError, match="normal"):
        fm.Road(normal=(0, 0, 0))


@given(ego_motions())
def test_arc_candidates_are_static_points_spaced_along_the_arc(case):
    """Every candidate of the off-arc test's search is a static point's ray (the constraints'
    epipolar and depth deviations 0), angle 0 is the point searched around, and unclamped
    candidates are the given angles apart along the epipolar circle."""
    from fisheyemotion.constraints import nearest_static_ray
    from fisheyemotion.photometric import arc_candidates

    rng, pose0, pose1 = case
    x = scene_points(rng, pose0)
    p, q = rays_of(x, pose0), rays_of(x, pose1)
    noisy = q + rng.normal(scale=0.05, size=q.shape)
    noisy /= np.linalg.norm(noisy, axis=-1, keepdims=True)
    arc = nearest_static_ray(p, noisy, pose0, pose1)
    step = rng.uniform(1e-4, 3e-3, len(p))
    angles = np.arange(-4, 5)[:, None] * step
    cand = arc_candidates(p, arc, pose0, pose1, angles)
    assert cand.shape == (9, len(p), 3)
    np.testing.assert_allclose(cand[4], arc, atol=1e-9)
    flat = cand.reshape(-1, 3)
    ok = np.isfinite(flat).all(axis=-1)
    r = fm.constraints(np.tile(p, (9, 1))[ok], flat[ok], pose0, pose1)
    assert r.valid.mean() > 0.9
    assert np.abs(r.epipolar[r.valid]).max() < 1e-9 and np.abs(r.depth[r.valid]).max() < 1e-9
    # Neighbours inside the arc are one step apart on the circle; clamped ones sit at its ends,
    # e' (range 0) and the rotated p (range infinite).
    b = pose0[:3, 3] - pose1[:3, 3]
    ends = (pose1[:3, :3].T @ (b / np.linalg.norm(b)), p @ (pose1[:3, :3].T @ pose0[:3, :3]).T)
    inside = np.all([np.linalg.norm(cand - end, axis=-1) > 1e-7 for end in ends], axis=0)
    gap = np.arccos(np.clip(np.einsum("mij,mij->mi", cand[1:], cand[:-1]), -1, 1))
    both = inside[1:] & inside[:-1]
    assert both.mean() > 0.5
    np.testing.assert_allclose(gap[both], np.broadcast_to(step, gap.shape)[both], rtol=1e-5)
    assert (gap <= step * (1 + 1e-5) + 1e-12).all()       # clamping only shortens a gap
    assert np.isnan(arc_candidates(p, arc, pose0, pose0, angles)).all()   # no baseline


def test_road_moves_with_a_change_of_world_frame():
    road = fm.Road(normal=(0, 0, 1), offset=0.2)
    t = make_transform(random_rotation(np.random.default_rng(8)), [1.0, 2.0, 3.0])
    moved = road.transformed(t)
    point = np.array([4.0, -1.0, 0.2])  # on the road
    assert moved.height(t[:3, :3] @ point + t[:3, 3]) == pytest.approx(0.0, abs=1e-12)


@given(ego_motions())
def test_the_nearest_static_ray_is_a_static_point_and_leaves_static_rays_alone(case):
    from fisheyemotion.constraints import nearest_static_ray

    rng, pose0, pose1 = case
    x = scene_points(rng, pose0)
    p, q = rays_of(x, pose0), rays_of(x, pose1)
    np.testing.assert_allclose(nearest_static_ray(p, q, pose0, pose1), q, atol=1e-9)
    noisy = q + rng.normal(scale=0.05, size=q.shape)
    noisy /= np.linalg.norm(noisy, axis=-1, keepdims=True)
    arc = nearest_static_ray(p, noisy, pose0, pose1)
    np.testing.assert_allclose(np.linalg.norm(arc, axis=-1), 1.0, atol=1e-12)
    r = fm.constraints(p, arc, pose0, pose1)
    v = r.valid
    assert v.mean() > 0.9
    assert np.abs(r.epipolar[v]).max() < 1e-9 and np.abs(r.depth[v]).max() < 1e-9
    # No static ray is nearer: the arc's point is at least as near as a static point at any range.
    c0, c1 = pose0[:3, 3], pose1[:3, 3]
    for lam in (0.5, 2.0, 8.0, 50.0):
        other = rays_of(c0 + lam * (p @ pose0[:3, :3].T), pose1)
        gap_arc = np.einsum("ij,ij->i", arc, noisy)
        gap_other = np.einsum("ij,ij->i", other, noisy)
        assert np.all(gap_arc[v] >= gap_other[v] - 1e-12)
    assert np.isnan(nearest_static_ray(p, q, pose0, pose0)).all()   # no baseline
    del c1
