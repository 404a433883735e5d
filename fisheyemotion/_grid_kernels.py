"""numba kernels over the detection grid's cells, where a profile showed numpy's passes over
whole images cost: :func:`transfer` (``fisheyemotion.flow.grid_transfer``; 1.4 ms in numpy, 0.05
ms here), :func:`cell_variance` (``fisheyemotion.significance.cell_sigma``; 0.6 ms in numpy
and OpenCV, 0.1 ms here), :func:`block_residuals` (``fisheyemotion.photometric``: the
gathering, maps and ``cv2.remap`` of the tested cells' blocks cost 0.2 ms a flow in numpy),
:func:`landed_pixels` (``fisheyemotion.flow.pixel_transfer``; 0.88 -> 0.45 ms a frame for the
whole function), :func:`nearest_landed` (``RangeMemory.remember``'s z-buffer; the three views
1.45 -> 0.8 ms) and :func:`grown_labels` (``fisheyemotion.grow.grow_regions``; 1.28 -> 0.68 ms
for the detector's growth step). Each does numpy's arithmetic in numpy's order, so that the
results are the same to the bit (the stream benchmark's masks hash the same).
"""

from __future__ import annotations

import numba
import numpy as np

# The four lines through a cell, as pairs of opposite directions (row step, column step).
_LINES = ((0, -1, 0, 1), (-1, 0, 1, 0), (-1, -1, 1, 1), (-1, 1, 1, -1))


@numba.njit(cache=True, nogil=True)
def _rank(value, nan_rank):
    return nan_rank if value != value else value


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
def transfer(col, row, order, reach, landed, out):
    """``col``, ``row`` (rows, cols): the cell each cell lands in (NaN or outside: nowhere);
    ``order`` (rows * cols,): the landing priority (largest wins, ties to the later cell; NaN
    lowest) and the gap-filling priority (smallest wins; NaN last). Fills ``out`` (rows, cols)
    with the flat source index per cell, -1 where none (see ``grid_transfer``); ``landed``
    (rows, cols) is scratch, -1 on entry. (Arrays are allocated by the caller: numba's
    ``np.full`` and ``copy`` took a third of this kernel's first compilation.)"""
    rows, cols = col.shape
    for r in range(rows):
        for c in range(cols):
            tc, tr = col[r, c], row[r, c]
            if not (tc >= 0 and tc < cols and tr >= 0 and tr < rows):  # NaN fails too
                continue
            i = r * cols + c
            dr, dc = int(tr), int(tc)
            j = landed[dr, dc]
            if j < 0 or _rank(order[i], -np.inf) >= _rank(order[j], -np.inf):
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
                    rank = _rank(order[cand], np.inf)
                    if rank < best_rank or best < 0:
                        best, best_rank = cand, rank
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


