"""The flow's spill onto the road, trimmed from the mask where the images show road.

Farneback's and DIS's smoothing carries a moving object's flow onto the road beside and below
it; the cells there deviate as the object does, so the region takes them, and its growth to
the object's extent (:mod:`fisheyemotion.extent`) starts from them. On the bundled open-road
scenes nearly all the static pixels a detection flags lie in regions that touch an object, most
of them on the road (``docs/evaluation.md``, *Road spill*).

The road is the one surface whose static motion is known at every pixel without a measurement:
the plane and the two poses. A pixel ``y`` of the current frame whose ray meets the road at a
point ``X`` in front of the camera was at ``x_r = project(R0^T (X - C0))`` in the previous
frame if it is road. It is road spill when, averaged over the ``window`` x ``window`` block
around it (the cell size):

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
front of the camera within ``FAR`` metres, are not explained. Where the camera stood still
between the frames, every static point moves as the rotation alone takes it, road or not: that
is the hypothesis at every pixel (``still``), and there is no parallax to ask for.

:func:`trim_regions` removes each region's explained pixels, unless that splits it into two or
more pieces of ``PIECE`` cells or more: two parts of one object with road between them, or a
pedestrian beside a vehicle in one region, where which piece is the object is not known, so the
region stays whole. Otherwise the region keeps its largest piece (crumbs are dropped: a region
broken into a piece and its crumbs would otherwise count as several) with what that piece
encloses (explained pixels inside an object, a plain patch its carried motion got wrong, stay),
and is dropped when all of it is explained. The likelihood maps and ``Detection.cell_mask``
are not changed.
"""

from __future__ import annotations

import cv2
import numpy as np
from numpy.typing import NDArray

from .calib.base import CameraModel
from .extent import _filled
from .road import Road
from .segment import Region

__all__ = ["road_explained", "trim_regions", "MARGIN", "PARALLAX", "PIECE", "FAR"]

#: Grey levels by which the road must explain a block better than its carried motion does.
MARGIN = 3.0
#: Cells the road point's image must be from its point at infinity (its parallax).
PARALLAX = 1.0
#: Cells a piece must have for the split it makes to leave its region whole.
PIECE = 16
#: Metres beyond which a ray's road point is not used (a ray grazing the road's horizon).
FAR = 100.0

_UNEXPLAINED = np.float32(255.0)  # the difference where a hypothesis has no sample


def road_explained(prev: NDArray[np.uint8], curr: NDArray[np.uint8], pixels: NDArray[np.bool_],
                   camera: CameraModel, pose0: NDArray[np.float64], pose1: NDArray[np.float64],
                   road: Road, motion: NDArray[np.float32], *, window: int,
                   tolerance: float, still: bool = False) -> NDArray[np.bool_]:
    """Which of ``pixels`` the road explains better than their carried motion (module doc).

    Parameters
    ----------
    prev, curr : ndarray of uint8, shape (H, W)
        The pair's frames (gray); the pixels are ``curr``'s.
    pixels : ndarray of bool, shape (H, W)
        The pixels to test (a mask).
    camera : CameraModel
    pose0, pose1 : ndarray, shape (4, 4)
        ``world_from_cam`` of ``prev`` and ``curr``.
    road : Road
        A known road in the poses' world frame.
    motion : ndarray of float32, shape (H, W, 2)
        The displacement each pixel of ``curr`` was carried with (``prev`` to ``curr``; NaN:
        none), read in the block around each tested pixel.
    window : int
        Side of the block the differences are averaged over (pixels, odd or even).
    tolerance : float
        Mean absolute difference (grey levels) below which the road explains a block.
    still : bool
        The camera stood still between the frames (the pair's baseline below
        ``Params.min_baseline``): every static point then moves as the rotation alone takes
        it, road or not, and that is the hypothesis at every pixel, without a parallax
        condition (``road`` is not used).

    Returns
    -------
    ndarray of bool, shape (H, W)
        True on the pixels of ``pixels`` that are road spill.
    """
    h, w = curr.shape
    out = np.zeros((h, w), np.bool_)
    if not pixels.any() or not (road.known or still):
        return out
    # The blocks of the tested pixels: a crop around them, with every pixel of their windows.
    ys, xs = np.nonzero(pixels)
    half = window // 2 + 1
    y0, y1 = max(0, int(ys.min()) - half), min(h, int(ys.max()) + half + 1)
    x0, x1 = max(0, int(xs.min()) - half), min(w, int(xs.max()) + half + 1)
    v, u = np.mgrid[y0:y1, x0:x1].astype(np.float64)
    rays, ok = camera.unproject(np.stack([u, v], axis=-1))
    r1, c1 = pose1[:3, :3], pose1[:3, 3]
    r0, c0 = pose0[:3, :3], pose0[:3, 3]
    world = rays @ r1.T
    at_infinity, seen_far = camera.project(world @ r0)
    ok &= seen_far
    if still:
        at_road = at_infinity
    else:
        up = road.up
        with np.errstate(invalid="ignore", divide="ignore"):
            reach = (road.offset - up @ c1) / (world @ up)  # along the ray to the road
            ok &= (reach > 0) & (reach * np.linalg.norm(world, axis=-1) < FAR)
        point = c1 + np.where(ok, reach, 0.0)[..., None] * world
        at_road, seen = camera.project((point - c0) @ r0)
        ok &= seen
        with np.errstate(invalid="ignore"):
            ok &= np.linalg.norm(at_road - at_infinity, axis=-1) >= PARALLAX * window
    if not ok.any():
        return out
    here = curr[y0:y1, x0:x1].astype(np.float32)
    road_diff = _difference(prev, here, at_road, ok)
    carried = motion[y0:y1, x0:x1].astype(np.float64)
    moved = np.stack([u, v], axis=-1) - carried
    has_motion = np.isfinite(moved).all(axis=-1)
    motion_diff = _difference(prev, here, np.where(has_motion[..., None], moved, -1e4),
                              has_motion)
    road_mean = cv2.blur(road_diff, (window, window), borderType=cv2.BORDER_REPLICATE)
    motion_mean = cv2.blur(motion_diff, (window, window), borderType=cv2.BORDER_REPLICATE)
    # Every pixel of the block must have a road sample: eroding the samples by the window.
    whole = cv2.erode(ok.view(np.uint8), np.ones((window, window), np.uint8),
                      borderType=cv2.BORDER_REPLICATE) > 0
    out[y0:y1, x0:x1] = (pixels[y0:y1, x0:x1] & whole & (road_mean < tolerance)
                         & (road_mean + MARGIN < motion_mean))
    return out


