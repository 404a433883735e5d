"""detect() at 640x480 split into its stages, beside the flow method alone; renderer; streams.

Groups (peer in brackets, see report.py): detect-farneback [Farneback alone], detect-dis-*
[DIS preset alone], render-640x480 [one flow computation], stream-64x48 [none: per frame].
"""

from __future__ import annotations

import os
import time

import cv2
import numpy as np
import pytest

import fisheyemotion as fm
from fisheyemotion import synth
from fisheyemotion.constraints import constraints
from fisheyemotion.flow import FlowEstimator, grid_average
from fisheyemotion.second_pass import BoxFlows

CAM = fm.calib.load(os.path.join(os.path.dirname(__file__), "..", "data", "calib",
                                 "front_kb_640x480.yaml"))
SCENARIO = synth.load_scenario("crossing")
#: The opt-in swept scene ranges as docs/evaluation.md measures them.
SWEEP = os.path.join(os.path.dirname(__file__), "..", "data", "params", "scene_sweep.yaml")


@pytest.fixture(scope="module")
def frames():
    r = synth.Renderer(CAM, SCENARIO)
    out = [r.render(k) for k in range(STREAM_FRAMES)]
    return out, r.roi()


STREAM_FRAMES = 18  # the stream benchmark: 6 frames to fill the gap and the scene model, 12 timed
STREAM_WARMUP = 6


def _gray(f):
    return cv2.cvtColor(f.image, cv2.COLOR_BGR2GRAY)


CONFIGS = {
    "farneback": dict(flow="farneback"),
    "dis-ultrafast": dict(flow="dis", dis_preset="ultrafast"),
    "dis-fast": dict(flow="dis", dis_preset="fast"),
    "dis-medium": dict(flow="dis", dis_preset="medium"),
}


def _after_flow(benchmark, det, g0, g1, p0, p1):
    """Time ``det.detect_flow`` on the pair, each round right after a real flow call (untimed),
    which leaves the caches as a stream finds them; three passes first build a scene model."""
    flow = det.flow(g0, g1, p0, p1)
    for _ in range(3):
        det.detect_flow(flow, p0, p1, prev=g0, curr=g1, stream=True)

    def setup():
        return (det.flow(g0, g1, p0, p1), p0, p1), {"prev": g0, "curr": g1, "stream": True}

    return benchmark.pedantic(det.detect_flow, setup=setup, rounds=40, warmup_rounds=2)


THREADED = ("flow_alone", "paper_pipeline", "default_pipeline", "default_after_flow")


@pytest.mark.parametrize("threads", [1, 2], ids=["1t", "2t"])
@pytest.mark.parametrize("name", CONFIGS)
@pytest.mark.parametrize("stage", ["flow_alone", "paper_pipeline", "default_pipeline",
                                   "non_flow", "default_non_flow", "default_after_flow",
                                   "no_extent_after_flow",
                                   "ray_lookup", "constraints", "segmentation"])
