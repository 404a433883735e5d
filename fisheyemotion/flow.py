"""Dense optical flow (OpenCV) and its average on a square grid, as the paper feeds the engine."""

from __future__ import annotations

import functools

import cv2
import numpy as np
from numpy.typing import NDArray

from . import _warmup
from .params import Params

_DIS_PRESETS = {"ultrafast": cv2.DISOPTICAL_FLOW_PRESET_ULTRAFAST,
                "fast": cv2.DISOPTICAL_FLOW_PRESET_FAST,
                "medium": cv2.DISOPTICAL_FLOW_PRESET_MEDIUM}


def warp_by(image: NDArray, flow: NDArray[np.float32]) -> NDArray:
    """``image`` sampled at ``u + flow(u)`` for every pixel ``u`` (bilinear, edges replicated):
    the image a flow ``(H, W, 2)`` points into, warped back onto the flow's pixels.
    (``cv2.WARP_RELATIVE_MAP``, OpenCV 4.10: the flow is the map, no pixel grid added to it;
    the same bits as ``cv2.remap`` of the absolute map.)"""
    return cv2.remap(image, np.ascontiguousarray(flow, dtype=np.float32), None,
                     cv2.INTER_LINEAR | cv2.WARP_RELATIVE_MAP, borderMode=cv2.BORDER_REPLICATE)


class FlowEstimator:
    """Dense flow from ``prev`` to ``curr``: ``prev(y, x) ~ curr(y + f_y, x + f_x)``.

    Holds the OpenCV object (DIS) between calls, as ``cv2`` apps do.
    """

    def __init__(self, params: Params) -> None:
        self.params = params
        self._dis = (cv2.DISOpticalFlow_create(_DIS_PRESETS[params.dis_preset])
                     if params.flow == "dis" else None)

    def __call__(self, prev: NDArray[np.uint8], curr: NDArray[np.uint8],
                 initial: NDArray[np.float32] | None = None) -> NDArray[np.float32]:
        """Flow ``(H, W, 2)`` float32; ``initial`` is an optional starting estimate."""
        if self._dis is not None:
            # DIS uses the flow argument as its initial estimate when one is given.
            flow = None if initial is None else initial.astype(np.float32, copy=True)
            return self._dis.calc(prev, curr, flow)
        fb = self.params.farneback
        flags = 0
        flow = None
        if initial is not None:
            flow = initial.astype(np.float32, copy=True)
            flags = cv2.OPTFLOW_USE_INITIAL_FLOW
        return cv2.calcOpticalFlowFarneback(
            prev, curr, flow, fb["pyr_scale"], int(fb["levels"]), int(fb["winsize"]),
            int(fb["iterations"]), int(fb["poly_n"]), fb["poly_sigma"], flags)


@functools.lru_cache(maxsize=4)
def pixel_grid(height: int, width: int) -> tuple[NDArray[np.float32], NDArray[np.float32]]:
    """Every pixel's x and y coordinate, float32 ``(height, width)`` each, read-only: made once
    per image size, and cut into the maps of the boxes that are warped."""
    xs, ys = np.meshgrid(np.arange(width, dtype=np.float32), np.arange(height, dtype=np.float32))
    xs.flags.writeable = ys.flags.writeable = False
    return xs, ys


def grid_shape(width: int, height: int, grid: int) -> tuple[int, int]:
    """``(rows, cols)`` of whole ``grid x grid`` cells covering the image from its top-left."""
    return height // grid, width // grid


def grid_centres(width: int, height: int, grid: int) -> NDArray[np.float64]:
    """Pixel coordinates ``(rows, cols, 2)`` of the cell centres (OpenCV pixel convention)."""
    rows, cols = grid_shape(width, height, grid)
    u = np.arange(cols) * grid + (grid - 1) / 2
    v = np.arange(rows) * grid + (grid - 1) / 2
    uu, vv = np.meshgrid(u, v)
    return np.stack([uu, vv], axis=-1)


def grid_average(image: NDArray, grid: int) -> NDArray:
    """Mean of each ``grid x grid`` cell: ``(H, W, ...)`` -> ``(H // grid, W // grid, ...)``.

    Pixels beyond the last whole cell (right and bottom remainders) are not averaged.
    """
    rows, cols = image.shape[0] // grid, image.shape[1] // grid
    crop = image[: rows * grid, : cols * grid]
    if crop.dtype.kind == "f" and (crop.ndim == 2 or crop.shape[2] <= 4):
        # An area resize by a whole factor is the block mean (20x faster than numpy here).
        return cv2.resize(np.ascontiguousarray(crop), (cols, rows), interpolation=cv2.INTER_AREA)
    blocks = crop.reshape(rows, grid, cols, grid, *image.shape[2:])
    return blocks.mean(axis=(1, 3), dtype=np.float64)


def grid_upsample(cells: NDArray, grid: int, width: int, height: int) -> NDArray:
    """Cell values back to ``(H, W, ...)``: each pixel takes its cell's value; remainder rows and
    columns beyond the last whole cell take the last cell's, and cells reaching beyond the
    image are cropped (a view then)."""
    # Columns first, then whole rows: 3x faster than cv2's nearest resize at 640x480, the
    # rows' repeat being plain copies; the same values.
    full = np.repeat(cells, grid, axis=1).repeat(grid, axis=0)[:height, :width]
    bottom, right = height - full.shape[0], width - full.shape[1]
    if not (bottom or right):
        return full
    if cells.dtype in (np.float32, np.uint8) and (cells.ndim == 2 or cells.shape[2] <= 4):
        return cv2.copyMakeBorder(full, 0, bottom, 0, right, cv2.BORDER_REPLICATE)
    pad = [(0, bottom), (0, right)] + [(0, 0)] * (cells.ndim - 2)
    return np.pad(full, pad, mode="edge")


