"""Detected regions grown to their object's extent in the current frame (marker watershed).

A region of the mask is the cells whose deviations pass the threshold: where the object's
surface is textured enough to be scored and its flow is measured off the static scene. Its plain
parts (cells without texture are not scored) and the cells whose flow Farneback's or DIS's
smoothing pulled towards the background stay below, so a detection covers part of its object,
in blocks of cells. :func:`grow_to_extent` grows each region to where the image of the frame the
mask belongs to says its object ends:

1. Around each region, a crop of the frame reaching ``reach`` times the region's larger box
   side beyond its box (at least ``min_reach`` pixels): the growth's limit.
2. Markers: the region's pixels eroded by one pixel (the object); the crop's border where the
   reach ends it, not at the frame's edge, beyond which the object may go on (the ring inside
   the outermost pixels, which OpenCV's watershed keeps as watershed lines), every
   pixel of the crop outside the region whose likelihood is below ``static_fraction`` times the
   threshold (scored far below it, or not scored at all: no texture, outside the domain) and,
   given the cells' residual flows (measured minus the static scene's), the pixels of cells
   that move less than ``SLOWER`` times the region's mean residual (the background). Only
   pixels with weak or strong deviations that move about as much as the object are left to the
   flooding. Where the static prediction knows the structure beside the road (a stream's
   scene model, ``residual_decides``), a known residual alone decides: a part of the object
   scored far below the threshold (plain, or near the epipole, where deviations are small)
   that moves like the object is flooded too.
3. OpenCV's marker watershed (``cv2.watershed``: Meyer's flooding, ordered by the grey-level
   difference to the neighbours, on the frame smoothed by a Gaussian of 1 px) gives each of
   them to the object or to the background. The object's pixels and the holes they enclose
   (what the crop's border cannot reach around them: an object's plain, unscored middle) join
   the region.

A region only grows: every pixel it had stays (the eroded ring is flooded like the rest, and the
union is taken). It stops at the object's image boundary where that is the strongest edge
between the region and the background markers, and at the crop's border. Unscored pixels are
background because a plain wall or floor beside a detected arm (the real Aria clips) would
otherwise be flooded whole: they join only as enclosed holes. Other regions inside a crop are flooded like
unknown pixels. The likelihood map is not changed: the mask can hold pixels below the
threshold.

Measured in ``docs/evaluation.md`` (*Extent*): coverage and pixel IoU up in every scene group,
with both flows and the exact one; detection unchanged, false-positive frames within a point (a
false region grows too, which shows in the static pixels flagged).
"""

from __future__ import annotations

import cv2
import numpy as np
from numpy.typing import NDArray

from .flow import grid_upsample
from .segment import Region, with_pixels

__all__ = ["grow_to_extent", "with_holes_filled"]

#: Standard deviation (pixels) of the Gaussian the frame is smoothed by before the flooding.
SMOOTHING = 1.0
#: A cell whose residual flow is shorter than this share of the region's mean residual is
#: background: static, or slower than the object (the real kitchen clip's bowl, whose contents
#: the moving spoon stirs, would be flooded from the spoon otherwise; docs/evaluation.md).
SLOWER = 0.35
_CROSS = np.ones((3, 3), np.uint8)
#: Pixels of frame around a crop that its smoothing reads (the 8-bit Gaussian's radius, 3
#: sigmas, and one more).
_BLUR_MARGIN = int(np.ceil(3 * SMOOTHING)) + 1


