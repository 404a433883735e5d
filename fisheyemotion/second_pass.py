"""A second flow pass near the cells a pair flagged: the flow method measures the rest of a motion
that its first pass fell short of.

The detector warps the current frame back by the static scene's predicted flow, so that Farneback
or DIS only measure the residual; a moving object's residual is its own motion. Both methods
measure a residual short: given the warp, a uniform 10 px residual comes back about 2 px short
(median on a street frame's textured static pixels, ``docs/evaluation.md``, *Second flow pass*),
because their windows and pyramids pull each estimate towards the zero motion around it. An
object's deviations are then smaller than its motion, its cells fall under the threshold at its
edges and in its plain middle, and it is covered in part.

Warping the current frame back again by the first pass's whole flow and measuring once more,
``flow_2 = flow_1 + F(prev, curr(u + flow_1(u)))``, measures what is left: on the same pixels the
10 px residual comes back 0.7 px short. Where the static prior is wrong (a wall read at the wrong
range by the scene model), the first pass stays near the prior and so near a *static* reading;
a second pass there departs from it by the flow's errors, and run over the whole frame it raised
false alarms (measured). So it runs only where the first pass already flagged cells: within
``reach`` cells of them, each group of such cells on its own image box (plus ``MARGIN`` pixels
of context for the flow method), and a cell's likelihood is the second pass's only where the
new flow explains the frames better (:class:`fisheyemotion.MotionDetector`): the images decide
which of the two measurements holds, in either direction.
"""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Callable

import cv2
import numpy as np
from numpy.typing import NDArray

from .flow import pixel_grid

__all__ = ["BETTER_BY", "MARGIN", "SIZE_STEP", "BoxFlows", "better_explained", "near_cells",
           "second_flow"]

#: Pixels of context around the cells' box that the second pass's flow method sees.
MARGIN = 16

#: Grey levels by which the second pass's flow must explain a cell better than the first's
#: (mean absolute residual over the cell) for the cell to take its likelihood. Chosen on the
#: tuning street and the real kitchen clip, whose static background must stay under 1 %
#: flagged (0: 1.03 %, 1: 0.99 %, 2: 0.96 %, as without the pass; ``docs/evaluation.md``).
BETTER_BY = 2.0

#: Box sides are multiples of this, pixels.
SIZE_STEP = 32

#: The smallest side of a box (OpenCV's pyramids need some room).
_MIN_SIDE = 48


class BoxFlows:
    """The detector's flow method for the second pass's boxes: one estimator per box size, the
    last ``keep`` sizes kept (a DIS object reallocates its buffers when the size changes, about
    3 ms with the ultrafast preset, more than its flow on a box).

    Parameters
    ----------
    make : callable
        ``make() -> estimator``, ``estimator(a, b) -> (h, w, 2)`` float32.
    keep : int
    """

    def __init__(self, make: Callable[[], Callable], keep: int = 16) -> None:
        self._make, self._keep = make, int(keep)
        self._by_size: OrderedDict[tuple[int, int], Callable] = OrderedDict()

    def __call__(self, a: NDArray[np.uint8], b: NDArray[np.uint8]) -> NDArray[np.float32]:
        size = a.shape[:2]
        estimator = self._by_size.pop(size, None)
        if estimator is None:
            estimator = self._make()
            while len(self._by_size) >= self._keep:
                self._by_size.popitem(last=False)
        self._by_size[size] = estimator
        return estimator(a, b)


def near_cells(flagged: NDArray[np.bool_], reach: int) -> NDArray[np.bool_]:
    """The cells within ``reach`` cells (a square, Chebyshev distance) of a ``flagged`` cell.

    Parameters
    ----------
    flagged : ndarray of bool, shape (rows, cols)
    reach : int
        Cells, at least 0.

    Returns
    -------
    ndarray of bool, shape (rows, cols)
    """
    if reach <= 0 or not flagged.any():
        return flagged.copy()
    kernel = np.ones((2 * reach + 1, 2 * reach + 1), np.uint8)
    return cv2.dilate(flagged.astype(np.uint8), kernel) > 0


