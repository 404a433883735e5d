"""Every knob of the detector in one frozen, validated dataclass."""

from __future__ import annotations

import dataclasses
import difflib
import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

FLOW_METHODS = ("farneback", "dis")
DIS_PRESETS = ("ultrafast", "fast", "medium")
LAMBDA_P_MODES = ("constant", "adaptive")
POSE_REFINEMENTS = ("off", "on", "auto")
FLOW_PRIORS = ("none", "ego", "warp")
SECOND_PASS_FLOWS = ("same", "dis-ultrafast", "dis-fast", "dis-medium")

#: Radians per pixel at the image centre of the cameras the defaults were chosen on (200 px/rad).
REFERENCE_PIXEL_ANGLE = 1 / 200

#: Farneback settings; OpenCV's sample values, the paper does not state its own.
FARNEBACK_DEFAULTS = {"pyr_scale": 0.5, "levels": 3, "winsize": 15, "iterations": 3,
                      "poly_n": 5, "poly_sigma": 1.2}


@dataclass(frozen=True, kw_only=True)
class Params:
    """Parameters of :func:`fisheyemotion.constraints` and :func:`fisheyemotion.detect`.

    The defaults are the paper's constraints and weights fed by the flow configuration the
    evaluation on rendered ground truth found best (frames 3 apart, the next frame warped back
    by the ego prior so that the flow method measures only the residual, textureless cells not
    scored, threshold 0.004, and in streams the likelihood accumulated with decay 0.3);
    :meth:`paper` gives the paper's pipeline.

    Attributes
    ----------
    weights : tuple of 4 floats
        ``(mu_e, mu_d, mu_h, mu_p)`` of the weighted mean (paper: 1, 1, 0.2, 0.2).
    lambda_h : float
        Dead band of the positive-height deviation (paper: 0.001).
    lambda_p : float
        Dead band of the anti-parallel deviation in ``constant`` mode (paper: 0.001).
    lambda_p_mode : {'constant', 'adaptive'}
        ``adaptive``: ``lambda_p = lambda_p_ratio * |p'_r x p|``, proportional to the displacement
        a road point would have at that pixel (the paper's alternative).
    lambda_p_ratio : float
        Factor of the adaptive mode.
    depth_both_views : bool
        Positive depth in both views: also flag points that triangulate behind the *previous*
        camera (``p'`` beyond ``e'``). The paper checks the current camera only.
    min_baseline : float
        Metres; below it the camera is standing still and ``xi = |p' x p|`` is used.
    epipole_margin : float
        Rays with ``|p x e'| <`` this (sine of the angle to the epipole) are invalid.
    horizon_margin : float
        Height and anti-parallel apply where ``p . h >`` this and ``p' . h >`` this.
    grid : int
        Side of the square cells the flow is averaged on (paper: 5).
    flow : {'farneback', 'dis'}
    farneback : dict
        ``cv2.calcOpticalFlowFarneback`` settings (``pyr_scale``, ``levels``, ``winsize``,
        ``iterations``, ``poly_n``, ``poly_sigma``).
    dis_preset : {'ultrafast', 'fast', 'medium'}
    flow_prior : {'none', 'ego', 'warp'}
        The flow a static scene would have (road plane below the horizon, ``prior_distance``
        above it), predicted from the poses and the camera. ``ego``: the flow method's initial
        estimate. ``warp``: the current frame is warped back by it and the flow method only
        measures the residual (removing large displacements *and* the fisheye/perspective
        deformation of the road); flow = prior + residual.
    scene_prior : bool
        Streams only: warp by the static-scene model as well (:mod:`fisheyemotion.static_scene`):
        the points earlier detections judged static give the prior's range along each ray, so
        that buildings, walls, parked cars and poles get a small residual too, not only the
        road. The road plane and ``prior_distance`` remain the prior where nothing is known.
    significance : float
        A cell whose positive-height or positive-depth deviation is this many flow-error sigmas
        (:mod:`fisheyemotion.significance`) reaches the threshold: these two terms are quiet on
        a static scene once the flow's error is accounted for, so a significant value is motion
        even near the epipole, where raw angles are tiny (a preceding car). 0 keeps the paper's
        raw angles only.
    epipolar_significance : float
        A cell whose epipolar deviation is this many flow-error sigmas reaches the threshold
        too, as ``significance`` does for height and depth (a pedestrian crossing near the
        epipole, or slowly, deviates from its arc by less than the raw threshold but by many of
        its flow's sigmas; the sigmas include the poses' error, ``position_sigma``). 0 keeps the
        epipolar term's raw angle only (``Params.paper()``;
        ``data/params/no_epipolar_significance.yaml``). Chosen on the tuning street
        (docs/evaluation.md, *Epipolar significance*).
    flow_sigma : float
        Pixels: the flow's error on a well-measured cell (the floor of the error model).
    position_sigma : float
        The given poses' position error between a pair's frames, in the poses' units (metres):
        the direction of travel is known to ``position_sigma / baseline`` radians, an error the
        significance's model adds to the flow's (:func:`fisheyemotion.significance.pose_sigma`;
        it matters where the baseline is millimetres, as a head-mounted camera's between 30-Hz
        frames; 2 mm, a VIO's error over a frame pair). Raise it for odometry whose steps are off
        by a share of their length.
    pose_refinement : {'off', 'on', 'auto'}
        Streams with given poses: the rotation and the direction of travel between consecutive
        frames are also estimated from the images (:mod:`fisheyemotion.egomotion`); ``on``
        always uses them, ``auto`` where the rotation disagrees with the given poses' by more
        than ``refine_tolerance`` degrees or the direction by five times that (odometry or a
        loosely synchronised IMU: every tenth of a degree of rotation error is a flow error
        everywhere). The length of each step stays as given.
    refine_tolerance : float
        Degrees, for ``pose_refinement='auto'``.
    photometric_check : bool
        A region is reported only if one of its cells is not explained photometrically by the
        static scene (the ego prior with the static-scene model): the two frames' mean
        absolute difference after warping by the static scene's flow exceeds the one after
        warping by the measured flow by more than ``photometric_margin``
        (:mod:`fisheyemotion.photometric`). Regions made only of flow errors on static
        structure are dropped. Needs both frames (``detect``, ``apply``, or
        ``detect_flow(..., prev=, curr=)``).
    photometric_margin : float
        Grey levels by which the static scene's mean absolute difference may exceed the
        measured flow's for a cell to count as explained.
    photometric_tolerance : float
        Pixels by which the static scene's prediction may be off along the cell's epipolar
        curve: a cell also counts as explained when the static flow moved by this either way
        along it explains it (the scene model's ranges, the road and the step length are a few
        per cent off, which moves the prediction only along that curve and, on a sharp edge,
        by tens of grey levels). 0 tests the prediction as it is.
    photometric_range_error : float
        Relative error of the static prediction's range (the scene model's, the road's): the
        tolerance along the epipolar curve is at least this times the cell's parallax in pixels
        (its static prediction's distance from the image of the point at infinity), which is
        how far such an error moves the prediction. Structure close to the camera, measured
        over tens of pixels of parallax, is predicted a pixel or more off where the road is
        predicted within ``photometric_tolerance``. Used only where it reaches
        ``photometric.MIN_REACH`` (0.8 px: a parallax of 27 px at 0.03), close structure. 0:
        the fixed tolerance only.
    photometric_edge : float
        Depth edges in the photometric check. A cell the static prediction leaves unexplained
        is explained where the static motion of a neighbouring cell whose parallax exceeds its
        own by this share (the nearer side of a depth edge, whose motion carries a cell that
        holds both surfaces) explains the frames as well as the measured flow
        (:func:`fisheyemotion.photometric.edge_explained`); where such a neighbour's static
        point lands on the cell's in the current frame, the cell is hidden there and is a seed
        only if its measured flow explains the frames
        (:func:`~fisheyemotion.photometric.hidden_cells`). 0: off
        (``data/params/no_edge_explained.yaml``). Measured in docs/evaluation.md (*Depth
        edges*).
    photometric_span : float
        Two spans of a stream in the photometric check. A seed is explained where one static
        point along its ray, at a range within this relative spread (log-uniform, either way)
        of the scene model's and not under the road, explains the cell both in the pair's
        current frame and in the frame a gap before the pair's previous one, each at least as
        well as the measured flow explains the pair
        (:func:`fisheyemotion.photometric.span_explained`): static structure whose model range
        is off, which a pair alone cannot tell from an object moving along its epipolar arc.
        Not where the region tests found motion along the direction of travel (a floating or
        receding region), which reads as one static point in any number of views. Streams only
        (the previous span's frame); 0: off (``data/params/no_two_spans.yaml``). Measured in
        docs/evaluation.md (*Two spans*).
    photometric_arc : bool
        A cell the static scene does not explain starts a region only if the images support
        its deviation from the epipolar arc (moved onto the arc, the measured flow explains the
        frames worse by more than ``photometric_margin``) or its deviations on the arc reach
        the threshold (:mod:`fisheyemotion.photometric`): a flow error along an edge counts for
        nothing.
    photometric_view : bool
        A cell whose static prediction leaves the view (the usable pixels shrunk by one cell)
        cannot be compared with the static scene: it starts a region only if its measured
        flow explains the frames by itself (mean absolute difference below
        ``photometric_margin``: it is seen where a static point would have left the view, as
        an overtaking vehicle is). Off: such a cell is compared with the image's replicated
        border (0.8.9), which no static prediction explains (docs/evaluation.md, *Seeds the
        images can test*).
    photometric_search : float
        Pixels either way along the epipolar arc from the static correspondence nearest the
        measured one over which ``photometric_arc`` looks for the static correspondence that
        best explains the frames: the deviation is supported only if the measured flow
        explains them better than all of those (a flow error at a depth discontinuity is off
        the static point in any direction, so the arc's nearest point can be pixels from it).
        0 compares with the nearest point only (0.7.2); 4 until 0.8.12. 16: where a wrong
        static prior was not corrected, the flow stays 5-20 px from the static
        correspondence (docs/evaluation.md, *Photometric search*, *Second flow pass*).
    grow : int
        Cells a detected region may grow by into neighbours whose residual flow (measured minus
        the static scene's) is like the region's (:mod:`fisheyemotion.grow`): the object's flow
        boundary becomes the region's, and a small seeded region reaches ``min_area``. Streams
        only, once the static-scene model holds points (a single pair's static prediction knows
        only the road and the far field: a wall's residual would be its own parallax). 0
        disables it (``Params.paper()``; ``data/params/no_growth.yaml``). Chosen on the tuning
        street and the open road (docs/evaluation.md, *Growth by the residual flow*).
    extent_reach : float
        Each region of the mask grown to its object's extent in the current frame, by a marker
        watershed on that frame (:mod:`fisheyemotion.extent`), at most this share of the
        region's larger box side beyond its box; needs the frames (not :meth:`detect_flow`).
        0 disables it (``Params.paper()``). Chosen on the tuning street (docs/evaluation.md,
        *Extent*).
    extent_static : float
        Pixels scored below this share of ``threshold`` are background to the growth.
    extent_residual : bool
        In streams, where the static-scene model informs the static prediction, a cell's
        residual flow (measured minus the static scene's) decides whether the growth may take
        it, instead of ``extent_static``: a part of the object scored far below the threshold
        (plain, or near the epipole, where deviations are small) that moves like the object is
        left to the flooding; a cell that moves less than the object is background. Where the
        residual is unknown, and in a single pair (whose prediction is the road and the far
        field, wrong on structure beside the road), the likelihood decides (0.8.10). Measured
        in docs/evaluation.md, *Extent*.
    road_spill : float
        Mask pixels the road explains are trimmed from their regions
        (:mod:`fisheyemotion.spill`): where, over the cell-sized block around a pixel, the
        previous frame seen through the road point of its ray matches the current frame
        within this mean absolute difference (grey levels), better than the motion the mask
        carried the pixel with, and the road point has a cell of parallax. That is the flow's
        smoothing of a moving object onto the road beside and below it. With the camera
        still, every static pixel likewise (the rotation alone is the hypothesis). A region
        the trim would split into two large pieces stays whole; one it leaves less than
        ``spill.PIECE`` cells of goes. Needs a known road (or a still camera) and both frames;
        the likelihood and ``Detection.cell_mask`` are not changed. 0 disables it
        (``Params.paper()``; ``data/params/no_road_spill.yaml``). Chosen on the tuning street
        (docs/evaluation.md, *Road spill*).
    ground_contact : bool
        Regions led by the anti-parallel term that stand on the road (the static range just
        below their lower edge is about their own) are static structure: their anti-parallel
        deviation is removed (:mod:`fisheyemotion.ground_contact`). An oncoming object seen as
        static floats above the road and keeps it.
    contact_ratio : float
        Ground-contact ratio below which a region stands on the road.
    contact_columns : int
        A column's ground-contact ratio is the median of its region's ratios within this many
        columns on either side (0: each column's own). One column's walk below the edge meets
        the flow's errors (a smeared boundary, a cell of another surface); its neighbours on the
        same object meet others.
    contact_arc : float
        Flow-error sigmas: a standing column's cell whose epipolar deviation is below this
        many of its flow's sigmas (``significance``'s error model) is explained even where its
        range disagrees with the scene model: a static object is seen on its epipolar arc, a
        pedestrian stepping out beside it moves off it. Such a cell is not added to the scene
        model (its range or the model's is wrong). 0 leaves the scene model's veto alone.
    contact_epipolar : bool
        In the cells the ground-contact test explains (they stand on the road and agree with
        the scene model or lie on their arc), the epipolar deviation counts only in flow-error
        sigmas (``epipolar_significance``), not also as a raw angle: a static object close to
        the camera at the image's side is measured with a flow error of a degree or more, and
        its raw angle alone would keep it above the threshold at 1-2 sigmas. Needs
        ``epipolar_significance > 0``.
    range_consistency : float
        Streams only: flow-error sigmas by which a cell's range may disagree with the range
        the previous pair triangulated for the static point that landed in it
        (:mod:`fisheyemotion.range_consistency`: three views of a static point agree, of a point
        moving along its epipolar arc do not); a cell at this many reaches the threshold. The
        scene model still stores the cells it alone raises. 1.5 (0.8.22); 0: off
        (``Params.paper()``; ``data/params/no_three_views.yaml``). Measured in
        ``docs/evaluation.md`` (*Three views*, *Confirmed by the frame before*).
    range_consistency_alone : float
        Flow-error sigmas a cell's three-view disagreement needs where it is the cell's only
        evidence: the photometric check explains the cell by the static scene (it is not a
        seed). Below this the cell keeps the pair's own likelihood. The three views' error
        model is exceeded on static cells beside the objects (a flow smeared across an
        object's outline, the far road), and their raised cells joined the objects' regions
        as larger masks; a pedestrian walking along its arc, which the images do not tell from
        a static point, reads further off (``docs/evaluation.md``, *Three views where the
        images explain the cell*). Needs the photometric check; at or below
        ``range_consistency`` every raise counts (0.8.21's opt-in,
        ``data/params/three_views_unchecked.yaml``).
    scene_sweep : float
        Streams only, 0 (off) by default: grey levels. A cell about to enter the scene model
        whose measured flow explains the frames worse than this (mean absolute residual) is
        stored at the range along its epipolar arc that explains them best
        (:func:`fisheyemotion.photometric.sweep_ranges`), where that range beats the measured
        one by ``scene_sweep_margin``: the model stops reading its own wrong ranges back through
        the flow its prior warped. Measured, not the default (``docs/evaluation.md``,
        *Swept scene ranges*).
    scene_sweep_margin : float
        Grey levels by which the swept range must explain the cell better than the measured one.
    scene_memory : int
        Detections whose static points the scene model keeps.
    scene_bootstrap : bool
        Streams only, with a frame gap above 1: when a stream's first pair forms, the scene
        model first learns from the consecutive pairs between its frames (each warped by what
        the pairs before it stored), so that the first pair's prior already knows the static
        structure that is near when the stream starts, where the gap's displacements are too
        large for the flow method to find from the road/far-field prior alone.
    prior_distance : float
        Metres, for the ego prior's rays that do not meet the road closer than that (the default,
        1 km, stands for infinity: the sky and distant structure move with the rotation only;
        the evaluation measured 15 m and 50 m as worse).
    frame_gap : int
        Streaming (``MotionDetector.apply``, eval): compare each frame with the one ``frame_gap``
        frames earlier (paper: 1, consecutive frames). Larger gaps multiply both the ego
        baseline and an object's own motion while the flow error stays about the same.
    min_texture : float
        Cells whose mean gradient magnitude (grey levels per pixel, Sobel on the previous frame)
        is below this are not scored: flow in textureless areas (sky, flat walls) is whatever the
        flow method's smoothness or initial estimate makes it. 0 disables the check.
    temporal_decay : float
        Streams only: the likelihood is accumulated over frames,
        ``L = (1 - decay) L_now + decay L_before``, the previous map carried to the current frame
        by the flow. 0 keeps each frame's own likelihood (the paper); the default 0.3 lowered
        false-positive frames (79 % -> 72-76 %, measured with the visibility check on) without
        losing a category below the paper's rate.
    persistence : int
        Streams only: a region is reported only once some of its cells have been moving in this
        many consecutive detections (carried by the flow). 1 (default) reports at once.
    confirm_reach : int
        Cells. Streams only: a region is reported only where the stream's previous result had a
        region (reported or not) within this many cells (:mod:`fisheyemotion.confirm`): the
        track confirmation of a radar or lidar tracker, which drops the flow errors on static
        structure that do not repeat, and reports every object one result after it is first
        flagged. 8 (0.8.22); 0: off, every region reported at once (``Params.paper()``;
        ``data/params/no_confirmation.yaml``). Measured in ``docs/evaluation.md``
        (*Confirmed by the frame before*).
    visibility_check : bool
        Cells whose static-scene point (the ego prior's prediction: the road, or
        ``prior_distance`` above the horizon) leaves the current view -- outside the image, the
        camera's domain or the ROI (the vehicle's own body), within ``grid`` pixels -- are not
        scored: their correspondence is not in the current frame, so any flow there is wrong.
        With a frame gap at speed this is the near road at the bottom of a fisheye image. Off by
        default: with the warp prior those cells already get the prior's (static) flow, and the
        check cost overtaking vehicles at the image edge (91 % vs 96 % detected).
    min_parallax : float
        Pixels; cells where the static-scene point (road, or ``prior_distance`` above the
        horizon) moves less than this through the camera's translation -- near the epipole and
        the horizon -- are not scored: there the flow's error is as large as everything depth
        changes, so height and depth cannot be resolved. 0 disables the check; never applied
        when the camera stands still.
    fb_check : bool
        Forward-backward consistency: also compute the flow from ``curr`` to ``prev``; cells whose
        mean round-trip error exceeds ``fb_tolerance + fb_relative * |flow|`` pixels are not
        scored (invalid) instead of producing a deviation from a wrong flow.
    fb_tolerance : float
        Pixels.
    fb_relative : float
        Fraction of the flow magnitude added to the tolerance.
    threshold : float
        Likelihood above which a cell is moving (the paper does not state its value).
    seed_threshold : float
        Hysteresis: a region is kept only if one of its cells exceeds this (its other cells need
        only ``threshold``; scikit-image's ``apply_hysteresis_threshold``). At or below
        ``threshold`` it has no effect.
    extend_threshold : float
        Extension: every region that is a detection by itself (``min_area`` pixels above
        ``threshold``) also takes the cells above this likelihood connected to it through such
        cells, so that more of a detected object is covered (hysteresis with the region as its
        seed; :func:`fisheyemotion.segment.segment_cells`). 0 (default) or at or above
        ``threshold``: off. Measured (docs/evaluation.md): 0.002 takes crossing coverage from
        31 % to 49 % on the open road and IoU up in every scene group, but false regions grow
        as much: static pixels flagged 1.6 -> 2.3 % there, and 0.85-0.88 -> 1.51-1.65 % of the
        real kitchen clip's static background.
    min_area : int
        Regions smaller than this many pixels are dropped.
    region_gap : int
        Cells. Every region kept (seeded, at least ``min_area``) takes the pieces of cells
        above the threshold at most ``2 region_gap`` cells from it along a row or column and is
        closed over those gaps (:func:`fisheyemotion.segment.segment_cells`' ``gap``): one
        object is one region, not a detection and specks around it, and its unflagged middle is
        covered. 0: off (the paper). Measured in docs/evaluation.md (*Regions closed over small
        gaps*).
    antiparallel_seeds : int
        Seed cells (:mod:`fisheyemotion.photometric`) a region led by the anti-parallel term
        needs (its weighted deviation half the region's likelihood or more: where the false
        regions on parked cars and walls are); other regions need one. 1 (default): as any
        other. ``data/params/fewer_false_alarms.yaml`` sets 2: fewer false-positive frames
        at the cost of pedestrians stepping out with a single seed (docs/evaluation.md,
        *Fewer false alarms*).
    second_pass : int
        Cells. The flow method measures the pair again, warped back by its own first result,
        on the groups of cells within this many cells of those above the threshold that hold a
        seed (:mod:`fisheyemotion.second_pass`): it measures a residual short, so an object's
        motion is measured in full only by a second pass. A cell takes the second pass's
        likelihood (higher or lower) where the new flow explains the frames better by
        ``second_pass.BETTER_BY`` grey levels; cells a region test decided (the ground-contact
        test explained them, :attr:`receding` raised them) keep theirs. Only for the detector's
        own flow (``apply``, ``detect``, ``stream``, or ``detect_flow`` given the array
        :meth:`MotionDetector.flow` returned). 0: off (the paper;
        ``data/params/no_second_pass.yaml``). Measured in docs/evaluation.md (*Second
        flow pass*).
    second_pass_flow : {'same', 'dis-ultrafast', 'dis-fast', 'dis-medium'}
        The second pass's flow method. ``'same'`` (default): the detector's own flow method
        and settings. ``'dis-<preset>'``: DIS at that preset whatever :attr:`flow` is, on boxes
        whose sides are multiples of ``second_pass.SIZE_STEP``; ``'dis-fast'``
        (``data/params/fast_second_pass.yaml``) takes about 5 ms a frame off a Farneback
        stream's second pass at 2-3 points of crossing coverage (docs/evaluation.md, *Second
        pass's flow method*).
    carry_share : float
        The result is measured on the previous frame's cells and carried to the current
        frame's: each cell by its mean flow (its centre's landing cell takes it), and, where
        this is above 0, every pixel of the cells above the threshold by its own flow. A cell
        of the current frame that such pixels cover by at least this share of its area takes
        the most likely cell among them (:func:`fisheyemotion.flow.pixel_transfer`). An object
        two or three cells wide that moves across its background otherwise lands partly beside
        itself. 0: cells only (the paper's pipeline; ``data/params/no_pixel_carry.yaml``).
        Measured in docs/evaluation.md (*Carried by each pixel's flow*).
    receding : float
        Range-error sigmas. A region (the connected cells above ``receding_candidates`` times
        the threshold that do not read the road plane) whose lowest cells, where the road is
        seen directly below them, read beyond the road by this many of their relative range
        errors moves away along its epipolar arc: a static point is never under the road
        (:mod:`fisheyemotion.receding`). Its cells in those columns are raised to
        ``threshold * z / receding``. Needs a known road. 0: off (the paper;
        ``data/params/no_receding.yaml``). Measured in docs/evaluation.md (*Receding regions*).
    receding_candidates : float
        Share of the threshold above which cells form the regions :attr:`receding` tests.
    saturation : float
        Likelihood mapped to full colour when drawing (paper: 0.02).
    """

    weights: tuple[float, float, float, float] = (1.0, 1.0, 0.2, 0.2)
    lambda_h: float = 0.001
    lambda_p: float = 0.001
    lambda_p_mode: str = "constant"
    lambda_p_ratio: float = 0.5
    depth_both_views: bool = True
    min_baseline: float = 1e-3
    epipole_margin: float = 1e-3
    horizon_margin: float = 0.0
    grid: int = 5
    flow: str = "farneback"
    farneback: dict = field(default_factory=lambda: dict(FARNEBACK_DEFAULTS))
    dis_preset: str = "medium"
    flow_prior: str = "warp"
    prior_distance: float = 1000.0
    significance: float = 3.0
    epipolar_significance: float = 2.0
    flow_sigma: float = 0.25
    position_sigma: float = 0.002
    ground_contact: bool = True
    grow: int = 4
    extent_reach: float = 0.5
    extent_static: float = 0.1
    extent_residual: bool = True
    road_spill: float = 15.0
    photometric_check: bool = True
    photometric_margin: float = 10.0
    photometric_tolerance: float = 0.25
    photometric_range_error: float = 0.03
    photometric_edge: float = 0.1
    photometric_span: float = 0.2
    photometric_arc: bool = True
    photometric_view: bool = True
    photometric_search: float = 16.0
    pose_refinement: str = "off"
    refine_tolerance: float = 0.1
    contact_ratio: float = 1.05
    contact_columns: int = 3
    contact_arc: float = 0.03
    contact_epipolar: bool = True
    range_consistency: float = 1.5
    range_consistency_alone: float = 3.0
    scene_sweep: float = 0.0
    scene_sweep_margin: float = 5.0
    scene_prior: bool = True
    scene_memory: int = 3
    scene_bootstrap: bool = True
    frame_gap: int = 3
    min_texture: float = 2.0
    temporal_decay: float = 0.3
    persistence: int = 1
    confirm_reach: int = 8
    visibility_check: bool = False
    min_parallax: float = 0.0
    fb_check: bool = False
    fb_tolerance: float = 1.0
    fb_relative: float = 0.05
    threshold: float = 0.004
    seed_threshold: float = 0.0
    extend_threshold: float = 0.0
    min_area: int = 100
    region_gap: int = 1
    antiparallel_seeds: int = 1
    second_pass: int = 2
    second_pass_flow: str = "same"
    carry_share: float = 0.6
    receding: float = 2.0
    receding_candidates: float = 0.25
    saturation: float = 0.02

    def __post_init__(self) -> None:
        try:
            w = tuple(self.weights)
        except TypeError:
            raise ValueError(f"weights: expected 4 non-negative numbers with a positive sum, "
                             f"got {_short(self.weights)}") from None
        if len(w) != 4 or not all(_finite(v) and v >= 0 for v in w) or sum(w) <= 0:
            raise ValueError("weights: expected 4 non-negative numbers with a positive sum, "
                             f"got {_short(self.weights)}")
        object.__setattr__(self, "weights", tuple(float(v) for v in w))
        for name in ("lambda_h", "lambda_p", "lambda_p_ratio", "min_baseline", "epipole_margin",
                     "threshold", "saturation", "fb_tolerance", "fb_relative", "min_texture",
                     "min_parallax", "seed_threshold", "extend_threshold", "contact_ratio",
                     "contact_arc", "range_consistency", "range_consistency_alone",
                     "scene_sweep", "scene_sweep_margin",
                     "extent_reach", "extent_static", "road_spill",
                     "photometric_margin", "photometric_tolerance", "photometric_range_error",
                     "photometric_edge", "photometric_span",
                     "photometric_search",
                     "significance", "epipolar_significance", "flow_sigma", "position_sigma",
                     "refine_tolerance", "receding", "receding_candidates"):
            v = getattr(self, name)
            if not _finite(v) or v < 0:
                raise ValueError(f"{name}: expected a finite number >= 0, got {_short(v)}")
        if not _finite(self.horizon_margin) or not -1 < self.horizon_margin < 1:
            raise ValueError("horizon_margin: expected a number in (-1, 1), got "
                             f"{_short(self.horizon_margin)}")
        if not _finite(self.prior_distance) or self.prior_distance <= 0:
            raise ValueError(f"prior_distance: expected > 0 metres, got {_short(self.prior_distance)}")
        if self.saturation <= 0:
            raise ValueError(f"saturation: expected > 0, got {self.saturation!r}")
        for name, options in (("lambda_p_mode", LAMBDA_P_MODES), ("flow", FLOW_METHODS),
                              ("dis_preset", DIS_PRESETS), ("flow_prior", FLOW_PRIORS),
                              ("pose_refinement", POSE_REFINEMENTS),
                              ("second_pass_flow", SECOND_PASS_FLOWS)):
            if getattr(self, name) not in options:
                raise ValueError(f"{name}: expected one of {', '.join(options)}, got "
                                 f"{_short(getattr(self, name))}")
        if not _finite(self.carry_share) or not 0 <= self.carry_share <= 1:
            raise ValueError("carry_share: expected a number in [0, 1], got "
                             f"{_short(self.carry_share)}")
        if not _finite(self.temporal_decay) or not 0 <= self.temporal_decay < 1:
            raise ValueError("temporal_decay: expected a number in [0, 1), got "
                             f"{_short(self.temporal_decay)}")
        for name, low in (("grid", 1), ("min_area", 0), ("frame_gap", 1), ("persistence", 1),
                          ("scene_memory", 1), ("grow", 0), ("region_gap", 0),
                          ("antiparallel_seeds", 1), ("second_pass", 0),
                          ("contact_columns", 0), ("confirm_reach", 0)):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or v < low:
                raise ValueError(f"{name}: expected an integer >= {low}, got {_short(v)}")
        for name in ("depth_both_views", "fb_check", "visibility_check", "scene_prior",
                     "scene_bootstrap",
                     "ground_contact", "contact_epipolar", "photometric_check", "photometric_arc",
                     "photometric_view", "extent_residual"):
            if not isinstance(getattr(self, name), bool):
                raise ValueError(f"{name}: expected a bool, got {_short(getattr(self, name))}")
        fb = dict(self.farneback) if isinstance(self.farneback, dict) else None
        if fb is None or set(fb) - set(FARNEBACK_DEFAULTS):
            raise ValueError(f"farneback: expected a dict with keys among "
                             f"{sorted(FARNEBACK_DEFAULTS)}, got {_short(self.farneback)}")
        fb = {**FARNEBACK_DEFAULTS, **fb}
        _check_farneback(fb)
        object.__setattr__(self, "farneback", fb)

    @classmethod
    def paper(cls, **changes: Any) -> Params:
        """The paper's pipeline: Farneback on consecutive frames, no ego prior or scene model, no
        visibility, forward-backward, texture or photometric check, raw angles (no
        significance), no ground-contact test (the defaults add some of these, as chosen by
        ``docs/evaluation.md``). The paper does not state its likelihood threshold; this uses
        0.005."""
        return cls(**{"flow_prior": "none", "scene_prior": False, "scene_bootstrap": False,
                      "ground_contact": False,
                      "significance": 0.0, "epipolar_significance": 0.0, "grow": 0,
                      "extent_reach": 0.0, "region_gap": 0, "second_pass": 0, "carry_share": 0.0,
                      "receding": 0.0, "road_spill": 0.0, "range_consistency": 0.0,
                      "confirm_reach": 0,
                      "photometric_check": False,
                      "fb_check": False,
                      "frame_gap": 1, "min_texture": 0.0,
                      "visibility_check": False, "threshold": 0.005, "temporal_decay": 0.0,
                      **changes})

    def for_camera(self, camera, **changes: Any) -> Params:
        """These parameters with the pixel-sized ones (``grid``, ``min_area``) scaled to
        ``camera``'s angular resolution at its centre, so that cameras of any resolution see
        the same cells in degrees: the defaults were chosen at ``REFERENCE_PIXEL_ANGLE``
        (200 px per radian, a 190-degree fisheye 640 px wide). ``grid`` is
        ``round(5 s)`` (at least 3) and ``min_area`` ``100 s^2`` pixels, ``s`` the ratio of the
        reference angle to the camera's; ``changes`` are applied after scaling."""
        from .significance import pixel_angle

        cx, cy = (camera.width - 1) / 2, (camera.height - 1) / 2
        angle = float(pixel_angle(camera, np.array([[cx, cy]]))[0])
        if not math.isfinite(angle) or angle <= 0:
            raise ValueError(f"camera: no ray at the image centre ({cx}, {cy}) to scale from")
        scale = REFERENCE_PIXEL_ANGLE / angle
        grid = max(3, int(round(self.grid * scale)))
        area = int(round(self.min_area * (grid / self.grid) ** 2))
        return self.replace(**{"grid": grid, "min_area": area, **changes})

    def replace(self, **changes: Any) -> Params:
        """A copy with some fields changed (validated again)."""
        return dataclasses.replace(self, **changes)

    def to_dict(self) -> dict[str, Any]:
        out = dataclasses.asdict(self)
        out["weights"] = list(self.weights)
        return out

    @classmethod
    def from_dict(cls, values: dict[str, Any]) -> Params:
        """Build from a mapping; unknown keys are an error naming them."""
        if not isinstance(values, dict):
            raise ValueError(f"params: expected a mapping, got {type(values).__name__}")
        if any(not isinstance(k, str) for k in values):
            raise ValueError(f"params: expected text keys, got {_short(list(values))}")
        known = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(values) - known)
        if unknown:
            close = sorted({m for k in unknown[:20] for m in difflib.get_close_matches(k, known)})
            hint = (f"; did you mean {close}?" if close
                    else "; expected the fields of fisheyemotion.Params (docs/api.md)")
            raise ValueError(f"params: unknown key(s) {_short(unknown)}{hint}")
        values = dict(values)
        if "weights" in values and isinstance(values["weights"], list):
            values["weights"] = tuple(values["weights"])
        return cls(**values)

    @classmethod
    def load(cls, path: str | Path) -> Params:
        """Read a YAML or JSON file of parameters."""
        import yaml

        try:
            text = Path(path).read_text(encoding="utf-8")
        except FileNotFoundError:
            raise ValueError(f"{path}: no such parameter file") from None
        except UnicodeDecodeError:
            raise ValueError(f"{path}: not a UTF-8 text file of parameters") from None
        except OSError as exc:
            raise ValueError(f"{path}: cannot be read: {exc}") from None
        try:
            values = json.loads(text) if str(path).endswith(".json") else yaml.safe_load(text)
        except (ValueError, yaml.YAMLError, RecursionError) as exc:
            raise ValueError(f"{path}: cannot parse parameters: {_short(str(exc), 300)}") from None
        if isinstance(values, dict) and isinstance(values.get("pose_refinement"), bool):
            # YAML 1.1 reads an unquoted on / off (yes / no) as a boolean.
            values["pose_refinement"] = "on" if values["pose_refinement"] else "off"
        try:
            return cls.from_dict(values or {})
        except ValueError as exc:
            raise ValueError(f"{path}: {exc}") from None


