"""MotionDetector.stream: apply()'s results, one frame pair's decision beside the next pair's flow."""

from __future__ import annotations

import threading

import cv2
import numpy as np
import pytest

import fisheyemotion as fm
from fisheyemotion import synth

from .cameras import tumvi_kb

CAM = tumvi_kb(320, 240, 100.0)
STREET = synth.parse_scenario({
    "name": "stream", "frames": 10, "ego": {"speed_kmh": 20},
    "camera": {"position": [2, 0, 1.0], "pitch_deg": 10},
    "static": [{"id": 20, "kind": "wall", "center": [12, -4.0], "size": [14, 0.3, 3.0]},
               {"id": 21, "kind": "parked_car", "center": [9, 3.0]}],
    "objects": [{"id": 1, "kind": "pedestrian", "category": "crossing", "start": [8, -2.5],
                 "heading_deg": 90, "speed_kmh": 5}],
})
# Unconfirmed, so that the short street reports regions in several frames to compare (the
# confirmation's own stream-versus-apply test below turns it on).
PARAMS = fm.Params(flow="dis", dis_preset="fast", confirm_reach=0)


@pytest.fixture(scope="module")
def frames():
    return synth.render_frames(CAM, STREET, supersample=1)


def _applied(detector, items):
    out = []
    for frame, pose in items:
        out.append((detector.apply(frame, pose), detector.last_pose))
    return out


def _streamed(detector, items):
    return [(result, detector.last_pose) for result in detector.stream(items)]


def _assert_same(a, b):
    assert len(a) == len(b)
    for (ra, pa), (rb, pb) in zip(a, b, strict=True):
        np.testing.assert_array_equal(pa, pb)
        assert (ra is None) == (rb is None)
        if ra is not None:
            np.testing.assert_array_equal(ra.likelihood, rb.likelihood)
            np.testing.assert_array_equal(ra.mask, rb.mask)
            assert [r.bbox for r in ra.regions] == [r.bbox for r in rb.regions]


@pytest.mark.parametrize("road", [None, "auto"], ids=["given-road", "road-auto"])
def test_stream_gives_apply_results_deciding_in_a_second_thread(frames, road, monkeypatch):
    items = [(f.image, f.pose) for f in frames]
    expected = _applied(fm.MotionDetector(CAM, road, PARAMS), items)
    # Something to compare beyond the likelihood maps (compared in every frame): masks in two
    # frames (three until 0.8.17's depth edges removed a false region of this street).
    assert sum(r is not None and r.mask.any() for r, _ in expected) >= 2

    threads = []
    decide = fm.MotionDetector._decide

    def recording(self, measured):
        threads.append(threading.current_thread().name)
        return decide(self, measured)

    monkeypatch.setattr(fm.MotionDetector, "_decide", recording)
    got = _streamed(fm.MotionDetector(CAM, road, PARAMS), items)
    _assert_same(expected, got)
    assert len(threads) == len(frames) - PARAMS.frame_gap
    assert all(name.startswith("fisheyemotion-decide") for name in threads)


@pytest.mark.parametrize("api", ["apply", "stream"])
def test_each_frame_is_checked_for_texture_once_and_in_the_decision_as_it_arrives(frames, api,
                                                                                 monkeypatch):
    """The texture check of a stream's frame runs once: in the decision of the pair it ends
    (stream(): in the second thread, beside the next pair's flow), and only the first frames,
    which end no pair, when they begin one. A frame passed to detect() is checked each time."""
    items = [(f.image, f.pose) for f in frames]
    checked = []
    sobel = cv2.Sobel

    def counting(image, *args, **kwargs):
        if args[1:3] == (1, 0):  # one call per check
            checked.append((image.tobytes(), threading.current_thread().name))
        return sobel(image, *args, **kwargs)

    monkeypatch.setattr(cv2, "Sobel", counting)
    detector = fm.MotionDetector(CAM, params=PARAMS)
    got = _applied(detector, items) if api == "apply" else _streamed(detector, items)
    grays = [cv2.cvtColor(f.image, cv2.COLOR_BGR2GRAY).tobytes()
             for f in frames]
    assert sorted(g for g, _ in checked) == sorted(grays)  # every frame once, none twice
    gap = PARAMS.frame_gap
    threads = dict(checked)
    first = [threads[g] for g in grays[:gap]]  # checked as previous frames, measured in turn
    later = [threads[g] for g in grays[gap:]]  # checked as current frames, in the decision
    assert all(name == threading.main_thread().name for name in first)
    decider = "fisheyemotion-decide" if api == "stream" else threading.main_thread().name
    assert all(name.startswith(decider) for name in later)
    assert sum(r is not None for r, _ in got) == len(frames) - gap
    checked.clear()
    prev, curr = frames[0], frames[gap]
    for _ in range(2):
        detector.detect(prev.image, curr.image, prev.pose, curr.pose)
    assert len(checked) == 2  # not a stream: the previous frame's check each call


