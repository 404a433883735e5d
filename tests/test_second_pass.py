"""``Params.second_pass`` (:mod:`fisheyemotion.second_pass`): the flow measured again near the
flagged cells, warped back by its own first result."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import fisheyemotion as fm
from fisheyemotion import synth
from fisheyemotion.flow import FlowEstimator
from fisheyemotion.second_pass import MARGIN, BoxFlows, better_explained, near_cells, second_flow

from .cameras import tumvi_kb


def _textured(seed: int, h: int = 160, w: int = 200) -> np.ndarray:
    rng = np.random.default_rng(seed)
    noise = rng.uniform(0, 255, (h // 4, w // 4)).astype(np.float32)
    return np.clip(cv2.resize(noise, (w, h), interpolation=cv2.INTER_CUBIC), 0, 255).astype(
        np.uint8)


def _shifted(image: np.ndarray, dx: float) -> np.ndarray:
    """``image`` moved right by ``dx`` pixels: ``image(u) = out(u + dx)``."""
    m = np.float32([[1, 0, dx], [0, 1, 0]])
    return cv2.warpAffine(image, m, image.shape[::-1], flags=cv2.INTER_CUBIC,
                          borderMode=cv2.BORDER_REFLECT)


@given(st.integers(0, 2**31 - 1), st.integers(0, 4))
@settings(max_examples=40, deadline=None)
def test_near_cells_are_those_within_reach_in_chebyshev_distance(seed, reach):
    rng = np.random.default_rng(seed)
    flagged = rng.random((12, 15)) < 0.05
    near = near_cells(flagged, reach)
    r, c = np.nonzero(flagged)
    rr, cc = np.mgrid[:12, :15]
    if len(r):
        distance = np.max(np.abs(np.stack([rr[..., None] - r, cc[..., None] - c])), axis=0)
        expected = distance.min(axis=-1) <= reach
    else:
        expected = np.zeros_like(flagged)
    np.testing.assert_array_equal(near, expected)


def test_a_second_pass_measures_the_rest_of_a_motion_the_first_fell_short_of():
    """A 6 px motion of which the first pass measured 3 px: the second pass, warped back by the
    3 px, measures the rest on the cells asked for and leaves every other pixel as it was."""
    grid = 5
    prev = _textured(1)
    curr = _shifted(prev, 6.0)
    first = np.zeros(prev.shape + (2,), np.float32)
    first[..., 0] = 3.0
    cells = np.zeros((prev.shape[0] // grid, prev.shape[1] // grid), bool)
    cells[10:18, 12:20] = True
    out = second_flow(prev, curr, first, cells, grid, FlowEstimator(fm.Params()))
    inside = np.repeat(np.repeat(cells, grid, 0), grid, 1)
    assert np.median(np.abs(out[inside][:, 0] - 6.0)) < 0.2
    assert np.median(np.abs(out[inside][:, 1])) < 0.2
    np.testing.assert_array_equal(out[~inside], first[~inside])
    assert out is not first and (first[..., 0] == 3.0).all()


def test_each_group_of_cells_is_measured_on_its_own_box():
    """Two groups far apart: each box holds its group and MARGIN pixels around it, not the
    image between them (the estimator sees the boxes' sizes)."""
    grid = 5
    prev = _textured(2, 240, 320)
    curr = _shifted(prev, 2.0)
    first = np.zeros(prev.shape + (2,), np.float32)
    cells = np.zeros((48, 64), bool)
    cells[4:8, 4:8] = True      # pixels 20-40
    cells[36:40, 52:56] = True  # pixels 180-200 down, 260-280 across
    seen = []

    def estimator(a, b):
        seen.append(a.shape)
        return FlowEstimator(fm.Params())(a, b)

    out = second_flow(prev, curr, first, cells, grid, estimator)
    assert sorted(seen) == [(20 + 2 * MARGIN, 20 + 2 * MARGIN)] * 2
    inside = np.repeat(np.repeat(cells, grid, 0), grid, 1)
    assert np.median(np.abs(out[inside][:, 0] - 2.0)) < 0.2
    np.testing.assert_array_equal(out[~inside], 0.0)


def test_no_cells_no_second_pass():
    prev = _textured(3)
    first = np.full(prev.shape + (2,), 1.5, np.float32)

    def estimator(a, b):
        raise AssertionError("not called")

    out = second_flow(prev, prev, first, np.zeros((32, 40), bool), 5, estimator)
    np.testing.assert_array_equal(out, first)


def test_better_explained_asks_a_margin_of_the_new_flow():
    grid = 5
    prev = _textured(4)
    curr = _shifted(prev, 4.0)
    right = np.zeros(prev.shape + (2,), np.float32)
    right[..., 0] = 4.0
    wrong = np.zeros_like(right)
    r, c = np.nonzero(np.ones((32, 40), bool))
    r, c = r[(r > 2) & (r < 29) & (c > 2) & (c < 37)], c[(r > 2) & (r < 29) & (c > 2) & (c < 37)]
    assert better_explained(prev, curr, wrong, right, grid, r, c, (32, 40)).mean() > 0.95
    assert not better_explained(prev, curr, right, wrong, grid, r, c, (32, 40)).any()
    assert not better_explained(prev, curr, right, right, grid, r, c, (32, 40)).any()


# ---- in the detector -----------------------------------------------------------------------

@pytest.fixture(scope="module")
def crossing_pair():
    cam = tumvi_kb(640, 480, 200.0)
    renderer = synth.Renderer(cam, synth.load_scenario("crossing"))
    return cam, renderer, renderer.render(9), renderer.render(12)


def test_the_second_pass_covers_more_of_a_crossing_pedestrian_and_not_more_around_it(
        crossing_pair):
    """Measured on the crossing scene's pair 9 -> 12: coverage 56 -> 68 %, static pixels
    flagged 3,005 -> 2,727 (where the new flow explains the frames better, a cell's likelihood
    is the new one, lower too). Without the road-spill trim, which would take some of either
    mask's static pixels and blur what the second pass itself does."""
    cam, renderer, f0, f3 = crossing_pair
    out = {g: fm.MotionDetector(cam, params=fm.Params(second_pass=g, road_spill=0.0),
                                roi=renderer.roi())
           .detect(f0.image, f3.image, f0.pose, f3.pose) for g in (0, 2)}
    obj = f3.moving > 0
    before, after = (out[g].mask > 0 for g in (0, 2))
    assert after[obj].mean() > before[obj].mean() + 0.08
    assert (after & ~obj).sum() <= (before & ~obj).sum()
    assert (out[2].likelihood < out[0].likelihood).any()  # lowered where it explains better


def test_a_dis_second_pass_measures_with_dis_whatever_the_detectors_flow(crossing_pair,
                                                                         monkeypatch):
    cam, renderer, f0, f3 = crossing_pair
    made = []
    real = cv2.DISOpticalFlow_create

    def create(preset):
        made.append(preset)
        return real(preset)

    monkeypatch.setattr(cv2, "DISOpticalFlow_create", create)
    for method, presets in (("same", []), ("dis-fast", [cv2.DISOPTICAL_FLOW_PRESET_FAST])):
        made.clear()
        det = fm.MotionDetector(cam, params=fm.Params(second_pass_flow=method),
                                roi=renderer.roi())
        det.detect(f0.image, f3.image, f0.pose, f3.pose)
        assert sorted(set(made)) == presets  # Farneback's first pass creates no DIS object


def test_only_the_detectors_own_flow_is_measured_again(crossing_pair):
    """``detect_flow`` of the array ``flow()`` returned is ``detect``; a flow from elsewhere
    (here a copy of the same) is taken as it is, as with the pass off."""
    cam, renderer, f0, f3 = crossing_pair

    def detector(**kw):
        return fm.MotionDetector(cam, params=fm.Params(**kw), roi=renderer.roi())

    g0, g3 = (cv2.cvtColor(f.image, cv2.COLOR_BGR2GRAY) for f in (f0, f3))
    whole = detector().detect(f0.image, f3.image, f0.pose, f3.pose)
    det = detector()
    own = det.flow(g0, g3, f0.pose, f3.pose)
    np.testing.assert_array_equal(
        det.detect_flow(own, f0.pose, f3.pose, prev=g0, curr=g3).likelihood, whole.likelihood)
    det = detector()
    foreign = det.flow(g0, g3, f0.pose, f3.pose).copy()
    taken = det.detect_flow(foreign, f0.pose, f3.pose, prev=g0, curr=g3)
    off = detector(second_pass=0).detect(f0.image, f3.image, f0.pose, f3.pose)
    np.testing.assert_array_equal(taken.likelihood, off.likelihood)
    assert (whole.likelihood > off.likelihood).any()


def test_box_sides_are_rounded_up_to_the_step_and_still_hold_the_group():
    grid = 5
    prev = _textured(5, 240, 320)
    cells = np.zeros((48, 64), bool)
    cells[3:6, 60:63] = True  # near the right edge: the box is shifted inwards, not cut
    seen = []

    def estimator(a, b):
        seen.append(a.shape)
        return np.zeros(a.shape + (2,), np.float32)

    second_flow(prev, prev, np.zeros(prev.shape + (2,), np.float32), cells, grid, estimator,
                size_step=32)
    (h, w), = seen
    assert h % 32 == 0 and w % 32 == 0 and h >= 15 + 2 * MARGIN and w <= 320


def test_box_flows_keep_one_estimator_per_size_and_forget_the_oldest():
    made = []

    def make():
        made.append(object())
        n = len(made)
        return lambda a, b: np.full(a.shape + (2,), n, np.float32)

    flows = BoxFlows(make, keep=2)
    a, b, c = (np.zeros(s, np.uint8) for s in ((48, 48), (48, 64), (64, 64)))
    assert flows(a, a)[0, 0, 0] == 1 and flows(b, b)[0, 0, 0] == 2
    assert flows(a, a)[0, 0, 0] == 1 and len(made) == 2    # the same size: the same estimator
    flows(c, c)                                             # a third size: (48, 64) goes
    assert len(made) == 3 and flows(a, a)[0, 0, 0] == 1
    flows(b, b)
    assert len(made) == 4
