"""Run detection over sequence folders and collect tidy tables (serially, in a process pool or
on a Dask cluster)."""

from __future__ import annotations

import ctypes
import operator
import os
from collections.abc import Callable, Iterable
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np
import pandas as pd
from tqdm import tqdm

from fisheyemotion.detection import CONSTRAINT_NAMES
from fisheyemotion.detector import MotionDetector
from fisheyemotion.frames import to_gray
from fisheyemotion.params import Params
from fisheyemotion.road import Road
from fisheyemotion.sequence import Sequence
from fisheyemotion.synth import Renderer, load_scenario

__all__ = ["ADDITIONS", "ABLATION_WEIGHTS", "SequenceResult", "additions_table", "combine",
           "evaluate", "evaluate_sequence", "sequence_paths"]

from .metrics import false_positive_surfaces, frame_metrics, likelihood_histograms, object_metrics
from .pose_sources import Perturbation, pose_errors, poses_for

#: The additions beyond the paper (docs/geometry.md), each alone on top of ``Params.paper()``;
#: "all (defaults)" is ``Params()``.
ADDITIONS = {
    "paper": {},
    "+ ego prior": {"flow_prior": "ego"},
    "+ warp prior": {"flow_prior": "warp"},
    "+ visibility check": {"visibility_check": True},
    "+ forward-backward check": {"fb_check": True},
    "+ texture check": {"min_texture": 2.0},
    "+ frame gap 3": {"frame_gap": 3},
    "+ temporal decay 0.3": {"temporal_decay": 0.3},
    "+ temporal persistence 2": {"persistence": 2},
    "+ threshold 0.004": {"threshold": 0.004},
    "+ warp and scene prior": {"flow_prior": "warp", "scene_prior": True},
    "+ significance 3 sigma": {"significance": 3.0},
    "+ ground contact": {"ground_contact": True},
    "+ growth 4 cells": {"grow": 4},
    "+ extension to half the threshold": {"extend_threshold": 0.0025},
    "+ extent 0.5 (watershed)": {"extent_reach": 0.5},
    "+ photometric check": {"photometric_check": True},
    "+ regions closed over small gaps": {"region_gap": 1},
    "+ second flow pass": {"second_pass": 2},
    "+ pixels carried by their own flow": {"carry_share": 0.6},
    "+ receding regions": {"receding": 2.0},
    "+ confirmed by the frame before": {"confirm_reach": 8},
}

#: Ablation: weights (mu_e, mu_d, mu_h, mu_p) of each variant; "paper" is the configured Params.
ABLATION_WEIGHTS = {
    "epipolar only": (1.0, 0.0, 0.0, 0.0),
    "depth only": (0.0, 1.0, 0.0, 0.0),
    "height only": (0.0, 0.0, 1.0, 0.0),
    "antiparallel only": (0.0, 0.0, 0.0, 1.0),
    "equal weights": (1.0, 1.0, 1.0, 1.0),
}


@dataclass
class SequenceResult:
    """Everything measured on one sequence for one flow method."""

    sequence: str
    flow: str
    objects: pd.DataFrame
    frames: pd.DataFrame
    moving_above: np.ndarray
    static_above: np.ndarray
    n_moving: int
    n_static: int
    ablation: pd.DataFrame = field(default_factory=pd.DataFrame)
    examples: dict = field(default_factory=dict)


#: Flow (pixels) given to the exact-flow mode where the point leaves the camera's domain.
OUT_OF_VIEW = 1e5

#: The ``flow`` label of the results of the exact-flow mode (``exact_flow=True``).
EXACT = "exact"