def _check_farneback(fb: dict) -> None:
    """OpenCV's own ranges, checked before cv2 sees them (it aborts the process on some)."""
    def bad(key: str, expected: str) -> ValueError:
        return ValueError(f"farneback.{key}: expected {expected}, got {_short(fb[key])}")

    if not _finite(fb["pyr_scale"]) or not 0 < fb["pyr_scale"] < 1:
        raise bad("pyr_scale", "a number in (0, 1)")
    for key, low, high in (("levels", 0, 10), ("winsize", 3, 255), ("iterations", 1, 100)):
        v = fb[key]
        if isinstance(v, bool) or not isinstance(v, int) or not low <= v <= high:
            raise bad(key, f"an integer in [{low}, {high}]")
    if fb["poly_n"] not in (5, 7) or isinstance(fb["poly_n"], bool):
        raise bad("poly_n", "5 or 7 (OpenCV's supported neighbourhoods)")
    if not _finite(fb["poly_sigma"]) or not 0 < fb["poly_sigma"] <= 10:
        raise bad("poly_sigma", "a number in (0, 10]")


def _short(value: Any, limit: int = 120) -> str:
    """``repr(value)`` cut to ``limit`` characters: error messages stay small whatever the
    input (a YAML 'billion laughs' expands to gigabytes)."""
    import reprlib

    r = reprlib.Repr()
    r.maxstring = r.maxother = limit
    r.maxlist = r.maxdict = r.maxtuple = 8
    r.maxlevel = 3
    text = r.repr(value)
    return text if len(text) <= limit else text[:limit] + "..."


def _finite(v: Any) -> bool:
    return isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)
