"""Region test: a region read beyond the road it stands on is moving away along its arc.

A static point is not under the road: seen along a unit ray ``r`` from a camera ``h`` above the
road, the road plane is met at range ``rho(r) = h / (r . down)`` (for a ray pointing down), and
a point at range ``lambda`` on that ray is ``h (1 - lambda / rho)`` above the road. So every
static point's range satisfies

    lambda <= rho(r),

which is the positive-height condition (``xi_h``, ``docs/geometry.md``) read as ranges.

An object that moves along the direction of travel by ``delta`` while the camera moves ``b``
keeps its rays on their epipolar circles, and the two views triangulate it at ``b / (b - delta)``
times its true range (scaled about the first camera centre; ``docs/geometry.md``, *Receding
objects*). A car ahead in the same lane (``0 < delta < b``) is seen to move less along its arc
than a static point at its range would: it reads farther than it is, by ``b / (b - delta)``, and
its lowest part, which stands on the road, reads under the road. So does any motion whose
component along the arc points towards the epipole, such as a pedestrian walking towards the
camera's path. With the exact flow, the bundled scenes' preceding cars read
1.7-3.9 times the road's range at their base, their crossing pedestrians 1.06-1.42 times (the
medians over each scene's object-frames; ``docs/measurements.py base_ratios``).

Cell by cell that is the height term, and a weak one exactly where it matters: near the epipole
and for slow objects the angles involved are fractions of the flow's error. A region's lowest
cells, where the road is seen directly below them, measure the same thing on an object's whole
width. :func:`receding_z` takes, for every region (connected cells above a fraction of the
threshold) and every column in which

1. the ``ROAD_ROWS`` cells below its lowest cell there read the road plane within
   ``ROAD_TOLERANCE`` (the region ends where the road is seen: it stands there), and
2. its ``EDGE_ROWS`` lowest cells there do not read the road along their own rays (below),

the median range of its ``EDGE_ROWS`` lowest cells there, ``lambda``, and its excess over the
road plane's range along the lowest cell's ray in units of that cell's relative range error
``epsilon`` (the flow's angular error over the parallax):

    z = (lambda / rho - 1) / epsilon.

A column's ``z`` is then the median of the region's measured columns within ``COLUMNS`` on either
side (:func:`fisheyemotion.ground_contact.smooth_columns`: one column's flow error does not
decide), and a region needs ``MIN_COLUMNS`` measured columns. A static object that stands on
the road has ``z`` about 0 or below (its base reads the road's range, its upright body no
farther); an object whose base is hidden, or that stands on something other than the road, is
not tested.

The median over the lowest three cells assumes an upright base (vehicles, pedestrians, walls,
poles). A region's cells that are road (the flow's error around an object lifts them above the
fraction of the threshold) slope away upwards: higher cells read farther (at 200 px per radian
and 5-px cells, the road one cell up is 1.26 times farther 7 degrees below the horizon, 1.06
times 30 degrees below). So a column whose lowest cells read the road plane along *their own*
rays (the median of ``lambda / rho`` within ``ROAD_TOLERANCE`` of 1) is road and is not tested.
Cells that read the road are not taken out of the regions: that also took out the bases of the
pedestrians, which read only 1.06-1.42 times beyond it, and covered less of them
(``docs/evaluation.md``).

The detector raises the likelihood of a region's cells in the columns at ``z >= Params.receding``
to ``threshold * z / receding`` (:meth:`fisheyemotion.MotionDetector.detect_flow`): the
object's region in those columns, not only the cells whose deviations reached the threshold. Measured
in ``docs/evaluation.md`` (*Receding regions*).
"""

from __future__ import annotations

import cv2
import numpy as np
from numpy.typing import NDArray

from .calib.transforms import rotate
from .ground_contact import lower_edges, row_nanpercentile, smooth_columns
from .road import Road

__all__ = ["COLUMNS", "EDGE_ROWS", "MIN_COLUMNS", "ROAD_ROWS", "ROAD_TOLERANCE", "receding_cells",
           "receding_z", "road_ranges"]

#: Cells below a region's lowest cell in a column that must read the road plane.
ROAD_ROWS = 2
#: Relative difference from the road plane's range within which a cell reads the road.
ROAD_TOLERANCE = 0.1
#: A region's lowest cells in a column whose median range is its range there.
EDGE_ROWS = 3
#: A column's z is the median of its region's measured columns within this many on either side.
COLUMNS = 2
#: Measured columns a region needs to be tested.
MIN_COLUMNS = 2


def road_ranges(rays: NDArray[np.float64], pose: NDArray, road: Road) -> NDArray[np.float64]:
    """Range along each camera-frame ray ``(..., 3)`` to the road plane from ``pose``'s centre
    (``world_from_cam``); ``inf`` where the ray does not point down, NaN where it is NaN."""
    return road.ray_range(pose[:3, 3], rotate(rays, pose[:3, :3]))


