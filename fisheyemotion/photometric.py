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

Two kinds of motion the check cannot see: an object moving along its epipolar line (oncoming,
preceding) seen as static is a consistent static scene at another depth, which the static-scene
model may hold (the anti-parallel ambiguity, :mod:`fisheyemotion.ground_contact`), and plain,
slowly moving parts of an object. The detector therefore judges regions, not cells: a region
is reported only if at least one of its cells is *not* explained (``segment_cells(seeds=...)``);
cells are not removed from a region that has one. Only cells above the threshold are tested.
"""

from __future__ import annotations

import cv2
import numpy as np
from numpy.typing import NDArray

from .flow import grid_average, warp_by

__all__ = ["cell_residual", "static_explained"]

_ROWS = 32000  # cells per remap call


def cell_residual(prev: NDArray[np.uint8], curr: NDArray[np.uint8], flow: NDArray[np.float32],
                  grid: int, cells: NDArray[np.bool_] | None = None) -> NDArray[np.float32]:
    """Mean absolute grey-level difference ``|prev(u) - curr(u + flow(u))|`` of each cell
    (bilinear sampling, edges replicated, as :func:`fisheyemotion.flow.warp_by`).

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
        difference = cv2.absdiff(prev, warp_by(curr, flow))
        return grid_average(difference.astype(np.float32), grid)
    return _cell_residuals(prev, curr, (flow,), grid, cells)[0]


def _blocks(image: NDArray, grid: int, r: NDArray[np.intp], c: NDArray[np.intp]) -> NDArray:
    """The ``grid x grid`` pixels of cells ``(r, c)``: shape ``(n, grid, grid, ...)``."""
    rows, cols = image.shape[0] // grid, image.shape[1] // grid
    view = image[: rows * grid, : cols * grid].reshape(rows, grid, cols, grid, *image.shape[2:])
    return view.swapaxes(1, 2)[r, c]


def _cell_residuals(prev, curr, flows, grid, cells) -> list[NDArray[np.float32]]:
    """:func:`cell_residual` of ``cells`` for each of ``flows``, sharing the gathering and one
    remap of all of them."""
    outs = [np.full(cells.shape, np.nan, np.float32) for _ in flows]
    r, c = np.nonzero(cells)
    n = len(r)
    if n == 0:
        return outs
    d = np.arange(grid, dtype=np.float32)
    # Pixel coordinates in float32, as warp_by's identity map: the same samples as it takes.
    u = (c * grid).astype(np.float32)[:, None, None] + d[None, None, :]
    v = (r * grid).astype(np.float32)[:, None, None] + d[None, :, None]
    maps = np.concatenate([np.stack([u + f[..., 0], v + f[..., 1]], axis=-1)
                           for f in (_blocks(flow, grid, r, c) for flow in flows)])
    # One row of the map per cell (OpenCV's maps are under 32767 on a side).
    maps = maps.reshape(len(flows) * n, grid * grid, 2)
    sampled = np.concatenate([
        cv2.remap(curr, maps[i:i + _ROWS], None, cv2.INTER_LINEAR,
                  borderMode=cv2.BORDER_REPLICATE)
        for i in range(0, len(maps), _ROWS)])
    before = np.tile(_blocks(prev, grid, r, c).reshape(n, grid * grid), (len(flows), 1))
    means = cv2.absdiff(before, sampled).astype(np.float32).mean(axis=1)
    for k, out in enumerate(outs):
        out[r, c] = means[k * n:(k + 1) * n]
    return outs


def static_explained(prev: NDArray[np.uint8], curr: NDArray[np.uint8],
                     flow: NDArray[np.float32], static_flow: NDArray[np.float32], grid: int,
                     margin: float, cells: NDArray[np.bool_] | None = None) -> NDArray[np.bool_]:
    """Cells ``(H // grid, W // grid)`` where the static scene's flow explains the frames within
    ``margin`` grey levels of the measured flow: ``r_s <= r_f + margin`` (module doc); with
    ``cells``, only those are tested (False elsewhere)."""
    if cells is None:
        measured = cell_residual(prev, curr, flow, grid)
        static = cell_residual(prev, curr, static_flow, grid)
    else:
        measured, static = _cell_residuals(prev, curr, (flow, static_flow), grid, cells)
    with np.errstate(invalid="ignore"):
        return static <= measured + margin