def _difference(prev: NDArray[np.uint8], here: NDArray[np.float32], at: NDArray[np.float64],
                ok: NDArray[np.bool_]) -> NDArray[np.float32]:
    """``|here - prev(at)|`` (bilinear), 255 where not ``ok`` or outside ``prev``."""
    mx = np.where(ok, at[..., 0], -1e4).astype(np.float32)
    my = np.where(ok, at[..., 1], -1e4).astype(np.float32)
    sampled = cv2.remap(prev, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT,
                        borderValue=0).astype(np.float32)
    inside = cv2.remap(np.ones(prev.shape, np.uint8), mx, my, cv2.INTER_NEAREST,
                       borderMode=cv2.BORDER_CONSTANT, borderValue=0) > 0
    diff = np.abs(here - sampled)
    diff[~(ok & inside)] = _UNEXPLAINED
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
    before = (pixel_labels > 0).view(np.uint8)
    explained = explained & (pixel_labels > 0)
    if not explained.any():
        return before * np.uint8(255), regions
    _, part = cv2.connectedComponents(before, connectivity=8)
    pieces, piece, stats, _ = cv2.connectedComponentsWithStats(
        (before.astype(np.bool_) & ~explained).view(np.uint8), connectivity=8)
    area = stats[:, cv2.CC_STAT_AREA]
    # The part each piece lies in (a piece lies in one part), and per part its pieces.
    first = np.zeros(pieces, np.intp)
    first[piece.ravel()] = np.arange(piece.size)
    owner = part.ravel()[first]
    owner[0] = 0
    big = np.bincount(owner[1:], weights=area[1:] >= PIECE * grid * grid,
                      minlength=part.max() + 1)
    whole = big >= 2  # which piece is the object is not known: the part stays whole
    largest = np.full(part.max() + 1, -1, np.intp)
    order = np.argsort(area[1:], kind="stable") + 1  # the last written is the largest
    largest[owner[order]] = order
    keep_piece = np.zeros(pieces, np.bool_)
    keep_piece[largest[largest > 0]] = True
    kept_pixels = whole[part] | (keep_piece[piece] & (piece > 0))
    # What the kept pieces enclose stays (a plain patch inside an object): only the spill
    # around them goes.
    kept_pixels = _filled(kept_pixels) & before.astype(np.bool_)
    mask = kept_pixels.view(np.uint8) * np.uint8(255)
    kept: list[Region] = []
    for region in regions:
        x, y, bw, bh = region.bbox
        own = pixel_labels[y:y + bh, x:x + bw] == region.label
        left = own & kept_pixels[y:y + bh, x:x + bw]
        if not left.any():
            continue
        if np.array_equal(left, own):
            kept.append(region)
            continue
        binary = left.view(np.uint8)
        m = cv2.moments(binary, binaryImage=True)
        bx, by, gw, gh = cv2.boundingRect(binary)
        kept.append(region._replace(bbox=(x + bx, y + by, gw, gh), area=int(m["m00"]),
                                    centroid=(m["m10"] / m["m00"] + x, m["m01"] / m["m00"] + y)))
    kept.sort(key=lambda reg: -reg.area)
    return mask, kept
