"""Three views of a static point: its range from one frame pair must match the next pair's.

Two views cannot tell a static point from a point that moves along its epipolar arc: a
pedestrian crossing away from the focus of expansion, or an oncoming car, is seen exactly as a
static point nearer the camera would be (``docs/geometry.md``). A third view can, in part: a
static point triangulates to the *same world point* from every pair, a point moving across the
direction of travel (a pedestrian crossing) or changing its speed to a different one each time.
A point moving parallel to the travel at a constant speed (an oncoming or preceding vehicle)
does not: its fictitious static point ``C + k (X - C)`` is the same from every pair
(``(1 - k) Delta + k delta = 0``: ``docs/geometry.md``, *Three views*); the ground-contact test
(:mod:`fisheyemotion.ground_contact`) is what tells such a vehicle from a static object.

:class:`RangeMemory` keeps, for the current frame of a pair, where each of the pair's static
cells landed (its flow's end) with its triangulated world point and relative range error.
When that frame is the *previous* frame of a later pair, each cell's range there is compared
with the world point that landed in the cell::

    z = |lambda / |X_before - C| - 1| / sqrt(e^2 + e_before^2)

(``lambda`` the cell's range now from the frame's camera centre ``C``, ``e`` and
``e_before`` the two relative range errors: the flow's angular error over the rays' parallax,
:mod:`fisheyemotion.significance`). ``z`` counts the disagreement in units of what the flows'
errors explain; the detector raises a cell with ``z`` above ``params.range_consistency`` to the
threshold and beyond, as it does the significance of the height and depth deviations. Where the
photometric check explains the cell by the static scene, the raise counts only from
``params.range_consistency_alone``: a flow smeared across an object's outline, or the far road,
exceeds the error model on static cells by less than a crossing pedestrian does. Per
point, not per sample of the static-scene model, whose medians mix the two ranges of a depth
discontinuity. Cells without a stored point (nothing static landed there, or the frame was
never a current frame of this detector) have no ``z`` (NaN).
"""

from __future__ import annotations

from collections import deque

import numpy as np
from numpy.typing import NDArray

__all__ = ["RangeMemory"]


class RangeMemory:
    """Where the static cells of recent pairs landed, for the pairs whose previous frame that is.

    Parameters
    ----------
    frames : int
        Frames remembered (a detector with frame gap ``g`` needs ``g + 1``).
    """

    def __init__(self, frames: int) -> None:
        self._kept: deque[tuple[NDArray, NDArray[np.float64], NDArray[np.float64]]] = deque(
            maxlen=frames)

    def clear(self) -> None:
        self._kept.clear()

    def __len__(self) -> int:
        return len(self._kept)

    def remember(self, frame: NDArray, points: NDArray[np.float64], error: NDArray[np.float64],
                 landing: NDArray[np.float64], static: NDArray[np.bool_], grid: int,
                 centre: NDArray[np.float64]) -> None:
        """Keep, for ``frame`` (the pair's current frame, an image ``(H, W)``; matched later
        by identity or equal pixels: ``detect_flow`` callers pass copies),
        the world points ``(rows, cols, 3)`` and relative range errors ``(rows, cols)`` of the
        ``static`` cells at the cells their flows' ends ``landing`` ``(rows, cols, 2)`` (pixels
        of that frame) fall in; where several land in one cell, the point nearest the frame's
        camera centre ``centre`` (3,) (it hides the others)."""
        from ._grid_kernels import nearest_landed  # numba on first use: a light import

        rows, cols = static.shape
        kept_points = np.full((rows, cols, 3), np.nan)
        kept_error = np.full((rows, cols), np.nan)
        nearest_landed(np.ascontiguousarray(points, np.float64),
                       np.ascontiguousarray(error, np.float64),
                       np.ascontiguousarray(landing, np.float64), np.ascontiguousarray(static),
                       int(grid), np.ascontiguousarray(centre, np.float64), kept_points,
                       kept_error)
        self._kept.append((frame, kept_points, kept_error))

    def deviation(self, frame: NDArray, ranges: NDArray[np.float64], error: NDArray[np.float64],
                  centre: NDArray[np.float64]) -> NDArray[np.float64] | None:
        """``z`` (module doc) of each cell of ``frame`` (now a pair's previous frame) with
        ``ranges`` and relative ``error`` ``(rows, cols)`` from its camera centre ``centre``;
        NaN where nothing was kept; None if ``frame`` was not remembered."""
        for kept, points, kept_error in tuple(self._kept):
            if kept is frame or (kept.shape == frame.shape and np.array_equal(kept, frame)):
                before = np.linalg.norm(points - centre, axis=-1)
                with np.errstate(invalid="ignore", divide="ignore"):
                    return np.abs(ranges / before - 1) / np.sqrt(error * error
                                                                 + kept_error * kept_error)
        return None