def grid_transfer(cell_flow: NDArray, order: NDArray, grid: int, *,
                  reach: int = 3) -> NDArray[np.intp]:
    """Which cell of the first frame lands on each cell of the second, by the cells' flow.

    Every cell ``(r, c)`` of the first frame is moved by its flow ``cell_flow[r, c]``; the cell
    of the second frame its centre lands in takes it. Where several land on one cell, the one
    with the largest ``order`` wins. A cell on which none lands between two cells that have
    sources, within ``reach`` cells on a line through it (a gap where a region expands), takes
    the one with the smallest ``order``; other cells on which none lands (background uncovered
    behind a moving region) have no source.

    Parameters
    ----------
    cell_flow : ndarray, shape (rows, cols, 2)
        NaN where a cell has no flow.
    order : ndarray, shape (rows, cols)
        Priority (e.g. the likelihood); NaN ranks lowest.
    grid : int

    Returns
    -------
    ndarray of intp, shape (rows, cols)
        Flat index of the source cell, -1 where none.
    """
    from ._grid_kernels import transfer  # numba on first use: a light import

    _warmup.wait()

    rows, cols = order.shape
    offset = (grid - 1) / 2  # the cell centres, broadcast (grid_centres without its meshgrid)
    with np.errstate(invalid="ignore"):
        col = np.floor(((np.arange(cols) * grid + offset) + cell_flow[..., 0]) / grid)
        row = np.floor(((np.arange(rows) * grid + offset)[:, None] + cell_flow[..., 1]) / grid)
    out = np.empty((rows, cols), np.intp)
    transfer(np.ascontiguousarray(col, np.float64), np.ascontiguousarray(row, np.float64),
             np.ascontiguousarray(order, np.float64).ravel(), int(reach),
             np.full((rows, cols), -1, np.intp), out)
    return out


def pixel_transfer(source: NDArray[np.intp], flow: NDArray[np.float32], order: NDArray,
                   cells: NDArray[np.bool_], grid: int, *, share: float) -> NDArray[np.intp]:
    """A :func:`grid_transfer` map refined by the pixels of some cells, each moved by its own flow.

    :func:`grid_transfer` moves a cell by one flow (its centre's landing cell takes it), so an
    object two or three cells wide that moves across its background lands partly beside itself
    (its cells' flow is mixed with the background's, and a cell is all or nothing). Here every
    pixel of ``cells`` moves by its own flow; a cell of the second frame that those pixels cover
    by at least ``share`` of its area takes, among the cells whose pixels land on it, the one
    with the largest ``order``, where that is larger than its source's.

    Parameters
    ----------
    source : ndarray of intp, shape (rows, cols)
        A :func:`grid_transfer` map (flat source index, -1 where none).
    flow : ndarray, shape (H, W, 2)
        The dense flow (pixels of whole cells are read; NaN: the pixel does not move anywhere).
    order : ndarray, shape (rows, cols)
        Priority (e.g. the likelihood); NaN ranks lowest.
    cells : ndarray of bool, shape (rows, cols)
        The cells whose pixels move (e.g. those above the detection threshold).
    grid : int
        Cell size, pixels.
    share : float
        Share of a cell's pixels (0-1] that must land on it.

    Returns
    -------
    ndarray of intp, shape (rows, cols)
    """
    rows, cols = source.shape
    if not cells.any():
        return source
    from ._grid_kernels import landed_pixels  # numba on first use: a light import

    rank = np.where(np.isnan(order), -np.inf, order).ravel()
    r, c = np.nonzero(cells)
    # The most likely cell landing on each target: the moved cells numbered by rank (ties by
    # index), each pixel carrying its cell's number, the largest number per target.
    flat = r * cols + c
    ranked = np.lexsort((flat, rank[flat]))  # the moved cells, least likely first
    number = np.empty(len(flat), np.intp)
    number[ranked] = np.arange(len(flat))
    count = np.zeros(rows * cols, np.intp)
    top = np.full(rows * cols, -1, np.intp)
    # Pixel centres are integers: pixel q lies in cell floor((q + 0.5) / grid).
    landed_pixels(np.ascontiguousarray(flow, np.result_type(flow.dtype, np.float32)), r, c,
                  number, int(grid), rows, cols, count, top)
    if not (top >= 0).any():
        return source
    best = np.where(top >= 0, flat[ranked][np.maximum(top, 0)], -1)
    out = source.ravel().copy()
    current = np.where(out >= 0, rank[np.maximum(out, 0)], -np.inf)
    take = (count >= share * grid * grid) & (best >= 0)
    take[take] = rank[best[take]] > current[take]
    out[take] = best[take]
    return out.reshape(rows, cols)


def grid_gather(cells: NDArray, source: NDArray[np.intp], fill=np.nan) -> NDArray:
    """``cells`` (rows, cols, ...) rearranged by a :func:`grid_transfer` map; ``fill`` (of the
    cells' dtype) where there is no source."""
    rows, cols = source.shape
    out = cells.reshape(rows * cols, *cells.shape[2:])[np.maximum(source, 0)]
    out[source < 0] = fill
    return out
