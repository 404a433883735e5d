"""Three views of a static point (``fisheyemotion.range_consistency``): ground-truth geometry."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fisheyemotion.range_consistency import RangeMemory
from fisheyemotion.static_scene import triangulate_range, world_points

from .scenes import camera_pose, moved, rays_of


def _cells(points: np.ndarray, pose: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Ranges from ``pose`` and unit rays of world points (one per cell of a 1 x n grid)."""
    ranges = np.linalg.norm(points - pose[:3, 3], axis=-1)
    return ranges, rays_of(points, pose)


@pytest.mark.parametrize("seed", range(5))
def test_static_points_agree_and_points_moving_along_their_ray_do_not(seed):
    """The points a first pair saw land in the cells of the second pair's previous frame; a
    static point's range there is the one remembered (z = 0), a point that moved 0.5 m along
    the line of sight is off by 0.5 m over its range, many errors of 1 %."""
    rng = np.random.default_rng(seed)
    pose1 = camera_pose(rng, height=1.0)
    n = 20
    points = np.column_stack([rng.uniform(5, 15, n), rng.uniform(-4, 4, n), rng.uniform(0, 2, n)])
    grid = 5
    landing = np.column_stack([np.arange(n) * grid + 2.0, np.full(n, 2.0)])[None]  # 1 x n cells
    error = np.full((1, n), 0.01)
    memory = RangeMemory(4)
    frame = np.zeros((2, 2), np.uint8)
    memory.remember(frame, points[None], error, landing, np.ones((1, n), bool), grid,
                    pose1[:3, 3])
    ranges, _ = _cells(points, pose1)
    z = memory.deviation(frame, ranges[None], error, pose1[:3, 3])
    np.testing.assert_allclose(z, 0.0, atol=1e-12)
    away = points + 0.5 * (points - pose1[:3, 3]) / ranges[:, None]  # 0.5 m further along
    z_moved = memory.deviation(frame, np.linalg.norm(away - pose1[:3, 3], axis=-1)[None],
                               error, pose1[:3, 3])
    np.testing.assert_allclose(z_moved, 0.5 / ranges[None] / np.sqrt(2 * 0.01 ** 2), rtol=1e-9)
    assert (z_moved > 2).all()


def test_the_nearest_point_landing_in_a_cell_is_kept_and_other_frames_are_not_matched():
    pose = moved(np.eye(4), [0, 0, 0])
    far, near = np.array([0.0, 0.0, 20.0]), np.array([0.0, 0.0, 5.0])
    memory = RangeMemory(2)
    frame = np.zeros((2, 2), np.uint8)
    landing = np.array([[[2.0, 2.0], [2.5, 1.0]]])  # both land in cell (0, 0)
    memory.remember(frame, np.stack([far, near])[None], np.full((1, 2), 0.01), landing,
                    np.ones((1, 2), bool), 5, pose[:3, 3])
    z = memory.deviation(frame, np.array([[5.0, np.nan]]), np.full((1, 2), 0.01), pose[:3, 3])
    assert z[0, 0] == pytest.approx(0.0)
    assert np.isnan(z[0, 1])  # nothing landed in cell (0, 1)
    copy = memory.deviation(frame.copy(), np.array([[5.0, np.nan]]), np.full((1, 2), 0.01),
                            pose[:3, 3])  # a copy of the frame (detect_flow's callers)
    np.testing.assert_array_equal(copy, z)
    assert memory.deviation(np.ones((2, 2), np.uint8), np.ones((1, 2)), np.ones((1, 2)), pose[:3, 3]) is None
    memory.remember(np.full((2, 2), 7, np.uint8), np.zeros((1, 2, 3)), np.ones((1, 2)), landing,
                    np.zeros((1, 2), bool), 5, pose[:3, 3])
    memory.remember(np.full((2, 2), 7, np.uint8), np.zeros((1, 2, 3)), np.ones((1, 2)), landing,
                    np.zeros((1, 2), bool), 5, pose[:3, 3])
    assert memory.deviation(frame, np.ones((1, 2)), np.ones((1, 2)), pose[:3, 3]) is None
    assert len(memory) == 2


def test_cells_not_static_or_landing_outside_are_not_remembered():
    memory = RangeMemory(1)
    frame = np.zeros((2, 2), np.uint8)
    points = np.array([[[0.0, 0.0, 10.0], [0.0, 0.0, 10.0], [0.0, 0.0, 10.0]]])
    landing = np.array([[[2.0, 2.0], [-3.0, 2.0], [7.0, 2.0]]])
    memory.remember(frame, points, np.full((1, 3), 0.01), landing,
                    np.array([[False, True, True]]), 5, np.zeros(3))
    z = memory.deviation(frame, np.full((1, 3), 10.0), np.full((1, 3), 0.01), np.zeros(3))
    # cell 0: its own point was not static; the third lands in cell 1; the second outside.
    assert np.isnan(z[0, 0]) and z[0, 1] == pytest.approx(0.0) and np.isnan(z[0, 2])


