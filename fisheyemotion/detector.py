"""The streaming :class:`MotionDetector` of one camera, in the style of cv2's background
subtractors: ``apply(frame, pose)`` gives the result on ``frame``'s pixels.

>>> detector = fisheyemotion.MotionDetector(cam)
>>> for frame, pose in stream:
...     result = detector.apply(frame, pose)   # None for the first frame

Each frame pair is measured (flow warped by the static-scene prior, the constraints, their
significance, the ground-contact and receding tests, the scene model's update: ``_measure``) and
then decided (the photometric check's seeds, the growth, the transfer to the current frame, the
temporal filter, the segmentation and the extent: ``_decide``); :meth:`MotionDetector.stream` runs the
next pair's flow beside the decision.
"""

from __future__ import annotations

import contextlib
import itertools
import warnings
from collections import OrderedDict, deque
from collections.abc import Iterable, Iterator
from concurrent.futures import Future, ThreadPoolExecutor
from typing import NamedTuple

import cv2
import numpy as np
from numpy.typing import NDArray

from . import _warmup
from .calib.base import CameraModel
from .calib.transforms import check_rigid
from .confirm import confirmed_regions
from .constraints import ConstraintResult, constraints, nearest_static_ray
from .detection import CONSTRAINT_NAMES, Detection, Grid, LazyMaps
from .egomotion import PoseTracker
from .extent import grow_to_extent
from .flow import (
    FlowEstimator,
    grid_average,
    grid_centres,
    grid_gather,
    grid_transfer,
    grid_upsample,
    pixel_transfer,
    warp_by,
)
from .frames import to_gray
from .ground import GroundEstimator, provisional_road
from .ground_contact import standing_regions
from .grow import grow_regions, reach
from .params import Params
from .photometric import (
    SEARCH_STEP,
    SPAN_CANDIDATES,
    UNDER_ROAD,
    arc_candidates,
    cell_residual,
    edge_explained,
    epipolar_directions,
    hidden_cells,
    off_arc_supported,
    span_explained,
    static_explained,
    sweep_ranges,
    testable_cells,
)
from .prior import EgoFlowPrior, lands_on, static_scene_targets
from .range_consistency import RangeMemory
from .receding import receding_cells, road_ranges
from .refinement import PoseRefiner
from .road import Road
from .second_pass import SIZE_STEP, BoxFlows, better_explained, near_cells, second_flow
from .segment import LED, grown_from, segment_cells
from .significance import cell_sigma, pixel_angle, pose_sigma
from .spill import road_explained, trim_regions
from .static_scene import TRIANGULATION_PARALLAX, StaticScene, triangulate_range, world_points

#: Share of the image flagged moving above which a given road (or the poses) is suspect.
FLOODED = 0.5
#: The width of the image, as a share, by which the mask a pose step excludes is widened: it is
#: the result of the frame before the previous one (:meth:`MotionDetector._exclusion`), and its
#: objects have moved by a frame since (16 px at 640 px: a car crossing 5 m away at 30 km/h,
#: 15 fps, moves about that far).
EXCLUSION_MARGIN = 0.025

#: Relative range difference within which a cell agrees with the static-scene model.
SCENE_AGREEMENT = 0.05
#: ... or within this many of the cell's range errors (from its flow's error), if larger.
AGREEMENT_SIGMAS = 2.0
#: Relative range difference within which ``Params.scene_sweep`` takes a cell's range for the
#: road plane's (and leaves the cell alone).
ROAD_READING = 0.1


class _Measured(NamedTuple):
    """A frame pair between :meth:`MotionDetector._measure` and ``_decide``."""

    flow: NDArray[np.float32]
    cell_flow: NDArray[np.float64]
    res: ConstraintResult
    likelihood: NDArray[np.float64]
    valid: NDArray[np.bool_]
    rays1: NDArray[np.float64]
    t0: NDArray[np.float64]
    t1: NDArray[np.float64]
    gray: NDArray[np.uint8] | None
    curr: NDArray[np.uint8] | None
    sigma: NDArray[np.float64] | None
    static_flow: NDArray[np.float32] | None
    road: Road
    prior_road: Road | None  # the road of the pair's prior, where the growth needs it
    stream: bool
    check_curr: bool  # ``curr`` is the stream's newest frame: check its texture for later
    informed: bool  # the static prediction read the scene model's points (the growth's residual)
    decided: NDArray[np.bool_] | None  # cells a region test explained (ground contact) or raised
    own_flow: bool  # the flow is the detector's own (its flow method may measure again)
    # The span before the pair's (its previous frame's pose and gray image; None without
    # ``scene_ranges``) and the cells whose motion along the travel no number of views tells
    # from a static point (floating, receding): the two-span test's (``params.photometric_span``).
    span_before: tuple[NDArray[np.float64], NDArray[np.uint8]] | None = None
    along_travel: NDArray[np.bool_] | None = None
    # The scene model's ranges at the cells as the pair's prior read them (before this pair's
    # update; None outside streams or while the model is empty): the static prediction of the
    # growth and of the two-span test's candidates.
    scene_ranges: NDArray[np.float64] | None = None
    # The cells the three-view test raised by less than ``params.range_consistency_alone``,
    # and the pair's own likelihood they keep unless the photometric check finds them a seed.
    views_alone: NDArray[np.bool_] | None = None
    pair_likelihood: NDArray[np.float64] | None = None


