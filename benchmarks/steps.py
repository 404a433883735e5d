"""Where the defaults' work besides the flow goes, step by step (docs/performance.md).

    .venv/bin/python benchmarks/steps.py            # the benchmark's `crossing` pair
    .venv/bin/python benchmarks/steps.py street     # the tuning street's frames 20 and 23
                                                    # (needs `make demo`'s sequences)
    .venv/bin/python benchmarks/steps.py street data/params/scene_sweep.yaml   # other Params
    .venv/bin/python benchmarks/steps.py stream     # apply() over the stream benchmark's frames
    .venv/bin/python benchmarks/steps.py stream data/params/fast_second_pass.yaml farneback
                                                    # with Farneback instead of DIS ultrafast

``stream``: ``MotionDetector.apply`` frame by frame over the ``crossing`` scene's frames 6-17
(after six that fill the frame gap and the scene model), as ``make bench``'s
``test_stream_640x480[apply-...]``, ``ROUNDS // 10`` times; the flow method's own call is a row
(``flow method``) and every other row is the non-flow work of a stream, per frame.

``MotionDetector.detect_flow`` with ``Params(flow="dis", dis_preset="ultrafast")`` (or a Params
file's, with that flow; a third argument names another flow method, with the file's or the
default settings), OpenCV on
one thread, each of ``ROUNDS`` rounds right after a real flow call (as ``make bench``'s
``default_after_flow``), three passes first to fill the scene model. Each step is timed by a
wrapper around the function of that name; a step's time includes the steps it calls, so the
rows do not add up. A profiling aid, not a benchmark: the wrappers cost a little each, and the
figures move with the machine as ``make bench``'s do.
"""

from __future__ import annotations

import collections
import functools
import importlib
import sys
import time
from pathlib import Path

import cv2
import numpy as np

import fisheyemotion as fm
from fisheyemotion import synth
from fisheyemotion.frames import to_gray
from fisheyemotion.sequence import Sequence

ROOT = Path(__file__).resolve().parents[1]
ROUNDS = 100
#: Methods of MotionDetector, then functions as the detector module calls them.
METHODS = ("_measure", "_decide", "_assemble", "_explain_standing", "_textured_cells",
           "_supported_off_arc", "_grown", "_temporal_filter", "_static_prior", "_one_flow",
           "_second_pass", "_receding", "_span_explained", "_three_views")
FUNCTIONS = ("constraints", "cell_sigma", "triangulate_range", "grid_upsample", "grow_to_extent",
             "static_explained", "cell_residual", "grid_transfer", "pixel_transfer",
             "segment_cells", "grid_average", "warp_by", "second_flow", "better_explained",
             "receding_cells", "edge_explained", "hidden_cells", "confirmed_regions",
             "road_explained", "trim_regions")


def _pair(which: str):
    if which == "street":
        seq = Sequence(ROOT / "data" / "generated" / "demo" / "sequences" / "street_kb")
        return (seq.camera, to_gray(seq.frame(20), "frame"), to_gray(seq.frame(23), "frame"),
                seq.poses[20], seq.poses[23], seq.roi(),
                (to_gray(seq.frame(17), "frame"), seq.poses[17]))
    cam = fm.calib.load(ROOT / "data" / "calib" / "front_kb_640x480.yaml")
    renderer = synth.Renderer(cam, synth.load_scenario("crossing"))
    frames = [renderer.render(k) for k in (0, 3)]
    g0, g1 = (np.ascontiguousarray(f.image.mean(axis=-1).astype(np.uint8)) for f in frames)
    return cam, g0, g1, frames[0].pose, frames[1].pose, renderer.roi(), None


