"""``Params.receding`` (:mod:`fisheyemotion.receding`): regions whose base reads beyond the road
they stand on move away along their epipolar arcs; static ones never do."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import fisheyemotion as fm
from fisheyemotion import synth
from fisheyemotion.flow import grid_centres
from fisheyemotion.receding import (
    EDGE_ROWS,
    MIN_COLUMNS,
    ROAD_ROWS,
    receding_cells,
    receding_z,
    road_ranges,
)
from fisheyemotion.static_scene import triangulate_range, world_points

from .cameras import tumvi_kb
from .scenes import camera_pose, moved, rays_of

G = 5
CAM = tumvi_kb(320, 240, 100.0)


@settings(max_examples=80, deadline=None)
@given(seed=st.integers(0, 2**31 - 1))
def test_a_point_beyond_the_road_along_its_ray_is_under_the_road(seed):
    """``lambda <= rho(r)`` is ``height >= 0``: the module's condition is the height term's."""
    rng = np.random.default_rng(seed)
    height = rng.uniform(0.3, 3.0)
    pose = camera_pose(rng, height=height, pitch_deg=rng.uniform(-20, 30),
                       yaw_deg=rng.uniform(-180, 180), roll_deg=rng.uniform(-10, 10))
    rays = rng.normal(size=(200, 3))
    rays /= np.linalg.norm(rays, axis=-1, keepdims=True)
    rho = road_ranges(rays, pose, fm.Road())
    down = np.isfinite(rho)
    assert (rays[~down] @ pose[:3, :3].T @ [0, 0, -1] <= 0).all()  # up or level: no road
    lam = rho[down] * rng.uniform(0.2, 2.0, down.sum())
    above = fm.Road().height(world_points(rays[down], lam, pose))
    np.testing.assert_allclose(above, height * (1 - lam / rho[down]), atol=1e-9)
    assert np.array_equal(above >= -1e-12, lam <= rho[down] * (1 + 1e-12))


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), share=st.floats(-1.0, 0.8))
def test_an_object_moving_along_the_travel_reads_scaled_from_the_first_camera(seed, share):
    """The camera moves ``b`` along ``d``, the point ``delta = share * b``: the two views
    triangulate it at ``b / (b - delta)`` times its range (farther when it moves away)."""
    rng = np.random.default_rng(seed)
    pose0 = camera_pose(rng, height=1.5, yaw_deg=rng.uniform(-180, 180))
    heading = pose0[:3, :3] @ [0.0, 0.0, 1.0]
    heading[2] = 0
    heading /= np.linalg.norm(heading)
    b = rng.uniform(0.3, 2.0)
    pose1 = moved(pose0, b * heading)
    point = pose0[:3, 3] + rng.uniform(4, 30) * (heading + rng.uniform(-0.6, 0.6, 3) * [1, 1, 0.3])
    later = point + share * b * heading
    lam, ok = triangulate_range(rays_of(point, pose0), rays_of(later, pose1), pose0, pose1,
                                far=1e6)
    true = np.linalg.norm(point - pose0[:3, 3])
    assert ok
    np.testing.assert_allclose(lam, true / (1 - share), rtol=1e-6)


def _grid_scene(base_ratio: float, *, below: float = 1.0):
    """A region 4 cells tall over 6 columns (rows 30-33, columns 20-25) of a 320x240 camera
    1.5 m above the road: an upright surface at ``base_ratio`` times the road plane's range
    along its lowest cells' rays; the road (``below`` times the plane's range) around it."""
    pose = camera_pose(np.random.default_rng(0), height=1.5, pitch_deg=0)
    centres = grid_centres(CAM.width, CAM.height, G)
    rays, _ = CAM.unproject(centres)
    plane = road_ranges(rays, pose, fm.Road())
    ranges = np.where(np.isfinite(plane), plane, 1000.0)
    labels = np.zeros(plane.shape, np.intp)
    labels[30:34, 20:26] = 1
    ranges[30:34, 20:26] = base_ratio * plane[33, 20:26]
    ranges[34:, 20:26] = below * plane[34:, 20:26]
    return labels, ranges, plane, rays, pose


@pytest.mark.parametrize("ratio", [0.7, 1.25, 1.5])
def test_z_is_how_far_the_base_reads_beyond_the_road_in_range_errors(ratio):
    labels, ranges, plane, _, _ = _grid_scene(ratio)
    error = np.full(ranges.shape, 0.05)
    z = receding_z(labels, ranges, error, plane)
    np.testing.assert_allclose(z[30:34, 20:26], (ratio - 1) / 0.05, atol=1e-9)
    assert np.isnan(z[labels == 0]).all()


def test_a_static_object_standing_on_the_road_is_never_receding():
    """Its base reads the road's range: it reads the road along its lowest rays too (not
    tested), or, a wider tolerance given, z 0."""
    labels, ranges, plane, _, _ = _grid_scene(1.0)
    error = np.full(ranges.shape, 0.05)
    assert np.isnan(receding_z(labels, ranges, error, plane)).all()
    import fisheyemotion.receding as receding

    tolerance = receding.ROAD_TOLERANCE
    try:
        receding.ROAD_TOLERANCE = 0.02
        z = receding_z(labels, ranges, error, plane)
    finally:
        receding.ROAD_TOLERANCE = tolerance
    np.testing.assert_allclose(z[30:34, 20:26], 0.0, atol=1e-9)


def test_no_road_seen_below_no_test():
    """A nearer object below the region (its base hidden), or the region at the image's
    bottom: nothing is measured."""
    labels, ranges, plane, _, _ = _grid_scene(1.5, below=0.5)
    assert np.isnan(receding_z(labels, ranges, np.full(ranges.shape, 0.05), plane)).all()
    labels, ranges, plane, _, _ = _grid_scene(1.5)
    labels[:] = 0
    labels[-ROAD_ROWS - 1:, 20:26] = 1  # its lowest cells have fewer than ROAD_ROWS below
    assert np.isnan(receding_z(labels, ranges, np.full(ranges.shape, 0.05), plane)).all()


def test_one_column_is_outvoted_and_a_single_column_is_not_tested():
    labels, ranges, plane, _, _ = _grid_scene(0.7)
    error = np.full(ranges.shape, 0.05)
    ranges[30:34, 22] = 1.5 * plane[33, 22]  # one column's flow error: reads far
    z = receding_z(labels, ranges, error, plane)
    assert np.isfinite(z[30:34, 20:26]).all() and np.nanmax(z) < 0
    narrow = np.zeros_like(labels)
    narrow[30:34, 22:22 + MIN_COLUMNS - 1] = 1
    assert np.isnan(receding_z(narrow, ranges, error, plane)).all()


def test_the_base_is_the_median_of_the_lowest_cells():
    """A region's lowest cell in a column mixes object and road (the flow's boundary): the
    median of its ``EDGE_ROWS`` lowest cells reads the object."""
    labels, ranges, plane, _, _ = _grid_scene(1.5)
    ranges[33, 20:26] = plane[33, 20:26]  # the lowest row reads the road
    z = receding_z(labels, ranges, np.full(ranges.shape, 0.05), plane)
    assert EDGE_ROWS >= 3 and np.allclose(z[30:34, 20:26], 10.0)


def test_a_patch_of_road_is_not_an_upright_base():
    """Road cells in a region read farther up their column (the median of the lowest three
    1.11 times the lowest one's road range here, 2.2 sigmas at 5 %): they read the road along
    their own rays, and are not tested."""
    labels, ranges, plane, _, _ = _grid_scene(1.0)
    ranges[30:34, 20:26] = plane[30:34, 20:26]
    assert ((np.median(ranges[31:34, 20:26] / plane[33, 20:26], axis=0) - 1) / 0.05 > 2).all()
    assert np.isnan(receding_z(labels, ranges, np.full(ranges.shape, 0.05), plane)).all()


def test_candidates_are_labelled_four_connected():
    """Two regions touching at a corner keep their own z (8-connected, one region, the
    columns' median would mix them)."""
    labels, ranges, plane, rays, pose = _grid_scene(1.5)
    error = np.full(ranges.shape, 0.05)
    z = receding_cells(labels > 0, ranges, error, rays, pose, fm.Road())
    np.testing.assert_allclose(z[30:34, 20:26], 10.0)
    assert np.isnan(z[labels == 0]).all()
    touching = labels > 0
    touching[26:30, 26:32] = True
    ranges[26:30, 26:32] = 1.4 * plane[29, 26:32]
    z = receding_cells(touching, ranges, error, rays, pose, fm.Road())
    np.testing.assert_allclose(z[30:34, 20:26], 10.0)
    np.testing.assert_allclose(z[26:30, 26:32], 8.0)


@pytest.fixture(scope="module")
def preceding_pair():
    cam = tumvi_kb(640, 480, 200.0)
    renderer = synth.Renderer(cam, synth.load_scenario("preceding"))
    f0, f3 = renderer.render(3), renderer.render(6)
    return cam, renderer, f0, f3


def test_a_preceding_car_is_covered_by_its_base(preceding_pair):
    """The preceding scene's pair 3 -> 6 with Farneback (measured: the car covered 4 -> 21 %,
    by the flagged cells alone 3 -> 8 %; static pixels flagged 5737 -> 6628)."""
    cam, renderer, f0, f3 = preceding_pair
    g0, g3 = (cv2.cvtColor(f.image, cv2.COLOR_BGR2GRAY) for f in (f0, f3))
    car = f3.moving > 0
    out = {r: fm.MotionDetector(cam, params=fm.Params(receding=r), roi=renderer.roi())
           .detect(g0, g3, f0.pose, f3.pose) for r in (0.0, 2.0)}
    before, after = (out[r].mask > 0 for r in (0.0, 2.0))
    assert after[car].mean() > max(3 * before[car].mean(), before[car].mean() + 0.1)
    assert (after & ~car).sum() < 1.25 * (before & ~car).sum()
    # The flagged cells themselves, before the extent: more than twice as much of the car.
    cells = {r: out[r].cell_mask > 0 for r in (0.0, 2.0)}
    assert cells[2.0][car].mean() > 2 * cells[0.0][car].mean() > 0


def test_with_exact_correspondences_the_car_recedes_and_static_structure_does_not(
        preceding_pair):
    """The exact flow of the same pair, every cell of the car and of the static scene a
    candidate, a range error of 0.25 px over the parallax: the car's base reads beyond the road
    by more than ``Params().receding`` sigmas; nothing static comes near."""
    cam, renderer, f0, f3 = preceding_pair
    flow = renderer.flow(6, gap=3)
    centres = grid_centres(cam.width, cam.height, G)
    at = np.rint(centres).astype(int)
    cell_flow = flow[at[..., 1], at[..., 0]]
    rays0, ok0 = cam.unproject(centres)
    rays1, ok1 = cam.unproject(centres + cell_flow)
    ranges, ok, parallax = triangulate_range(rays0, rays1, f0.pose, f3.pose, far=1000.0,
                                             with_parallax=True)
    pixel = 1.0 / 200.0  # radians per pixel near the centre
    with np.errstate(invalid="ignore", divide="ignore"):
        error = 0.25 * pixel / parallax
    ids = f0.ids[at[..., 1], at[..., 0]]
    car = f0.moving[at[..., 1], at[..., 0]] > 0
    static_objects = (ids > 0) & ~car
    candidates = (car | static_objects) & ok0 & ok1 & ok
    z = receding_cells(candidates, ranges, error, rays0, f0.pose, fm.Road())
    assert np.nanmax(z[car]) >= fm.Params().receding
    assert not (z[static_objects] >= fm.Params().receding).any()


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), scale=st.floats(0.01, 100.0))
def test_z_is_only_on_regions_and_does_not_depend_on_the_unit_of_length(seed, scale):
    """Random regions, ranges and errors (some NaN): z is NaN outside the regions, and scaling
    every range and the road's together (another unit of length) changes no z."""
    rng = np.random.default_rng(seed)
    rows, cols = rng.integers(3, 30), rng.integers(3, 40)
    labels = np.zeros((rows, cols), np.intp)
    for i in range(1, rng.integers(1, 5)):
        r, c = rng.integers(0, rows), rng.integers(0, cols)
        labels[r:r + rng.integers(1, 6), c:c + rng.integers(1, 8)] = i
    plane = np.where(rng.random((rows, cols)) < 0.1, np.inf, rng.uniform(2, 40, (rows, cols)))
    ranges = plane * rng.uniform(0.5, 2.0, (rows, cols))
    ranges[rng.random((rows, cols)) < 0.1] = np.nan
    error = rng.uniform(0.01, 0.5, (rows, cols))
    z = receding_z(labels, ranges, error, plane)
    assert z.shape == labels.shape and np.isnan(z[labels == 0]).all()
    np.testing.assert_allclose(receding_z(labels, scale * ranges, error, scale * plane), z,
                               rtol=1e-9, atol=1e-9)
