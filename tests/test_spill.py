"""The flow's spill onto the road trimmed from the mask (fisheyemotion.spill)."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
from hypothesis import given
from hypothesis import strategies as st
from scipy import ndimage

import fisheyemotion as fm
from fisheyemotion import synth
from fisheyemotion.flow import grid_average, grid_centres
from fisheyemotion.road import Road
from fisheyemotion.segment import Region
from fisheyemotion.spill import PIECE, road_explained, trim_regions

GRID = 5
ROOT = Path(__file__).resolve().parents[1]
#: The bundled scenes' camera and scenes: a road texture as the demo renders it.
FRONT = fm.calib.load(ROOT / "data" / "calib" / "front_kb_640x480.yaml")


def _gray(frame):
    return cv2.cvtColor(frame.image, cv2.COLOR_BGR2GRAY)


def _spill_case(scenario: str, gap: int = 3):
    """A pair of a bundled scene (frames 0 and ``gap``), the moving objects' pixels in the
    second frame, and a mask of them with a 6-px ring of spill around, every pixel carried with
    the exact motion of the nearest object pixel (as a flow smoothed over an object's
    surroundings carries them)."""
    renderer = synth.Renderer(FRONT, synth.load_scenario(scenario))
    before, after = renderer.render(0), renderer.render(gap)
    flow = renderer.flow(gap, gap=gap)
    moving = after.moving > 0
    mask = cv2.dilate(moving.view(np.uint8), np.ones((13, 13), np.uint8)) > 0
    # The objects' exact motion splatted onto the second frame, then spread to the ring.
    ys, xs = np.nonzero((before.moving > 0) & np.isfinite(flow).all(axis=-1))
    motion = flow[ys, xs]
    to_x, to_y = np.rint(xs + motion[:, 0]).astype(int), np.rint(ys + motion[:, 1]).astype(int)
    inside = (to_x >= 0) & (to_x < moving.shape[1]) & (to_y >= 0) & (to_y < moving.shape[0])
    known = np.zeros(moving.shape, bool)
    carried = np.zeros((*moving.shape, 2), np.float32)
    carried[to_y[inside], to_x[inside]] = motion[inside]
    known[to_y[inside], to_x[inside]] = True
    _, (iy, ix) = ndimage.distance_transform_edt(~known, return_indices=True)
    return before, after, moving, mask, carried[iy, ix]


RAYS = FRONT.unproject(grid_centres(FRONT.width, FRONT.height, GRID))[0]


def _explained(before, after, mask, carried, road=None, *, pose1=None, still=False):
    """:func:`road_explained` on a case's pair, its motion averaged over each cell (as the
    detector carries cells)."""
    return road_explained(_gray(before), _gray(after), mask, RAYS, FRONT, before.pose,
                          after.pose if pose1 is None else pose1,
                          Road() if road is None else road, grid_average(carried, GRID),
                          grid=GRID, tolerance=15.0, still=still)


def _inner(pixels, carried):
    """``pixels`` without those within a window (half a cell) of their boundary, whose
    window holds some background, and without those whose window came from outside the
    previous frame's view (a car entering it: no motion explains them)."""
    h, w = pixels.shape
    v, u = np.mgrid[0:h, 0:w]
    x, y = np.rint(u - carried[..., 0]).astype(int), np.rint(v - carried[..., 1]).astype(int)
    seen = (x >= 0) & (x < w) & (y >= 0) & (y < h)
    seen[seen] = FRONT.valid_pixel_mask()[y[seen], x[seen]]
    window = np.ones((GRID, GRID), np.uint8)
    return cv2.erode((pixels & seen).view(np.uint8), window) > 0


def test_the_road_explains_the_spill_around_a_pedestrian_not_the_pedestrian():
    before, after, moving, mask, carried = _spill_case("crossing")
    explained = _explained(before, after, mask, carried)
    road = mask & ~moving & (after.ids == 0) & np.isfinite(after.range) & (after.range < 1e3)
    assert road.sum() > 200
    assert explained[road].mean() > 0.2
    assert explained[_inner(moving, carried)].mean() < 0.02
    assert not explained[~mask].any()
    # Without a road nothing is explained; without the margin over the carried motion, a plain
    # block both explain would be: the carried motion as good as the road's explains nothing.
    assert not _explained(before, after, mask, carried, Road.unknown()).any()
    no_motion = np.full_like(carried, np.nan)
    assert _explained(before, after, mask, no_motion)[road].mean() > 0.5


def test_without_parallax_the_road_explains_nothing():
    """Frames of the same pair with the second pose put back on the first: the road point of
    every ray is its point at infinity, and road and far field cannot be told apart."""
    before, after, moving, mask, carried = _spill_case("crossing")
    assert not _explained(before, after, mask, carried, pose1=before.pose).any()


def test_a_still_camera_explains_every_static_pixel_road_or_not():
    before, after, moving, mask, carried = _spill_case("static_ego")
    static = mask & ~moving & np.isfinite(after.range)
    explained = _explained(before, after, mask, carried, Road.unknown(), still=True)
    assert explained[static & (after.ids > 0)].mean() > 0.5  # a parked car, not road
    assert explained[static].mean() > 0.5
    assert explained[_inner(moving, carried)].mean() < 0.02


def _region(label, pixels):
    ys, xs = np.nonzero(pixels)
    x, y = int(xs.min()), int(ys.min())
    return Region(label, (x, y, int(xs.max()) - x + 1, int(ys.max()) - y + 1), int(pixels.sum()),
                  0.01, (float(xs.mean()), float(ys.mean())))