def test_detect_stage(benchmark, frames, name, stage, threads):
    """One frame pair (3 apart) at 640x480 with cv2 pinned to ``threads``; the stages besides
    the flow at one thread only."""
    if threads == 2 and stage not in THREADED:
        pytest.skip("the non-flow stages are timed at one thread")
    fr, roi = frames
    g0, g1 = _gray(fr[0]), _gray(fr[3])
    p0, p1 = fr[0].pose, fr[3].pose
    benchmark.group = f"detect-{name}-{threads}t"
    paper = fm.MotionDetector(CAM, params=fm.Params.paper(**CONFIGS[name]), roi=roi)
    if stage == "flow_alone":
        benchmark(paper._flow, g0, g1)
    elif stage == "paper_pipeline":
        benchmark(paper.detect, g0, g1, p0, p1)
    elif stage == "default_pipeline":
        det = fm.MotionDetector(CAM, params=fm.Params(**CONFIGS[name]), roi=roi)
        benchmark(det.detect, g0, g1, p0, p1)
    elif stage == "non_flow":  # everything detect() does besides the flow (paper pipeline)
        flow = paper._flow(g0, g1)
        benchmark(paper.detect_flow, flow, p0, p1, prev=g0)
    elif stage == "default_non_flow":  # the same with Params() in a stream that has a scene model
        det = fm.MotionDetector(CAM, params=fm.Params(**CONFIGS[name]), roi=roi)
        flow = det.flow(g0, g1, p0, p1)
        for _ in range(3):
            det.flow(g0, g1, p0, p1)
            det.detect_flow(flow, p0, p1, prev=g0, curr=g1, stream=True)
        det.flow(g0, g1, p0, p1)
        cache = det._static_flow
        assert cache is not None

        def warm():  # untimed: the warp prior the flow call left for the photometric check
            det._static_flow = cache
            return (flow, p0, p1), {"prev": g0, "curr": g1, "stream": True}

        benchmark.pedantic(det.detect_flow, setup=warm, rounds=200, warmup_rounds=3)
    elif stage in ("default_after_flow", "no_extent_after_flow"):
        # the same, each round right after a real flow call (and without the growth of the
        # regions to their objects' extent: its cost is the difference)
        extent = {} if stage == "default_after_flow" else {"extent_reach": 0.0}
        det = fm.MotionDetector(CAM, params=fm.Params(**CONFIGS[name], **extent), roi=roi)
        _after_flow(benchmark, det, g0, g1, p0, p1)
    else:
        flow = paper._flow(g0, g1)
        cells = grid_average(flow, 5)
        if stage == "ray_lookup":
            benchmark(lambda: (grid_average(flow, 5), CAM.unproject(paper._centres + cells)))
        elif stage == "constraints":
            rays1, _ = CAM.unproject(paper._centres + cells)
            benchmark(constraints, paper._rays0, rays1, p0, p1, road=paper.road,
                      params=paper.params)
        else:
            rays1, _ = CAM.unproject(paper._centres + cells)
            res = constraints(paper._rays0, rays1, p0, p1, road=paper.road, params=paper.params)
            valid = res.valid & paper._cell_valid
            benchmark(paper._assemble, flow, cells, res, res.likelihood, valid)


@pytest.fixture(scope="module")
def street_pair():
    """Frames 20 and 23 of the tuning street (parked cars, walls, a crossing pedestrian): a pair
    with regions, where the photometric check, the ground-contact test and the growth to the
    objects' extent have work (the `crossing` pair above has none)."""
    r = synth.Renderer(CAM, synth.load_scenario("street"))
    f0, f1 = r.render(20), r.render(23)
    return _gray(f0), _gray(f1), f0.pose, f1.pose, r.roi()


@pytest.mark.parametrize("name", ["farneback", "dis-ultrafast"])
@pytest.mark.parametrize("stage", ["flow_alone", "default_after_flow", "sweep_after_flow"])
def test_detect_street_pair(benchmark, street_pair, name, stage):
    """``default_after_flow`` of :func:`test_detect_stage` on a cluttered street's pair, cv2 on
    one thread; ``sweep_after_flow`` the same with the opt-in swept scene ranges
    (``data/params/scene_sweep.yaml``)."""
    g0, g1, p0, p1, roi = street_pair
    benchmark.group = f"street-{name}-1t"
    params = fm.Params.load(SWEEP) if stage == "sweep_after_flow" else fm.Params()
    det = fm.MotionDetector(CAM, params=params.replace(**CONFIGS[name]), roi=roi)
    if stage == "flow_alone":
        benchmark(det._flow, g0, g1)
        return
    assert _after_flow(benchmark, det, g0, g1, p0, p1).regions  # the point of this pair


@pytest.mark.benchmark(group="render-640x480")
def test_render_frame(benchmark):
    r = synth.Renderer(CAM, SCENARIO)
    r.render(0)
    counter = iter(range(1, 10_000))
    benchmark.pedantic(lambda: r.render(next(counter)), rounds=5, iterations=1)


@pytest.mark.benchmark(group="render-640x480")
def test_render_peer_farneback(benchmark, frames):
    fr, _ = frames
    benchmark(fm.MotionDetector(CAM, params=fm.Params.paper())._flow, _gray(fr[0]), _gray(fr[1]))


