"""Threshold + connected components on the grid of cell likelihoods (OpenCV's labelling, 8-connected;
region properties for all labels at once with numpy; scikit-image's hysteresis threshold when a
seed threshold is set; the extension of kept regions to weaker connected cells; the closing of
kept regions over small gaps, which joins the pieces of one object)."""

from __future__ import annotations

from typing import NamedTuple

import cv2
import numpy as np
from numpy.typing import NDArray


class Region(NamedTuple):
    """A connected moving region, in pixels of the full image.

    Attributes
    ----------
    label : int
    bbox : (x, y, w, h)
        As ``cv2.boundingRect``.
    area : int
        Pixels (cells times ``grid**2``).
    mean_likelihood : float
    centroid : (u, v)
    """

    label: int
    bbox: tuple[int, int, int, int]
    area: int
    mean_likelihood: float
    centroid: tuple[float, float]


def with_pixels(region: Region, pixels: NDArray[np.uint8], x: int, y: int) -> Region:
    """``region`` (label and mean likelihood kept) with the box, area and centroid of
    ``pixels``, a 0/1 crop whose top-left pixel is ``(x, y)`` of the image; at least one pixel
    set."""
    m = cv2.moments(pixels, binaryImage=True)
    bx, by, bw, bh = cv2.boundingRect(pixels)
    return region._replace(bbox=(x + bx, y + by, bw, bh), area=int(m["m00"]),
                           centroid=(m["m10"] / m["m00"] + x, m["m01"] / m["m00"] + y))


def segment_cells(cell_likelihood: NDArray[np.float64], *, threshold: float, grid: int,
                  min_area: int, age: NDArray | None = None, persistence: int = 1,
                  seed_threshold: float = 0.0, extend_threshold: float = 0.0,
                  seeds: NDArray[np.bool_] | None = None, gap: int = 0,
                  led: NDArray[np.float64] | None = None, led_seeds: int = 1,
                  with_labels: bool = False
                  ) -> tuple[NDArray[np.bool_], list[Region]] | tuple[
                      NDArray[np.bool_], list[Region], NDArray[np.int32]]:
    """Cells above ``threshold`` grouped 8-connected; regions under ``min_area`` pixels dropped,
    and, with ``age``, regions none of whose cells has been moving ``persistence`` times.

    Parameters
    ----------
    cell_likelihood : ndarray, shape (rows, cols)
        NaN for invalid cells (never moving).
    age : ndarray of int, shape (rows, cols), optional
        Consecutive detections each cell has been moving in (streams).
    seed_threshold : float
        Hysteresis: a region (8-connected) is kept only if one of its cells exceeds this.
    extend_threshold : float
        Below ``threshold``: each region kept (of ``min_area`` cells above ``threshold``) is
        extended to the cells above this connected to it (8-connected) through such cells: a
        hysteresis threshold whose seeds are the kept regions, not single cells. 0, or at or
        above ``threshold``: off.
    seeds : ndarray of bool, shape (rows, cols), optional
        Regions none of whose cells is a seed are dropped (the photometric check's cells the
        static scene does not explain, :mod:`fisheyemotion.photometric`).
    gap : int
        Cells. Each region kept by the rules above (seeded, at least ``min_area``, persistent)
        is closed together with the pieces of cells above ``threshold`` near it (a
        morphological closing by a plus ``2 gap + 1`` cells across): where a piece faces the
        region, or a piece joined to it, across at most ``2 gap`` cells of a row or column, the
        cells between are filled, flagged or not, and the piece joins the region (the parts of
        an object without a seed of their own, or under ``min_area`` by themselves). One
        region per object instead of specks beside it, its plain middle covered. Pieces the
        closing does not join are dropped as before. 0: off.
    led : ndarray, shape (rows, cols), optional
        With ``seeds``: each cell's share of its likelihood from one term (the anti-parallel
        deviation's, weighted; NaN counts 0). A region whose mean share is at least
        :data:`LED` is led by that term and needs ``led_seeds`` seed cells, not one.
    led_seeds : int
        Seeds a region led by that term needs (1: as any other).

    Returns
    -------
    mask : ndarray of bool, shape (rows, cols)
    regions : list of Region, largest first
    labels : ndarray of int32, shape (rows, cols)
        With ``with_labels``: each region's cells by its ``label`` (0 elsewhere).
    """
    values = np.nan_to_num(cell_likelihood, nan=0.0)
    if seed_threshold > threshold:  # hysteresis: regions need a cell above the seed threshold
        # 8-connected, as the regions are (scikit-image's hysteresis joins 4-connected cells
        # only, which split a region at a diagonal step).
        moving = grown_from(values > seed_threshold, values > threshold)
    else:
        moving = values > threshold
    if 0 < extend_threshold < threshold:
        # Only regions that count as detections by themselves seed an extension: a speck under
        # min_area must not grow past it through weak cells.
        kept, _, _ = _kept_regions(moving, values, grid, min_area, None, 1)
        moving = grown_from(kept, values > extend_threshold)
    candidates = moving if seeds is None else grown_from(seeds & moving, moving)
    if gap > 0:  # the pieces are all the cells above the threshold, seeded or not
        candidates = _joined(candidates, moving, values, grid, min_area, age, persistence, gap)
    if seeds is not None and led is not None and led_seeds > 1 and candidates.any():
        candidates = _seeded_enough(candidates, seeds, led, led_seeds)
    mask, regions, labels = _kept_regions(candidates, values, grid, min_area, age, persistence)
    return (mask, regions, labels) if with_labels else (mask, regions)


#: A term leads a region when its share of the region's likelihood is at least this, on
#: average over the region's cells (:mod:`fisheyemotion.ground_contact` too).
LED = 0.5