def evaluate_sequence(path: str | os.PathLike, params: Params | None = None, *,
                      range_limit: float = 8.0, min_coverage: float = 0.0,
                      ablation: bool = True, exact_flow: bool = False,
                      world: str = "scene", road: str = "given",
                      camera_height: float | str | None = None, poses: str = "true",
                      noise: Perturbation | None = None) -> SequenceResult:
    """Detect on every consecutive frame pair of a sequence folder and score it.

    The detection on pair ``(k - gap, k)`` is on frame ``k``'s pixels (``gap = params.frame_gap``),
    as a user draws it, and is scored against frame ``k``'s ground truth.

    ``exact_flow=True`` replaces the flow method by the exact flow of the rendered scene
    (re-cast from the folder's ``scenario.yaml``): what the constraints do with perfect
    correspondences, separating their own limits from the flow's.

    ``world`` gives the poses in another world frame, as users' tools write them: ``scene``
    (z up, road at z = 0), ``first_camera`` (the first camera's frame, as most VO/SLAM systems
    write it) or ``raised`` (z up with the road at z = -1.7 m, and rotated 30 deg about z).
    ``road``: ``given`` (the scene's road, in that frame) or ``auto`` (estimated from the
    stream, :mod:`fisheyemotion.ground`; ``camera_height`` if known, in metres, or ``"scene"``
    for each sequence's own, read off its true first pose).

    ``poses``: ``true``, ``estimated`` (from the images) or ``perturbed`` (``noise``), refined
    first when ``params.pose_refinement`` is not ``off`` (:mod:`.pose_sources`); the frames table
    gets each pair's relative rotation and translation-direction errors.
    """
    params = Params() if params is None else params
    seq = Sequence(path)
    cam = seq.camera
    roi = seq.roi()
    if camera_height == "scene":
        camera_height = float(Road().height(seq.poses[0, :3, 3]))
    elif camera_height is not None and not isinstance(camera_height, int | float):
        raise ValueError(f"camera_height: expected metres or 'scene', got {camera_height!r}")
    if road not in ("given", "auto"):
        raise ValueError(f"road: expected 'given' or 'auto', got {road!r}")
    # The refinement knows what the detector knows: the road given (the scene's, z = 0, in the
    # frame the poses are refined in) or the camera's height.
    given = poses_for(seq, poses, params, noise=noise, roi=roi,
                      road=Road() if road == "given" else None, camera_height=camera_height)
    errors = pose_errors(given.poses, seq.poses, params.frame_gap).set_index("frame")
    valid = cam.valid_pixel_mask() & (True if roi is None else roi > 0)
    moved, road_given = world_transform(world, seq.poses[0])
    road_arg = road_given if road == "given" else "auto"
    main = MotionDetector(cam, road_arg, params=params, roi=roi, camera_height=camera_height)
    variants = {name: MotionDetector(cam, road_arg, params=params.replace(weights=w), roi=roi,
                                     camera_height=camera_height)
                for name, w in ABLATION_WEIGHTS.items()} if ablation else {}
    obj_rows, frame_rows, abl_rows = [], [], []
    moving_above = static_above = None
    n_moving = n_static = 0
    examples: dict = {}
    objects = seq.objects
    kinds = dict(zip(objects.id.astype(int), objects.kind.astype(str), strict=True))
    gap = params.frame_gap
    renderer = _exact_flow_renderer(seq) if exact_flow else None
    grays = [to_gray(seq.frame(i), "frame") for i in range(min(gap, len(seq)))]
    for i, gray in enumerate(grays):  # a stream's road estimate sees every frame, as apply() does
        for detector in (main, *variants.values()):
            detector._observe_ground(gray, moved @ given.anchors[i] @ given.poses[i])
    for k in range(gap, len(seq)):
        grays.append(to_gray(seq.frame(k), "frame"))
        g0, g1 = grays.pop(0), grays[-1]
        pose0, pose1 = (moved @ pose for pose in given.pair(k, gap))
        if k == gap:  # the stream's first pair: its scene model learns from the frames between
            frames = [(g, moved @ given.anchors[k] @ given.poses[i])
                      for i, g in enumerate([g0, *grays])]
            between = None if renderer is None else [
                np.nan_to_num(renderer.flow(i, gap=1), nan=OUT_OF_VIEW) for i in range(1, k + 1)]
            between = main._bootstrap_scene(frames, between)
            for detector in variants.values():  # the main detector's flows, as for the pairs
                detector._bootstrap_scene(frames, between)
        if renderer is not None:
            # Where the surface point leaves the camera's domain the exact flow is NaN: carry it
            # out of the image (its cell is then not scored), not to a zero flow.
            flow, backward = np.nan_to_num(renderer.flow(k, gap=gap), nan=OUT_OF_VIEW), None
        elif params.fb_check:
            flow, backward = main.flow(g0, g1, pose0, pose1, backward=True)
        else:
            flow, backward = main.flow(g0, g1, pose0, pose1), None
        det = main.detect_flow(flow, pose0, pose1, backward=backward, prev=g0, curr=g1,
                               stream=True)
        ids, gt = seq.ids(k), seq.mask(k)
        frame_objects = objects[objects.frame == k]
        rows = object_metrics(det.mask, ids, frame_objects, range_limit=range_limit,
                              min_coverage=min_coverage)
        weighted = {n: w * det.maps[n] for n, w in zip(CONSTRAINT_NAMES, params.weights,
                                                       strict=True)}
        for r in rows:
            pix = ids == r["id"]
            r.update({"sequence": seq.name, "frame": k})
            r.update({f"c_{n}": float(weighted[n][pix].mean()) for n in CONSTRAINT_NAMES})
            score = r["pixels"]  # the largest view of each category, detected or not
            if score > examples.get(r["category"], (0,))[0]:
                examples[r["category"]] = (score, str(seq.path), k, gap)
        obj_rows += rows
        fm = frame_metrics(det.mask, gt, valid)
        fp_pix = (det.mask > 0) & (gt == 0) & valid
        fm.update({"sequence": seq.name, "frame": k, "ego_static": det.static_camera,
                   **errors.loc[k].to_dict()})
        fm.update({f"fp_{n}": float(weighted[n][fp_pix].sum()) for n in CONSTRAINT_NAMES})
        surfaces = false_positive_surfaces(det.mask, gt, valid, ids, kinds)
        fm.update({f"fp_on_{name}": v for name, v in surfaces.items()})
        frame_rows.append(fm)
        m_above, s_above = likelihood_histograms(det.likelihood, gt, valid)
        moving_above = m_above if moving_above is None else moving_above + m_above
        static_above = s_above if static_above is None else static_above + s_above
        n_moving += int(((gt > 0) & valid).sum())
        n_static += int(((gt == 0) & valid).sum())
        for name, detector in variants.items():
            d = detector.detect_flow(flow, pose0, pose1, backward=backward, prev=g0, curr=g1,
                                     stream=True)
            for r in object_metrics(d.mask, ids, frame_objects, range_limit=range_limit,
                                    min_coverage=min_coverage):
                abl_rows.append({"variant": name, "kind": "object", **r})
            f = frame_metrics(d.mask, gt, valid)
            abl_rows.append({"variant": name, "kind": "frame", "fp_frame": f["fp_frame"],
                             "static_flagged": f["static_flagged"]})
    return SequenceResult(
        sequence=seq.name, flow=EXACT if exact_flow else params.flow,
        objects=pd.DataFrame(obj_rows),
        frames=pd.DataFrame(frame_rows), moving_above=moving_above, static_above=static_above,
        n_moving=n_moving, n_static=n_static, ablation=pd.DataFrame(abl_rows), examples=examples)