def receding_z(labels: NDArray[np.intp], ranges: NDArray[np.float64],
               range_error: NDArray[np.float64], plane: NDArray[np.float64], *,
               columns: int = COLUMNS) -> NDArray[np.float64]:
    """How far each labelled region's base reads beyond the road, per column (module doc).

    Parameters
    ----------
    labels : ndarray of int, shape (rows, cols)
        Regions ``1..n`` on the cell grid, 0 elsewhere.
    ranges : ndarray, shape (rows, cols)
        Static range of each cell (metres; NaN where unknown).
    range_error : ndarray, shape (rows, cols)
        Relative error of each range (the flow's angular error over the parallax).
    plane : ndarray, shape (rows, cols)
        The road plane's range along each cell's ray (:func:`road_ranges`).
    columns : int
        Columns on either side a column's z is the median over.

    Returns
    -------
    ndarray, shape (rows, cols)
        The z of each region cell's column; NaN where that column was not measured, the region
        has fewer than ``MIN_COLUMNS`` measured columns, and outside the regions.
    """
    rows, cols = labels.shape
    n = int(labels.max()) if labels.size else 0
    out = np.full(labels.shape, np.nan)
    if n == 0:
        return out
    er, ec = lower_edges(labels)
    keep = er < rows - ROAD_ROWS
    er, ec = er[keep], ec[keep]
    own = labels[er, ec]
    with np.errstate(invalid="ignore", divide="ignore"):
        on_road = np.ones(len(er), bool)
        for j in range(1, ROAD_ROWS + 1):
            r = er + j
            on_road &= (labels[r, ec] != own) & (np.abs(ranges[r, ec] / plane[r, ec] - 1)
                                                 < ROAD_TOLERANCE)
        er, ec, own = er[on_road], ec[on_road], own[on_road]
        samples = np.full((len(er), EDGE_ROWS), np.nan)
        along = np.full((len(er), EDGE_ROWS), np.nan)  # each over the road's range on its ray
        for j in range(EDGE_ROWS):
            r = np.maximum(er - j, 0)
            mine = (er >= j) & (labels[r, ec] == own)
            samples[:, j] = np.where(mine, ranges[r, ec], np.nan)
            along[:, j] = np.where(mine, ranges[r, ec] / plane[r, ec], np.nan)
        lam = row_nanpercentile(samples, 50.0)
        z = (lam / plane[er, ec] - 1) / range_error[er, ec]
        # Lowest cells that read the road along their own rays are road, not an upright base.
        z[np.abs(row_nanpercentile(along, 50.0) - 1) < ROAD_TOLERANCE] = np.nan
    ok = np.isfinite(z)
    own, ec, z = own[ok], ec[ok], z[ok]
    per_column = np.full((n + 1, cols), np.nan)
    # The smaller z where a region meets the road twice in one column (a notch, a hole).
    np.fmin.at(per_column, (own, ec), z)
    tested = np.flatnonzero(np.isfinite(per_column).sum(axis=1) >= MIN_COLUMNS)
    if not len(tested):
        return out
    row = np.full(n + 1, -1)
    row[tested] = np.arange(len(tested))
    smoothed = smooth_columns(per_column[tested], columns)
    r = row[labels]
    inside = r >= 0
    out[inside] = smoothed[r[inside], np.broadcast_to(np.arange(cols), labels.shape)[inside]]
    return out


def receding_cells(candidates: NDArray[np.bool_], ranges: NDArray[np.float64],
                   range_error: NDArray[np.float64], rays: NDArray[np.float64], pose: NDArray,
                   road: Road) -> NDArray[np.float64]:
    """:func:`receding_z` of the regions of ``candidates`` (4-connected cells with a range).

    Parameters
    ----------
    candidates : ndarray of bool, shape (rows, cols)
        Cells that may belong to a moving object (above a fraction of the threshold).
    ranges, range_error : ndarray, shape (rows, cols)
        As :func:`receding_z`.
    rays : ndarray, shape (rows, cols, 3)
        The cells' rays, camera frame.
    pose : ndarray, shape (4, 4)
        ``world_from_cam`` of that camera.
    road : Road
        The road, known.

    Returns
    -------
    ndarray, shape (rows, cols)
        z of each candidate cell's column (NaN where not measured).
    """
    plane = road_ranges(rays, pose, road)
    regions = candidates & np.isfinite(ranges)
    if not regions.any():
        return np.full(candidates.shape, np.nan)
    _, labels = cv2.connectedComponents(regions.astype(np.uint8), connectivity=4,
                                        ltype=cv2.CV_32S)
    return receding_z(labels.astype(np.intp), ranges, range_error, plane)