@numba.njit(cache=True, nogil=True)
def sample_medians(cell, rng, start, pos, buf, med, out):
    """The median ``rng`` of the points in each sample, holes filled from their neighbours.

    ``cell`` (N,): each point's flat sample index, -1 where outside; ``rng`` (N,): its value;
    ``out`` (rows, cols): per sample the upper median of its points' values (``rng[count // 2]``
    of the sorted values); a sample with no point but a neighbour (of the eight) that has one,
    the smallest neighbouring median; NaN where neither. Scratch, allocated by the caller:
    ``start`` (rows * cols + 1,) zeros, ``pos`` (rows * cols,), ``buf`` (N,), ``med`` (rows *
    cols,)."""
    rows, cols = out.shape
    n = rows * cols
    for i in range(cell.shape[0]):
        if cell[i] >= 0:
            start[cell[i] + 1] += 1
    for k in range(n):
        start[k + 1] += start[k]
        pos[k] = start[k]
    for i in range(cell.shape[0]):
        k = cell[i]
        if k >= 0:
            buf[pos[k]] = rng[i]
            pos[k] += 1
    for k in range(n):
        lo, hi = start[k], start[k + 1]
        if lo == hi:
            med[k] = np.inf
            continue
        for j in range(lo + 1, hi):  # insertion sort: a handful of points per sample
            v = buf[j]
            m = j - 1
            while m >= lo and buf[m] > v:
                buf[m + 1] = buf[m]
                m -= 1
            buf[m + 1] = v
        med[k] = buf[lo + (hi - lo) // 2]
    for r in range(rows):
        for c in range(cols):
            v = med[r * cols + c]
            if not v < np.inf:
                for rr in range(max(r - 1, 0), min(r + 2, rows)):
                    for cc in range(max(c - 1, 0), min(c + 2, cols)):
                        v = min(v, med[rr * cols + cc])
            out[r, c] = v if v < np.inf else np.nan


_F32_MAX = float(np.finfo(np.float32).max)


@numba.njit(cache=True, nogil=True)
def accumulate(source, likelihood, carrier, acc_before, age_before, decay, threshold, gap,
               grid, acc, age):
    """The temporal filter's step (``MotionDetector._temporal_filter``) in one pass.

    For each cell ``(r, c)`` of the current detection: its carrier flow is the source cell's
    (``carrier[source]``, 0 where none or NaN, as ``np.nan_to_num``); the previous detection's
    cell it came from is the one nearest to ``centre - flow / gap`` (clipped to the grid); then
    ``acc = (1 - decay) * likelihood + decay * acc_before[there]`` (``likelihood`` NaN counts 0)
    and ``age = age_before[there] + 1`` where ``acc > threshold``, else 0. ``source`` (rows,
    cols): flat source index or -1; ``carrier`` (rows, cols, 2) float32; ``acc`` (rows, cols)
    and ``age`` (rows, cols) are filled. The arithmetic is numpy's, operation for operation
    (float32 division of the flow by the gap), so the result is the same to the bit."""
    rows, cols = source.shape
    off = (grid - 1) / 2
    g32 = np.float32(gap)
    for r in range(rows):
        for c in range(cols):
            j = source[r, c]
            mx = np.float32(0.0)
            my = np.float32(0.0)
            if j >= 0:
                mx = carrier[j // cols, j % cols, 0]
                my = carrier[j // cols, j % cols, 1]
                mx = np.float32(0.0) if mx != mx else np.float32(min(max(mx, -_F32_MAX), _F32_MAX))
                my = np.float32(0.0) if my != my else np.float32(min(max(my, -_F32_MAX), _F32_MAX))
            bx = (c * grid + off) - mx / g32
            by = (r * grid + off) - my / g32
            cc = int(min(max(np.rint((bx - off) / grid), 0.0), cols - 1.0))
            rr = int(min(max(np.rint((by - off) / grid), 0.0), rows - 1.0))
            now = likelihood[r, c]
            if now != now:
                now = 0.0
            a = (1 - decay) * now + decay * acc_before[rr, cc]
            acc[r, c] = a
            age[r, c] = age_before[rr, cc] + 1 if a > threshold else 0


@numba.njit(cache=True, nogil=True)
def block_residuals(prev, curr, flow, rows, cols, grid, shift, out):
    """Fill ``out`` (n,) with the mean ``|prev(u) - curr(u + flow(u) + shift_i)|`` over the
    ``grid x grid`` pixels of cells ``(rows[i], cols[i])``: ``curr`` sampled bilinearly, edges
    replicated (as ``cv2.remap`` with ``BORDER_REPLICATE``, in exact rather than 1/32-pixel
    weights). NaN for a cell with a non-finite sample position."""
    h, w = curr.shape
    inv = 1.0 / (grid * grid)
    for i in range(rows.shape[0]):
        total = 0.0
        sx, sy = shift[i, 0], shift[i, 1]
        for y in range(rows[i] * grid, rows[i] * grid + grid):
            for x in range(cols[i] * grid, cols[i] * grid + grid):
                px = x + flow[y, x, 0] + sx
                py = y + flow[y, x, 1] + sy
                if not (np.isfinite(px) and np.isfinite(py)):
                    total = np.nan
                    break
                # Beyond the edge every position samples the edge pixel: clamp before the floor.
                px = min(max(px, -1.0), np.float64(w))
                py = min(max(py, -1.0), np.float64(h))
                x0, y0 = np.floor(px), np.floor(py)
                fx, fy = px - x0, py - y0
                xa = min(max(int(x0), 0), w - 1)
                xb = min(max(int(x0) + 1, 0), w - 1)
                ya = min(max(int(y0), 0), h - 1)
                yb = min(max(int(y0) + 1, 0), h - 1)
                top = curr[ya, xa] + fx * (np.float64(curr[ya, xb]) - curr[ya, xa])
                bottom = curr[yb, xa] + fx * (np.float64(curr[yb, xb]) - curr[yb, xa])
                total += abs(prev[y, x] - (top + fy * (bottom - top)))
        out[i] = total * inv


@numba.njit(cache=True, nogil=True)
def landed_pixels(flow, rows, cols, number, grid, n_rows, n_cols, count, top):
    """For :func:`fisheyemotion.flow.pixel_transfer`: every pixel of cells ``(rows[i], cols[i])``
    moved by its own ``flow`` (float32, (H, W, 2)) lands in the cell
    ``floor((x + flow + 0.5) / grid)``; ``count`` (n_rows * n_cols,) counts the pixels landing on
    each cell and ``top`` (the same, -1 to start) keeps the largest ``number[i]`` among them.
    Pixels whose target is not finite or not on the grid land nowhere. The arithmetic is numpy's
    (float64 sums of the integer pixel and the float32 flow), so the cells are the same."""
    for i in range(rows.shape[0]):
        for dy in range(grid):
            y = rows[i] * grid + dy
            for dx in range(grid):
                x = cols[i] * grid + dx
                tc = np.floor((x + np.float64(flow[y, x, 0]) + 0.5) / grid)
                tr = np.floor((y + np.float64(flow[y, x, 1]) + 0.5) / grid)
                if not (tc >= 0 and tc < n_cols and tr >= 0 and tr < n_rows):
                    continue
                t = int(tr) * n_cols + int(tc)
                count[t] += 1
                if number[i] > top[t]:
                    top[t] = number[i]


@numba.njit(cache=True, nogil=True)
def nearest_landed(points, error, landing, static, grid, centre, kept_points, kept_error):
    """For :meth:`fisheyemotion.range_consistency.RangeMemory.remember`: a z-buffer. Each
    ``static`` cell (rows, cols) with finite ``error`` and world point ``points`` (rows, cols,
    3) lands in the cell ``floor(landing / grid)`` of ``landing`` (rows, cols, 2; pixels) if
    that is on the grid; each cell of ``kept_points`` / ``kept_error`` (NaN to start) keeps the
    point nearest ``centre`` (3,) among those landing on it (of equal ones the last in
    row-major order, as the stable sort the numpy version wrote by)."""
    rows, cols = static.shape
    best = np.full((rows, cols), np.inf)
    for r in range(rows):
        for c in range(cols):
            if not static[r, c]:
                continue
            tc = np.floor(landing[r, c, 0] / grid)
            tr = np.floor(landing[r, c, 1] / grid)
            if not (tc >= 0 and tc < cols and tr >= 0 and tr < rows):
                continue
            e = error[r, c]
            x, y, z = points[r, c, 0], points[r, c, 1], points[r, c, 2]
            if not (np.isfinite(e) and np.isfinite(x) and np.isfinite(y) and np.isfinite(z)):
                continue
            dx, dy, dz = x - centre[0], y - centre[1], z - centre[2]
            d = np.sqrt(dx * dx + (dy * dy + dz * dz))  # numpy's norm's order of sums
            i, j = int(tr), int(tc)
            if d <= best[i, j]:
                best[i, j] = d
                kept_points[i, j, 0] = x
                kept_points[i, j, 1] = y
                kept_points[i, j, 2] = z
                kept_error[i, j] = e


@numba.njit(cache=True, nogil=True)
def grown_labels(components, n, residual, valid, steps, tolerance, relative, out):
    """For :func:`fisheyemotion.grow.grow_regions`: ``components`` (rows, cols; OpenCV's labels
    ``1..n``, 0 elsewhere) renumbered in the raster order of each region's first cell, then grown
    ``steps`` rings into ``valid`` cells whose ``residual`` (rows, cols, 2; NaN: unknown) is like
    the region's mean (over its cells with a known residual, divided by all its cells); a cell
    two regions reach takes the larger number. ``out`` (rows, cols) gets the grown labels. The
    arithmetic is numpy's (the sums in raster order, the norms' order of sums, ``nan_to_num``'s
    infinities), so the cells are the same as the numpy version's."""
    rows, cols = components.shape
    big = np.finfo(np.float64).max
    order = np.zeros(n + 1, np.int64)
    k = 0
    for r in range(rows):
        for c in range(cols):
            lab = components[r, c]
            if lab > 0 and order[lab] == 0:
                k += 1
                order[lab] = k
    res = np.empty((rows, cols, 2))
    known = np.empty((rows, cols), np.bool_)
    count = np.zeros(n + 1, np.int64)
    sums = np.zeros((n + 1, 2))
    for r in range(rows):
        for c in range(cols):
            lab = order[components[r, c]]
            out[r, c] = lab
            count[lab] += 1
            for i in range(2):
                v = residual[r, c, i]
                res[r, c, i] = np.inf if v != v else (big if v == np.inf else (-big if v == -np.inf else v))
            known[r, c] = np.isfinite(res[r, c, 0]) and np.isfinite(res[r, c, 1])
            if lab > 0 and known[r, c]:
                sums[lab, 0] += res[r, c, 0]
                sums[lab, 1] += res[r, c, 1]
    mean = np.zeros((n + 1, 2))
    norm = np.zeros(n + 1)
    for lab in range(n + 1):
        m = max(count[lab], 1)
        mean[lab, 0] = sums[lab, 0] / m
        mean[lab, 1] = sums[lab, 1] / m
        norm[lab] = np.sqrt(mean[lab, 0] * mean[lab, 0] + mean[lab, 1] * mean[lab, 1])
    before = out.copy()
    for _ in range(steps):
        before[:, :] = out
        changed = False
        for r in range(rows):
            for c in range(cols):
                if before[r, c] != 0 or not (valid[r, c] and known[r, c]):
                    continue
                lab = 0
                for dr in range(-1, 2):
                    for dc in range(-1, 2):
                        rr, cc = r + dr, c + dc
                        if 0 <= rr < rows and 0 <= cc < cols and before[rr, cc] > lab:
                            lab = before[rr, cc]
                if lab == 0:
                    continue
                dx, dy = res[r, c, 0] - mean[lab, 0], res[r, c, 1] - mean[lab, 1]
                far = np.sqrt(dx * dx + dy * dy)
                own = np.sqrt(res[r, c, 0] * res[r, c, 0] + res[r, c, 1] * res[r, c, 1])
                if far <= tolerance + relative * norm[lab] and own >= 0.5 * norm[lab]:
                    out[r, c] = lab
                    changed = True
        if not changed:
            break