def world_transform(world: str, first_pose: np.ndarray) -> tuple[np.ndarray, Road]:
    """``new_from_scene`` for :func:`evaluate_sequence`'s ``world`` and the road in it."""
    if world == "scene":
        t = np.eye(4)
    elif world == "first_camera":
        t = np.linalg.inv(first_pose)
    elif world == "raised":
        c, s_ = np.cos(np.radians(30)), np.sin(np.radians(30))
        t = np.array([[c, -s_, 0, 5.0], [s_, c, 0, -3.0], [0, 0, 1, -1.7], [0, 0, 0, 1]])
    else:
        raise ValueError(f"world: expected scene, first_camera or raised, got {world!r}")
    return t, Road().transformed(t)


def _exact_flow_renderer(seq: Sequence) -> Renderer:
    spec = seq.path / "scenario.yaml"
    if not spec.is_file():
        raise ValueError(f"{seq.path}: exact_flow needs the scenario.yaml the sequence was "
                         "rendered from")
    return Renderer(seq.camera, load_scenario(spec), supersample=1)


def evaluate(paths: Iterable[str | os.PathLike], params: Params | None = None, *,
             workers: int | None = None, scheduler: str | None = None, progress: bool = True,
             **options) -> list[SequenceResult]:
    """:func:`evaluate_sequence` over many sequences, in input order.

    Parameters
    ----------
    workers : int, optional
        Local processes (default: the number of CPUs; 1 runs in this process).
    scheduler : str, optional
        Address of a Dask distributed scheduler (``tcp://host:port``); needs the ``dask`` extra.
    """
    paths = [str(p) for p in paths]
    params = Params() if params is None else params
    if workers is not None:
        try:
            count = 0 if isinstance(workers, bool) else operator.index(workers)
        except TypeError:
            count = 0
        if count < 1:
            raise ValueError(f"workers: expected a number of processes >= 1 (or None), got "
                             f"{workers!r}")
        workers = count
    job: Callable = _Job(params, options)
    if scheduler:
        try:
            from dask.distributed import Client
        except ImportError:
            raise ValueError("scheduler: Dask is not installed; pip install "
                             "'fisheyemotion[dask]'") from None
        job = _Job(params, options, dask_worker=True)
        try:
            client = Client(scheduler)
        except (OSError, ValueError, TypeError) as error:  # a bad address, no scheduler there
            raise ValueError(f"scheduler: cannot use {scheduler!r}: {error}") from None
        with client:
            futures = client.map(job, paths, pure=False)
            return client.gather(futures)
    if workers is None:
        workers = os.cpu_count() or 1
    if workers <= 1 or len(paths) <= 1:
        return [job(p) for p in tqdm(paths, desc="eval", disable=not progress, leave=False)]
    threads = cv2.getNumThreads()
    cv2.setNumThreads(1)  # inherited by the forked workers (see _Job)
    try:
        with ProcessPoolExecutor(max_workers=min(workers, len(paths))) as pool:
            return list(tqdm(pool.map(job, paths), total=len(paths), desc="eval",
                             disable=not progress, leave=False))
    finally:
        cv2.setNumThreads(threads)