def main(which: str = "crossing", params: str | None = None, flow: str = "dis") -> None:
    cv2.setNumThreads(1)
    detector_module = importlib.import_module("fisheyemotion.detector")
    totals: collections.defaultdict[str, float] = collections.defaultdict(float)

    def timed(owner, name):
        function = getattr(owner, name)

        @functools.wraps(function)
        def wrapper(*args, **kwargs):
            start = time.perf_counter()
            try:
                return function(*args, **kwargs)
            finally:
                totals[name] += time.perf_counter() - start
        setattr(owner, name, wrapper)

    for name in METHODS:
        timed(detector_module.MotionDetector, name)
    for name in FUNCTIONS:
        timed(detector_module, name)
    settings = fm.Params() if not params else fm.Params.load(params)  # a Params file
    settings = (settings.replace(flow="dis", dis_preset="ultrafast") if flow == "dis"
                else settings.replace(flow=flow))
    if which == "stream":
        _stream(settings, timed, totals)
        return
    cam, g0, g1, p0, p1, roi, before = _pair(which)
    det = fm.MotionDetector(cam, params=settings, roi=roi)
    if before is not None:  # the pair before, so that the two-span test has its span
        gb, pb = before
        det.detect_flow(det.flow(gb, g0, pb, p0), pb, p0, prev=gb, curr=g0, stream=True)
    flow = det.flow(g0, g1, p0, p1)
    for _ in range(3):
        det.detect_flow(flow, p0, p1, prev=g0, curr=g1, stream=True)
    # The first region of a process imports the extent's scikit-image and scipy modules: out of
    # the rounds.
    importlib.import_module("skimage.segmentation")
    importlib.import_module("skimage.morphology")
    totals.clear()
    total = 0.0
    for _ in range(ROUNDS):
        flow = det.flow(g0, g1, p0, p1)
        start = time.perf_counter()
        det.detect_flow(flow, p0, p1, prev=g0, curr=g1, stream=True)
        total += time.perf_counter() - start
    print(f"{which}{'' if params is None else ', ' + params}: detect_flow "
          f"{1000 * total / ROUNDS:.2f} ms a pair ({ROUNDS} rounds)")
    for name, seconds in sorted(totals.items(), key=lambda item: -item[1]):
        print(f"  {name:20s} {1000 * seconds / ROUNDS:6.2f}")


def _stream(settings, timed, totals) -> None:
    """The ``stream`` mode (module docstring)."""
    from fisheyemotion import flow as flow_module

    timed(flow_module.FlowEstimator, "__call__")
    cam = fm.calib.load(ROOT / "data" / "calib" / "front_kb_640x480.yaml")
    renderer = synth.Renderer(cam, synth.load_scenario("crossing"))
    frames = [renderer.render(k) for k in range(18)]
    grays = [cv2.cvtColor(f.image, cv2.COLOR_BGR2GRAY) for f in frames]
    importlib.import_module("skimage.segmentation")
    importlib.import_module("skimage.morphology")
    total, count = 0.0, 0
    steps: collections.defaultdict[str, float] = collections.defaultdict(float)
    for round_ in range(1 + ROUNDS // 10):
        det = fm.MotionDetector(cam, params=settings, roi=renderer.roi())
        for k in range(6):
            det.apply(grays[k], frames[k].pose)
        if round_ == 0:  # a first round out of the figures
            continue
        before = dict(totals)  # only the timed frames' steps count, not the six before them
        start = time.perf_counter()
        for k in range(6, 18):
            det.apply(grays[k], frames[k].pose)
        total += time.perf_counter() - start
        count += 12
        for name, seconds in totals.items():
            steps[name] += seconds - before.get(name, 0.0)
    totals.clear()
    totals.update(steps)
    totals["flow method"] = totals.pop("__call__")
    print(f"stream: apply {1000 * total / count:.2f} ms a frame, of which the flow method "
          f"{1000 * totals['flow method'] / count:.2f} ({count} frames)")
    for name, seconds in sorted(totals.items(), key=lambda item: -item[1]):
        print(f"  {name:20s} {1000 * seconds / count:6.2f}")


if __name__ == "__main__":
    main(*sys.argv[1:4])
