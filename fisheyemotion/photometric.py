"""The photometric check of the static hypothesis: does the static scene explain the frames?

The constraints judge a cell by its flow. Where the flow is wrong -- a flow method that locked
onto a repeated texture, smoothed across a depth discontinuity or did not recover a large
residual -- a static cell gets a deviation and becomes a false alarm. The images can tell: the
flow claims that the previous frame's content at ``u`` is at ``u + f(u)`` in the current frame,
the static scene (the ego prior with the static-scene model, :mod:`fisheyemotion.prior`)
predicts ``u + s(u)``. Each claim has a photometric residual, the cell's mean absolute
grey-level difference

    r_f = mean |I0(u) - I1(u + f(u))|,    r_s = mean |I0(u) - I1(u + s(u))|

(bilinear sampling). A moving object is not where the static scene predicts it, so ``r_s``
exceeds ``r_f`` there; where ``r_s <= r_f + margin`` the static scene explains the frames at
least as well as the measured flow, and the cell's deviation is not evidence of motion.

The static scene's prediction is itself a little off: the scene model's ranges, the road and the
given step length carry errors of a few per cent, which move the predicted point along its
epipolar curve (a static point's image at another range; ``docs/geometry.md``) by a fraction
of a pixel -- and on a sharp edge a quarter of a pixel is tens of grey levels. With a
``tolerance`` ``t`` (pixels) a cell also counts as explained when the static flow moved by
``t`` either way along the epipolar curve at the predicted point explains it:
``min(r_s, r_s(+t d), r_s(-t d)) <= r_f + margin``, ``d`` the curve's unit image direction
(:func:`epipolar_directions`). The two are sampled only at the cells the unmoved static flow
does not explain. A moving object is off its curve by its own motion, which a quarter of a
pixel along the curve does not undo.

A fixed tolerance fits the road and the far field, not structure close to the camera: the
scene model's range of a parked car or a wall is a few per cent off (each pair's flow there is
a few pixels off over tens of pixels of parallax), and a relative range error ``epsilon`` moves
the prediction along the curve by about ``epsilon`` times the cell's parallax in pixels (its
distance from the image of the point at infinity, ``d u / d ln(lambda)`` for a translation
that is small against the range). With a ``reach`` (the detector's
``Params.photometric_range_error`` times that parallax) a cell's tolerance is the larger of
the two, sampled at moves at most ``t`` apart; only where the reach is at least
:data:`MIN_REACH` (close structure: farther, slower-moving pedestrians walking along their
curve were explained away by smaller reaches, measured).

At a depth edge a cell holds two surfaces, and the static prediction, interpolated between the
scene model's samples on either side, lands between their motions and explains neither. The
nearer surface occludes the farther one, so its motion carries most of such a cell: with an
``edge`` ratio, a cell still unexplained is explained where the static motion of one of its
eight neighbouring cells whose parallax exceeds its own by that share (the nearer side of an
edge) explains the frames at least as well as the measured flow, without the margin
(:func:`edge_explained`). The parked cars' outlines on the demo streets are such cells; a
pedestrian stepping out beside a parked car reads as static at the car's range when it walks
towards the camera's path, which a looser comparison explained away (measured). The nearer
surface also hides what lies behind it: a cell whose static point lands, in the current frame,
where a nearer neighbour's lands (within :data:`COVERS` of a cell) is not shown by the current
frame, and no static prediction can explain it (:func:`hidden_cells`); like a prediction out of
view, it is a seed only where its measured flow explains the frames (:func:`testable_cells`).

A stream has seen more than the pair. The scene model's range of a parked car is off by ten per
cent where each pair's flow followed the prior it was warped by, and no tolerance tells that
from a pedestrian walking along its epipolar arc, whose pair two views read as a static point
at another range. Over a longer time the two part: a static point stays where it is, so one
range explains its cell both in the pair's current frame and in the frame one span *before*
the pair's previous frame, while no one range fits a pedestrian in both (the best misses by
0.7–2 px for one walking towards the path 4–6 m away, at 6 m/s and 15 fps, a 3-frame span;
within one pair it fits exactly). A seed is therefore explained where one of a few ranges along
its ray, around the scene model's and above the road, explains the cell in both frames at least
as well as the measured flow explains the pair (:func:`span_explained`). Motion along the
direction of travel at a constant speed reads as one static point in any number of views
(docs/geometry.md, *Three views of a static point*): the detector leaves out the cells the
region tests found floating or receding.

The images can only test a static prediction they show: where a cell's static point leaves
the view (the previous frame's side of the image as the camera moves forward), its residual
would compare the cell with the image's replicated border, and every such cell would look
unexplained. Such a cell is a seed only if its measured flow itself explains the frames (a
mean absolute difference below the margin): a point seen in the current frame where a static
point would have left the view, as an overtaking vehicle is (:func:`testable_cells`).

What the images do not support counts for nothing. A cell the static scene does not explain
is a seed only if the images also support its deviation from the epipolar arc: moved onto the
arc, the measured flow must explain the frames worse by more than the margin
(:func:`off_arc_supported`); where it does not (a flow error along an edge, the aperture
problem), the cell counts only by its deviations on the arc (height and anti-parallel), which
the detector scores at the static correspondence nearest the measured one
(:func:`fisheyemotion.constraints.nearest_static_ray`). "Onto the arc" is not only that nearest
point: a flow method that smoothed across a depth discontinuity or locked onto the wrong
texture is off the true correspondence by pixels in any direction, so the nearest point of the
arc can be pixels from the static point too, and explain the frames badly. The off-arc test
therefore compares the measured flow with the best of the static correspondences within a
search reach either way along the arc from the nearest one (:func:`arc_candidates`); the
deviation is supported only if the measured flow beats them all.

Two kinds of motion the check cannot see: an object moving along its epipolar line (oncoming,
preceding) seen as static is a consistent static scene at another depth, which the static-scene
model may hold (the anti-parallel ambiguity, :mod:`fisheyemotion.ground_contact`), and plain,
slowly moving parts of an object. The detector therefore judges regions, not cells: a region
is reported only if at least one of its cells is *not* explained (``segment_cells(seeds=...)``);
cells are not removed from a region that has one. Only cells above the threshold are tested.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from .calib.base import CameraModel
from .calib.transforms import rotate
from .constraints import nearest_static_ray
from .prior import lands_on, static_scene_targets
from .road import Road

_STEP = 1e-4  # radians along the epipolar circle, either way, for its image direction
#: Pixels between the static correspondences that the off-arc test compares
#: (``Params.photometric_search``).
SEARCH_STEP = 1.0
#: The most moves either way along the epipolar curve that :func:`static_explained` samples: a
#: tolerance up to 4 times ``Params.photometric_tolerance`` is sampled at that spacing, a wider
#: one at quarters of itself.
TOLERANCE_STEPS = 4
#: Pixels: a ``reach`` below this is not used by :func:`static_explained` (the fixed tolerance
#: stands). With ``Params.photometric_range_error`` 0.03 it is a parallax of 27 px, structure
#: within a few metres beside the camera; pedestrians 6-8 m away, with less parallax, lost
#: detections to smaller reaches on the demo streets (docs/evaluation.md, *Range tolerance*).
MIN_REACH = 0.8

#: Cells: a static point that a nearer neighbouring cell's static point lands within this
#: distance of in the current frame is hidden there (:func:`hidden_cells`). A whole cell
#: (measured) also hid parts of preceding and approaching vehicles.
COVERS = 0.5

#: Candidate ranges of the two-span test (:func:`span_explained`): log-uniform over
#: ``Params.photometric_span`` either way of the scene model's (29 over 0.2: 1.4 % apart).
SPAN_CANDIDATES = 29
#: Metres: a candidate point more than this under the road is no static point.
UNDER_ROAD = 0.1

#: Ranges (metres) that :func:`sweep_ranges` tries: 24 from 40 m to 1 m, uniform in inverse
#: range (so uniform in parallax).
SWEEP_RANGES = 1.0 / np.linspace(1.0 / 40.0, 1.0, 24)

__all__ = ["COVERS", "MIN_REACH", "SEARCH_STEP", "SPAN_CANDIDATES", "SWEEP_RANGES",
           "TOLERANCE_STEPS", "UNDER_ROAD",
           "arc_candidates", "best_candidate", "cell_residual", "edge_explained",
           "epipolar_directions", "hidden_cells", "off_arc_supported", "span_explained",
           "static_explained", "sweep_ranges", "testable_cells"]


def cell_residual(prev: NDArray[np.uint8], curr: NDArray[np.uint8], flow: NDArray[np.float32],
                  grid: int, cells: NDArray[np.bool_] | None = None) -> NDArray[np.float32]:
    """Mean absolute grey-level difference ``|prev(u) - curr(u + flow(u))|`` of each cell
    (exact bilinear sampling, edges replicated; NaN where a sample position is not finite).

    Parameters
    ----------
    prev, curr : ndarray of uint8, shape (H, W)
    flow : ndarray of float32, shape (H, W, 2)
    grid : int
        Cell size, pixels (whole cells only, as :func:`fisheyemotion.flow.grid_average`).
    cells : ndarray of bool, shape (H // grid, W // grid), optional
        Only these cells are computed (the others are NaN): their pixels are sampled alone.

    Returns
    -------
    ndarray of float32, shape (H // grid, W // grid)
    """
    if cells is None:
        cells = np.ones((prev.shape[0] // grid, prev.shape[1] // grid), bool)
    return _cell_residuals(prev, curr, flow, grid, cells, (None,))[0]


def _cell_residuals(prev, curr, flow, grid, cells, shifts) -> list[NDArray[np.float32]]:
    """:func:`cell_residual` of ``cells`` for ``flow`` moved by each of ``shifts`` (``(n, 2)``
    pixels, one row per cell of ``cells`` in row-major order; None: not moved)."""
    outs = [np.full(cells.shape, np.nan, np.float32) for _ in shifts]
    r, c = np.nonzero(cells)
    if len(r) == 0:
        return outs
    values = _residuals(prev, curr, flow, grid, cells, np.stack(
        [np.zeros((len(r), 2)) if shift is None else shift for shift in shifts]))
    for out, row in zip(outs, values, strict=True):
        out[r, c] = row
    return outs


def _residuals(prev, curr, flow, grid, cells, shifts) -> NDArray[np.float64]:
    """``(m, n)``: the residual of each of the ``n`` cells of ``cells`` (row-major) for
    ``flow`` moved by each of ``shifts`` (``(m, n, 2)`` pixels; a NaN shift gives NaN), in one
    kernel pass."""
    from ._grid_kernels import block_residuals  # numba on first use: a light import

    r, c = (np.ascontiguousarray(i) for i in np.nonzero(cells))  # one kernel signature
    m, n = shifts.shape[:2]
    values = np.empty(m * n)
    if n:
        block_residuals(np.ascontiguousarray(prev), np.ascontiguousarray(curr),
                        np.ascontiguousarray(flow, np.float32), np.tile(r, m), np.tile(c, m),
                        int(grid), np.ascontiguousarray(shifts, np.float64).reshape(m * n, 2),
                        values)
    return values.reshape(m, n)


def _moved_residuals(prev, curr, grid, cells, shifts) -> NDArray[np.float64]:
    """``(m, n)``: :func:`_residuals` of the ``n`` cells moved as a whole by each of ``shifts``
    (``(m, n, 2)`` pixels, no flow under them; a NaN shift gives NaN)."""
    return _residuals(prev, curr, _no_flow(*prev.shape[:2]), grid, cells, shifts)


@functools.lru_cache(maxsize=4)
def _no_flow(height: int, width: int) -> NDArray[np.float32]:
    """A zero flow ``(height, width, 2)``, allocated once per frame size, not per call (a fresh
    640x480 one cost 0.5 ms a frame in page faults). Never written to (kept writeable: a
    read-only array would be another signature of the numba kernel that reads it)."""
    return np.zeros((height, width, 2), np.float32)


def testable_cells(predicted: NDArray[np.float64], view: NDArray[np.bool_],
                   measured: NDArray, margin: float) -> NDArray[np.bool_]:
    """Cells whose static prediction the images can test: it lands on ``view``, or the
    measured flow explains the cell by itself (mean absolute difference below ``margin`` grey
    levels: the cell is seen where a static point would have left the view).

    Parameters
    ----------
    predicted : ndarray, shape (..., 2)
        Each cell centre's static prediction in the current frame, pixels (NaN: none).
    view : ndarray of bool, shape (H, W)
        Pixels around which a whole cell is sampled from the image (the usable pixels shrunk
        by one cell).
    measured : ndarray, shape (...)
        The measured flow's :func:`cell_residual` at those cells (NaN: not testable).
    margin : float

    Returns
    -------
    ndarray of bool, shape (...)
    """
    height, width = view.shape
    seen = lands_on(predicted, np.isfinite(predicted).all(axis=-1), view, width, height)
    with np.errstate(invalid="ignore"):
        return seen | (measured < margin)


def epipolar_directions(camera: CameraModel, pixels: NDArray, pose0: NDArray, pose1: NDArray
                        ) -> NDArray[np.float64]:
    """Unit image direction, at ``pixels`` of the current image, of the epipolar curve through
    each: where a static point seen there moves when its range changes (the great circle
    through its ray ``q`` and the epipole ``e'``, :mod:`fisheyemotion.constraints`).

    Parameters
    ----------
    camera : CameraModel
    pixels : ndarray, shape (n, 2)
        Points of the current image.
    pose0, pose1 : ndarray, shape (4, 4)
        ``world_from_cam`` of the previous and current camera (validated by the caller).

    Returns
    -------
    ndarray of float64, shape (n, 2)
        NaN where the pixel has no ray, the camera did not move, the ray is along the epipole
        or the curve leaves the camera's domain there.
    """
    q, ok = camera.unproject(pixels)
    baseline = pose0[:3, 3] - pose1[:3, 3]
    b = float(np.linalg.norm(baseline))
    if not b > 0:
        return np.full((len(q), 2), np.nan)
    e = pose1[:3, :3].T @ (baseline / b)  # e' in the current camera's frame
    tangent = e - (q @ e)[:, None] * q
    with np.errstate(invalid="ignore", divide="ignore"):
        tangent /= np.linalg.norm(tangent, axis=-1, keepdims=True)
        ahead, ok_ahead = camera.project(q + _STEP * tangent)
        behind, ok_behind = camera.project(q - _STEP * tangent)
        step = ahead - behind  # central: the curve's tangent to O(step^2)
        direction = step / np.linalg.norm(step, axis=-1, keepdims=True)
    return np.where((ok & ok_ahead & ok_behind)[:, None], direction, np.nan)


def static_explained(prev: NDArray[np.uint8], curr: NDArray[np.uint8],
                     flow: NDArray[np.float32], static_flow: NDArray[np.float32], grid: int,
                     margin: float, cells: NDArray[np.bool_] | None = None,
                     tolerance: float = 0.0,
                     directions: Callable[[NDArray[np.bool_]], NDArray] | None = None,
                     measured: NDArray[np.float32] | None = None,
                     reach: Callable[[NDArray[np.bool_]], NDArray] | None = None
                     ) -> NDArray[np.bool_]:
    """Cells ``(H // grid, W // grid)`` where the static scene's flow explains the frames within
    ``margin`` grey levels of the measured flow, or the same moved along ``directions(cells)``
    (``(n, 2)`` unit image directions of the ``n`` cells still unexplained, row-major; NaN: no
    such test) by up to ``tolerance`` pixels either way does (module doc). With ``reach``
    (``(n,)`` pixels for those cells, NaN: none; below :data:`MIN_REACH`: not used) a cell's
    tolerance is the larger of the two, and the moves are spaced at most ``tolerance`` apart
    (at most :data:`TOLERANCE_STEPS` a side). With ``cells`` only those are tested (False
    elsewhere); without, every whole cell. ``measured``: the measured flow's
    :func:`cell_residual` at those cells, if the caller has it.
    """
    if cells is None:
        cells = np.ones((prev.shape[0] // grid, prev.shape[1] // grid), bool)
    if measured is None:
        measured = cell_residual(prev, curr, flow, grid, cells)
    static = cell_residual(prev, curr, static_flow, grid, cells)
    with np.errstate(invalid="ignore"):
        explained = static <= measured + margin
    left = cells & ~explained
    if tolerance > 0 and directions is not None and left.any():
        extent = np.full(int(left.sum()), float(tolerance))
        if reach is not None:
            wide = np.asarray(reach(left), np.float64)
            with np.errstate(invalid="ignore"):
                extent = np.where(wide >= MIN_REACH, np.fmax(extent, wide), extent)
        steps = min(TOLERANCE_STEPS, math.ceil(float(extent.max()) / tolerance - 1e-9))
        unit = np.nan_to_num(np.asarray(directions(left), np.float64))
        shifts = [unit * (extent * (k / steps))[:, None] for k in range(1, steps + 1)]
        moved = _cell_residuals(prev, curr, static_flow, grid, left,
                                tuple(s for shift in shifts for s in (shift, -shift)))
        with np.errstate(invalid="ignore"):
            for residual in moved:
                explained |= left & (residual <= measured + margin)
    return explained


_OFFSETS = np.array([(dr, dc) for dr in (-1, 0, 1) for dc in (-1, 0, 1) if dr or dc])


def _nearer_neighbours(r: NDArray[np.intp], c: NDArray[np.intp], shape: tuple[int, int],
                       parallax: NDArray[np.float64], ratio: float
                       ) -> tuple[NDArray[np.intp], NDArray[np.intp], NDArray[np.bool_]]:
    """The eight neighbours ``(rn, cn)`` of cells ``(r, c)``, each ``(8, n)`` (clipped to the
    grid), and whether each is inside the grid with a parallax at least ``1 + ratio`` times the
    cell's (the nearer side of a depth edge)."""
    rows, cols = shape
    rn, cn = r + _OFFSETS[:, :1], c + _OFFSETS[:, 1:]
    inside = (rn >= 0) & (rn < rows) & (cn >= 0) & (cn < cols)
    rn, cn = np.clip(rn, 0, rows - 1), np.clip(cn, 0, cols - 1)
    with np.errstate(invalid="ignore"):
        return rn, cn, inside & (parallax[rn, cn] >= (1.0 + ratio) * parallax[r, c])


def edge_explained(prev: NDArray[np.uint8], curr: NDArray[np.uint8], grid: int,
                   cells: NDArray[np.bool_], measured: NDArray[np.float32],
                   motion: NDArray[np.float64], parallax: NDArray[np.float64], ratio: float
                   ) -> NDArray[np.bool_]:
    """Cells that the static motion of a nearer neighbouring cell explains (module doc).

    Cell ``(r, c)`` of ``cells`` is explained where, for one of its eight neighbours ``n``
    with ``parallax[n] >= (1 + ratio) parallax[r, c]``, the cell moved as a whole by
    ``motion[n]`` explains the frames as well as the measured flow: ``r_n <= measured``.

    Parameters
    ----------
    prev, curr : ndarray of uint8, shape (H, W)
    grid : int
        Cell size, pixels.
    cells : ndarray of bool, shape (rows, cols)
        The cells to test.
    measured : ndarray, shape (rows, cols)
        The measured flow's :func:`cell_residual` (at least at ``cells``; NaN: not explained).
    motion : ndarray, shape (rows, cols, 2)
        Each cell's static displacement, pixels (the static scene's flow at its centre; NaN
        where unknown).
    parallax : ndarray, shape (rows, cols)
        Each cell's static parallax, pixels (its prediction's distance from the image of its
        point at infinity; NaN where unknown).
    ratio : float
        How much larger a neighbour's parallax must be, as a share of the cell's (>= 0).

    Returns
    -------
    ndarray of bool, shape (rows, cols)
        False outside ``cells``.
    """
    out = np.zeros(cells.shape, bool)
    r, c = np.nonzero(cells)
    if len(r) == 0:
        return out
    rn, cn, nearer = _nearer_neighbours(r, c, cells.shape, parallax, ratio)
    # Each cell moved rigidly (the static flow interpolates across the edge, a ramp over the
    # cell); a NaN shift gives a NaN residual, which explains nothing.
    residuals = _moved_residuals(prev, curr, grid, cells,
                                 np.where(nearer[..., None], motion[rn, cn], np.nan))
    with np.errstate(invalid="ignore"):
        out[r, c] = (residuals <= measured[r, c]).any(axis=0)
    return out


def span_explained(prev: NDArray[np.uint8], curr: NDArray[np.uint8], before: NDArray[np.uint8],
                   grid: int, cells: NDArray[np.bool_], measured: NDArray,
                   to_curr: NDArray[np.float64], to_before: NDArray[np.float64]
                   ) -> NDArray[np.bool_]:
    """Cells that one static point explains over two spans of a stream (module doc).

    Each cell ``(r, c)`` of ``cells`` (row-major, as :func:`numpy.nonzero` lists them) has
    ``k`` candidate static points (ranges along its ray); candidate ``j`` moves the cell as a
    whole by ``to_curr[j, i]`` into ``curr`` and by ``to_before[j, i]`` into ``before`` (the
    frame a span before ``prev``). The cell is explained where, for one candidate, the larger
    of the two residuals is at most ``measured``: one point explains the frames on both sides
    of ``prev`` as well as the measured flow explains the pair.

    Parameters
    ----------
    prev, curr, before : ndarray of uint8, shape (H, W)
    grid : int
        Cell size, pixels.
    cells : ndarray of bool, shape (rows, cols)
        The ``n`` cells to test.
    measured : ndarray, shape (rows, cols)
        The measured flow's :func:`cell_residual` (at least at ``cells``; NaN: not explained).
    to_curr, to_before : ndarray, shape (k, n, 2)
        Pixels; NaN where a candidate is not a static point (out of the camera's domain,
        under the road): such a candidate explains nothing.

    Returns
    -------
    ndarray of bool, shape (rows, cols)
        False outside ``cells``.
    """
    out = np.zeros(cells.shape, bool)
    r, c = np.nonzero(cells)
    if len(r) == 0:
        return out
    worse = np.maximum(_moved_residuals(prev, curr, grid, cells, to_curr),  # NaN stays NaN
                       _moved_residuals(prev, before, grid, cells, to_before))
    with np.errstate(invalid="ignore"):  # NaN (no candidate) compares False
        out[r, c] = (worse <= measured[r, c]).any(axis=0)
    return out


def hidden_cells(grid: int, cells: NDArray[np.bool_], motion: NDArray[np.float64],
                 parallax: NDArray[np.float64], ratio: float) -> NDArray[np.bool_]:
    """Cells whose static point a nearer neighbouring cell's covers in the current frame
    (module doc): for one of the eight neighbours ``n`` with ``parallax[n] >= (1 + ratio)
    parallax[r, c]``, the two static predictions (cell centre plus ``motion``) land within
    :data:`COVERS` cells of each other.

    Parameters
    ----------
    grid : int
        Cell size, pixels.
    cells : ndarray of bool, shape (rows, cols)
        The cells to test.
    motion, parallax : ndarray, shape (rows, cols, 2) and (rows, cols)
        As for :func:`edge_explained`.
    ratio : float

    Returns
    -------
    ndarray of bool, shape (rows, cols)
        False outside ``cells`` and where a prediction is not finite.
    """
    out = np.zeros(cells.shape, bool)
    r, c = np.nonzero(cells)
    if len(r) == 0:
        return out
    rn, cn, nearer = _nearer_neighbours(r, c, cells.shape, parallax, ratio)
    # Where the neighbour lands relative to where the cell lands: its offset plus the motions'
    # difference.
    dx = (cn - c) * grid + motion[rn, cn, 0] - motion[r, c, 0]
    dy = (rn - r) * grid + motion[rn, cn, 1] - motion[r, c, 1]
    with np.errstate(invalid="ignore"):
        out[r, c] = (nearer & (dx * dx + dy * dy < (COVERS * grid) ** 2)).any(axis=0)
    return out


def arc_candidates(rays0: NDArray[np.float64], arc: NDArray[np.float64], pose0: NDArray,
                   pose1: NDArray, angles: NDArray[np.float64]) -> NDArray[np.float64]:
    """Static correspondences along the epipolar arc of each ray, around a point of it.

    The current ray of ``rays0``'s static point turned by ``angles`` along its epipolar great
    circle from ``arc`` (positive towards the epipole ``e'``), clamped to the static arc from
    ``e'`` (range 0) to the rotated ``p`` (range infinite) by
    :func:`fisheyemotion.constraints.nearest_static_ray`: every candidate is a static point's
    image at some range.

    Parameters
    ----------
    rays0 : ndarray of float64, shape (n, 3)
        Rays in the previous camera's frame.
    arc : ndarray of float64, shape (n, 3)
        A static correspondence of each in the current camera's frame (on its arc), e.g. the
        nearest to the measured ray.
    pose0, pose1 : ndarray, shape (4, 4)
        ``world_from_cam`` of the two cameras (validated by the caller).
    angles : ndarray of float64, shape (m, n)
        Radians along the circle, one row per candidate.

    Returns
    -------
    ndarray of float64, shape (m, n, 3)
        Unit rays in the current camera's frame; NaN where ``arc`` is, or the camera did not
        move.
    """
    baseline = pose0[:3, 3] - pose1[:3, 3]
    b = float(np.linalg.norm(baseline))
    angles = np.asarray(angles, np.float64)
    if not b > 0:
        return np.full((*angles.shape, 3), np.nan)
    e = pose1[:3, :3].T @ (baseline / b)  # e' in the current camera's frame
    p = rotate(rays0, pose1[:3, :3].T @ pose0[:3, :3])  # rays0 in the current camera's frame
    # The circle's tangent at arc, towards e' (well defined at e' itself too).
    towards = np.cross(np.cross(p, e), arc)
    with np.errstate(invalid="ignore", divide="ignore"):
        towards /= np.linalg.norm(towards, axis=-1, keepdims=True)
    turned = (np.cos(angles)[..., None] * arc + np.sin(angles)[..., None] * towards)
    m, n = angles.shape
    out = nearest_static_ray(np.tile(rays0, (m, 1)), turned.reshape(m * n, 3), pose0, pose1)
    return out.reshape(m, n, 3)


def best_candidate(prev: NDArray[np.uint8], curr: NDArray[np.uint8], flow: NDArray[np.float32],
                   grid: int, cells: NDArray[np.bool_], shifts: NDArray
                   ) -> tuple[NDArray[np.intp], NDArray[np.float64]]:
    """The candidate that explains each cell best: the smallest :func:`cell_residual` of the
    flow moved by each of ``shifts``.

    Parameters
    ----------
    prev, curr : ndarray of uint8, shape (H, W)
    flow : ndarray of float32, shape (H, W, 2)
    grid : int
    cells : ndarray of bool, shape (H // grid, W // grid)
        The ``n`` cells, row-major.
    shifts : ndarray, shape (m, n, 2)
        Pixels, ``m`` candidates per cell; a non-finite one is not tried.

    Returns
    -------
    index : ndarray of int, shape (n,)
        The best candidate's row of ``shifts``; -1 where none was tried or sampled.
    residual : ndarray of float64, shape (n,)
        Its residual, grey levels; NaN where ``index`` is -1.
    """
    shifts = np.asarray(shifts, np.float64)
    n = shifts.shape[1]
    finites = np.isfinite(shifts).all(axis=-1)
    moves = _residuals(prev, curr, flow, grid, cells, np.where(finites[..., None], shifts, 0.0))
    moves = np.where(finites, moves, np.nan)
    tried = np.isfinite(moves).any(axis=0)
    index = np.where(tried, np.argmin(np.where(np.isnan(moves), np.inf, moves), axis=0), -1)
    residual = np.where(tried, moves[np.maximum(index, 0), np.arange(n)], np.nan)
    return index, residual


def off_arc_supported(prev: NDArray[np.uint8], curr: NDArray[np.uint8],
                      flow: NDArray[np.float32], grid: int, margin: float,
                      cells: NDArray[np.bool_], shift: NDArray,
                      measured: NDArray[np.float32] | None = None) -> NDArray[np.bool_]:
    """Cells ``(H // grid, W // grid)`` of ``cells`` whose measured flow explains the frames
    better, by more than ``margin`` grey levels, than the same flow moved by ``shift`` onto the
    epipolar arc (module doc) -- than every one of the shifts, with several.

    ``shift`` is ``(n, 2)`` pixels, one row per cell of ``cells`` in row-major order, or
    ``(m, n, 2)``: ``m`` candidates per cell (:func:`arc_candidates`), of which the best counts
    (:func:`best_candidate`). False elsewhere; True where no shift of the cell is finite.
    ``measured``: the flow's :func:`cell_residual` at ``cells``, if the caller has it."""
    shift = np.asarray(shift, np.float64)
    shifts = shift[None] if shift.ndim == 2 else shift
    if measured is None:
        measured = cell_residual(prev, curr, flow, grid, cells)
    r, c = np.nonzero(cells)
    shifted = np.isfinite(shifts).all(axis=-1).any(axis=0)  # a finite shift was tried
    _, best = best_candidate(prev, curr, flow, grid, cells, shifts)
    out = np.zeros(cells.shape, bool)
    with np.errstate(invalid="ignore"):
        out[r, c] = (best > measured[r, c] + margin) | ~shifted
    return out


def sweep_ranges(camera: CameraModel, prev: NDArray[np.uint8], curr: NDArray[np.uint8],
                 flow: NDArray[np.float32], grid: int, cells: NDArray[np.bool_],
                 rays0: NDArray[np.float64], measured_at: NDArray[np.float64], pose0: NDArray,
                 pose1: NDArray, ranges: NDArray[np.float64] = SWEEP_RANGES, *,
                 distance: float = 1e3) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The range along each cell's epipolar arc whose static correspondence explains the frames
    best: a plane sweep of whole cells.

    For each of ``ranges``, the static point at that range along the cell's ray of the previous
    frame is seen at ``t`` in the current one (:func:`fisheyemotion.prior.static_scene_targets`);
    the cell's measured flow moved as a whole by ``t - measured_at`` is scored by its
    :func:`cell_residual`, and the best range wins (:func:`best_candidate`). The measured flow's
    own shape inside the cell is kept: only where the cell lands changes, along its arc.

    Parameters
    ----------
    camera : CameraModel
    prev, curr : ndarray of uint8, shape (H, W)
    flow : ndarray of float32, shape (H, W, 2)
        The measured flow.
    grid : int
    cells : ndarray of bool, shape (H // grid, W // grid)
        The ``n`` cells, row-major.
    rays0 : ndarray, shape (n, 3)
        Their rays in the previous camera's frame.
    measured_at : ndarray, shape (n, 2)
        Where the measured flow puts each cell's centre in the current frame.
    pose0, pose1 : ndarray, shape (4, 4)
        ``world_from_cam`` of the two frames (validated by the caller).
    ranges : ndarray, shape (m,)
        Metres to try.
    distance : float
        Metres beyond which a range counts as the far field (as the ego prior's).

    Returns
    -------
    range : ndarray of float64, shape (n,)
        The best range; NaN where no range's correspondence could be scored.
    residual : ndarray of float64, shape (n,)
        Its residual, grey levels; NaN there too.
    """
    ranges = np.asarray(ranges, np.float64)
    shape = (len(ranges), len(rays0))  # every candidate of every cell, in one projection
    target, ok = static_scene_targets(camera, np.broadcast_to(rays0, (*shape, 3)), pose0, pose1,
                                      Road.unknown(), distance,
                                      np.broadcast_to(ranges[:, None], shape))
    shifts = np.where(ok[..., None], target - measured_at, np.nan)
    index, residual = best_candidate(prev, curr, flow, grid, cells, shifts)
    best = np.where(index >= 0, ranges[np.maximum(index, 0)], np.nan)
    return best, residual
