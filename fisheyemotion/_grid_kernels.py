"""numba kernels over the detection grid's cells, where a profile showed numpy's passes over
whole images cost: :func:`transfer` (``fisheyemotion.flow.grid_transfer``; 1.4 ms in numpy, 0.05
ms here) and :func:`cell_variance` (``fisheyemotion.significance.cell_sigma``; 0.6 ms in numpy
and OpenCV, 0.1 ms here)."""

from __future__ import annotations

import numba
import numpy as np

# The four lines through a cell, as pairs of opposite directions (row step, column step).
_LINES = ((0, -1, 0, 1), (-1, 0, 1, 0), (-1, -1, 1, 1), (-1, 1, 1, -1))


@numba.njit(cache=True, nogil=True)
def _first_landed(landed, r, c, dr, dc, reach):
    rows, cols = landed.shape
    for d in range(1, reach + 1):
        rr, cc = r + d * dr, c + d * dc
        if rr < 0 or rr >= rows or cc < 0 or cc >= cols:
            return -1
        if landed[rr, cc] >= 0:
            return landed[rr, cc]
    return -1


@numba.njit(cache=True, nogil=True)
def transfer(col, row, rank, fill_rank, reach, landed, out):
    """``col``, ``row`` (rows, cols): the cell each cell lands in (NaN or outside: nowhere);
    ``rank``, ``fill_rank`` (rows * cols,): the landing priority (largest wins, ties to the later
    cell) and the gap-filling priority (smallest wins). Fills ``out`` (rows, cols) with the flat
    source index per cell, -1 where none (see ``grid_transfer``); ``landed`` (rows, cols) is
    scratch, -1 on entry. (Arrays are allocated by the caller: numba's ``np.full`` and ``copy``
    took a third of this kernel's first compilation.)"""
    rows, cols = col.shape
    for r in range(rows):
        for c in range(cols):
            tc, tr = col[r, c], row[r, c]
            if not (tc >= 0 and tc < cols and tr >= 0 and tr < rows):  # NaN fails too
                continue
            i = r * cols + c
            dr, dc = int(tr), int(tc)
            j = landed[dr, dc]
            if j < 0 or rank[i] >= rank[j]:
                landed[dr, dc] = i
    for r in range(rows):
        for c in range(cols):
            out[r, c] = landed[r, c]
            if landed[r, c] >= 0:
                continue
            best, best_rank = -1, np.inf
            for k in range(4):
                ar, ac, br, bc = _LINES[k]
                pa = _first_landed(landed, r, c, ar, ac, reach)
                if pa < 0:
                    continue
                pb = _first_landed(landed, r, c, br, bc, reach)
                if pb < 0:
                    continue
                for cand in (pa, pb):
                    if fill_rank[cand] < best_rank or best < 0:
                        best, best_rank = cand, fill_rank[cand]
            out[r, c] = best


@numba.njit(cache=True, nogil=True)
def cell_variance(flow, grid, mean, out):
    """Mean squared deviation of each ``grid x grid`` cell's flow vectors from the cell's mean
    ``mean`` (rows, cols, 2), summed over u and v, into ``out`` (rows, cols); ``flow`` (H, W,
    2)."""
    rows, cols = mean.shape[0], mean.shape[1]
    inv = 1.0 / (grid * grid)
    for r in range(rows):
        for c in range(cols):
            mu, mv = mean[r, c, 0], mean[r, c, 1]
            acc = 0.0
            for y in range(r * grid, (r + 1) * grid):
                for x in range(c * grid, (c + 1) * grid):
                    du = flow[y, x, 0] - mu
                    dv = flow[y, x, 1] - mv
                    acc += du * du + dv * dv
            out[r, c] = acc * inv