def test_stream_without_poses_equals_apply(frames):
    items = [(f.image, None) for f in frames]
    with pytest.warns(UserWarning, match="scale is unknown"):
        expected = _applied(fm.MotionDetector(CAM, params=PARAMS), items)
    with pytest.warns(UserWarning, match="scale is unknown"):
        got = _streamed(fm.MotionDetector(CAM, params=PARAMS), items)
    _assert_same(expected, got)


def test_stream_refining_its_poses_equals_apply(frames):
    rng = np.random.default_rng(4)
    items = []
    for f in frames:  # each pose turned by about 0.3 deg: the refinement has work to do
        pose = f.pose.copy()
        pose[:3, :3] = pose[:3, :3] @ cv2.Rodrigues(rng.normal(0, 0.003, 3))[0]
        items.append((f.image, pose))
    params = PARAMS.replace(pose_refinement="on")
    expected = _applied(fm.MotionDetector(CAM, params=params), items)
    assert sum(r is not None and r.mask.any() for r, _ in expected) >= 2  # not a vacuous match
    _assert_same(expected, _streamed(fm.MotionDetector(CAM, params=params), items))


def test_a_stream_without_poses_decides_beside_the_next_pairs_flow(frames, monkeypatch):
    """A frame's pose step excludes the result two frames before it, so estimating the poses
    does not stop the stream deciding one pair while it measures the next: each decision after
    the first waits here until the next pair's flow has started (it would wait for ever if the
    stream ran one frame after the other, as it did before 0.8.7)."""
    flows, waited = [], []
    pair_flow, decide = fm.MotionDetector._pair_flow, fm.MotionDetector._decide
    started = threading.Condition()

    def flow(self, *args):
        with started:
            flows.append(threading.current_thread().name)
            started.notify_all()
        return pair_flow(self, *args)

    pairs = len(frames) - PARAMS.frame_gap

    def deciding(self, measured):
        i = len(waited)
        if 1 <= i < pairs - 1:
            with started:
                waited.append(started.wait_for(lambda: len(flows) >= i + 2, timeout=5))
        else:
            waited.append(None)
        return decide(self, measured)

    monkeypatch.setattr(fm.MotionDetector, "_pair_flow", flow)
    monkeypatch.setattr(fm.MotionDetector, "_decide", deciding)
    with pytest.warns(UserWarning, match="scale is unknown"):
        got = _streamed(fm.MotionDetector(CAM, params=PARAMS), [(f.image, None) for f in frames])
    assert sum(r is not None for r, _ in got) == pairs
    assert [w for w in waited if w is not None] == [True] * (pairs - 2)


def test_leaving_a_stream_early_leaves_the_detector_as_apply_would(frames):
    items = [(f.image, f.pose) for f in frames]
    expected = _applied(fm.MotionDetector(CAM, params=PARAMS), items)
    detector = fm.MotionDetector(CAM, params=PARAMS)
    got = []
    for result in detector.stream(items):
        got.append((result, detector.last_pose))
        if len(got) == 6:
            break
    _assert_same(expected[:6], got)
    # The 7th frame was taken in (its flow measured beside the 6th result's decision): it is
    # detected on leaving, unseen, so the detector goes on as apply() after 7 frames.
    np.testing.assert_array_equal(detector.last_pose, frames[6].pose)
    _assert_same(expected[7:], _applied(detector, items[7:]))


def test_a_bad_frame_mid_stream_is_a_value_error_after_the_results_before_it(frames):
    items = [(f.image, f.pose) for f in frames[:6]] + [(frames[6].image[:100], frames[6].pose)]
    detector = fm.MotionDetector(CAM, params=PARAMS)
    got = []
    with pytest.raises(ValueError, match="frame"):
        for result in detector.stream(items):
            got.append(result)
    assert len(got) == 6  # every frame before the refused one has its result
    assert got[2] is None and got[3] is not None


@pytest.mark.parametrize("item", [np.zeros((240, 320), np.uint8), (np.zeros((240, 320), np.uint8),),
                                  "frame.png"], ids=["bare-frame", "1-tuple", "string"])