class MotionDetector:
    """Stateful detector for one camera: caches the grid rays, the valid mask and the flow object.

    Parameters
    ----------
    camera : CameraModel
        Any model of :mod:`fisheyemotion.calib`; frames must have its size.
    road : Road or 'auto', optional
        Road plane in the world frame. Default: the plane ``z = 0`` of the world frame (the
        scenes of :mod:`fisheyemotion.synth`). ``'auto'``: estimated from the stream
        (:mod:`fisheyemotion.ground`, the world frame is any): until a plausible plane is found
        the road is :meth:`Road.unknown` (no height, anti-parallel or ground-contact terms);
        :attr:`road` then holds the estimate. ``Road.unknown()``: never use a road.
    params : Params, optional
    camera_height : float, optional
        Metres, for ``road='auto'``: the estimate must put the camera this high (+-25 %).
    roi : ndarray, shape (H, W), optional
        Pixels to use (non-zero), e.g. without the vehicle's own body; default: every pixel
        the camera model gives a ray.
    """

    def __init__(self, camera: CameraModel, road: Road | str | None = None,
                 params: Params | None = None, *, roi: NDArray | None = None,
                 camera_height: float | None = None) -> None:
        if not isinstance(camera, CameraModel):
            raise ValueError("camera: expected a fisheyemotion.calib camera model, "
                             f"got {type(camera).__name__}")
        self.camera = camera
        self.camera_height = camera_height
        self.ground: GroundEstimator | None = None
        if isinstance(road, str):
            if road != "auto":
                raise ValueError(f"road: expected a fisheyemotion.Road, None or 'auto', got {road!r}")
            self.ground = GroundEstimator(camera_height=camera_height)
            road = Road.unknown()
        self.road = Road() if road is None else road
        self.params = Params() if params is None else params
        if not isinstance(self.road, Road):
            raise ValueError(f"road: expected a fisheyemotion.Road, got {type(self.road).__name__}")
        if not isinstance(self.params, Params):
            raise ValueError(f"params: expected a fisheyemotion.Params, got {type(self.params).__name__}")
        g = self.params.grid
        if g > min(camera.width, camera.height):
            raise ValueError(f"params.grid: {g} is larger than the {camera.width}x{camera.height} image")
        self.size = (camera.width, camera.height)
        _warmup.start()  # a cold numba cache: the camera-independent kernels on a second core
        self._centres = grid_centres(camera.width, camera.height, g)
        self._rays0, valid0 = camera.unproject(self._centres)
        pixel_valid = camera.valid_pixel_mask()
        if roi is not None:
            roi = np.asarray(roi)
            if roi.shape != pixel_valid.shape:
                raise ValueError(f"roi: expected shape {pixel_valid.shape} (the camera's), got {roi.shape}")
            pixel_valid &= roi != 0
        # A cell is used only if all of its pixels have rays.
        self._cell_valid = valid0 & (grid_average(pixel_valid.astype(np.float32), g) > 1 - 1e-6)
        self._pixel_valid = pixel_valid
        # Every result is 0 outside the valid pixels: bit masks for the masks (uint8) and for
        # the maps (float32, through an int32 view: NaN or not, a value ANDed with 0 is +0.0).
        self._inside_u8 = np.where(pixel_valid, 255, 0).astype(np.uint8)
        self._inside_bits = np.where(pixel_valid, -1, 0).astype(np.int32)
        self._flow = FlowEstimator(self.params)
        self._second_flow: BoxFlows | None = None
        self._own_flow: NDArray[np.float32] | None = None
        self._prior = (EgoFlowPrior(camera, distance=self.params.prior_distance)
                       if self.params.flow_prior != "none" or self.params.photometric_check
                       else None)
        self.scene = (StaticScene(camera, memory=self.params.scene_memory)
                      if self.params.scene_prior and self.params.flow_prior != "none" else None)
        self._road_warned = False
        self._tracker: PoseTracker | None = None
        self._refiner: PoseRefiner | None = None
        # The frames taken in so far, and the cell masks of the last two results by the frame
        # they belong to: a frame's pose step excludes the mask of the frame two before it
        # (:meth:`_exclusion`).
        self._taken = 0
        self._masks: deque[tuple[int, NDArray[np.bool_]]] = deque(maxlen=2)
        self.last_pose: NDArray[np.float64] | None = None
        self._pixel_angle: NDArray[np.float64] | None = None
        self._view: NDArray[np.bool_] | None = None
        self._cell_samples: NDArray[np.intp] | None = None
        self._static_flow: tuple[bytes, NDArray[np.float32]] | None = None
        self._temporal: tuple[NDArray, NDArray] | None = None
        self._candidates: NDArray[np.bool_] | None = None  # the last result's regions' cells
        self._history: deque[tuple[NDArray[np.uint8], NDArray[np.float64]]] = deque(
            maxlen=self.params.frame_gap)
        self._bootstrapped = False
        self._ranges = RangeMemory(self.params.frame_gap + 1)
        # The texture check's cells of the last frames (gray image, cells): a stream's frame is
        # checked when it is the current frame, in the decision, and read when it is the
        # previous one (MotionDetector.stream decides beside the next pair's flow).
        self._textures: deque[tuple[NDArray[np.uint8], NDArray[np.bool_]]] = deque(
            maxlen=self.params.frame_gap + 1)
        # A stream's last pairs, by their current pose's bytes: (previous pose, previous gray
        # image). The span before a pair is the one whose current frame is its previous frame.
        self._spans: OrderedDict[bytes, tuple[NDArray[np.float64], NDArray[np.uint8]]] = \
            OrderedDict()

    def detect(self, prev: NDArray[np.uint8], curr: NDArray[np.uint8], pose0: NDArray,
               pose1: NDArray) -> Detection:
        """Detect moving objects between two frames.

        Parameters
        ----------
        prev, curr : ndarray of uint8, shape (H, W) or (H, W, 3)
            Gray or BGR frames of the camera's size.
        pose0, pose1 : ndarray, shape (4, 4)
            ``world_from_cam`` at ``prev`` and at ``curr``.
        """
        g0 = to_gray(prev, "prev", size=self.size)
        g1 = to_gray(curr, "curr", size=self.size)
        t0, t1 = check_rigid(pose0, "pose0"), check_rigid(pose1, "pose1")
        return self._detect_gray(g0, g1, t0, t1)

    def apply(self, frame: NDArray[np.uint8], pose: NDArray | None = None) -> Detection | None:
        """Streaming: detect between the frame ``params.frame_gap`` calls ago and this one.

        Returns None until that many frames have been seen. Only the last ``frame_gap`` frames
        and poses are kept. ``pose=None``: the pose is estimated from the images
        (:mod:`fisheyemotion.egomotion`; the world is the first camera's frame). With
        ``road='auto'`` and ``camera_height`` each step's length comes from the road in metres
        and the road is estimated as with given poses; otherwise one unit of translation per
        frame, the scale unknown, and the road terms off (``Road.unknown()``, said once as a
        warning). :attr:`last_pose` is the pose used.
        """
        pair = self._take(frame, pose)
        if pair is None:
            return None
        result = self._detect_gray(*pair, stream=True)
        self._masks.append((self._taken - 1, result.cell_mask > 0))
        return result

    def stream(self, items: Iterable[tuple[NDArray[np.uint8], NDArray | None]]
               ) -> Iterator[Detection | None]:
        """:meth:`apply` over ``(frame, pose)`` items: one result per item, in order, the same
        results as ``apply`` gives, on two cores.

        While one frame pair's result is decided (the photometric check, the transfer to the
        current frame, the temporal filter, the segmentation, the texture check of its current
        frame for the pair that begins with it) in a second thread, the next
        pair's flow is computed: it needs only the static-scene model, which the pair updated
        before its decision. Both threads spend most of their time in OpenCV and in numba
        kernels, which release the GIL. Streams that estimate or refine their poses do too: a
        frame's pose step excludes what the result two frames before found moving
        (:meth:`_exclusion`), which is decided by then. After each result is yielded,
        :attr:`last_pose` is its pose. A
        refused frame or pose raises ``ValueError`` after the results of the frames before it;
        a consumer that leaves early has had one frame more taken in than it was given results
        for: that frame is detected on leaving, unseen, so the detector goes on as ``apply``
        would after the same frames.

        >>> for k, result in enumerate(detector.stream(zip(frames, poses))):
        ...     if result is not None:  # None while the frame gap fills
        ...         cv2.imwrite(f"mask_{k:06d}.png", result.mask)
        """
        # The decision under way: its future, its pose and the frame it belongs to.
        pending: tuple[Future, NDArray, int] | None = None
        taken = None  # a pair whose flow is measured, until its own decision is under way

        def record(result: Detection, pose: NDArray, index: int) -> Detection:
            self._masks.append((index, result.cell_mask > 0))
            self.last_pose = pose
            return result

        def flush():  # the decision under way, if any, as the next result
            nonlocal pending
            if pending is not None:
                (future, pose, index), pending = pending, None
                yield record(future.result(), pose, index)

        def measure(flow, backward, g0, g1, t0, t1) -> _Measured:
            return self._measure(flow, t0, t1, backward, g0, curr=g1, stream=True,
                                 own_flow=True)

        with ThreadPoolExecutor(max_workers=1, thread_name_prefix="fisheyemotion-decide") as pool:
            try:
                items = iter(items)
                while True:
                    try:
                        frame, pose = _pair_item(next(items))
                        if pending is not None and self._waits_for_last(pose):
                            yield from flush()  # the first result: this pose excludes it
                        pair = self._take(frame, pose)
                    except StopIteration:
                        break
                    except Exception:  # a refused frame or pose: the results before it first
                        yield from flush()
                        raise
                    world, index = self.last_pose, self._taken - 1
                    if pair is not None:  # its flow beside the decision
                        taken = (*self._pair_flow(*pair), *pair), world, index
                    yield from flush()
                    self.last_pose = world
                    if pair is None:  # the frame gap is filling
                        yield None
                        continue
                    pending = (pool.submit(self._decide, measure(*taken[0])), world, index)
                    taken = None
                yield from flush()
            finally:
                # Left early (or failing): the frames taken in still update the detector as
                # apply() would, their results unseen.
                with contextlib.suppress(Exception):
                    if pending is not None:
                        record(pending[0].result(), pending[1], pending[2])
                    if taken is not None:
                        record(self._decide(measure(*taken[0])), taken[1], taken[2])

    def _take(self, frame: NDArray[np.uint8], pose: NDArray | None
              ) -> tuple[NDArray[np.uint8], NDArray[np.uint8], NDArray, NDArray] | None:
        """:meth:`apply`'s bookkeeping of a new frame: its gray image, its pose (checked, or
        estimated, or refined and anchored: :attr:`last_pose`), the road's observation and the
        frame history. Returns the pair to detect, ``(prev, curr, pose0, pose1)``, or None
        while the frame gap fills."""
        gray = to_gray(frame, "frame", size=self.size)
        anchor = None  # world_from_chain of refined poses: one for both poses of a pair
        if pose is None:
            t = self._estimated_pose(gray)
        else:
            if self._tracker is not None:
                raise ValueError("pose: this stream estimates its poses (it was started "
                                 "without them); reset() before giving poses")
            t = check_rigid(pose, "pose")
            if self.params.pose_refinement != "off":
                if self._refiner is None:
                    self._refiner = PoseRefiner(self.camera, mode=self.params.pose_refinement,
                                                tolerance=self.params.refine_tolerance,
                                                mask=self._pixel_valid,
                                                camera_height=self.camera_height)
                # The road as given, not as estimated from the refined poses themselves.
                t = self._refiner.step(gray, t, self._exclusion(),
                                       road=self.road if self.ground is None else None)
                anchor = self._refiner.anchor
        world = t if anchor is None else anchor @ t
        self.last_pose = world
        self._observe_ground(gray, world)
        full = len(self._history) == self._history.maxlen
        prev, prev_pose = self._history[0] if full else (None, None)
        if full and not self._bootstrapped:
            self._bootstrap_scene([(g, q if anchor is None else anchor @ q)
                                   for g, q in self._history] + [(gray, world)])
        self._history.append((gray, t))
        self._taken += 1
        if prev is None:
            return None
        return prev, gray, prev_pose if anchor is None else anchor @ prev_pose, world

    def _bootstrap_scene(self, frames: list[tuple[NDArray[np.uint8], NDArray]],
                         flows: list[NDArray[np.float32]] | None = None
                         ) -> list[NDArray[np.float32]] | None:
        """``params.scene_bootstrap``: before a stream's first pair (``frames``: its gray
        frames and poses, the previous frame first, the current last), the scene model learns
        from each consecutive pair between them in turn, each warped by what the pairs before it
        stored (``flows``: their flows, if measured elsewhere). Once per stream (again after
        :meth:`reset`); nothing is decided or reported. Returns the flows used (None if it did
        not run)."""
        if (self._bootstrapped or self.scene is None or not self.params.scene_bootstrap
                or len(frames) < 3):
            return None
        self._bootstrapped = True
        textures = self.params.min_texture > 0
        used = []
        for i, ((g0, t0), (g1, t1)) in enumerate(itertools.pairwise(frames)):
            flow = self._one_flow(g0, g1, t0, t1) if flows is None else flows[i]
            used.append(flow)
            if textures:  # checked once: read by this pair and, kept, by the stream's own
                self._textures.extend([(g0, self._textured_cells(g0))] * 2)
            self._measure(flow, t0, t1, None, g0, curr=g1, stream=True)
        self._static_flow = None
        return used

    def _estimated_pose(self, gray: NDArray[np.uint8]) -> NDArray[np.float64]:
        if self._tracker is None:
            if self._history:
                raise ValueError("pose: this stream was given poses; reset() before leaving "
                                 "them out")
            self._tracker = PoseTracker(self.camera, mask=self._pixel_valid,
                                        camera_height=self.camera_height)
            if self.camera_height is not None and self.ground is not None:
                pass  # metric steps from the road: the road is estimated in the same world
            elif self.road.known or self.ground is not None:
                warnings.warn("pose: estimating poses from the images, whose scale is unknown "
                              "without camera_height: the road terms are off (Road.unknown())",
                              stacklevel=3)
                self.road, self.ground = Road.unknown(), None
        return self._tracker(gray, self._exclusion())

    def _exclusion(self) -> NDArray[np.bool_] | None:
        """Pixels of the previous frame that the pose step of the frame being taken in leaves
        out: what the result of the frame before the previous one found moving (its cell mask),
        widened by ``EXCLUSION_MARGIN`` of the image width for the frame its objects have
        moved since; where that frame has none, the previous frame's own (the first result),
        else None. Not the previous frame's result otherwise: a stream decides that one beside
        this frame's flow (:meth:`stream`), and ``apply`` reads the same frame's so that both
        give the same poses."""
        masks = dict(self._masks)
        if self._taken - 2 in masks:
            r = max(1, round(EXCLUSION_MARGIN * self.size[0]))
            kernel = np.ones((2 * r + 1, 2 * r + 1), np.uint8)  # a square: 0.1 ms, a disc 2 ms
            return cv2.dilate(masks[self._taken - 2].view(np.uint8), kernel) > 0
        return masks.get(self._taken - 1)  # the stream's first result: waited for

    def _waits_for_last(self, pose: NDArray | None) -> bool:
        """Whether the pose step of the frame about to be taken in (given ``pose``) needs the
        previous frame's result (:meth:`_exclusion`: the first result of a stream that
        estimates or refines its poses)."""
        uses = pose is None or self._tracker is not None or self.params.pose_refinement != "off"
        return uses and all(index != self._taken - 2 for index, _ in self._masks)

    def reset(self) -> None:
        """Forget the stream's previous frames, its temporal state, its scene model and its
        estimated poses."""
        self._history.clear()
        self._bootstrapped = False
        self._textures.clear()
        self._spans.clear()
        self._ranges.clear()
        self._temporal = None
        self._candidates = None
        self._tracker, self.last_pose = None, None
        self._taken = 0
        self._masks.clear()
        self._refiner = None
        if self.scene is not None:
            self.scene.clear()

    def detect_flow(self, flow: NDArray, pose0: NDArray, pose1: NDArray, *,
                    backward: NDArray | None = None, prev: NDArray | None = None,
                    curr: NDArray | None = None, stream: bool = False) -> Detection:
        """Detect from a dense flow ``(H, W, 2)`` computed elsewhere (``u' = u + flow``).

        ``backward`` (the flow from the current to the previous frame) enables the
        forward-backward check when ``params.fb_check`` is set; ``prev`` (the previous frame)
        enables the texture check when ``params.min_texture > 0``; ``prev`` and ``curr`` (the
        current frame) enable the photometric check when ``params.photometric_check`` is set;
        ``stream=True`` treats the call as the next frame of a stream (temporal filtering, as
        :meth:`apply`).
        """
        shape = (self.size[1], self.size[0], 2)
        arrays = {"flow": flow, "backward": backward}
        for name, a in arrays.items():
            if a is None:
                continue
            a = np.asarray(a)
            if a.shape != shape or a.dtype.kind != "f":
                raise ValueError(f"{name}: expected a float array of shape {shape}, got {a.dtype} {a.shape}")
        t0, t1 = check_rigid(pose0, "pose0"), check_rigid(pose1, "pose1")
        gray = None if prev is None else to_gray(prev, "prev", size=self.size)
        gray1 = None if curr is None else to_gray(curr, "curr", size=self.size)
        own = flow is self._own_flow and gray is not None and gray1 is not None
        return self._from_flow(np.asarray(flow, np.float32), t0, t1,
                               None if backward is None else np.asarray(backward, np.float32),
                               gray, curr=gray1, stream=stream, own_flow=own)

    def flow(self, prev: NDArray[np.uint8], curr: NDArray[np.uint8], pose0: NDArray,
             pose1: NDArray, *, backward: bool = False):
        """The dense flow ``detect`` uses, from gray frames and checked poses, with the ego prior
        as set in ``params.flow_prior``; with ``backward=True`` also the flow from ``curr`` to
        ``prev``."""
        self._observe_ground(curr, pose1)
        forward = self._one_flow(prev, curr, pose0, pose1)
        self._own_flow = forward  # detect_flow() of this array measures again as apply() does
        if not backward:
            return forward
        return forward, self._one_flow(curr, prev, pose1, pose0)

    def _one_flow(self, a, b, pose_a, pose_b) -> NDArray[np.float32]:
        mode = self.params.flow_prior
        if mode == "none":
            return self._flow(a, b)
        prior, seen = self._static_prior(pose_a, pose_b)
        if self.params.photometric_check:  # for the check of this pair, once
            self._static_flow = (pose_a.tobytes() + pose_b.tobytes(), prior)
        if mode == "ego":
            return self._flow(a, b, prior)
        warped = warp_by(b, prior)
        # Where the static scene leaves the view there is nothing to match: keep `a` there, so
        # that the residual is 0 instead of garbage that the flow's smoothing spreads around.
        np.copyto(warped, a, where=~seen)
        # a(u) ~ warped(u + r) = b(u + r + prior(u + r)) ~ b(u + prior(u) + r)
        residual = self._flow(a, warped)
        residual += prior
        return residual

    def _pair_flow(self, g0, g1, t0, t1) -> tuple[NDArray[np.float32], NDArray | None]:
        """The pair's flow, and the backward one where ``params.fb_check`` asks for it."""
        if self.params.fb_check:
            return self.flow(g0, g1, t0, t1, backward=True)
        return self.flow(g0, g1, t0, t1), None

    def _detect_gray(self, g0, g1, t0, t1, *, stream: bool = False) -> Detection:
        flow, backward = self._pair_flow(g0, g1, t0, t1)
        return self._from_flow(flow, t0, t1, backward, g0, curr=g1, stream=stream,
                               own_flow=True)

    def _resolvable_cells(self, t0: NDArray, t1: NDArray, *, parallax: bool) -> NDArray[np.bool_]:
        """Cells the static-scene prediction says can be scored: its point is seen in the current
        frame (``visibility_check``) and moved by at least ``min_parallax`` pixels through the
        camera's translation (``parallax``: the displacement beyond what the rotation alone
        gives a point at infinity)."""
        p = self.params
        targets, ok = static_scene_targets(self.camera, self._rays0, t0, t1, self.road,
                                           p.prior_distance)
        keep = ok
        if p.visibility_check:
            keep = lands_on(targets, ok, self._inner_view(), *self.size)
        if parallax and p.min_parallax > 0:
            with np.errstate(invalid="ignore"):
                keep &= np.linalg.norm(targets - self._at_infinity(t0, t1), axis=-1) \
                    >= p.min_parallax
        return keep

    def _at_infinity(self, t0: NDArray, t1: NDArray, cells: NDArray[np.bool_] | None = None
                     ) -> NDArray[np.float64]:
        """Where the cells' points at infinity are seen in the current frame: their rays turned
        by the rotation alone (NaN outside the camera's domain), ``(rows, cols, 2)``, or
        ``(n, 2)`` for the ``cells`` given (row-major). A static point's displacement from
        there is its parallax."""
        rays = self._rays0 if cells is None else self._rays0[cells]
        at, _ = self.camera.project(rays @ (t0[:3, :3].T @ t1[:3, :3]))
        return at

    def _inner_view(self) -> NDArray[np.bool_]:
        """The usable pixels shrunk by one cell (H, W): where a cell's whole block is sampled
        from the image (computed on first use)."""
        if self._view is None:
            g = self.params.grid
            self._view = cv2.erode(self._pixel_valid.astype(np.uint8),
                                   np.ones((2 * g + 1,) * 2, np.uint8),
                                   borderType=cv2.BORDER_CONSTANT, borderValue=0) > 0
        return self._view

    def _textured_cells(self, gray: NDArray[np.uint8], *, keep: bool = False
                        ) -> NDArray[np.bool_]:
        """Cells whose mean Sobel gradient magnitude reaches ``params.min_texture``; with
        ``keep``, kept for when the frame begins a pair (a stream's frame is checked once: as
        the current frame of the pair it ends, or else as the previous one)."""
        for i, (seen, cells) in enumerate(tuple(self._textures)):
            if seen is gray:  # a frame is a stream's previous frame once
                del self._textures[i]
                return cells
        gx = cv2.Sobel(gray, cv2.CV_32F, 1, 0, ksize=3, scale=0.125)
        gy = cv2.Sobel(gray, cv2.CV_32F, 0, 1, ksize=3, scale=0.125)
        cells = grid_average(cv2.magnitude(gx, gy), self.params.grid) >= self.params.min_texture
        if keep:
            self._textures.append((gray, cells))
        return cells

    def _consistent_cells(self, flow, cell_flow, backward) -> NDArray[np.bool_]:
        """Cells whose mean forward-backward error is within tolerance (``cell_flow``: the
        cells' mean flow, already computed by the caller)."""
        back_at = warp_by(backward, flow)
        error = np.linalg.norm(flow + back_at, axis=-1)
        p = self.params
        cell_error = grid_average(error, p.grid)
        cell_mag = np.linalg.norm(cell_flow, axis=-1)
        return cell_error <= p.fb_tolerance + p.fb_relative * cell_mag

    def _from_flow(self, flow, t0, t1, backward=None, gray=None, *, curr=None,
                   stream=False, own_flow=False) -> Detection:
        return self._decide(self._measure(flow, t0, t1, backward, gray, curr=curr,
                                          stream=stream, own_flow=own_flow))

    def _measure(self, flow, t0, t1, backward=None, gray=None, *, curr=None,
                 stream=False, own_flow=False) -> _Measured:
        """A pair's cells scored, up to the static-scene model's update: what the next pair's
        flow prior needs (:meth:`stream` computes that flow while :meth:`_decide` runs)."""
        p = self.params
        cell_flow = grid_average(flow, p.grid)
        rays1, valid1 = self.camera.unproject(self._centres + cell_flow)
        res = constraints(self._rays0, rays1, t0, t1, road=self.road, params=p)
        valid = res.valid & valid1 & self._cell_valid
        if p.visibility_check or (p.min_parallax > 0 and not res.static_camera):
            valid &= self._resolvable_cells(t0, t1, parallax=not res.static_camera)
        if p.fb_check and backward is not None:
            valid &= self._consistent_cells(flow, cell_flow, backward)
        if p.min_texture > 0 and gray is not None:
            valid &= self._textured_cells(gray)
        static_flow = None  # before the scene model learns from this pair (the prior uses it)
        decided = along_travel = span_before = scene_ranges = views_alone = pair_only = None
        spans = stream and p.photometric_span > 0 and gray is not None and curr is not None
        if stream and (p.grow > 0 or spans) and self.scene is not None and len(self.scene):
            # the model as the pair's prior read it, before this pair's update
            scene_ranges = self._scene_ranges_at_cells(t0)
        if spans:
            span_before = self._spans.get(t0.tobytes())
            self._spans[t1.tobytes()] = (t0, gray)
            self._spans.move_to_end(t1.tobytes())
            while len(self._spans) > p.frame_gap + 2:  # the pairs a decision may still need
                self._spans.popitem(last=False)
            if scene_ranges is None:
                span_before = None
        # The pair's static prediction read the stream's scene model, not only the road and the
        # far field (before the model learns from this pair).
        informed = stream and self.scene is not None and len(self.scene) > 0
        if p.photometric_check and gray is not None and curr is not None:
            static_flow = self._static_flow_for(t0, t1)
        likelihood = res.likelihood
        sigma = None
        significant = _counts_sigmas(p)
        keep_scene = stream and self.scene is not None
        contact = p.ground_contact and self.road.known
        recede = p.receding > 0 and self.road.known
        if (significant or contact or keep_scene or recede) and not res.static_camera:
            # One triangulation for all: its parallax for the poses' error, every range for the
            # contact test, however little parallax it has; the scene model and the three views
            # use well-conditioned ones only.
            ranges, _, parallax = triangulate_range(self._rays0, rays1, t0, t1,
                                                    far=p.prior_distance, with_parallax=True)
        if (significant or contact or recede) and not res.static_camera:
            sigma = cell_sigma(flow, p.grid, self._cell_pixel_angle(), floor=p.flow_sigma,
                               mean=cell_flow)
            pose = pose_sigma(self._rays0, parallax, t0, t1, p.position_sigma)
            sigma *= sigma
            sigma += pose * pose
            np.sqrt(sigma, out=sigma)
        if significant and not res.static_camera:
            likelihood = self._with_significance(res, sigma, likelihood)
        three = (p.range_consistency > 0 and stream and gray is not None and curr is not None
                 and sigma is not None)
        if (keep_scene or contact or three or recede) and not res.static_camera:
            with np.errstate(invalid="ignore", divide="ignore"):
                range_error = sigma / parallax if sigma is not None else None  # d(lambda)/lambda
                conditioned = parallax >= np.sin(TRIANGULATION_PARALLAX)
            if contact:
                before = likelihood
                likelihood, doubted, along_travel = self._explain_standing(
                    res, likelihood, valid, ranges, range_error, sigma, t0)
                with np.errstate(invalid="ignore"):
                    decided = likelihood < before
            if recede:
                before = likelihood
                likelihood = self._receding(likelihood, valid, ranges, range_error, t0)
                with np.errstate(invalid="ignore"):
                    raised = likelihood > before
                decided = raised if decided is None else decided | raised
                along_travel = raised if along_travel is None else along_travel | raised
            pair_only = likelihood  # the pair's own evidence, which the scene model learns from
            if three:
                likelihood, views_alone = self._three_views(
                    likelihood, valid & conditioned, ranges, range_error, cell_flow, gray, curr,
                    t0, t1)
            if keep_scene:
                with np.errstate(invalid="ignore"):
                    static = valid & (pair_only < p.threshold)
                    if contact:  # static by its arc, but its range or the model's is wrong
                        static &= ~doubted
                stored = np.where(conditioned, ranges, np.nan)
                if p.scene_sweep > 0 and gray is not None and curr is not None:
                    stored = self._swept_ranges(stored, static, flow, cell_flow, gray, curr,
                                                t0, t1)
                self.scene.add(self._rays0, stored, t0, static)
        return _Measured(flow, cell_flow, res, likelihood, valid, rays1, t0, t1, gray, curr,
                         sigma, static_flow, self.road,
                         self._prior_road(t0, t1) if p.grow > 0 else None, stream,
                         p.min_texture > 0 and curr is not None and bool(self._history)
                         and self._history[-1][0] is curr, informed, decided, own_flow,
                         span_before, along_travel, scene_ranges, views_alone, pair_only)

    def _decide(self, m: _Measured) -> Detection:
        """A measured pair's result: the photometric check's seeds, the growth and the
        result on the current frame. Reads nothing of the detector that the next pair's flow
        changes (the road is the one the pair was measured with)."""
        p = self.params
        flow, cell_flow, res, likelihood, valid = m.flow, m.cell_flow, m.res, m.likelihood, m.valid
        t0, t1, gray, curr, static_flow = m.t0, m.t1, m.gray, m.curr, m.static_flow
        seeds = None
        if static_flow is not None:
            # A region is reported only if one of its cells (above the threshold: only they
            # are tested) is not explained by the static scene.
            with np.errstate(invalid="ignore"):
                above = valid & (likelihood > p.threshold)
            def predicted(r, c):  # the static scene's prediction of cells (r, c), pixels
                return self._centres[r, c] + self._at_cell_centres(static_flow)[r, c]

            def along(cells):  # the epipolar curves at the cells' predicted points
                return epipolar_directions(self.camera, predicted(*np.nonzero(cells)), t0, t1)

            def parallax(cells):  # the predictions' distance from their points at infinity
                return np.linalg.norm(predicted(*np.nonzero(cells))
                                      - self._at_infinity(t0, t1, cells), axis=-1)

            def reach(cells):  # how far the prediction's range error moves it, pixels
                return p.photometric_range_error * parallax(cells)

            measured = cell_residual(gray, curr, flow, p.grid, above)  # shared by both tests
            seeds = above & ~static_explained(
                gray, curr, flow, static_flow, p.grid, p.photometric_margin, cells=above,
                tolerance=p.photometric_tolerance, directions=along, measured=measured,
                reach=reach if p.photometric_range_error > 0 else None)
            if p.photometric_edge > 0 and seeds.any() and not res.static_camera:
                motion = self._at_cell_centres(static_flow)
                # The parallax of the seeds and their neighbours (NaN elsewhere).
                around = cv2.dilate(seeds.view(np.uint8), np.ones((3, 3), np.uint8)) > 0
                depth = np.full(seeds.shape, np.nan)  # parallax: the larger, the nearer
                depth[around] = parallax(around)
                seeds &= ~edge_explained(gray, curr, p.grid, seeds, measured, motion, depth,
                                         p.photometric_edge)
                # What a nearer neighbour hides now, only its own flow can show.
                with np.errstate(invalid="ignore"):
                    seeds &= ~(hidden_cells(p.grid, seeds, motion, depth, p.photometric_edge)
                               & ~(measured < p.photometric_margin))
            if p.photometric_view and seeds.any():
                r, c = np.nonzero(seeds)
                seeds[r, c] = testable_cells(predicted(r, c), self._inner_view(),
                                             measured[r, c], p.photometric_margin)
            if p.photometric_arc and seeds.any() and not res.static_camera:
                seeds &= self._supported_off_arc(seeds, flow, cell_flow, m.rays1, t0, t1, gray,
                                                 curr, m.sigma, measured, m.road)
            if p.photometric_span > 0 and m.span_before is not None and seeds.any() \
                    and not res.static_camera:
                seeds &= ~self._span_explained(m, seeds, measured)
            if m.views_alone is not None:
                # Raised by three views alone, explained by the images: weak evidence.
                weak = m.views_alone & ~seeds
                if weak.any():
                    likelihood = np.where(weak, m.pair_likelihood, likelihood)
                    m = m._replace(likelihood=likelihood)
        if p.second_pass > 0 and m.own_flow and gray is not None and curr is not None \
                and not res.static_camera:
            likelihood = self._second_pass(m, seeds)
        if p.grow > 0 and m.informed and not res.static_camera:
            # Only where the static prediction knows the structure beside the road: elsewhere
            # a wall's residual is its own parallax, and regions would grow over it.
            likelihood = self._grown(m, likelihood)
        if m.check_curr:  # for the stream's pair whose previous frame it will be
            self._textured_cells(curr, keep=True)
        self._check_road(t0)
        return self._assemble(flow, cell_flow, res, likelihood, valid, stream=m.stream,
                              seeds=seeds, curr=curr, static_flow=static_flow,
                              informed=m.informed, prev=gray, poses=(t0, t1), road=m.road)

    def _second_pass(self, m: _Measured, seeds: NDArray[np.bool_] | None) -> NDArray[np.float64]:
        """The pair's likelihood where a second flow pass (:mod:`fisheyemotion.second_pass`)
        explains the frames better: on the groups of cells within ``params.second_pass`` cells
        of those above the threshold that hold a seed (``seeds``, None: all), not on the cells
        a region test decided (the ground-contact test explained them, the receding test
        raised them: their evidence is the region's, not the cell's flow)."""
        p = self.params
        with np.errstate(invalid="ignore"):
            above = m.valid & (m.likelihood > p.threshold)
        if not above.any():
            return m.likelihood
        near = near_cells(above, p.second_pass) & m.valid
        if seeds is not None:  # only around what can be reported: regions need a seed
            near = grown_from(seeds & near, near)
        if m.decided is not None:
            near &= ~m.decided
        dis = p.flow == "dis" or p.second_pass_flow != "same"
        if self._second_flow is None:  # its own estimators: stream() runs the next flow meanwhile
            box = p if p.second_pass_flow == "same" else p.replace(
                flow="dis", dis_preset=p.second_pass_flow.removeprefix("dis-"))
            self._second_flow = BoxFlows(lambda: FlowEstimator(box))
        flow = second_flow(m.gray, m.curr, m.flow, near, p.grid, self._second_flow,
                           size_step=SIZE_STEP if dis else 1)
        r, c = np.nonzero(near)
        g = p.grid
        at = self._centres[r, c] + grid_average(flow, g)[r, c]
        rays1, ok = self.camera.unproject(at)
        # Where a cell's block, or the block it lands on, leaves the image, the new flow
        # matches the replicated border: no evidence.
        view = self._inner_view()
        ok &= lands_on(at, ok, view, *self.size) & lands_on(self._centres[r, c], ok, view,
                                                              *self.size)
        res = constraints(self._rays0[r, c], rays1, m.t0, m.t1, road=m.road, params=p)
        likelihood = res.likelihood
        if m.sigma is not None and _counts_sigmas(p):
            likelihood = self._with_significance(res, m.sigma[r, c], likelihood)
        out = m.likelihood.copy()
        take = ok & res.valid & np.isfinite(likelihood)
        if take.any():  # the flow that explains the frames better measures the cell
            take[take] = better_explained(m.gray, m.curr, m.flow, flow, g, r[take], c[take],
                                          near.shape)
        out[r[take], c[take]] = likelihood[take]
        return out

    def _span_explained(self, m: _Measured, seeds: NDArray[np.bool_], measured: NDArray
                        ) -> NDArray[np.bool_]:
        """The seeds that one static point explains over the pair and the span before it
        (:func:`~fisheyemotion.photometric.span_explained`): candidate ranges within
        ``params.photometric_span`` of the scene model's (log-uniform), none under the road;
        not the cells whose motion along the travel the region tests found (``m.along_travel``),
        which no number of views tells from a static point."""
        p = self.params
        pose_before, before = m.span_before
        model = m.scene_ranges
        cells = seeds & np.isfinite(model)
        if m.along_travel is not None:
            cells &= ~m.along_travel
        if not cells.any():
            return cells
        r, c = np.nonzero(cells)
        factors = np.exp(np.linspace(-p.photometric_span, p.photometric_span, SPAN_CANDIDATES))
        points = world_points(self._rays0[r, c][None], model[r, c] * factors[:, None], m.t0)
        static = m.road.height(points) >= -UNDER_ROAD if m.road.known else True

        def moves(pose: NDArray) -> NDArray[np.float64]:  # each candidate's cell shift, pixels
            pixels, ok = self.camera.project((points - pose[:3, 3]) @ pose[:3, :3])
            return np.where((ok & static)[..., None], pixels - self._centres[r, c], np.nan)

        return span_explained(m.gray, m.curr, before, p.grid, cells, measured, moves(m.t1),
                              moves(pose_before))

    def _cell_pixel_angle(self) -> NDArray[np.float64]:
        """Radians per pixel at each cell centre (:func:`~fisheyemotion.significance.pixel_angle`),
        computed on first use."""
        if self._pixel_angle is None:
            self._pixel_angle = pixel_angle(self.camera, self._centres)
        return self._pixel_angle

    def _supported_off_arc(self, seeds, flow, cell_flow, rays1, t0, t1, gray, curr, sigma,
                           measured, road: Road) -> NDArray[np.bool_]:
        """The seed cells whose evidence the images support (:mod:`fisheyemotion.photometric`):
        their deviation from the epipolar arc (against the static correspondences within
        ``photometric_search`` pixels along it of the nearest one), or else their likelihood at
        the nearest (on the arc: the height and anti-parallel deviations, the height's
        significance)."""
        p = self.params
        r, c = np.nonzero(seeds)
        rays0 = self._rays0[r, c]
        arc = nearest_static_ray(rays0, rays1[r, c], t0, t1)
        measured_at = self._centres[r, c] + cell_flow[r, c]
        at, _ = self.camera.project(arc)
        off_arc = off_arc_supported(gray, curr, flow, p.grid, p.photometric_margin, seeds,
                                    at - measured_at, measured)
        on_arc = constraints(rays0, arc, t0, t1, road=road, params=p)
        likelihood = on_arc.likelihood
        if sigma is not None and _counts_sigmas(p):
            likelihood = self._with_significance(on_arc, sigma[r, c], likelihood)
        with np.errstate(invalid="ignore"):
            scored = likelihood > p.threshold
        # The search can only take support away: it runs where the nearest point gave it and
        # the arc's deviations do not make the cell a seed anyway.
        search = off_arc[r, c] & ~scored
        if p.photometric_search > 0 and search.any():
            reach = np.arange(-p.photometric_search, p.photometric_search + 1e-9, SEARCH_STEP)
            angle = self._cell_pixel_angle()[r[search], c[search]]
            candidates = arc_candidates(rays0[search], arc[search], t0, t1, reach[:, None] * angle)
            at, _ = self.camera.project(candidates)
            cells = np.zeros_like(seeds)
            cells[r[search], c[search]] = True
            off_arc &= ~cells | off_arc_supported(gray, curr, flow, p.grid, p.photometric_margin,
                                                  cells, at - measured_at[search], measured)
        out = off_arc.copy()
        out[r, c] |= scored
        return out

    def _swept_ranges(self, ranges, static, flow, cell_flow, gray, curr, t0, t1
                      ) -> NDArray[np.float64]:
        """``ranges`` with the cells about to be stored whose flow explains the frames worse
        than ``params.scene_sweep`` replaced by the range along their arc that explains them
        better by ``params.scene_sweep_margin`` (:func:`~fisheyemotion.photometric.sweep_ranges`);
        not on the cells read on the road."""
        p = self.params
        with np.errstate(invalid="ignore"):
            # Cells the flow reads on the road (within ROAD_READING of its plane) are left to
            # the plane: the prior reads the model only where it holds something nearer.
            road = road_ranges(self._rays0, t0, self.road)
            cells = static & np.isfinite(ranges) & ~(np.abs(ranges / road - 1) < ROAD_READING)
            residual = cell_residual(gray, curr, flow, p.grid, cells)
            poor = cells & (residual >= p.scene_sweep)
        if not poor.any():
            return ranges
        r, c = np.nonzero(poor)
        swept, best = sweep_ranges(self.camera, gray, curr, flow, p.grid, poor, self._rays0[r, c],
                                   self._centres[r, c] + cell_flow[r, c], t0, t1,
                                   distance=p.prior_distance)
        with np.errstate(invalid="ignore"):
            better = best < residual[r, c] - p.scene_sweep_margin
        out = ranges.copy()
        out[r[better], c[better]] = swept[better]
        return out

    def _static_prior(self, pose_a: NDArray, pose_b: NDArray
                      ) -> tuple[NDArray[np.float32], NDArray[np.bool_]]:
        """The ego prior's flow from ``pose_a`` to ``pose_b`` with the static-scene model as it
        is now, and where it is seen."""
        return self._prior(pose_a, pose_b, self._prior_road(pose_a, pose_b),
                           view=self._pixel_valid, scene=self.scene)

    def _static_flow_for(self, t0: NDArray, t1: NDArray) -> NDArray[np.float32]:
        """The static scene's flow for this pair: the prior the flow was just warped by (taken
        once: the scene model learns from the pair after the check), or computed now (a flow
        from elsewhere)."""
        cached, self._static_flow = self._static_flow, None
        if cached is not None and cached[0] == t0.tobytes() + t1.tobytes():
            return cached[1]
        return self._static_prior(t0, t1)[0]

    def _grown(self, m: _Measured, likelihood: NDArray[np.float64]) -> NDArray[np.float64]:
        """The likelihood with the cells that regions grow into (:mod:`fisheyemotion.grow`)
        raised to just above the threshold. A cell's residual is its flow less the static
        prediction of the pair's prior: the road it used (``m.prior_road``), the far field and
        the scene model's ranges as the prior read them (``m.scene_ranges``; in ``stream()``
        the next pair updates the model meanwhile). Streams only, once the model holds points
        (``m.informed``)."""
        p = self.params
        with np.errstate(invalid="ignore"):
            moving = m.valid & (likelihood > p.threshold)
        box = reach(moving, p.grow)
        if box is None:
            return likelihood
        # The residual where the growth reads it: the cells within its reach of a region.
        targets, ok = static_scene_targets(
            self.camera, self._rays0[box], m.t0, m.t1, m.prior_road, p.prior_distance,
            None if m.scene_ranges is None else m.scene_ranges[box])
        residual = np.full(m.cell_flow.shape, np.nan)
        residual[box] = np.where(ok[..., None], self._centres[box] + m.cell_flow[box] - targets,
                                 np.nan)
        grown = grow_regions(moving, residual, m.valid, steps=p.grow)
        raised = np.nextafter(p.threshold, np.inf)
        return np.where(grown & ~moving, np.fmax(likelihood, raised), likelihood)

    def _check_road(self, pose: NDArray) -> None:
        """Warn (once per detector) when a given road is implausible for the camera."""
        if self._road_warned or not self.road.known or self.ground is not None:
            return
        height = float(self.road.height(pose[:3, 3]))
        if height <= 0.05:
            self._road_warned = True
            warnings.warn(f"road: the camera is {height:.2f} m above the given road (on or "
                          "under it); is the road's normal pointing up in this world frame? "
                          "road='auto' estimates it", stacklevel=3)

    def _observe_ground(self, gray: NDArray[np.uint8], pose: NDArray) -> None:
        """``road='auto'``: the estimator sees every frame (it tracks consecutive frames) and
        refits now and then; a plausible fit becomes the road."""
        if self.ground is None:
            return
        road = self.ground.observe(self.camera, gray, pose, mask=self._pixel_valid)
        if road is not None:
            self.road = road

    def _prior_road(self, pose: NDArray, pose_b: NDArray) -> Road:
        """The road the ego prior warps by: the known one or, while ``road='auto'`` has not
        found one yet, a provisional plane (:func:`fisheyemotion.ground.provisional_road`:
        ``camera_height`` below the camera, its normal the camera's image-down axis with the
        direction of travel projected out). The constraints never see it."""
        if self.road.known or self.ground is None:
            return self.road
        return provisional_road(pose, pose_b, self.ground.camera_height)

    def _with_significance(self, res: ConstraintResult, sigma, likelihood) -> NDArray:
        """The likelihood raised where a deviation is significant: at ``params.significance``
        flow-error sigmas of height or depth, or ``params.epipolar_significance`` of the
        epipolar deviation, a cell reaches the threshold (:mod:`fisheyemotion.significance`;
        ``sigma``: the cells' angular flow error; a scale of 0 leaves that term raw)."""
        p = self.params
        z = np.full(likelihood.shape, np.nan)
        with np.errstate(invalid="ignore", divide="ignore"):
            if p.significance > 0:
                z = np.fmax(res.height, res.depth) / (sigma * p.significance)
            if p.epipolar_significance > 0:
                z = np.fmax(z, res.epipolar / (sigma * p.epipolar_significance))
        return np.fmax(likelihood, np.where(np.isfinite(z), p.threshold * z, np.nan))

    def _antiparallel_part(self, res: ConstraintResult) -> NDArray[np.float64]:
        """The anti-parallel deviation's weighted part of each cell's likelihood (0 where it is
        NaN): what the ground-contact test explains and what leads a region."""
        p = self.params
        return p.weights[3] * np.where(np.isnan(res.antiparallel), 0.0, res.antiparallel) / sum(
            p.weights)

    def _explain_standing(self, res: ConstraintResult, likelihood, valid, ranges, range_error,
                          sigma, pose0) -> tuple[NDArray, NDArray[np.bool_], NDArray[np.bool_]]:
        """The likelihood with the anti-parallel deviation removed from regions that stand on
        the road (:mod:`fisheyemotion.ground_contact`) and agree with the scene model or,
        with ``params.contact_arc``, lie on their epipolar arc (``range_error``: each cell's
        relative range error from its flow's; ``sigma``: its flow's angular error), and, with
        ``params.contact_epipolar``, their epipolar deviation counted in sigmas only; and the
        cells explained by their arc alone, whose range disagrees with the model's; and the
        cells of the regions led by the anti-parallel term that float (do not stand)."""
        p = self.params
        doubted = np.zeros(likelihood.shape, bool)
        weighted = self._antiparallel_part(res)
        with np.errstate(invalid="ignore", divide="ignore"):
            moving = valid & (likelihood > p.threshold)
            share = np.where(moving, weighted / likelihood, 0.0)
        if not moving.any():
            return likelihood, doubted, doubted.copy()
        stands = standing_regions(moving, share, ranges, self._rays0, pose0, self.camera,
                                  self.road, p.grid, ratio=p.contact_ratio,
                                  columns=p.contact_columns)
        floating = moving & (share >= LED) & ~stands  # led by the anti-parallel term
        if self.scene is not None and len(self.scene) and stands.any():
            # A static point stays where it was: a cell whose range disagrees with what the
            # scene model measured along its ray before, by more than the flow's error explains,
            # has moved (e.g. a pedestrian stepping out beside a parked car, which stands on the
            # road too).
            before = self._scene_ranges_at_cells(pose0)
            with np.errstate(invalid="ignore", divide="ignore"):
                tolerance = np.fmax(SCENE_AGREEMENT, AGREEMENT_SIGMAS * range_error)
                moved = np.abs(ranges / before - 1) > tolerance
                if p.contact_arc > 0:
                    # ... unless it is seen where a static point would be, on its epipolar
                    # arc: a pedestrian stepping out moves off it, a parked car does not.
                    doubted = stands & moved & (res.epipolar < p.contact_arc * sigma)
                    moved &= ~doubted
            stands &= ~moved
        explained = np.where(stands, likelihood - weighted, likelihood)
        if p.contact_epipolar and p.epipolar_significance > 0 and stands.any():
            # A standing static cell's epipolar deviation counts in sigmas only: within
            # `epipolar_significance` of them the flow's error explains it, however large the
            # raw angle (the significance's epipolar part is then below the threshold).
            with np.errstate(invalid="ignore"):
                on_arc = stands & (res.epipolar < p.epipolar_significance * sigma)
            if on_arc.any():
                epipolar = np.where(np.isnan(res.epipolar), 0.0, res.epipolar)
                rest = res.likelihood - weighted - p.weights[0] * epipolar / sum(p.weights)
                rest = self._with_significance(res, sigma, rest)
                explained = np.where(on_arc, rest, explained)
        return explained, doubted, floating

    def _receding(self, likelihood, valid, ranges, range_error, pose0) -> NDArray[np.float64]:
        """The likelihood raised on the regions whose base reads beyond the road it stands on
        (:mod:`fisheyemotion.receding`): regions of the cells above
        ``params.receding_candidates`` times the threshold, in the columns where the base is
        ``params.receding`` range-error sigmas or more beyond the road."""
        p = self.params
        with np.errstate(invalid="ignore"):
            candidates = valid & (likelihood > p.receding_candidates * p.threshold)
        if not candidates.any():
            return likelihood
        z = receding_cells(candidates, np.where(valid, ranges, np.nan), range_error,
                           self._rays0, pose0, self.road)
        with np.errstate(invalid="ignore"):
            raised = np.where(z >= p.receding, p.threshold * z / p.receding, np.nan)
        return np.fmax(likelihood, raised)

    def _three_views(self, likelihood, usable, ranges, range_error, cell_flow, prev, curr,
                     t0, t1) -> tuple[NDArray[np.float64], NDArray[np.bool_] | None]:
        """The likelihood raised where a cell's range disagrees with the static point the
        previous pair landed in it, by ``params.range_consistency`` flow-error sigmas or more
        (:mod:`fisheyemotion.range_consistency`), and the cells raised by less than
        ``params.range_consistency_alone`` (None where ``prev`` was not remembered); and this
        pair's static cells remembered for the pair whose previous frame ``curr`` will be."""
        p = self.params
        usable = usable & np.isfinite(ranges) & (ranges < p.prior_distance)
        z = self._ranges.deviation(prev, ranges, range_error, t0[:3, 3])
        alone = None
        if z is not None:
            with np.errstate(invalid="ignore"):
                beyond = usable & (z > p.range_consistency)
                raised = np.where(beyond, p.threshold * z / p.range_consistency, np.nan)
                alone = beyond & (z < p.range_consistency_alone) & (raised > likelihood)
            likelihood = np.fmax(likelihood, raised)
        with np.errstate(invalid="ignore"):
            static = usable & (likelihood < p.threshold)
        self._ranges.remember(curr, world_points(self._rays0, ranges, t0), range_error,
                              self._centres + cell_flow, static, p.grid, t1[:3, 3])
        return likelihood, alone

    def _at_cell_centres(self, image: NDArray) -> NDArray:
        """A full-resolution map ``(H, W, ...)`` read at each cell's centre pixel (exact for odd
        grids): ``(rows, cols, ...)``, a view."""
        g = self.params.grid
        centre = (g - 1) // 2
        rows, cols = self._centres.shape[:2]
        return image[centre:rows * g:g, centre:cols * g:g]

    def _scene_ranges_at_cells(self, pose0: NDArray) -> NDArray[np.float64]:
        """The scene model's ranges at the cell centres, read off the prior's coarser samples
        (computed once per frame pair: the prior asked for the same)."""
        step = self._prior.step
        w, h = self.size
        coarse = self.scene.ranges(pose0, step, (-(-h // step), -(-w // step)))
        if self._cell_samples is None:  # each cell's sample: fixed by the camera and the grid
            c = (self._centres[..., 0] // step).astype(np.intp)
            r = (self._centres[..., 1] // step).astype(np.intp)
            self._cell_samples = r * coarse.shape[1] + c
        return coarse.ravel()[self._cell_samples]

    def _temporal_filter(self, cell_likelihood, carrier, source):
        """Accumulated likelihood and the age (consecutive moving detections) of every cell:
        ``L = (1 - decay) L_now + decay L_before``, the previous detection's map read where each
        cell came from (consecutive detections are one frame apart, so regions moved by about
        ``flow / frame_gap``; ``carrier[source]`` is each cell's flow)."""
        from ._grid_kernels import accumulate  # numba on first use: a light import

        p = self.params
        if self._temporal is None:
            acc = np.nan_to_num(cell_likelihood, nan=0.0)
            age = np.where(acc > p.threshold, 1, 0)
        else:
            acc_before, age_before = self._temporal
            acc, age = np.empty(cell_likelihood.shape), np.empty(cell_likelihood.shape, np.int64)
            accumulate(source, np.ascontiguousarray(cell_likelihood, np.float64), carrier,
                       acc_before, age_before, float(p.temporal_decay), float(p.threshold),
                       int(p.frame_gap), int(p.grid), acc, age)
        self._temporal = (acc, age)
        return np.where(np.isnan(cell_likelihood), np.nan, acc), age

    def _assemble(self, flow, cell_flow, res: ConstraintResult, likelihood, valid, *,
                  stream: bool = False, seeds: NDArray[np.bool_] | None = None,
                  curr: NDArray[np.uint8] | None = None,
                  static_flow: NDArray[np.float32] | None = None,
                  informed: bool = False, prev: NDArray[np.uint8] | None = None,
                  poses: tuple[NDArray, NDArray] | None = None,
                  road: Road | None = None) -> Detection:
        p, (w, h) = self.params, self.size
        measured = np.where(valid, likelihood, np.nan)
        # The measurement lives on the previous frame's cells; the result belongs to the current
        # frame: every cell moves by the mean flow it was scored with (the most likely one wins
        # where several land), median-filtered over 3x3 cells so that a lone wrong flow does not
        # throw its cell across the image.
        carrier = cv2.medianBlur(np.ascontiguousarray(cell_flow, dtype=np.float32), 3)
        source = grid_transfer(carrier, measured, p.grid)
        if p.carry_share > 0:
            # ... and the flagged cells' pixels by their own flow: an object a few cells wide
            # moving across its background is not carried partly beside itself.
            with np.errstate(invalid="ignore"):  # NaN where not valid: never flagged
                flagged = measured > p.threshold
            source = pixel_transfer(source, flow, measured, flagged, p.grid, share=p.carry_share)
        valid_now = grid_gather(valid, source, False)

        def to_image(cells: NDArray[np.float64]) -> NDArray[np.float32]:
            full = grid_upsample(np.where(valid_now, cells, 0.0).astype(np.float32), p.grid, w, h)
            bits = full.view(np.int32)
            cv2.bitwise_and(bits, self._inside_bits, dst=bits)
            return full

        def now(cells: NDArray[np.float64]) -> NDArray[np.float64]:
            return grid_gather(cells, source)

        cell_likelihood = now(measured)
        maps = LazyMaps(CONSTRAINT_NAMES, lambda name: to_image(now(getattr(res, name))))
        age = None
        if stream and (p.temporal_decay > 0 or p.persistence > 1):
            cell_likelihood, age = self._temporal_filter(cell_likelihood, carrier, source)
        likelihood = to_image(np.where(np.isnan(cell_likelihood), 0.0, cell_likelihood))
        led = None
        if p.antiparallel_seeds > 1 and seeds is not None:
            with np.errstate(invalid="ignore", divide="ignore"):  # the anti-parallel share
                led = now(self._antiparallel_part(res) / measured)
        cell_mask, regions, labels = segment_cells(
            cell_likelihood, threshold=p.threshold, grid=p.grid, min_area=p.min_area, age=age,
            persistence=p.persistence, seed_threshold=p.seed_threshold,
            extend_threshold=p.extend_threshold,
            seeds=None if seeds is None else grid_gather(seeds, source, False),
            gap=p.region_gap, led=led, led_seeds=p.antiparallel_seeds, with_labels=True)

        def on_pixels(cells: NDArray[np.bool_]) -> NDArray[np.uint8]:
            return cv2.bitwise_and(grid_upsample(cells.astype(np.uint8) * 255, p.grid, w, h),
                                   self._inside_u8)

        mask = cells_now = on_pixels(cell_mask)
        if p.region_gap > 0:
            # What the constraints flagged: not the cells the closing over small gaps filled in,
            # which the pose step need not leave out.
            with np.errstate(invalid="ignore"):
                cells_now = on_pixels(cell_mask & (cell_likelihood > p.threshold))
        flagged_cells = cell_mask
        if stream and p.confirm_reach > 0:
            # Reported only where the previous result had a region (its candidates: the test
            # does not feed on itself); the pose step still leaves every candidate out.
            labels, regions = confirmed_regions(labels, regions, self._candidates,
                                                p.confirm_reach)
            self._candidates = cell_mask
            cell_mask = labels > 0
            mask = on_pixels(cell_mask)
        if p.extent_reach > 0 and curr is not None and regions:
            # The mask of the frame the user passed last, grown on that frame's image.
            residual = None
            if static_flow is not None:  # the cells' own motion, on the current frame's cells
                at = self._at_cell_centres(static_flow)
                residual = now(np.where(valid[..., None], cell_flow - at, np.nan))
            mask, regions, pixel_labels = grow_to_extent(
                labels, regions, p.grid, curr, likelihood, threshold=p.threshold,
                reach=p.extent_reach, static_fraction=p.extent_static, residual=residual,
                inside=self._inside_u8, residual_decides=p.extent_residual and informed,
                with_labels=True)
        else:
            pixel_labels = None
        known = road is not None and (road.known or res.static_camera)
        if p.road_spill > 0 and regions and known and curr is not None and prev is not None \
                and poses is not None:
            # The flow's spill onto the road (or, the camera still, onto anything static),
            # where the images show it.
            if pixel_labels is None:
                pixel_labels = np.where(mask > 0, grid_upsample(labels, p.grid, w, h), 0)
            spill = road_explained(prev, curr, mask > 0, self._rays0, self.camera, *poses,
                                   road, now(carrier), grid=p.grid, tolerance=p.road_spill,
                                   still=res.static_camera)
            if spill.any():
                mask, regions = trim_regions(pixel_labels, regions, spill, grid=p.grid)
        if not self._road_warned and self.road.known and self.ground is None \
                and flagged_cells[self._cell_valid].mean() > FLOODED:
            self._road_warned = True
            warnings.warn(f"detection: more than {FLOODED:.0%} of the image is flagged moving; "
                          "are the poses world_from_cam and the road right for this world "
                          "frame? road='auto' estimates the road", stacklevel=3)
        grid = Grid(p.grid, self._centres, cell_flow, measured, valid)
        return Detection(likelihood, mask, maps, flow, grid, regions, res.static_camera,
                         cells_now)


def _counts_sigmas(params: Params) -> bool:
    """Whether some deviation counts in flow-error sigmas (:meth:`MotionDetector._with_significance`)."""
    return params.significance > 0 or params.epipolar_significance > 0


def _pair_item(item) -> tuple:
    """One ``(frame, pose)`` item of :meth:`MotionDetector.stream`, or a ValueError."""
    if isinstance(item, np.ndarray) or not isinstance(item, tuple | list) or len(item) != 2:
        raise ValueError("items: expected (frame, pose) pairs (pose None to estimate it), got "
                         f"{type(item).__name__}" + (f" of length {len(item)}"
                                                     if isinstance(item, tuple | list) else ""))
    return item[0], item[1]