#: glibc's mallopt parameters (malloc.h).
_M_TRIM_THRESHOLD, _M_MMAP_THRESHOLD = -1, -3


def restore_malloc_thresholds() -> bool:
    """Give a Dask worker process glibc's large-allocation behaviour back.

    Dask's nanny starts workers with ``MALLOC_TRIM_THRESHOLD_=65536``; any such variable turns
    off glibc's dynamic mmap threshold, so every array above 128 KiB (each frame, flow field and
    map here) is mapped and unmapped afresh: about six times the page faults, and the evaluation
    ran 1.5x slower on a Dask cluster than in a local process pool. Fixed thresholds well above
    a frame's arrays (mmap 64 MiB, trim 128 MiB) restore the pool's speed. Returns False where
    the C library is not glibc (nothing changed)."""
    try:
        libc = ctypes.CDLL("libc.so.6")
    except OSError:
        return False
    return bool(libc.mallopt(_M_MMAP_THRESHOLD, 64 << 20)) and bool(
        libc.mallopt(_M_TRIM_THRESHOLD, 128 << 20))


class _Job:
    """Picklable callable for pools and Dask.

    In a pool or on Dask each job runs OpenCV on one thread: the workers already run one job
    per core, and OpenCV's own thread pool on top oversubscribes the cores (the same evaluation
    took 6 % longer on Dask, whose workers start with OpenCV's default of a thread per core,
    than in a pool whose processes had inherited one thread). A Dask worker is a fresh process
    and sets it itself; a pool's processes are forked, where setting it would deadlock on the
    parent's copied thread pool, so :func:`evaluate` sets it in the parent before forking."""

    def __init__(self, params: Params, options: dict, *, dask_worker: bool = False) -> None:
        self.params, self.options, self.dask_worker = params, options, dask_worker

    def __call__(self, path: str) -> SequenceResult:
        if self.dask_worker:
            restore_malloc_thresholds()
            cv2.setNumThreads(1)
        return evaluate_sequence(path, self.params, **self.options)


