"""The flow's spill onto the road, trimmed from the mask where the images show road.

Farneback's and DIS's smoothing carries a moving object's flow onto the road beside and below
it; the cells there deviate as the object does, so the region takes them, and its growth to
the object's extent (:mod:`fisheyemotion.extent`) starts from them. On the bundled open-road
scenes nearly all the static pixels a detection flags lie in regions that touch an object, most
of them on the road (``docs/evaluation.md``, *Road spill*).

The road is the one surface whose static motion is known at every pixel without a measurement:
the plane and the two poses. A pixel ``y`` of the current frame whose ray meets the road at a
point ``X`` in front of the camera was at ``x_r = project(R0^T (X - C0))`` in the previous
frame if it is road. It is road spill when, averaged over the ``grid`` x ``grid`` block around
it (the cell size):

1. the road explains it: ``mean |I1(y) - I0(x_r)| < tolerance`` (grey levels);
2. better than the motion the mask carried it with, by ``MARGIN`` grey levels
   (``mean |I1(y) - I0(y - d)|``, ``d`` the displacement of the cell it was carried from): a
   block both explain (plain, or moving as the road there would) is left as it is;
3. the road point has parallax: ``x_r`` is at least ``PARALLAX`` cells from where the rotation
   alone takes the ray (its point at infinity). Near the epipole and the horizon a car ahead
   moves as the road behind it would; the images cannot tell them apart there, and a preceding
   car's cells are flagged by what its flow gets wrong (measured: its cells were trimmed
   without this condition).

Pixels outside the camera's domain in either frame, or whose ray does not meet the road in
front of the camera within ``FAR`` metres, are not explained. The road point's image ``x_r``
and the point at infinity are computed at the cell centres and interpolated bilinearly between
them (the map is smooth wherever the road is seen with parallax; a cell without a road point
leaves its neighbourhood unexplained), and the carried motion is the cell's: a test costs two
projections per cell and, per pixel, two samplings of the previous frame, on the boxes around
the mask's parts only. Where the camera stood still
between the frames, every static point moves as the rotation alone takes it, road or not: that
is the hypothesis at every pixel (``still``), and there is no parallax to ask for.

:func:`trim_regions` removes the explained pixels from each connected part of the mask (an
object and a region of its spill beside it are one part), unless that splits the part into two
or more pieces of ``PIECE`` cells or more: two parts of one object with road between them, or a
pedestrian beside a vehicle, where which piece is the object is not known, so the part stays
whole. Otherwise the part keeps its largest piece (crumbs are dropped: a part broken into a
piece and its crumbs would otherwise count as several regions) with what that piece encloses
(explained pixels inside an object, a plain patch its carried motion got wrong, stay), if that
piece has ``PIECE`` cells or more; else the part goes: what the road leaves of it is no piece of
an object (a false region on the road reaching a few cells onto the structure beside it, or a
detection that was mostly its own spill). The regions keep their labels, their boxes shrink to what is left.
The likelihood maps and ``Detection.cell_mask`` are not changed.
"""

from __future__ import annotations

import cv2
import numpy as np
from numpy.typing import NDArray

from .calib.base import CameraModel
from .extent import with_holes_filled
from .flow import grid_upsample, pixel_grid
from .road import Road
from .segment import Region, with_pixels

__all__ = ["road_explained", "trim_regions", "MARGIN", "PARALLAX", "PIECE", "FAR"]

#: Grey levels by which the road must explain a block better than its carried motion does.
MARGIN = 3.0
#: Cells the road point's image must be from its point at infinity (its parallax).
PARALLAX = 1.0
#: Cells a piece left by the trim must have to count: two such pieces leave their part whole,
#: and a part whose largest piece is smaller goes.
PIECE = 16
#: Metres beyond which a ray's road point is not used (a ray grazing the road's horizon).
FAR = 100.0

_UNEXPLAINED = np.float32(255.0)  # the difference where a hypothesis has no sample