@pytest.mark.benchmark(group="stream-640x480")
@pytest.mark.parametrize("poses", ["given", "estimated"])
@pytest.mark.parametrize("threads", [1, 2], ids=["1t", "2t"])
@pytest.mark.parametrize("name", ["dis-ultrafast", "farneback"])
@pytest.mark.parametrize("api", ["apply", "stream"])
def test_stream_640x480(benchmark, frames, name, threads, api, poses):
    """``Params()`` as a user streams it, frame by frame with ``MotionDetector.apply`` or with
    ``MotionDetector.stream`` (each pair's decision beside the next pair's flow, in a second
    Python thread): frames per second (extra_info) over the frames after the gap and the scene
    model have filled; with the scene's poses, or none (``pose=None``: estimated from the
    images, the camera's height given; Farneback at one thread only)."""
    if poses == "estimated" and (name != "farneback" or threads != 1):
        pytest.skip("poses from the images: Farneback at one thread")
    fr, roi = frames
    grays = [_gray(f) for f in fr]
    half = STREAM_WARMUP
    pose = {k: fr[k].pose if poses == "given" else None for k in range(STREAM_FRAMES)}

    flow_s: list[float] = []  # the flow method's own time (cv2's call), this round so far
    rounds: list[tuple[float, float, float]] = []  # (all, flow, second pass's flow) seconds

    second_s: list[float] = []  # of which the second pass's calls

    def timed_flow(estimate, *also: list[float]):
        def call(*args, **kwargs):
            start = time.perf_counter()
            try:
                return estimate(*args, **kwargs)
            finally:
                elapsed = time.perf_counter() - start
                for times in (flow_s, *also):
                    times.append(elapsed)
        return call

    def setup():
        det = fm.MotionDetector(CAM, road="auto" if poses == "estimated" else None,
                                params=fm.Params(**CONFIGS[name]), roi=roi,
                                camera_height=0.9 if poses == "estimated" else None)
        for k in range(half):
            det.apply(grays[k], pose[k])
        det._flow = timed_flow(det._flow)
        # The second pass's flow-method calls (Params.second_pass) are the flow method's too;
        # their share is reported apart (extra_info["second_flow_ms"]).
        det._second_flow = BoxFlows(lambda: timed_flow(FlowEstimator(det.params), second_s))
        return (det,), {}

    def run(det):
        flow_s.clear()
        second_s.clear()
        start = time.perf_counter()
        if api == "stream":
            for _ in det.stream((grays[k], pose[k]) for k in range(half, STREAM_FRAMES)):
                pass
        else:
            for k in range(half, STREAM_FRAMES):
                det.apply(grays[k], pose[k])
        rounds.append((time.perf_counter() - start, sum(flow_s), sum(second_s)))

    benchmark.pedantic(run, setup=setup, rounds=8, warmup_rounds=1)
    if benchmark.stats is None:  # --benchmark-disable: run once, nothing timed
        return
    frames_timed = STREAM_FRAMES - half
    per_frame = benchmark.stats.stats.median / frames_timed
    benchmark.extra_info.update(frames=frames_timed, fps=round(1 / per_frame, 1))
    if api == "apply":  # one thread: everything but the flow method's call is the rest
        rest = [(total - flow) / frames_timed for total, flow, _ in rounds[1:]]
        benchmark.extra_info["non_flow_ms"] = round(1e3 * float(np.median(rest)), 2)
        second = [s / frames_timed for _, _, s in rounds[1:]]
        benchmark.extra_info["second_flow_ms"] = round(1e3 * float(np.median(second)), 2)