def test_three_views_see_more_of_a_crossing_pedestrian_and_nothing_static(tmp_path):
    """With the renderer's exact flow: the three-view term covers more of the crossing scene's
    pedestrians (whose motion partly runs along their epipolar arcs, two-view ambiguous) and
    flags nothing in a static street."""
    from fisheyemotion.eval.evaluate import evaluate_sequence

    import fisheyemotion as fm
    from fisheyemotion import synth

    from .cameras import tumvi_kb

    cam = tumvi_kb(320, 240, 100.0)

    def run(name, frames, consistency):
        seq = synth.write_sequence(tmp_path / f"{name}-{consistency}", cam,
                                   synth.load_scenario(name), frames=frames, flow=False,
                                   progress=False, supersample=1)
        return evaluate_sequence(seq, fm.Params(range_consistency=consistency),
                                 exact_flow=True, ablation=False)

    two, three = run("crossing", 16, 0.0), run("crossing", 16, 2.0)
    assert three.objects.covered.sum() > 1.1 * two.objects.covered.sum()
    assert three.objects.detected.sum() >= two.objects.detected.sum()
    assert two.frames.fp_frame.sum() == three.frames.fp_frame.sum() == 0
    assert run("static_world", 12, 2.0).frames.fp_frame.sum() == 0


def test_the_documented_params_file_turns_it_on_and_bad_values_are_refused():
    from pathlib import Path

    import fisheyemotion as fm

    path = Path(__file__).resolve().parents[1] / "data" / "params" / "no_three_views.yaml"
    assert fm.Params.load(path).range_consistency == 0.0 == fm.Params.paper().range_consistency
    assert fm.Params().range_consistency == 1.5
    with pytest.raises(ValueError, match="range_consistency"):
        fm.Params(range_consistency=-1.0)


@given(st.integers(0, 2**31 - 1), st.floats(-0.8, 3.0), st.floats(0.5, 2.0))
@settings(max_examples=60, deadline=None)
def test_a_point_moving_along_the_travel_at_constant_speed_reads_as_one_static_point(
        seed, speed_ratio, lateral):
    """What three views can and cannot tell (docs/geometry.md, *Three views*): an object moving
    parallel to the camera's travel at a constant speed (oncoming, ``speed_ratio > 0`` of the
    camera's speed; preceding, ``< 0``) triangulates, as static, to the *same* world point
    ``C + k (X - C)`` from every pair, ``k = 1 / (1 + speed_ratio)``: ``(1 - k) Δ + k δ = 0``.
    Only a motion with a component across the travel (or a change of speed) moves it."""
    rng = np.random.default_rng(seed)
    travel = rng.normal(size=3)
    travel /= np.linalg.norm(travel)
    step = 0.4 * travel  # the camera's step between frames
    start = rng.normal(size=3) * 2.0
    side = np.cross(travel, rng.normal(size=3))
    side /= np.linalg.norm(side)
    point = start + 12.0 * travel + lateral * 3.0 * side  # ahead and beside the travel

    def camera(t):
        rotation, _ = np.linalg.qr(rng.normal(size=(3, 3)))
        pose = np.eye(4)
        pose[:3, :3] = rotation * np.sign(np.linalg.det(rotation))
        pose[:3, 3] = start + t * step
        return pose

    def fictitious(velocity, t0, t1):
        poses = [camera(t) for t in (t0, t1)]
        seen = [point + t * velocity for t in (t0, t1)]
        rays = [rays_of(x[None], pose)[0] for x, pose in zip(seen, poses, strict=True)]
        lam, ok = triangulate_range(rays[0], rays[1], poses[0], poses[1], far=1e9)
        assert ok
        return world_points(rays[0], lam, poses[0])

    along = -speed_ratio * step  # towards the camera when speed_ratio > 0
    first, second = fictitious(along, 0, 3), fictitious(along, 2, 5)
    np.testing.assert_allclose(second, first, atol=1e-7 * np.linalg.norm(point - start))
    k = 1.0 / (1.0 + speed_ratio)
    np.testing.assert_allclose(first, start + k * (point - start), atol=1e-7 * 12)
    # A crossing component of a tenth of the camera's speed moves the fictitious point.
    across = along + 0.1 * np.linalg.norm(step) * np.cross(travel, side)
    moved_by = np.linalg.norm(fictitious(across, 2, 5) - fictitious(across, 0, 3))
    assert moved_by > 1e-3
