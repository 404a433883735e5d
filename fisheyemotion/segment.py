"""Threshold + connected components on the grid of cell likelihoods (scikit-image labelling;
region properties for all labels at once with numpy and ``scipy.ndimage``)."""

from __future__ import annotations

from typing import NamedTuple

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
    from scipy import ndimage  # scikit-image/scipy on first use: `import fisheyemotion` stays light
    from skimage.filters import apply_hysteresis_threshold
    from skimage.measure import label
    values = np.nan_to_num(cell_likelihood, nan=0.0)
    if seed_threshold > threshold:  # hysteresis: regions need a cell above the seed threshold
        moving = apply_hysteresis_threshold(values, threshold, seed_threshold)
    else:
        moving = values > threshold
    labels, n = label(moving, connectivity=2, return_num=True)
    if n == 0:
        return np.zeros_like(moving), []
    # Region properties for all labels at once (regionprops' per-region objects cost ~80 us each).
    flat = labels.ravel()
    cells = np.bincount(flat, minlength=n + 1)[1:]
    rows, cols = np.indices(labels.shape)
    mean = np.bincount(flat, weights=values.ravel(), minlength=n + 1)[1:] / cells
    cy = np.bincount(flat, weights=rows.ravel(), minlength=n + 1)[1:] / cells
    cx = np.bincount(flat, weights=cols.ravel(), minlength=n + 1)[1:] / cells
    kept = cells * grid * grid >= min_area
    if age is not None and persistence > 1:
        oldest = np.zeros(n + 1, dtype=np.int64)
        np.maximum.at(oldest, flat, np.asarray(age, dtype=np.int64).ravel())
        kept &= oldest[1:] >= persistence
    regions = []
    for i, box in enumerate(ndimage.find_objects(labels)):
        if not kept[i]:
            continue
        r0, r1, c0, c1 = box[0].start, box[0].stop, box[1].start, box[1].stop
        regions.append(Region(
            label=0,
            bbox=(c0 * grid, r0 * grid, (c1 - c0) * grid, (r1 - r0) * grid),
            area=int(cells[i]) * grid * grid,
            mean_likelihood=float(mean[i]),
            centroid=(float(cx[i]) * grid + (grid - 1) / 2, float(cy[i]) * grid + (grid - 1) / 2),
        ))
    regions.sort(key=lambda r: -r.area)
    keep = np.concatenate([[False], kept])[labels]
    return keep, [r._replace(label=i + 1) for i, r in enumerate(regions)]
