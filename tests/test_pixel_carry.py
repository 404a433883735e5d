"""``Params.carry_share`` (:func:`fisheyemotion.flow.pixel_transfer`): the flagged cells carried
to the current frame by each pixel's own flow, not only by their cell's mean flow."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import fisheyemotion as fm
from fisheyemotion import synth
from fisheyemotion.flow import grid_gather, grid_transfer, pixel_transfer

from .cameras import tumvi_kb

G = 5


def _object_moving_across_still_cells(dx: float):
    """Cells rows 5-7, columns 10-11 (an object 10 px wide) whose pixels move ``dx`` right,
    while every cell's mean flow (as mixed with a still background) is 0."""
    rows, cols = 14, 24
    order = np.full((rows, cols), 0.001)
    order[5:8, 10:12] = 0.01
    flow = np.zeros((rows * G, cols * G, 2), np.float32)
    flow[25:40, 50:60, 0] = dx
    base = grid_transfer(np.zeros((rows, cols, 2), np.float32), order, G)
    return order, flow, base


def test_an_object_two_cells_wide_lands_where_its_pixels_do():
    """Its pixels x = 50..59 move 7 px to 57..66: cell 11 gets three of its five columns (60 %),
    cell 12 all five, cell 13 two (40 %)."""
    order, flow, base = _object_moving_across_still_cells(7.0)
    flagged = order > 0.005
    assert np.array_equal(grid_gather(order, base), order)  # the cells' flow left it in place
    # Cells 10 and 11 keep what the cells' flow put there (the carry adds the object where it
    # lands and never takes a more likely cell away); 12 and 13 are added as they are covered.
    for share, taken in ((0.6, [10, 11, 12]), (0.4, [10, 11, 12, 13]), (1.0, [10, 11, 12])):
        source = pixel_transfer(base, flow, order, flagged, G, share=share)
        out = grid_gather(order, source)
        now = np.argwhere(out > 0.005)
        assert sorted(set(now[:, 1])) == taken, share
        assert set(now[:, 0]) == {5, 6, 7}
        # Each row's added cells come from that row's object cells.
        for r, c in now[now[:, 1] >= 12]:
            assert source[r, c] // order.shape[1] == r


def test_nothing_flagged_or_nothing_moved_changes_nothing():
    order, flow, base = _object_moving_across_still_cells(7.0)
    none = np.zeros(order.shape, bool)
    np.testing.assert_array_equal(pixel_transfer(base, flow, order, none, G, share=0.6), base)
    still = np.zeros_like(flow)
    np.testing.assert_array_equal(
        pixel_transfer(base, still, order, order > 0.005, G, share=0.6), base)


def test_pixels_that_leave_the_image_or_have_no_flow_land_nowhere():
    order, flow, base = _object_moving_across_still_cells(7.0)
    flow[25:40, 50:60] = np.nan
    np.testing.assert_array_equal(pixel_transfer(base, flow, order, order > 0.005, G, share=0.2),
                                  base)
    flow[25:40, 50:60] = (-1e4, 0.0)
    np.testing.assert_array_equal(pixel_transfer(base, flow, order, order > 0.005, G, share=0.2),
                                  base)


@given(st.integers(0, 2**31 - 1), st.floats(0.05, 1.0))
@settings(max_examples=40, deadline=None)
def test_a_cell_only_ever_takes_a_more_likely_source_whose_pixels_cover_it(seed, share):
    rng = np.random.default_rng(seed)
    rows, cols = 10, 12
    order = rng.random((rows, cols))
    order[rng.random((rows, cols)) < 0.1] = np.nan
    cell_flow = rng.normal(0, 4, (rows, cols, 2)).astype(np.float32)
    base = grid_transfer(cell_flow, order, G)
    flow = (rng.normal(0, 6, (rows * G, cols * G, 2))
            + np.repeat(np.repeat(cell_flow, G, 0), G, 1)).astype(np.float32)
    cells = rng.random((rows, cols)) < 0.3
    out = pixel_transfer(base, flow, order, cells, G, share=share)
    rank = np.where(np.isnan(order), -np.inf, order).ravel()
    changed = out != base
    assert np.isin(out[changed], np.flatnonzero(cells)).all()  # only moved cells are sources
    before = np.where(base >= 0, rank[np.maximum(base, 0)], -np.inf)
    assert (rank[out[changed]] > before[changed]).all()
    # Brute force: a changed cell has at least `share` of its pixels landed on it by moved
    # cells' pixels, one of them from its new source.
    ys, xs = np.nonzero(np.repeat(np.repeat(cells, G, 0), G, 1))
    tc = np.floor((xs + flow[ys, xs, 0] + 0.5) / G)
    tr = np.floor((ys + flow[ys, xs, 1] + 0.5) / G)
    inside = (tc >= 0) & (tc < cols) & (tr >= 0) & (tr < rows)
    landed = (tr * cols + tc)[inside].astype(int)
    origin = ((ys // G) * cols + xs // G)[inside]
    for r, c in np.argwhere(changed):
        here = landed == r * cols + c
        assert here.sum() >= share * G * G
        assert out[r, c] in origin[here]
        assert rank[out[r, c]] == rank[origin[here]].max()
    # ... and an unchanged cell is one that is not covered enough, or whose most likely landing
    # cell is no more likely than its source.
    for r, c in np.argwhere(~changed):
        here = landed == r * cols + c
        assert here.sum() < share * G * G or rank[origin[here]].max() <= before[r, c]


@pytest.fixture(scope="module")
def crossing_exact():
    cam = tumvi_kb(640, 480, 200.0)
    renderer = synth.Renderer(cam, synth.load_scenario("crossing"))
    f0, f3 = renderer.render(9), renderer.render(12)
    flow = np.nan_to_num(renderer.flow(12, gap=3), nan=-1e4).astype(np.float32)
    return cam, renderer, f0, f3, flow


def test_a_crossing_pedestrian_is_carried_onto_itself(crossing_exact):
    """The crossing scene's pair 9 -> 12 with its exact flow (measured: coverage 48 -> 60 %, the
    cells the constraints flagged 36 -> 47 % of the pedestrian, static pixels 324 -> 342),
    without the road-spill trim, whose minimum piece drops the pedestrian's few cells carried
    beside it without the pixel carry."""
    cam, renderer, f0, f3, flow = crossing_exact
    g0, g3 = (cv2.cvtColor(f.image, cv2.COLOR_BGR2GRAY) for f in (f0, f3))
    obj = f3.moving > 0
    out = {s: fm.MotionDetector(cam, params=fm.Params(carry_share=s, road_spill=0.0),
                                roi=renderer.roi())
           .detect_flow(flow, f0.pose, f3.pose, prev=g0, curr=g3) for s in (0.0, 0.6)}
    before, after = out[0.0], out[0.6]
    assert (after.mask > 0)[obj].mean() > (before.mask > 0)[obj].mean() + 0.08
    assert (after.cell_mask > 0)[obj].mean() > (before.cell_mask > 0)[obj].mean() + 0.08
    assert ((after.mask > 0) & ~obj).sum() <= 1.2 * ((before.mask > 0) & ~obj).sum()
    # The likelihood on the previous frame's cells is the same: only where it lands changed.
    np.testing.assert_array_equal(after.grid.likelihood, before.grid.likelihood)