def grow_to_extent(labels: NDArray[np.int32], regions: list[Region], grid: int,
                   gray: NDArray[np.uint8], likelihood: NDArray[np.float32], *,
                   threshold: float, reach: float, static_fraction: float,
                   residual: NDArray[np.float64] | None = None,
                   inside: NDArray[np.uint8] | None = None, min_reach: int = 8,
                   residual_decides: bool = False, with_labels: bool = False
                   ) -> tuple[NDArray[np.uint8], list[Region]] | tuple[
                       NDArray[np.uint8], list[Region], NDArray[np.int32]]:
    """The mask of ``regions`` grown to their objects' extent in ``gray`` (module doc).

    Parameters
    ----------
    labels : ndarray of int32, shape (rows, cols)
        Cells of each region, by its ``label`` (0: none); ``rows * grid`` and ``cols * grid``
        at most the frame's size.
    regions : list of Region
        As :func:`fisheyemotion.segment.segment_cells` gives them.
    grid : int
        Cell size, pixels.
    gray : ndarray of uint8, shape (H, W)
        The frame the mask belongs to.
    likelihood : ndarray of float32, shape (H, W)
        The motion likelihood on that frame's pixels, 0 where not scored.
    threshold : float
        The likelihood threshold of the regions.
    reach : float
        How far a region may grow beyond its box, as a share of its box's larger side (> 0).
    static_fraction : float
        Pixels below this share of ``threshold`` are background.
    residual : ndarray, shape (rows, cols, 2), optional
        Each cell's residual flow (measured minus the static scene's, pixels; NaN where
        unknown): cells shorter than ``SLOWER`` times the region's mean are background.
    inside : ndarray of uint8, shape (H, W), optional
        255 where a pixel may be moving (the camera's domain and the region of interest).
    min_reach : int
        Pixels a region may grow by at least.
    residual_decides : bool
        Where a cell's ``residual`` is known it alone marks the background (slower than
        ``SLOWER`` times the region's), not ``static_fraction``: for residuals measured against
        a static prediction that knows the structure beside the road (a stream's scene model).
    with_labels : bool
        Also return the grown regions' pixels by label.

    Returns
    -------
    mask : ndarray of uint8, shape (H, W)
        255 on the grown regions.
    regions : list of Region
        The same regions (label, mean likelihood of their cells) with the box, area (pixels)
        and centroid of their grown pixels, largest first.
    pixel_labels : ndarray of int32, shape (H, W)
        With ``with_labels``: each grown pixel's region label, 0 elsewhere (where two regions
        grew over one pixel, the later one's in ``regions``' order).
    """
    h, w = gray.shape
    mask = np.zeros((h, w), np.uint8)
    pixel_labels = np.zeros((h, w), np.int32) if with_labels else None
    if not regions:
        return (mask, [], pixel_labels) if with_labels else (mask, [])
    static_below = np.float32(static_fraction * threshold)
    if residual is not None:
        speed = np.sqrt(residual[..., 0] ** 2 + residual[..., 1] ** 2)
    grown = []
    for region in regions:
        x, y, bw, bh = region.bbox
        r = max(min_reach, int(reach * max(bw, bh)))
        x0, y0 = max(0, x - r), max(0, y - r)
        x1, y1 = min(w, x + bw + r), min(h, y + bh + r)
        crop = (y0, y1, x0, x1)
        cells = slice(y0 // grid, -(-y1 // grid)), slice(x0 // grid, -(-x1 // grid))
        here = labels[cells] == region.label  # its cells (all inside the crop)
        own = _on_pixels(here, grid, crop)    # upsampled
        if inside is not None:
            own &= inside[y0:y1, x0:x1] // 255
        markers = np.zeros(own.shape, np.int32)
        lik = likelihood[y0:y1, x0:x1]
        background = lik < static_below
        if residual is not None:
            own_residual = residual[cells][here]
            known = own_residual[np.isfinite(own_residual).all(axis=-1)]
            mean = known.mean(axis=0) if len(known) else np.full(2, np.nan)
            if np.isfinite(mean).all():
                with np.errstate(invalid="ignore"):
                    slower = speed[cells] < SLOWER * np.linalg.norm(mean)
                if residual_decides:  # where known, the residual alone marks the background
                    background &= ~(_on_pixels(np.isfinite(speed[cells]), grid, crop) > 0)
                background |= _on_pixels(slower, grid, crop) > 0
        markers[background & (own == 0)] = 2
        # The crop's border where the reach ends it (at the frame's edge the object may go on):
        # cv2.watershed makes the image's outermost pixels watershed lines (-1), overwriting
        # any marker there, so the background ring is the one inside them.
        if y0 > 0:
            markers[1, :] = 2
        if y1 < h:
            markers[-2, :] = 2
        if x0 > 0:
            markers[:, 1] = 2
        if x1 < w:
            markers[:, -2] = 2
        core = cv2.erode(own, _CROSS)
        markers[(core if core.any() else own) > 0] = 1
        flooded = cv2.watershed(cv2.cvtColor(_smoothed(gray, crop), cv2.COLOR_GRAY2BGR), markers)
        pixels = with_holes_filled((flooded == 1) | (own > 0))
        if inside is not None:
            pixels &= inside[y0:y1, x0:x1] > 0
        binary = pixels.view(np.uint8)
        mask[y0:y1, x0:x1] |= binary * np.uint8(255)
        if pixel_labels is not None:
            pixel_labels[y0:y1, x0:x1][pixels] = region.label
        # A region with no pixel inside (not possible for a region of the mask) stays as it was.
        grown.append(with_pixels(region, binary, x0, y0) if pixels.any() else region)
    grown.sort(key=lambda reg: -reg.area)
    return (mask, grown, pixel_labels) if with_labels else (mask, grown)


def _smoothed(gray: NDArray[np.uint8], crop: tuple[int, int, int, int]) -> NDArray[np.uint8]:
    """``crop = (y0, y1, x0, x1)`` of ``gray`` smoothed by the Gaussian of :data:`SMOOTHING`
    pixels: the same pixels as a crop of the whole frame smoothed (OpenCV's kernel reaches
    3 sigmas for 8-bit images; the crop is smoothed with :data:`_BLUR_MARGIN` pixels around
    it, or the frame's own edge), at a crop's cost."""
    y0, y1, x0, x1 = crop
    h, w = gray.shape
    top, left = max(0, y0 - _BLUR_MARGIN), max(0, x0 - _BLUR_MARGIN)
    bottom, right = min(h, y1 + _BLUR_MARGIN), min(w, x1 + _BLUR_MARGIN)
    smooth = cv2.GaussianBlur(np.ascontiguousarray(gray[top:bottom, left:right]), (0, 0),
                              SMOOTHING)
    return np.ascontiguousarray(smooth[y0 - top:y1 - top, x0 - left:x1 - left])


def _on_pixels(cells: NDArray[np.bool_], grid: int, crop: tuple[int, int, int, int]
               ) -> NDArray[np.uint8]:
    """Cells (those of ``crop``'s rows and columns of cells) as 0/1 pixels of ``crop`` =
    ``(y0, y1, x0, x1)``, upsampled as the mask is (:func:`fisheyemotion.flow.grid_upsample`:
    pixels past the last whole cell take its value)."""
    y0, y1, x0, x1 = crop
    top, left = (y0 // grid) * grid, (x0 // grid) * grid
    rows, cols = cells.shape
    up = grid_upsample(cells.view(np.uint8), grid, max(x1 - left, cols * grid),
                       max(y1 - top, rows * grid))
    return np.ascontiguousarray(up[y0 - top:y1 - top, x0 - left:x1 - left])


def with_holes_filled(pixels: NDArray[np.bool_]) -> NDArray[np.bool_]:
    """``pixels`` (a crop or an image) with their holes filled: what its border cannot reach
    around them."""
    outside = cv2.copyMakeBorder((~pixels).view(np.uint8), 1, 1, 1, 1, cv2.BORDER_CONSTANT,
                                 value=1)
    cv2.floodFill(outside, None, (0, 0), 2, flags=8)
    return outside[1:-1, 1:-1] != 2