def _rss_mb() -> float:
    with open("/proc/self/statm") as fh:
        return int(fh.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2**20


@pytest.mark.benchmark(group="stream-64x48")
def test_stream_10000_frames(benchmark):
    cam = fm.calib.KannalaBrandt(fx=40, fy=40, cx=31.5, cy=23.5, width=64, height=48)
    rng = np.random.default_rng(0)
    images = [rng.integers(0, 255, (48, 64), dtype=np.uint8) for _ in range(4)]

    rss = {}

    def run():
        det = fm.MotionDetector(cam, params=fm.Params(flow="dis", dis_preset="ultrafast", grid=4))
        pose = np.eye(4)
        for i in range(10_000):
            pose = pose.copy()
            pose[0, 3] += 0.01
            det.apply(images[i % 4], pose)
            if i in (100, 9_999):
                rss[i] = _rss_mb()

    benchmark.pedantic(run, rounds=1, iterations=1)
    benchmark.extra_info["frames"] = 10_000
    benchmark.extra_info["rss_mb_at_frame_100"] = round(rss[100], 1)
    benchmark.extra_info["rss_growth_mb_100_to_10000"] = round(rss[9_999] - rss[100], 2)


@pytest.mark.benchmark(group="detect-interleaved")
@pytest.mark.parametrize("pipeline", ["paper", "default"])
def test_farneback_pipeline_interleaved_with_flow_alone(benchmark, frames, pipeline):
    """Farneback alone and detect() timed alternately in the same rounds: their ratio without
    the drift between groups timed minutes apart (extra_info)."""
    fr, roi = frames
    g0, g1 = _gray(fr[0]), _gray(fr[3])
    params = fm.Params.paper() if pipeline == "paper" else fm.Params()
    det = fm.MotionDetector(CAM, params=params, roi=roi)
    times: dict[str, list[float]] = {"flow": [], "detect": []}

    def pair():
        t = time.perf_counter()
        det._flow(g0, g1)
        times["flow"].append(time.perf_counter() - t)
        t = time.perf_counter()
        det.detect(g0, g1, fr[0].pose, fr[3].pose)
        times["detect"].append(time.perf_counter() - t)

    benchmark.pedantic(pair, rounds=25, iterations=1, warmup_rounds=2)
    flow_ms, detect_ms = (1e3 * float(np.median(times[k][2:])) for k in ("flow", "detect"))
    benchmark.extra_info.update(flow_ms=round(flow_ms, 2), detect_ms=round(detect_ms, 2),
                                ratio=round(detect_ms / flow_ms, 4))


@pytest.mark.benchmark(group="poses-640x480")
@pytest.mark.parametrize("what", ["pose_from_images", "pose_from_images_and_road_scale",
                                  "pose_first_pair", "peer_farneback"])
def test_pose_estimation(benchmark, frames, what):
    """One consecutive frame pair's pose from the images inside a stream (``PoseTracker.step``
    after two pairs: corners spread over the image, Lucas-Kanade from where the last step
    predicts them, PoseLib twice; with the camera height also the road scale), the first pair of
    a stream (no prediction yet: the careful estimate), beside a Farneback flow of the same
    pair."""
    from fisheyemotion.egomotion import PoseTracker

    fr, roi = frames
    grays = [_gray(f) for f in fr[:4]]
    if what == "peer_farneback":
        benchmark(fm.MotionDetector(CAM, params=fm.Params.paper())._flow, grays[2], grays[3])
        return
    height = 0.9 if "road" in what else None

    def primed():
        tracker = PoseTracker(CAM, mask=roi > 0, camera_height=height)
        first = 2 if what == "pose_first_pair" else 0
        for g in grays[first:3]:
            tracker.step(g)
        return (tracker,), {}

    result = benchmark.pedantic(lambda tracker: tracker.step(grays[3]), setup=primed,
                                rounds=30, warmup_rounds=2)
    assert result is not None


@pytest.mark.benchmark(group="road-640x480")
@pytest.mark.parametrize("what", ["track_pair", "fit", "peer_farneback"])
def test_road_estimate(benchmark, frames, what):
    """The road estimate of ``road='auto'``: one consecutive pair's corners tracked against the
    next frame warped by the road and triangulated, and one plane fit to the points of the
    first pairs, beside a Farneback flow of the same pair."""
    from fisheyemotion.ground import GroundEstimator, level_up

    fr, roi = frames
    grays = [_gray(f) for f in fr[:6]]
    if what == "peer_farneback":
        benchmark(fm.MotionDetector(CAM, params=fm.Params.paper())._flow, grays[4], grays[5])
        return
    ground = GroundEstimator()
    for g, f in zip(grays, fr, strict=False):
        ground.observe(CAM, g, f.pose, mask=roi > 0)
    assert ground.road is not None
    lower = np.zeros(grays[0].shape, bool)
    lower[CAM.height // 2:] = True
    if what == "track_pair":
        benchmark(ground._pair_points, CAM, grays[4], grays[5], fr[4].pose, fr[5].pose,
                  ground.road, lower & (roi > 0))
    else:
        points, p0, p1 = np.concatenate(ground._points), fr[4].pose, fr[5].pose
        benchmark(ground.fit, points, p0[:3, 3], p0[:3, 1], expected_up=level_up(p0, p1))
