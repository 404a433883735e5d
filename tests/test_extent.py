"""Regions grown to their object's extent in the image (fisheyemotion.extent)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import fisheyemotion as fm
from fisheyemotion import synth
from fisheyemotion.extent import SLOWER, SMOOTHING, _smoothed, grow_to_extent
from fisheyemotion.segment import segment_cells

from .cameras import tumvi_kb

THRESHOLD, GRID = 0.004, 5
H, W = 120, 160


def _scene(seed: int = 0):
    """A bright textured square object (rows 30-79, cols 40-99) on a darker textured background;
    its upper-left part scored above the threshold, the rest of it weakly, the background far
    below (likelihood on pixels, cells of 5 px)."""
    rng = np.random.default_rng(seed)
    gray = rng.integers(20, 60, (H, W)).astype(np.uint8)
    gray[30:80, 40:100] = rng.integers(180, 230, (50, 60))
    cells = np.full((H // GRID, W // GRID), 0.1 * THRESHOLD * 0.5)
    cells[6:16, 8:20] = 0.5 * THRESHOLD     # the object, weakly
    cells[6:11, 8:14] = 2 * THRESHOLD       # its detected part
    return gray, cells


def _grown(gray, cells, **kw):
    _, regions, labels = segment_cells(cells, threshold=THRESHOLD, grid=GRID, min_area=0,
                                       with_labels=True)
    likelihood = np.repeat(np.repeat(cells, GRID, 0), GRID, 1).astype(np.float32)
    options = {"threshold": THRESHOLD, "reach": 0.5, "static_fraction": 0.1, **kw}
    mask, grown = grow_to_extent(labels, regions, GRID, gray, likelihood, **options)
    before = np.repeat(np.repeat(labels > 0, GRID, 0), GRID, 1)
    return mask > 0, grown, before, regions


def test_a_region_grows_to_its_objects_image_boundary():
    gray, cells = _scene()
    mask, grown, before, regions = _grown(gray, cells, reach=2.0)
    obj = np.zeros((H, W), bool)
    obj[30:80, 40:100] = True
    assert before[obj].mean() < 0.35                   # the detection: a corner of the object
    assert mask[obj].mean() > 0.9                      # grown: nearly all of it
    assert (mask & ~obj).sum() < 0.03 * obj.sum()      # and little of the background
    assert mask[before].all()                          # nothing it had is lost
    # The region describes the grown pixels.
    (region,) = grown
    ys, xs = np.nonzero(mask)
    assert region.area == mask.sum()
    assert region.bbox == (xs.min(), ys.min(), xs.max() - xs.min() + 1, ys.max() - ys.min() + 1)
    assert region.centroid == pytest.approx((xs.mean(), ys.mean()))
    assert (region.label, region.mean_likelihood) == (regions[0].label,
                                                       regions[0].mean_likelihood)


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), reach=st.floats(0.1, 2.0))
def test_growth_never_leaves_the_reach_nor_loses_a_pixel(seed, reach):
    """On an image without edges and likelihood everywhere weak, the growth stops at the crop:
    ``reach`` times the box's larger side beyond the box (8 px at least)."""
    rng = np.random.default_rng(seed)
    cells = np.full((H // GRID, W // GRID), 0.5 * THRESHOLD)
    r0, c0 = rng.integers(2, 14), rng.integers(2, 20)
    cells[r0:r0 + 4, c0:c0 + 6] = 2 * THRESHOLD
    gray = np.full((H, W), 128, np.uint8)
    mask, (region,), before, (old,) = _grown(gray, cells, reach=reach)
    x, y, w, h = old.bbox
    r = max(8, int(reach * max(w, h)))
    ys, xs = np.nonzero(mask)
    assert xs.min() >= x - r and xs.max() < x + w + r
    assert ys.min() >= y - r and ys.max() < y + h + r
    assert mask[before].all()


def test_the_crops_border_is_background_where_nothing_else_is():
    """With no background marker inside the crop (the background scored weakly, no residuals),
    the crop's border where the reach ends it still is one: the growth stops at the object's
    image boundary, not at the crop (cv2.watershed overwrites the outermost pixels' markers).
    The frame's own edge is not a marker: an object may go on beyond it."""
    gray, cells = _scene()
    cells[:] = 0.5 * THRESHOLD                 # nothing is far below the threshold
    cells[6:11, 8:14] = 2 * THRESHOLD
    obj = np.zeros((H, W), bool)
    obj[30:80, 40:100] = True
    # The crop (36 px around the region's box) ends inside the frame but at its top.
    mask, _, before, _ = _grown(gray, cells, reach=1.2)
    assert mask[obj].mean() > 0.9
    assert (mask & ~obj).sum() < 0.03 * obj.sum()
    assert mask[before].all()
    # The crop is the whole frame: no border is a marker, and the growth reaches the frame's
    # edges (but their outermost pixels, which the watershed keeps as lines).
    mask, *_ = _grown(gray, cells, reach=3.0)
    assert mask[1:-1, 1:-1].all()


def test_unscored_pixels_join_only_as_enclosed_holes():
    gray, cells = _scene()
    cells[11:16, 8:20] = 0.0          # the object's lower part: unscored (a plain surface)
    cells[6:11, 20:30] = 0.0          # unscored background beside the region
    hole = np.zeros_like(cells, bool)
    cells[7:10, 10:12] = 0.0          # an unscored hole inside the detected part
    hole[7:10, 10:12] = True
    mask, *_ = _grown(gray, cells, reach=2.0)
    px = lambda c: np.repeat(np.repeat(c, GRID, 0), GRID, 1)  # noqa: E731
    beside = np.zeros_like(cells, bool)
    beside[6:11, 20:30] = True
    assert mask[px(hole)].all()
    assert not mask[px(beside) & (gray < 100)].any()


def test_cells_slower_than_the_region_are_background():
    """Cells that move less than SLOWER times the region's mean residual flow do not join,
    however weak or strong their likelihood."""
    gray, cells = _scene()
    residual = np.zeros(cells.shape + (2,))
    residual[6:16, 8:20] = (6.0, 0.0)                  # the object moves 6 px
    residual[11:16, 8:20] = (0.9 * SLOWER * 6, 0.0)    # its lower part: slower
    mask, *_ = _grown(gray, cells, residual=residual, reach=2.0)
    lower = np.zeros((H, W), bool)
    lower[56:80, 40:100] = True
    assert mask[lower].mean() < 0.05
    residual[11:16, 8:20] = (1.1 * SLOWER * 6, 0.0)    # fast enough
    mask, *_ = _grown(gray, cells, residual=residual, reach=2.0)
    assert mask[lower].mean() > 0.9


def test_a_part_scored_far_below_that_moves_like_the_object_joins_it_where_residuals_decide():
    """A plain part of the object, or one near the epipole, is scored far below the threshold
    (below ``static_fraction`` of it); where the residuals decide (a stream's scene model
    informs them) and its residual moves like the region's it is left to the flooding and
    joins, where it is slower it stays out, and the background, scored far below and not
    moving, stays out too. Otherwise the likelihood keeps it out."""
    gray, cells = _scene()
    lower = np.zeros((H, W), bool)
    lower[56:80, 40:100] = True
    cells[11:16, 8:20] = 0.5 * 0.1 * THRESHOLD         # the object's lower part: far below
    residual = np.zeros(cells.shape + (2,))            # the background does not move
    residual[6:16, 8:20] = (6.0, 0.0)                  # the object moves 6 px, all of it
    decides = {"residual": residual, "reach": 2.0, "residual_decides": True}
    alone, *_ = _grown(gray, cells, reach=2.0)         # without residuals: the likelihood
    single, *_ = _grown(gray, cells, residual=residual, reach=2.0)  # a single pair's residual
    mask, *_ = _grown(gray, cells, **decides)
    assert alone[lower].mean() < 0.05 and single[lower].mean() < 0.05
    assert mask[lower].mean() > 0.9
    background = np.ones((H, W), bool)
    background[30:80, 40:100] = False
    assert (mask & background).sum() < 0.03 * mask.sum()
    residual[11:16, 8:20] = (0.9 * SLOWER * 6, 0.0)    # slower: background again
    mask, *_ = _grown(gray, cells, **decides)
    assert mask[lower].mean() < 0.05
    residual[11:16, 8:20] = np.nan                     # unknown (not scored): the likelihood
    mask, *_ = _grown(gray, cells, **decides)
    assert mask[lower].mean() < 0.05


def test_a_region_keeps_the_pixels_past_the_last_whole_cell():
    """On a frame whose size is not a multiple of the grid the mask's last pixels take the last
    cells' values (``grid_upsample``); the grown mask keeps them."""
    from fisheyemotion.flow import grid_upsample

    h, w = H + 3, W + 4                   # 3 rows and 4 columns past the last whole cell
    rng = np.random.default_rng(1)
    gray = rng.integers(20, 60, (h, w)).astype(np.uint8)
    cells = np.full((H // GRID, W // GRID), 0.05 * THRESHOLD)
    cells[-4:, -5:] = 2 * THRESHOLD       # a region in the bottom-right corner
    _, regions, labels = segment_cells(cells, threshold=THRESHOLD, grid=GRID, min_area=0,
                                       with_labels=True)
    likelihood = grid_upsample(cells.astype(np.float32), GRID, w, h)
    mask, _ = grow_to_extent(labels, regions, GRID, gray, likelihood, threshold=THRESHOLD,
                             reach=0.5, static_fraction=0.1)
    before = grid_upsample((labels > 0).astype(np.uint8), GRID, w, h) > 0
    assert before[H:, :].any() and before[:, W:].any()
    assert (mask > 0)[before].all()


def test_no_regions_no_mask():
    gray, cells = _scene()
    mask, regions = grow_to_extent(np.zeros(cells.shape, np.int32), [], GRID, gray,
                                   np.zeros((H, W), np.float32), threshold=THRESHOLD,
                                   reach=0.5, static_fraction=0.1)
    assert regions == [] and not mask.any() and mask.dtype == np.uint8


def test_the_pipeline_grows_its_mask_on_the_current_frame_and_keeps_its_likelihood():
    cam = tumvi_kb(640, 480, 200.0)
    scenario = synth.load_scenario("crossing")
    renderer = synth.Renderer(cam, scenario)
    f0, f3 = renderer.render(10), renderer.render(13)
    # The growth alone: without the closing of regions over small gaps, which covers some of
    # what it grows into (test_detect.py tests that).
    out = {reach: fm.MotionDetector(cam, params=fm.Params(extent_reach=reach, region_gap=0),
                                    roi=renderer.roi()).detect(f0.image, f3.image, f0.pose,
                                                               f3.pose)
           for reach in (0.0, 0.5)}
    plain, grown = (out[r].mask > 0 for r in (0.0, 0.5))
    np.testing.assert_array_equal(out[0.0].likelihood, out[0.5].likelihood)
    assert grown[plain].all() and grown.sum() > plain.sum()
    obj = f3.moving > 0
    assert 0 < plain[obj].mean() < grown[obj].mean()
    iou = [(m & obj).sum() / (m | obj).sum() for m in (plain, grown)]
    assert iou[1] > iou[0] + 0.05   # measured 0.31 -> 0.36
    # A single pair's static prediction is the road and the far field: the likelihood marks
    # the background, whatever extent_residual says (it needs a stream's scene model).
    single = fm.MotionDetector(cam, params=fm.Params(extent_residual=False, region_gap=0),
                               roi=renderer.roi())
    np.testing.assert_array_equal(
        single.detect(f0.image, f3.image, f0.pose, f3.pose).mask, out[0.5].mask)


def test_a_stream_grows_over_the_parts_its_residuals_say_move_with_the_object():
    """In a stream the scene model informs the residual flows: the crossing pedestrian's
    masks cover more of it with ``extent_residual`` and hardly more of the static scene
    (measured with the result carried cell by cell, ``carry_share=0``, and not grown by the
    flow, ``grow=0``, to see the growth on the image alone)."""
    cam = tumvi_kb(640, 480, 200.0)
    renderer = synth.Renderer(cam, synth.load_scenario("crossing"))
    frames = [renderer.render(k) for k in range(12)]
    covered, static = {}, {}
    for on in (False, True):
        params = fm.Params(extent_residual=on, carry_share=0.0, grow=0)
        det = fm.MotionDetector(cam, params=params, roi=renderer.roi())
        results = [(det.apply(f.image, f.pose), f.moving > 0) for f in frames]
        covered[on] = np.array([((r.mask > 0) & obj).sum() for r, obj in results if r])
        static[on] = sum(((r.mask > 0) & ~obj).sum() for r, obj in results if r)
    assert (covered[True] >= covered[False]).all()
    assert covered[True].sum() > 1.02 * covered[False].sum()    # measured 1.04
    assert static[True] < 1.05 * static[False]                  # measured 1.03


def test_extent_parameters_are_checked_and_off_in_the_papers_pipeline():
    assert fm.Params.paper().extent_reach == 0.0
    for name in ("extent_reach", "extent_static"):
        with pytest.raises(ValueError, match=name):
            fm.Params(**{name: -1.0})


def test_the_documented_coverage_file_adds_the_extension():
    """(The files that turn the extent or its residual off: tests/test_params_files.py.)"""
    from pathlib import Path

    more = fm.Params.load(Path(__file__).resolve().parents[1] / "data" / "params"
                          / "coverage.yaml")
    assert more == fm.Params(extend_threshold=0.002)


@given(st.integers(0, 2**31 - 1))
@settings(max_examples=60, deadline=None)
def test_a_crop_is_smoothed_as_the_whole_frame_is(seed):
    """The flooding's smoothing is done per crop (with the Gaussian's reach around it): the
    same pixels as the whole frame smoothed, at the frame's edges too."""
    rng = np.random.default_rng(seed)
    h, w = (int(v) for v in rng.integers(3, 90, 2))
    gray = rng.integers(0, 256, (h, w)).astype(np.uint8)
    y0, x0 = int(rng.integers(0, h)), int(rng.integers(0, w))
    y1, x1 = int(rng.integers(y0 + 1, h + 1)), int(rng.integers(x0 + 1, w + 1))
    whole = cv2.GaussianBlur(gray, (0, 0), SMOOTHING)
    np.testing.assert_array_equal(_smoothed(gray, (y0, y1, x0, x1)), whole[y0:y1, x0:x1])