def combine(results: list[SequenceResult]) -> dict[str, pd.DataFrame]:
    """Concatenate the tables of several results (adds a ``flow`` column)."""
    def cat(attr):
        frames = [getattr(r, attr).assign(flow=r.flow) for r in results if len(getattr(r, attr))]
        return pd.concat(frames, ignore_index=True) if frames else pd.DataFrame()

    return {"objects": cat("objects"), "frames": cat("frames"), "ablation": cat("ablation")}


def additions_table(paths: list, flows: list[str], *, workers: int | None = None,
                    progress: bool = True, by_sequence: bool = False
                    ) -> pd.DataFrame | tuple[pd.DataFrame, pd.DataFrame]:
    """Table 2 figures of the paper's pipeline, each addition alone, and all of them (defaults),
    for each flow method (one evaluation per variant and flow); last, the defaults fed the
    exact flow of the rendered scenes (``flow`` column ``exact``).

    With ``by_sequence=True`` also returns, per sequence of every variant, the detection and
    coverage rate over its counted objects, its false-positive frames and static pixels flagged,
    and its pixel IoU.
    """
    from .metrics import pixel_scores, table2

    rows, scene_rows = [], []
    variants = {name: (Params.paper(**changes), False) for name, changes in ADDITIONS.items()}
    variants["all (defaults)"] = (Params(), False)
    variants["all, exact flow"] = (Params(), True)
    for flow in flows:
        for name, (params, exact) in variants.items():
            if exact and flow != flows[0]:
                continue  # the same for every flow method
            res = evaluate(paths, params.replace(flow=flow), workers=workers, progress=progress,
                           ablation=False, exact_flow=exact)
            tables = combine(res)
            t = table2(tables["objects"], tables["frames"]).set_index("category")
            row = {"flow": EXACT if exact else flow, "variant": name}
            for cat in t.index:
                row[f"{cat} det"] = t.loc[cat, "detection_rate"]
                row[f"{cat} cov"] = t.loc[cat, "coverage_rate"]
            row["iou"] = pixel_scores(tables["frames"])["iou"]
            rows.append(row)
            for r in res:
                objects = r.objects
                detected = objects[objects.detected] if len(objects) else objects
                scene_rows.append({
                    "flow": row["flow"], "variant": name, "sequence": r.sequence,
                    "detection": float(objects.detected.mean()) if len(objects) else np.nan,
                    "coverage": float(detected.coverage.mean()) if len(detected) else np.nan,
                    "fp_frames": float(r.frames.fp_frame.mean()),
                    "fp_static": float(r.frames.static_flagged.mean()),
                    "iou": pixel_scores(r.frames)["iou"]})
    table = pd.DataFrame(rows)
    return (table, pd.DataFrame(scene_rows)) if by_sequence else table


def sequence_paths(roots: Iterable[str | os.PathLike]) -> list[Path]:
    """Sequence folders given directly or found one level below the given folders."""
    out = []
    for root in map(Path, roots):
        if (root / "frames").is_dir():
            out.append(root)
        elif root.is_dir():
            out += sorted(p for p in root.iterdir() if (p / "frames").is_dir())
        else:
            raise ValueError(f"{root}: no such sequence folder")
    if not out:
        raise ValueError("SEQ_DIR: no sequence folders (with frames/) found")
    return out