def second_flow(prev: NDArray[np.uint8], curr: NDArray[np.uint8], flow: NDArray[np.float32],
                cells: NDArray[np.bool_], grid: int,
                estimator: Callable[[NDArray[np.uint8], NDArray[np.uint8]], NDArray[np.float32]],
                *, size_step: int = 1) -> NDArray[np.float32]:
    """``flow`` with a second pass added on ``cells``: the residual that ``estimator`` measures
    between ``prev`` and ``curr`` warped back by ``flow``, on the image box around each
    8-connected group of cells (plus :data:`MARGIN` pixels of context), kept on the group's
    own pixels.

    Parameters
    ----------
    prev, curr : ndarray of uint8, shape (H, W)
    flow : ndarray of float32, shape (H, W, 2)
        The first pass: ``prev(u) ~ curr(u + flow(u))``.
    cells : ndarray of bool, shape (H // grid, W // grid)
        The cells to measure again.
    grid : int
        Cell size, pixels.
    estimator : callable
        ``estimator(a, b) -> (h, w, 2)`` float32 flow from ``a`` to ``b`` (the detector's own
        flow method, without a prior).
    size_step : int
        Box sides are rounded up to a multiple of this (:data:`SIZE_STEP` for DIS, which keeps
        buffers per size: :class:`BoxFlows`; 1 for Farneback, whose time goes with the area).

    Returns
    -------
    ndarray of float32, shape (H, W, 2)
        A new array; equal to ``flow`` outside ``cells``' pixels.
    """
    out = np.array(flow, dtype=np.float32, copy=True)
    if not cells.any():
        return out
    h, w = prev.shape[:2]
    n, labels, stats, _ = cv2.connectedComponentsWithStats(cells.astype(np.uint8), connectivity=8,
                                                           ltype=cv2.CV_32S)
    for i in range(1, n):
        c0, r0, cw, ch = (int(v) for v in stats[i, :4])
        x0, x1 = _span(c0 * grid, (c0 + cw) * grid, w, size_step)
        y0, y1 = _span(r0 * grid, (r0 + ch) * grid, h, size_step)
        box = flow[y0:y1, x0:x1]
        grid_x, grid_y = (g[y0:y1, x0:x1] for g in pixel_grid(h, w))
        map_x, map_y = grid_x + box[..., 0], grid_y + box[..., 1]
        # Where the first pass has no finite flow the box keeps the previous frame: no residual.
        finite = np.isfinite(map_x) & np.isfinite(map_y)
        warped = cv2.remap(curr, np.where(finite, map_x, grid_x),
                           np.where(finite, map_y, grid_y), cv2.INTER_LINEAR,
                           borderMode=cv2.BORDER_REPLICATE)
        a = np.ascontiguousarray(prev[y0:y1, x0:x1])
        np.copyto(warped, a, where=~finite)
        residual = estimator(a, warped)
        # The group's own cells' pixels, within the box.
        own = np.repeat(np.repeat(labels[r0:r0 + ch, c0:c0 + cw] == i, grid, 0), grid, 1)
        oy, ox = r0 * grid - y0, c0 * grid - x0
        target = out[r0 * grid:(r0 + ch) * grid, c0 * grid:(c0 + cw) * grid]
        target += np.where(own[..., None], residual[oy:oy + ch * grid, ox:ox + cw * grid], 0)
    return out


def better_explained(prev: NDArray[np.uint8], curr: NDArray[np.uint8],
                     first: NDArray[np.float32], second: NDArray[np.float32], grid: int,
                     rows: NDArray[np.intp], cols: NDArray[np.intp],
                     shape: tuple[int, int]) -> NDArray[np.bool_]:
    """Whether ``second`` explains each cell ``(rows[i], cols[i])`` better than ``first`` by
    :data:`BETTER_BY` grey levels (:func:`fisheyemotion.photometric.cell_residual`).

    Parameters
    ----------
    prev, curr : ndarray of uint8, shape (H, W)
    first, second : ndarray of float32, shape (H, W, 2)
        Two flows from ``prev`` to ``curr``.
    grid : int
    rows, cols : ndarray of int, shape (n,)
        The cells.
    shape : (rows, cols)
        The cell grid's shape.

    Returns
    -------
    ndarray of bool, shape (n,)
        False where either residual is not finite.
    """
    from .photometric import cell_residual  # numba on first use

    cells = np.zeros(shape, bool)
    cells[rows, cols] = True
    before = cell_residual(prev, curr, first, grid, cells)[rows, cols]
    after = cell_residual(prev, curr, second, grid, cells)[rows, cols]
    with np.errstate(invalid="ignore"):
        return after < before - BETTER_BY


def _span(lo: int, hi: int, size: int, step: int) -> tuple[int, int]:
    """``[lo, hi)`` widened by :data:`MARGIN`, then to a multiple of ``step`` and at least
    ``_MIN_SIDE``, within ``[0, size)``."""
    lo, hi = max(0, lo - MARGIN), min(size, hi + MARGIN)
    want = min(size, max(_MIN_SIDE, -(-(hi - lo) // step) * step))
    lo = max(0, min(lo - (want - (hi - lo)) // 2, size - want))
    return lo, lo + want
