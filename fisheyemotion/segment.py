"""Threshold + connected components on the grid of cell likelihoods (scikit-image)."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray
from skimage.filters import apply_hysteresis_threshold
from skimage.measure import label, regionprops


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


def segment_cells(cell_likelihood: NDArray[np.float64], *, threshold: float, grid: int,
                  min_area: int, age: NDArray | None = None, persistence: int = 1,
                  seed_threshold: float = 0.0) -> tuple[NDArray[np.bool_], list[Region]]:
    """Cells above ``threshold`` grouped 8-connected; regions under ``min_area`` pixels dropped,
    and, with ``age``, regions none of whose cells has been moving ``persistence`` times.

    Parameters
    ----------
    cell_likelihood : ndarray, shape (rows, cols)
        NaN for invalid cells (never moving).
    age : ndarray of int, shape (rows, cols), optional
        Consecutive detections each cell has been moving in (streams).

    Returns
    -------
    mask : ndarray of bool, shape (rows, cols)
    regions : list of Region, largest first
    """
    values = np.nan_to_num(cell_likelihood, nan=0.0)
    if seed_threshold > threshold:  # hysteresis: regions need a cell above the seed threshold
        moving = apply_hysteresis_threshold(values, threshold, seed_threshold)
    else:
        moving = values > threshold
    labels = label(moving, connectivity=2)
    keep = np.zeros_like(moving)
    regions = []
    for prop in regionprops(labels, intensity_image=np.nan_to_num(cell_likelihood, nan=0.0)):
        area = int(prop.area) * grid * grid
        if area < min_area:
            continue
        if age is not None and persistence > 1 and age[labels == prop.label].max() < persistence:
            continue
        keep[labels == prop.label] = True
        r0, c0, r1, c1 = prop.bbox
        cy, cx = prop.centroid
        regions.append(Region(
            label=len(regions) + 1,
            bbox=(c0 * grid, r0 * grid, (c1 - c0) * grid, (r1 - r0) * grid),
            area=area,
            mean_likelihood=float(prop.intensity_mean),
            centroid=(cx * grid + (grid - 1) / 2, cy * grid + (grid - 1) / 2),
        ))
    regions.sort(key=lambda r: -r.area)
    return keep, [r._replace(label=i + 1) for i, r in enumerate(regions)]