def led_regions(cells: NDArray[np.bool_], share: NDArray[np.float64]
                ) -> tuple[NDArray[np.int32], NDArray[np.bool_]]:
    """The 8-connected regions of ``cells`` and which of them one term leads.

    Parameters
    ----------
    cells : ndarray of bool, shape (rows, cols)
    share : ndarray, shape (rows, cols)
        Each cell's share of its likelihood from the term (NaN counts 0).

    Returns
    -------
    labels : ndarray of int32, shape (rows, cols)
        Regions ``1..n``, 0 elsewhere.
    led : ndarray of bool, shape (n + 1,)
        ``led[i]``: region ``i``'s mean share is at least :data:`LED` (``led[0]`` False).
    """
    n, labels = cv2.connectedComponents(cells.astype(np.uint8), connectivity=8,
                                        ltype=cv2.CV_32S)
    flat = labels.ravel()
    counts = np.bincount(flat, minlength=n)
    mean = np.bincount(flat, weights=np.nan_to_num(share).ravel(), minlength=n) / np.maximum(
        counts, 1)
    led = mean >= LED
    led[0] = False
    return labels, led


def _seeded_enough(candidates: NDArray[np.bool_], seeds: NDArray[np.bool_],
                   led: NDArray[np.float64], led_seeds: int) -> NDArray[np.bool_]:
    """``candidates`` without the regions (8-connected) that the term of ``led`` leads and
    that hold fewer than ``led_seeds`` seed cells."""
    labels, leads = led_regions(candidates, led)
    held = np.bincount(labels[seeds & candidates], minlength=len(leads))
    keep = held >= np.where(leads, led_seeds, 1)
    keep[0] = False
    return keep[labels]


def grown_from(seeds: NDArray[np.bool_], weak: NDArray[np.bool_]) -> NDArray[np.bool_]:
    """The 8-connected components of ``seeds | weak`` that hold a seed cell."""
    n, labels = cv2.connectedComponents((seeds | weak).astype(np.uint8), connectivity=8,
                                        ltype=cv2.CV_32S)
    holds = np.zeros(n, dtype=bool)
    holds[labels[seeds]] = True
    holds[0] = False
    return holds[labels]


def _joined(candidates: NDArray[np.bool_], moving: NDArray[np.bool_], values: NDArray[np.float64],
            grid: int, min_area: int, age: NDArray | None, persistence: int, gap: int
            ) -> NDArray[np.bool_]:
    """The regions of ``candidates`` that are kept, closed with the pieces of ``moving``
    near them (``segment_cells``' ``gap``): the components of the closing that hold a kept
    cell."""
    kept, _, _ = _kept_regions(candidates, values, grid, min_area, age, persistence)
    if not kept.any():
        return kept
    # A plus: the pieces of an object lie above, below or beside each other; a square also
    # filled the background at a region's corners (docs/evaluation.md).
    plus = cv2.getStructuringElement(cv2.MORPH_CROSS, (2 * gap + 1, 2 * gap + 1))
    near = cv2.dilate(moving.astype(np.uint8), plus) > 0  # pieces that may join
    taken = grown_from(kept, near) & moving
    closed = cv2.morphologyEx(taken.astype(np.uint8), cv2.MORPH_CLOSE, plus) > 0
    return grown_from(kept & closed, closed)


def _kept_regions(moving: NDArray[np.bool_], values: NDArray[np.float64], grid: int,
                  min_area: int, age: NDArray | None, persistence: int
                  ) -> tuple[NDArray[np.bool_], list[Region], NDArray[np.int32]]:
    """The regions of ``moving`` of at least ``min_area`` pixels (and ``persistence``)."""
    # OpenCV's labelling gives each region's bounding box and size in the same pass, and keeps
    # scipy (0.17 s to import, through scikit-image's label) off a process's first detection.
    n, labels, stats, centroids = cv2.connectedComponentsWithStats(
        moving.astype(np.uint8), connectivity=8, ltype=cv2.CV_32S)
    n -= 1  # label 0 is the background
    if n == 0:
        return np.zeros_like(moving), [], labels
    # Region properties for all labels at once (regionprops' per-region objects cost ~80 us each).
    flat = labels.ravel()
    cells = stats[1:, cv2.CC_STAT_AREA].astype(np.int64)
    mean = np.bincount(flat, weights=values.ravel(), minlength=n + 1)[1:] / cells
    cx, cy = centroids[1:, 0], centroids[1:, 1]
    kept = cells * grid * grid >= min_area
    if age is not None and persistence > 1:
        oldest = np.zeros(n + 1, dtype=np.int64)
        np.maximum.at(oldest, flat, np.asarray(age, dtype=np.int64).ravel())
        kept &= oldest[1:] >= persistence
    regions = []
    for i in np.flatnonzero(kept):
        c0, r0, w, h = (int(v) for v in stats[i + 1, :4])
        regions.append(Region(
            label=0,
            bbox=(c0 * grid, r0 * grid, w * grid, h * grid),
            area=int(cells[i]) * grid * grid,
            mean_likelihood=float(mean[i]),
            centroid=(float(cx[i]) * grid + (grid - 1) / 2, float(cy[i]) * grid + (grid - 1) / 2),
        ))
    order = sorted(range(len(regions)), key=lambda j: -regions[j].area)
    relabel = np.zeros(n + 1, np.int32)
    relabel[np.flatnonzero(kept)[order] + 1] = np.arange(1, len(order) + 1)
    keep = np.concatenate([[False], kept])[labels]
    return keep, [regions[j]._replace(label=i + 1) for i, j in enumerate(order)], relabel[labels]
