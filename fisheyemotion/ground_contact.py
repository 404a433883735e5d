"""Region test: does a region led by the anti-parallel term stand on the road, or float above it?

The anti-parallel deviation ``xi_p`` is the one constraint a static object fails too: seen as
static, an object moving towards the camera triangulates *above the road, nearer than it is*,
exactly where a static obstacle (a parked car, a wall, a pole) does (the paper's Fig. 7). Two
views of a point cannot tell them apart; the road can (``docs/geometry.md``, "ground contact"):

- a static object stands on the road: below its region's lower edge in the image lie the rest of
  the object at the same range, then road nearer still. The static range just below the edge is
  about the edge's own (ratio 1.00);
- an oncoming object, read as static, is a scaled copy ``k (X - C)`` of itself,
  ``k = v_ego / (v_ego + v_obj) < 1``: it floats. Just below its lower edge lies the real road,
  at about ``1 / k`` of the edge's static range (ratio 1.4-1.7 measured at ``k = 0.5``).

For every region whose likelihood is mostly the anti-parallel term, each of its columns' lowest
cell (the edge) is followed *down the world vertical* (the image direction in which a point
below the edge's static point moves) for ``steps`` cells, skipping cells of the region itself;
the median static range met there, divided by the edge's, is that column's ratio (the largest
over the region's edge cells in a column). A column
whose ratio is below ``ratio`` stands on the road: its cells' anti-parallel deviation is
explained. The decision is per column because a pedestrian stepping out beside a parked car is
one region with it; but a column's own walk meets the flow's errors (a boundary the flow smears,
a cell of another surface), so its ratio is first the median of the region's columns within
``columns`` on either side (``Params.contact_columns``, 3: measured in docs/evaluation.md).
Columns with nothing measured below take the region's decision (the 75th percentile of its
columns' ratios).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from .calib.base import CameraModel
from .road import Road
from .segment import led_regions
from .static_scene import world_points

__all__ = ["WALK_PERCENTILE", "contact_ratios", "lower_edges", "row_nanpercentile",
           "smooth_columns", "standing_regions"]

#: The percentile of the ranges met below an edge cell that its column's ratio is taken from
#: (50: the median).
WALK_PERCENTILE = 50.0


def contact_ratios(labels: NDArray[np.intp], ranges: NDArray[np.float64],
                   rays: NDArray[np.float64], pose: NDArray, camera: CameraModel, road: Road,
                   grid: int, *, steps: int = 4) -> NDArray[np.float64]:
    """The ground-contact ratio of every column of every labelled region.

    Parameters
    ----------
    labels : ndarray of int, shape (rows, cols)
        Regions ``1..n`` on the cell grid, 0 elsewhere.
    ranges : ndarray, shape (rows, cols)
        Static range of each cell from the camera centre (NaN where unknown).
    rays : ndarray, shape (rows, cols, 3)
        The cells' rays, camera frame.
    pose : ndarray, shape (4, 4)
        ``world_from_cam`` of that camera.
    grid : int
        Cell size, pixels.
    steps : int
        Cells followed below each edge cell.

    Returns
    -------
    ndarray, shape (n + 1, cols)
        Ratio of region ``i`` in column ``c`` at ``[i, c]`` (the largest over the region's edge
        cells in that column); NaN where nothing was measured. Row 0 is unused.
    """
    rows, cols = labels.shape
    n = int(labels.max())
    out = np.full((n + 1, cols), np.nan)
    er, ec = lower_edges(labels)
    lam = ranges[er, ec]
    ok = np.isfinite(lam)
    er, ec, lam = er[ok], ec[ok], lam[ok]
    if not len(er):
        return out
    # Image direction of the world vertical at the edge's static point.
    centre = pose[:3, 3]
    points = world_points(rays[er, ec], lam, pose)
    drop = 0.05 * lam[:, None] * (-road.up)  # a short step down, scaled with the range
    both = np.stack([points, points + drop]) - centre
    pix, valid = camera.project(both @ pose[:3, :3])
    step = pix[1] - pix[0]
    norm = np.linalg.norm(step, axis=-1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        direction = step / norm
    good = valid.all(axis=0) & (norm[:, 0] > 1e-9)
    centres = np.stack([ec * grid + (grid - 1) / 2, er * grid + (grid - 1) / 2], axis=-1)
    samples = np.full((steps, len(er)), np.nan)
    own = labels[er, ec]
    for j in range(1, steps + 1):
        at = centres + direction * grid * j
        with np.errstate(invalid="ignore"):
            c = np.floor(at[:, 0] / grid)
            r = np.floor(at[:, 1] / grid)
            inside = good & (c >= 0) & (c < cols) & (r >= 0) & (r < rows)
        ci = np.where(inside, c, 0).astype(np.intp)
        ri = np.where(inside, r, 0).astype(np.intp)
        use = inside & (labels[ri, ci] != own)
        samples[j - 1] = np.where(use, ranges[ri, ci], np.nan)
    # The median of what was measured below each edge (NaN where nothing): the 50th percentile
    # (linear interpolation: the mean of the middle two of an even count), as np.nanmedian.
    ratio = row_nanpercentile(samples.T, WALK_PERCENTILE) / lam
    has = np.isfinite(ratio)
    np.fmax.at(out, (own[has], ec[has]), ratio[has])
    return out


def lower_edges(labels: NDArray[np.intp]) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
    """Rows and columns of the cells of labelled regions (``labels`` > 0) whose lower
    neighbour is not of their region (another region, none, or the grid's last row)."""
    below = np.zeros_like(labels)
    below[:-1] = labels[1:]
    return np.nonzero((labels > 0) & (below != labels))


def row_nanpercentile(a: NDArray[np.float64], q: float) -> NDArray[np.float64]:
    """``np.nanpercentile(a, q, axis=1)`` (linear interpolation) for a 2-D array, without its
    per-row Python loop: NaN sort last, so each row's finite values lead its sorted copy."""
    s = np.sort(a, axis=1)
    k = np.isfinite(a).sum(axis=1)
    pos = (k - 1) * (q / 100.0)
    lo = np.floor(pos).astype(np.intp)
    hi = np.minimum(lo + 1, np.maximum(k - 1, 0))
    rows = np.arange(len(a))
    lo = np.clip(lo, 0, a.shape[1] - 1)
    out = s[rows, lo] + (pos - np.floor(pos)) * (s[rows, hi] - s[rows, lo])
    out[k == 0] = np.nan
    return out


def smooth_columns(per_column: NDArray[np.float64], columns: int) -> NDArray[np.float64]:
    """Each finite ratio of ``per_column`` (n + 1, cols) replaced by the median of its row's
    finite ratios within ``columns`` columns on either side (NaN stays NaN; 0: unchanged)."""
    if columns <= 0 or per_column.shape[1] == 0:
        return per_column
    width = 2 * columns + 1
    padded = np.pad(per_column, ((0, 0), (columns, columns)), constant_values=np.nan)
    windows = np.lib.stride_tricks.sliding_window_view(padded, width, axis=1)
    finite = np.nonzero(np.isfinite(per_column))  # only these are smoothed
    out = np.full(per_column.shape, np.nan)
    out[finite] = row_nanpercentile(windows[finite], 50.0)
    return out


def standing_regions(moving: NDArray[np.bool_], antiparallel_share: NDArray[np.float64],
                     ranges: NDArray[np.float64], rays: NDArray[np.float64], pose: NDArray,
                     camera: CameraModel, road: Road, grid: int, *, ratio: float,
                     steps: int = 4, columns: int = 0) -> NDArray[np.bool_]:
    """Cells of the regions led by the anti-parallel term that stand on the road.

    Parameters
    ----------
    moving : ndarray of bool, shape (rows, cols)
        Cells above the detection threshold.
    antiparallel_share : ndarray, shape (rows, cols)
        The weighted anti-parallel deviation's share of each cell's likelihood.
    ratio : float
        Columns whose ground-contact ratio (:func:`contact_ratios`) is below this stand on the
        road.
    columns : int
        A column's ratio is first the median of its region's within this many columns on
        either side (:func:`smooth_columns`; 0: its own).

    Returns
    -------
    ndarray of bool, shape (rows, cols)
    """
    labels, led = led_regions(moving, antiparallel_share)
    if not led.any():
        return np.zeros_like(moving)
    candidates = np.where(led[labels], labels, 0)
    per_column = smooth_columns(
        contact_ratios(candidates, ranges, rays, pose, camera, road, grid, steps=steps), columns)
    region = row_nanpercentile(per_column, 75.0)
    decided = np.where(np.isnan(per_column), region[:, None], per_column)
    with np.errstate(invalid="ignore"):
        stands = decided < ratio
    stands[0] = False
    cols = np.broadcast_to(np.arange(moving.shape[1]), moving.shape)
    return stands[candidates, cols]