def road_explained(prev: NDArray[np.uint8], curr: NDArray[np.uint8], pixels: NDArray[np.bool_],
                   rays: NDArray[np.float64], camera: CameraModel, pose0: NDArray[np.float64],
                   pose1: NDArray[np.float64], road: Road, motion: NDArray[np.float32], *,
                   grid: int, tolerance: float, still: bool = False) -> NDArray[np.bool_]:
    """Which of ``pixels`` the road explains better than their carried motion (module doc).

    Parameters
    ----------
    prev, curr : ndarray of uint8, shape (H, W)
        The pair's frames (gray); the pixels are ``curr``'s.
    pixels : ndarray of bool, shape (H, W)
        The pixels to test (a mask).
    rays : ndarray, shape (rows, cols, 3)
        The unit rays of the cell centres (camera frame; NaN where none), cells of ``grid``
        pixels from the top-left corner.
    camera : CameraModel
    pose0, pose1 : ndarray, shape (4, 4)
        ``world_from_cam`` of ``prev`` and ``curr``.
    road : Road
        A known road in the poses' world frame (not used with ``still``).
    motion : ndarray of float32, shape (rows, cols, 2)
        The displacement each cell of ``curr`` was carried with (``prev`` to ``curr``; NaN:
        none).
    grid : int
        Cell size, pixels: also the side of the block the differences are averaged over.
    tolerance : float
        Mean absolute difference (grey levels) below which the road explains a block.
    still : bool
        The camera stood still between the frames (the pair's baseline below
        ``Params.min_baseline``): every static point then moves as the rotation alone takes
        it, road or not, and that is the hypothesis at every pixel, without a parallax
        condition.

    Returns
    -------
    ndarray of bool, shape (H, W)
        True on the pixels of ``pixels`` that are road spill.
    """
    h, w = curr.shape
    out = np.zeros((h, w), np.bool_)
    boxes = _part_boxes(pixels)
    if not boxes or not (road.known or still):
        return out
    # The cells around the parts (two cells beyond their blocks: the bilinear maps inside are
    # those of the whole grid), and their pixels from (top, left).
    rows, cols = rays.shape[:2]
    half = grid // 2 + 1
    r0 = max(0, min(y for _, y, _, _ in boxes) // grid - 2)
    c0 = max(0, min(x for x, _, _, _ in boxes) // grid - 2)
    r1 = min(rows, max(y + bh for _, y, _, bh in boxes) // grid + 3)
    c1 = min(cols, max(x + bw for x, _, bw, _ in boxes) // grid + 3)
    top, left = r0 * grid, c0 * grid
    bottom = h if r1 == rows else r1 * grid
    right = w if c1 == cols else c1 * grid
    rot1, centre1 = pose1[:3, :3], pose1[:3, 3]
    rot0, centre0 = pose0[:3, :3], pose0[:3, 3]
    world = rays[r0:r1, c0:c1] @ rot1.T
    at_infinity, ok = camera.project(world @ rot0)
    if still:
        at = at_infinity
    else:
        up = road.up
        with np.errstate(invalid="ignore", divide="ignore"):
            reach = (road.offset - up @ centre1) / (world @ up)  # along the ray to the road
            ok &= (reach > 0) & (reach < FAR)
        point = centre1 + np.where(ok, reach, 0.0)[..., None] * world
        at, seen = camera.project((point - centre0) @ rot0)
        ok &= seen
        with np.errstate(invalid="ignore"):
            ok &= np.linalg.norm(at - at_infinity, axis=-1) >= PARALLAX * grid
    if not ok.any():
        return out
    # Pixel maps: bilinear between the cell centres (cv2.resize by a whole factor puts source
    # sample k at pixel (grid - 1) / 2 + k * grid), the motion constant over each cell.
    n_rows, n_cols = ok.shape
    at_cells = np.where(ok[..., None], at, np.nan).astype(np.float32)
    at_pixels = _padded(cv2.resize(at_cells, (n_cols * grid, n_rows * grid),
                                   interpolation=cv2.INTER_LINEAR), bottom - top, right - left)
    moved = grid_upsample(np.ascontiguousarray(motion[r0:r1, c0:c1], dtype=np.float32), grid,
                          right - left, bottom - top)
    window = np.ones((grid, grid), np.uint8)
    for x, y, bw, bh in boxes:
        y0, y1, x0, x1 = max(0, y - half), min(h, y + bh + half), max(0, x - half), \
            min(w, x + bw + half)
        here = curr[y0:y1, x0:x1].astype(np.float32)
        u, v = (g[y0:y1, x0:x1] for g in pixel_grid(h, w))
        to_road = at_pixels[y0 - top:y1 - top, x0 - left:x1 - left]
        road_diff = _difference(prev, here, to_road[..., 0], to_road[..., 1])
        carried = moved[y0 - top:y1 - top, x0 - left:x1 - left]
        motion_diff = _difference(prev, here, u - carried[..., 0], v - carried[..., 1])
        road_mean = cv2.blur(road_diff, (grid, grid), borderType=cv2.BORDER_REPLICATE)
        motion_mean = cv2.blur(motion_diff, (grid, grid), borderType=cv2.BORDER_REPLICATE)
        # Every pixel of the block must have a road sample.
        whole = cv2.erode(np.isfinite(to_road[..., 0]).view(np.uint8), window,
                          borderType=cv2.BORDER_REPLICATE) > 0
        out[y0:y1, x0:x1] |= (pixels[y0:y1, x0:x1] & whole & (road_mean < tolerance)
                              & (road_mean + MARGIN < motion_mean))
    return out


def _part_boxes(pixels: NDArray[np.bool_]) -> list[tuple[int, int, int, int]]:
    """The boxes ``(x, y, w, h)`` of the 8-connected parts of ``pixels`` (labelled within
    their bounding box: OpenCV's statistics cost in proportion to the image labelled)."""
    x0, y0, bw, bh = cv2.boundingRect(pixels.view(np.uint8))
    if bw == 0:
        return []
    _, _, stats, _ = _labelled(np.ascontiguousarray(pixels[y0:y0 + bh, x0:x0 + bw]))
    return [(x0 + int(x), y0 + int(y), int(w), int(h)) for x, y, w, h, _ in stats[1:]]


def _labelled(pixels: NDArray[np.bool_]) -> tuple:
    """OpenCV's 8-connected labelling of ``pixels`` with statistics, by the block-based
    algorithm (a third of the default's time at 640x480 on OpenCV 5.1)."""
    return cv2.connectedComponentsWithStatsWithAlgorithm(pixels.view(np.uint8), 8, cv2.CV_32S,
                                                         cv2.CCL_BBDT)


def _padded(image: NDArray, h: int, w: int) -> NDArray:
    """``image`` cropped or padded (edge values) to ``h`` x ``w`` pixels."""
    image = image[:h, :w]
    bottom, right = h - image.shape[0], w - image.shape[1]
    if bottom or right:
        image = cv2.copyMakeBorder(image, 0, bottom, 0, right, cv2.BORDER_REPLICATE)
    return image


def _difference(prev: NDArray[np.uint8], here: NDArray[np.float32], mx: NDArray[np.float32],
                my: NDArray[np.float32]) -> NDArray[np.float32]:
    """``|here - prev(mx, my)|`` (bilinear), 255 where a coordinate is NaN or outside
    ``prev``."""
    bad = ~(np.isfinite(mx) & np.isfinite(my))
    h, w = prev.shape
    with np.errstate(invalid="ignore"):
        bad |= (mx < 0) | (mx > w - 1) | (my < 0) | (my > h - 1)
    mx = np.where(bad, -1e4, mx).astype(np.float32)
    my = np.where(bad, -1e4, my).astype(np.float32)
    sampled = cv2.remap(prev, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT,
                        borderValue=0).astype(np.float32)
    diff = np.abs(here - sampled)
    diff[bad] = _UNEXPLAINED
    return diff


def trim_regions(pixel_labels: NDArray[np.int32], regions: list[Region],
                 explained: NDArray[np.bool_], *, grid: int
                 ) -> tuple[NDArray[np.uint8], list[Region]]:
    """The mask without its explained pixels, where that does not split it (module doc).

    The rule applies to each connected part of the mask (8-connected), which may hold several
    touching regions: an object and a region of its spill beside it are one part.

    Parameters
    ----------
    pixel_labels : ndarray of int32, shape (H, W)
        Each region's pixels by its ``label`` (0: none); the mask is where it is not 0.
    regions : list of Region
        Each region's pixels lie within its ``bbox`` (the work is done within their union).
    explained : ndarray of bool, shape (H, W)
        Pixels :func:`road_explained` found.
    grid : int
        Cell size, pixels (``PIECE`` is in cells).

    Returns
    -------
    mask : ndarray of uint8, shape (H, W)
        255 on the pixels left.
    regions : list of Region
        The regions with pixels left, with the box, area and centroid of those (label and mean
        likelihood unchanged), largest first.
    """
    h, w = pixel_labels.shape
    mask = np.zeros((h, w), np.uint8)
    if not regions:
        return mask, regions
    # Everything within the regions' common box (their pixels are inside their boxes).
    x0 = min(r.bbox[0] for r in regions)
    y0 = min(r.bbox[1] for r in regions)
    x1 = max(r.bbox[0] + r.bbox[2] for r in regions)
    y1 = max(r.bbox[1] + r.bbox[3] for r in regions)
    labels = pixel_labels[y0:y1, x0:x1]
    kept = labels > 0
    crop = (slice(y0, y1), slice(x0, x1))
    road_here = explained[crop] & kept
    if not road_here.any():
        mask[crop] = kept.view(np.uint8) * np.uint8(255)
        return mask, regions
    piece = PIECE * grid * grid
    parts, part, stats, _ = _labelled(kept)
    changed = np.zeros(parts, np.bool_)
    for j in range(1, parts):
        x, y, bw, bh, _ = stats[j]
        box = (slice(y, y + bh), slice(x, x + bw))
        own = part[box] == j
        road = road_here[box] & own
        if not road.any():
            continue
        count, pieces = cv2.connectedComponents((own & ~road).view(np.uint8), connectivity=8)
        areas = np.bincount(pieces.ravel(), minlength=count)[1:]
        if np.count_nonzero(areas >= piece) >= 2:
            continue  # which piece is the object is not known: the part stays whole
        # Its largest piece, if that is one of an object; else the part goes.
        left = (with_holes_filled(pieces == 1 + int(np.argmax(areas))) & own) \
            if count > 1 and areas.max() >= piece else np.zeros_like(own)
        kept[box] &= ~own | left
        changed[j] = True
    mask[crop] = kept.view(np.uint8) * np.uint8(255)
    out: list[Region] = []
    for region in regions:
        x, y, bw, bh = region.bbox
        box = (slice(y - y0, y - y0 + bh), slice(x - x0, x - x0 + bw))
        own = labels[box] == region.label
        if not changed[part[box][own]].any():
            out.append(region)
            continue
        left = own & kept[box]
        if not left.any():
            continue
        out.append(with_pixels(region, left.view(np.uint8), x, y))
    out.sort(key=lambda reg: -reg.area)
    return mask, out
