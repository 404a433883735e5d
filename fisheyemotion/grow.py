"""Grow detected regions to the extent of their object by its flow.

The constraints flag the cells where a deviation is measured; the rest of a moving object often
stays below the threshold (its lower part near the road, where the height and anti-parallel
deviations vanish; its middle, where the flow is smooth). What the whole object shares is its
own motion: the *residual* flow, measured flow minus the flow the static scene would have there
(the ego prior's prediction, with the static-scene model's ranges). A region grows into a
neighbouring cell, up to ``steps`` cells out, when that cell's residual is like the region's
mean residual ``r``:

    |residual - r| <= tolerance + relative |r|     and     |residual| >= |r| / 2

so that a cell of static background (residual near 0) or of another object (another residual)
stops the growth: the object's flow boundary is the region's boundary.
"""

from __future__ import annotations

import cv2
import numpy as np
from numpy.typing import NDArray

__all__ = ["grow_regions", "reach"]

def grow_regions(moving: NDArray[np.bool_], residual: NDArray[np.float64],
                 valid: NDArray[np.bool_], *, steps: int, tolerance: float = 2.0,
                 relative: float = 0.5) -> NDArray[np.bool_]:
    """Cells of the moving regions grown along their residual flow.

    Parameters
    ----------
    moving : ndarray of bool, shape (rows, cols)
        Cells above the threshold.
    residual : ndarray, shape (rows, cols, 2)
        Measured minus static-scene flow of each cell, pixels (NaN where unknown).
    valid : ndarray of bool, shape (rows, cols)
        Cells that may join.
    steps : int
        Rings of cells a region may grow by.
    tolerance, relative : float
        Pixels, and a fraction of the region's mean residual: how far a cell's residual may be
        from the region's.

    Returns
    -------
    ndarray of bool, shape (rows, cols)
        ``moving`` and the cells grown into.
    """
    box = reach(moving, steps)
    out = moving.copy()
    if box is not None:  # only the cells within ``steps`` of a region can change
        out[box] = _grown(moving[box], residual[box], valid[box], steps, tolerance, relative)
    return out


def reach(moving: NDArray[np.bool_], steps: int) -> tuple[slice, slice] | None:
    """The bounding box of the cells within ``steps`` of a cell of ``moving`` (clipped to the
    grid), as slices; None where nothing can grow (no region, no step). Only there does
    :func:`grow_regions` read the residual."""
    rows, cols = np.nonzero(moving)
    if len(rows) == 0 or steps <= 0:
        return None
    return (slice(max(rows.min() - steps, 0), rows.max() + steps + 1),
            slice(max(cols.min() - steps, 0), cols.max() + steps + 1))


def _grown(moving, residual, valid, steps, tolerance, relative) -> NDArray[np.bool_]:
    """:func:`grow_regions` on a grid holding every cell it can change."""
    from ._grid_kernels import grown_labels  # numba on first use: a light import

    # OpenCV's labelling (8-connected; no scipy or scikit-image import in a detection); the
    # kernel renumbers it in the raster order of each region's first cell: where two regions
    # reach the same cell, the later one takes it.
    n, labels = cv2.connectedComponents(np.ascontiguousarray(moving, dtype=np.uint8),
                                        connectivity=8, ltype=cv2.CV_32S)
    grown = np.empty(labels.shape, np.int64)
    grown_labels(labels, n - 1, np.ascontiguousarray(residual, np.float64),
                 np.ascontiguousarray(valid, np.bool_), int(steps), float(tolerance),
                 float(relative), grown)
    return grown > 0