def test_trim_removes_the_spill_and_updates_the_region():
    labels = np.zeros((60, 80), np.int32)
    labels[10:40, 20:40] = 1                       # the object
    labels[40:50, 15:45] = 1                       # spill below it
    labels[5:15, 60:70] = 2                        # another region, untouched
    explained = np.zeros(labels.shape, bool)
    explained[40:50, 15:45] = True
    explained[20:24, 28:32] = True                 # enclosed by the object: stays
    regions = [_region(1, labels == 1), _region(2, labels == 2)]
    mask, kept = trim_regions(labels, regions, explained, grid=GRID)
    expected = (labels == 2) | (labels == 1) & ~explained | (labels == 1) & np.isin(
        np.arange(60)[:, None], range(20, 24)) & np.isin(np.arange(80), range(28, 32))
    np.testing.assert_array_equal(mask > 0, expected)
    assert kept[0] == regions[0]._replace(bbox=(20, 10, 20, 30), area=600,
                                          centroid=(29.5, 24.5))
    assert kept[1] is regions[1]


def test_trim_leaves_a_region_whole_where_it_would_split_it_and_drops_crumbs():
    side = int(np.ceil(np.sqrt(PIECE * GRID * GRID))) + 1
    labels = np.zeros((2 * side + 20, 2 * side + 40), np.int32)
    labels[5:5 + side, 5:5 + 2 * side + 20] = 1     # two big parts with road between them
    explained = np.zeros(labels.shape, bool)
    explained[:, 5 + side:5 + side + 20] = True
    regions = [_region(1, labels == 1)]
    mask, kept = trim_regions(labels, regions, explained, grid=GRID)
    np.testing.assert_array_equal(mask > 0, labels == 1)
    assert kept == regions
    # One big part and a crumb beyond the road: the crumb goes with the road.
    labels[:] = 0
    labels[5:5 + side, 5:5 + side + 20] = 1
    labels[5:9, 5 + side + 20:5 + side + 24] = 1
    regions = [_region(1, labels == 1)]
    mask, kept = trim_regions(labels, regions, explained, grid=GRID)
    big = np.zeros(labels.shape, bool)
    big[5:5 + side, 5:5 + side] = True
    np.testing.assert_array_equal(mask > 0, big)
    assert [r.bbox for r in kept] == [(5, 5, side, side)]
    # What the road leaves is smaller than a piece of an object: the region goes.
    labels[:] = 0
    labels[5:5 + side, 5:5 + side + 20] = 1
    labels[5:9, 5 + side + 20:5 + side + 24] = 1
    small = labels > 0
    small[:, 5:5 + side - 4] &= False               # only a few cells left beside the road
    explained_small = (labels > 0) & ~small | explained
    mask, kept = trim_regions(labels, regions, explained_small & (labels > 0), grid=GRID)
    assert not mask.any() and kept == []
    # All of it road: the region goes.
    mask, kept = trim_regions(labels, regions, labels > 0, grid=GRID)
    assert not mask.any() and kept == []


@given(seed=st.integers(0, 2**32 - 1), regions=st.integers(1, 4), fill=st.floats(0.0, 0.6))
def test_trim_only_removes_and_leaves_one_piece_of_each_part(seed, regions, fill):
    rng = np.random.default_rng(seed)
    labels = np.zeros((40, 50), np.int32)
    for label in range(1, regions + 1):
        y, x = rng.integers(0, 30), rng.integers(0, 40)
        labels[y:y + rng.integers(3, 12), x:x + rng.integers(3, 12)] = label
    listed = [_region(k, labels == k) for k in range(1, regions + 1) if (labels == k).any()]
    explained = rng.random(labels.shape) < fill
    mask, kept = trim_regions(labels, listed, explained, grid=1)
    before = labels > 0
    out = mask > 0
    assert not (out & ~before).any()
    parts_before, part = cv2.connectedComponents(before.view(np.uint8), connectivity=8)
    _, piece = cv2.connectedComponents(out.view(np.uint8), connectivity=8)
    for k in range(1, parts_before):
        assert len(np.unique(piece[(part == k) & out])) <= 1
    # The regions listed are those with pixels left, each box around them.
    assert {r.label for r in kept} == set(np.unique(labels[out])) - {0}
    for r in kept:
        x, y, w, h = r.bbox
        own = (labels == r.label) & out
        assert own[y:y + h, x:x + w].sum() == own.sum() == r.area
    if not (explained & before).any():
        np.testing.assert_array_equal(out, before)
        assert kept == listed


def test_detector_trims_only_mask_pixels():
    """In a stream the trim removes mask pixels, never adds them, and changes neither the
    likelihood nor the pose step's cells; Params.paper() and road_spill=0 do not trim."""
    renderer = synth.Renderer(FRONT, synth.load_scenario("crossing"), supersample=1)
    frames = [renderer.render(k) for k in range(8)]
    params = fm.Params()
    on = fm.MotionDetector(FRONT, None, params, roi=renderer.roi())
    off = fm.MotionDetector(FRONT, None, params.replace(road_spill=0.0), roi=renderer.roi())
    removed = 0
    for frame in frames:
        a, b = on.apply(frame.image, frame.pose), off.apply(frame.image, frame.pose)
        if a is None:
            continue
        np.testing.assert_array_equal(a.likelihood, b.likelihood)
        np.testing.assert_array_equal(a.cell_mask, b.cell_mask)
        assert not (a.mask > b.mask).any()
        removed += int((a.mask < b.mask).sum())
        for r in a.regions:
            x, y, w, h = r.bbox
            assert a.mask[y:y + h, x:x + w].any()
    assert removed > 0
    assert fm.Params.paper().road_spill == 0