def test_an_item_that_is_not_a_frame_and_pose_is_a_value_error_naming_items(frames, item):
    detector = fm.MotionDetector(CAM, params=PARAMS)
    items = [(f.image, f.pose) for f in frames[:4]] + [item]
    got = []
    with pytest.raises(ValueError, match="items: expected \\(frame, pose\\) pairs"):
        for result in detector.stream(items):
            got.append(result)
    assert len(got) == 4


def test_three_views_in_a_stream_equal_apply_and_change_its_results(frames):
    """``range_consistency`` works on apply()'s own frames (remembered by identity) and stream()
    gives the same results with it."""
    params = PARAMS.replace(range_consistency=0.5)  # low enough to change something here
    items = [(f.image, f.pose) for f in frames]
    on = _applied(fm.MotionDetector(CAM, None, params), items)
    _assert_same(on, _streamed(fm.MotionDetector(CAM, None, params), items))
    off = _applied(fm.MotionDetector(CAM, None, PARAMS), items)
    assert any(not np.array_equal(a.likelihood, b.likelihood)
               for (a, _), (b, _) in zip(on, off, strict=True) if a is not None)


def test_three_views_leave_the_scene_model_as_the_pairs_alone_build_it(frames):
    """A cell the three-view test alone raises is still stored as static (0.8.20): the scene
    model, and so every pair's prior and flow, is the one the stream builds without the test."""
    items = [(f.image, f.pose) for f in frames]
    models = []
    for params in (PARAMS, PARAMS.replace(range_consistency=0.5)):
        det = fm.MotionDetector(CAM, None, params)
        results = _applied(det, items)
        models.append((det.scene.points(), [r.flow for r, _ in results if r is not None]))
    (points_off, flows_off), (points_on, flows_on) = models
    assert len(points_off) > 0
    np.testing.assert_array_equal(points_on, points_off)
    for a, b in zip(flows_on, flows_off, strict=True):
        np.testing.assert_array_equal(a, b)


def test_confirmation_in_a_stream_equals_apply_and_only_removes_regions(frames):
    """``confirm_reach`` reads the last decided result's regions: stream(), which decides beside
    the next pair's flow, gives apply()'s results with it; every mask it reports is within the
    unconfirmed one (the likelihood is the same), and the pose step's cells are the same."""
    params = PARAMS.replace(confirm_reach=1)
    items = [(f.image, f.pose) for f in frames]
    on = _applied(fm.MotionDetector(CAM, None, params), items)
    _assert_same(on, _streamed(fm.MotionDetector(CAM, None, params), items))
    off = _applied(fm.MotionDetector(CAM, None, PARAMS), items)
    removed = 0
    for (a, _), (b, _) in zip(on, off, strict=True):
        if a is not None:
            np.testing.assert_array_equal(a.likelihood, b.likelihood)
            np.testing.assert_array_equal(a.cell_mask, b.cell_mask)
            assert not (a.mask > b.mask).any()
            removed += int((a.mask < b.mask).sum())
    assert removed > 0  # here: two frames' regions with none near them in the frame before


def test_three_view_raises_the_images_explain_need_range_consistency_alone(frames):
    """A cell the three-view test raises by less than ``range_consistency_alone`` sigmas, where
    the photometric check explains it by the static scene, keeps the pair's own likelihood:
    on this street (DIS fast, whose flow errors on the wall and the parked car exceed the
    three views' error model) every frame flags at most the static pixels that letting every
    raise count (``three_views_unchecked.yaml``) flags, and some frame fewer; the pedestrian's
    pixels are not lost with them."""
    items = [(f.image, f.pose) for f in frames]
    flagged = {}
    for alone in (1.5, 3.0):
        params = PARAMS.replace(range_consistency_alone=alone)
        results = _applied(fm.MotionDetector(CAM, None, params), items)
        flagged[alone] = [(int(((r.mask > 0) & (f.moving == 0)).sum()),
                           int(((r.mask > 0) & (f.moving > 0)).sum()))
                          for (r, _), f in zip(results, frames, strict=True) if r is not None]
    static = {a: np.array([s for s, _ in v]) for a, v in flagged.items()}
    moving = {a: sum(m for _, m in v) for a, v in flagged.items()}
    assert (static[3.0] <= static[1.5]).all() and static[3.0].sum() < static[1.5].sum()
    assert moving[3.0] >= moving[1.5] > 0
