"""No calibration file: a nominal camera from a circular fisheye frame's image circle.

A circular fisheye lens draws its field of view as a lit disc, the *image circle*, on a dark
sensor; beyond it lie the lens barrel's dark ring and, often, a dim halo of stray light.
:func:`find_image_circle` measures that disc on a frame, and :func:`nominal_camera` turns it into
an equidistant camera whose rim is the disc's edge:

    r = f theta,   f = R / (fov / 2)

with ``R`` the circle's radius in pixels, ``fov`` the lens's field of view across (the lens's
data sheet: 180-220 degrees for most circular fisheyes), the principal point the circle's centre
and ``fx = fy`` (square pixels). It is a :class:`~fisheyemotion.calib.KannalaBrandt` with
``k1 = k2 = k3 = k4 = 0``.

How nominal: the image circle fixes where ``theta = fov / 2`` is, not how the lens maps the
angles inside it. An equisolid lens (``r = 2 f sin(theta / 2)``) of the same circle and field of
view is 3.7 degrees off the equidistant guess at 45 degrees off-axis (180 degrees across); a
calibration (Kalibr, Basalt, ``cv2.fisheye.calibrate``) replaces the guess where the angles
matter. The camera is valid beyond the circle (its polynomial is): the pixels outside it are not
part of the image, :meth:`ImageCircle.mask` gives the ones inside as a region of interest.

The circle's edge is found where the frame's brightness falls from the lit disc to the dark ring:
a first guess from the lit area (the largest component above half Otsu's threshold, and its
enclosing circle), then along ``RAYS`` rays from its centre the steepest fall within 15 % of its
radius with darker beyond it (``DARK_AFTER``), and a circle fitted to those edge points by
trimmed least squares (the half nearest the circle, thrice; then every point within
``OUTLIER_SHARE`` of the radius). Dark scene content at the rim (a shadowed road) gives no edge
on its rays, nor do rays that leave the frame first (a cropped circle); a lens's rim is soft
(vignetting spreads its fall over a few pixels, a halo of stray light lies beyond it), so the
circle is good to a pixel or two, not to a tenth. On the real 640x640 frame pairs of
``data/real/fisheye_mc_pairs`` both frames of a pair give the same circle within 0.6 px. A frame
whose lit area fills its corners (a full-frame fisheye or a pinhole camera) has no image
circle, nor has a frame with two lit discs of about one size (a dual-fisheye 360-degree camera's
frame: each half is a camera of its own): ValueError.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from .models import KannalaBrandt

__all__ = ["ImageCircle", "find_image_circle", "nominal_camera"]

#: Rays cast from the first guess's centre to find the disc's edge.
RAYS = 360
#: Share of the radius an edge point may lie off the fitted circle and still count (a lens's rim
#: is soft: vignetting spreads the fall over a few pixels).
OUTLIER_SHARE = 0.015
#: Share of the rays whose edge must lie on the circle for it to be found (rays leave a cropped
#: circle's frame; dark content at the rim shows no edge).
MIN_SUPPORT = 0.25
#: An edge point's next 3 pixels are at most this share of the brightness of the 3 before it.
DARK_AFTER = 0.75


@dataclass(frozen=True)
class ImageCircle:
    """The lit disc of a circular fisheye frame: centre ``(cx, cy)`` in pixels (OpenCV's
    convention, (0, 0) the centre of the top-left pixel), radius in pixels, and the share of the
    rays cast that found its edge (``support``, 0-1)."""

    cx: float
    cy: float
    radius: float
    support: float = 1.0

    def mask(self, width: int, height: int, *, margin: float = 2.0) -> NDArray[np.uint8]:
        """Pixels at least ``margin`` pixels inside the circle: 255, else 0, shape
        ``(height, width)`` (a region of interest for :class:`fisheyemotion.MotionDetector`)."""
        v, u = np.mgrid[:height, :width]
        inside = np.hypot(u - self.cx, v - self.cy) <= self.radius - margin
        return np.where(inside, 255, 0).astype(np.uint8)


def _gray(image: NDArray, name: str) -> NDArray[np.uint8]:
    if not isinstance(image, np.ndarray) or image.dtype != np.uint8:
        raise ValueError(f"{name}: expected a uint8 image as cv2 reads it, got "
                         f"{getattr(image, 'dtype', type(image).__name__)}")
    if image.ndim == 3 and image.shape[2] in (3, 4):
        return cv2.cvtColor(image, cv2.COLOR_BGR2GRAY if image.shape[2] == 3
                            else cv2.COLOR_BGRA2GRAY)
    if image.ndim == 2:
        return image
    raise ValueError(f"{name}: expected shape (H, W) or (H, W, 3), got {image.shape}")


def _fit_circle(points: NDArray[np.float64]) -> tuple[float, float, float]:
    """Least-squares circle (Kasa's algebraic fit) through ``points`` (N, 2)."""
    a = np.column_stack([2 * points, np.ones(len(points))])
    b = (points ** 2).sum(axis=1)
    (cx, cy, c), *_ = np.linalg.lstsq(a, b, rcond=None)
    return float(cx), float(cy), float(math.sqrt(max(c + cx * cx + cy * cy, 0.0)))


def find_image_circle(image: NDArray[np.uint8]) -> ImageCircle:
    """The image circle of a circular fisheye frame (module docstring).

    Parameters
    ----------
    image : ndarray, shape (H, W) or (H, W, 3), uint8
        A frame as cv2 reads it. The circle may be cut by the frame's edges (a cropped circle).

    Returns
    -------
    ImageCircle

    Raises
    ------
    ValueError
        Not a uint8 image, or no image circle: nothing lit, the lit area reaching the frame's
        edges all round, or too few edge points on one circle.
    """
    gray = _gray(image, "image")
    h, w = gray.shape
    if min(h, w) < 16:
        raise ValueError(f"image: expected a frame of at least 16x16 pixels, got {w}x{h}")
    smooth = cv2.GaussianBlur(gray, (0, 0), 1.5)
    # First guess: the largest lit component (Otsu's threshold, halved: dim content inside the
    # disc stays lit, the dark ring does not), closed over small gaps, and its enclosing circle.
    otsu, _ = cv2.threshold(smooth, 0, 255, cv2.THRESH_BINARY + cv2.THRESH_OTSU)
    lit = (smooth > max(0.5 * otsu, 8.0)).astype(np.uint8)
    lit = cv2.morphologyEx(lit, cv2.MORPH_CLOSE, np.ones((9, 9), np.uint8))
    n, labels, stats, _ = cv2.connectedComponentsWithStats(lit, connectivity=8)
    if n < 2:
        raise ValueError("image: no image circle: nothing in the frame is lit")
    areas = stats[1:, cv2.CC_STAT_AREA]
    k = 1 + int(np.argmax(areas))
    if n > 2 and np.sort(areas)[-2] >= 0.5 * areas.max():
        raise ValueError("image: two image circles (a dual-fisheye frame?): crop each lens's "
                         "half and run it as a camera of its own")
    disc = labels == k
    corner = max(2, min(h, w) // 20)  # a circle's corners are dark, a full frame's lit
    corners = [disc[:corner, :corner], disc[:corner, -corner:], disc[-corner:, :corner],
               disc[-corner:, -corner:]]
    if sum(c.mean() > 0.5 for c in corners) >= 3:
        raise ValueError("image: no image circle: the lit area fills the frame's corners (a "
                         "full-frame fisheye or a pinhole camera?); give its calibration")
    contours, _ = cv2.findContours(disc.astype(np.uint8), cv2.RETR_EXTERNAL,
                                   cv2.CHAIN_APPROX_NONE)
    (cx, cy), radius = cv2.minEnclosingCircle(cv2.convexHull(max(contours, key=len)))
    # The disc's edge: the strongest fall of brightness along each ray near the first guess.
    angles = np.linspace(0.0, 2 * math.pi, RAYS, endpoint=False)
    radii = np.arange(0.85 * radius, 1.15 * radius, 0.5)
    ux = (cx + np.outer(np.cos(angles), radii)).astype(np.float32)
    uy = (cy + np.outer(np.sin(angles), radii)).astype(np.float32)
    profile = cv2.remap(smooth.astype(np.float32), ux, uy, cv2.INTER_LINEAR,
                        borderMode=cv2.BORDER_CONSTANT, borderValue=np.nan)
    fall = profile[:, :-2] - profile[:, 2:]  # brightness lost over one pixel outwards
    fall = np.where(np.isfinite(fall), fall, -np.inf)
    best = np.argmax(fall, axis=1)
    strength = fall[np.arange(RAYS), best]
    # An edge of the disc has darker beyond it, within the frame: its next 3 pixels (6 samples)
    # at most DARK_AFTER as bright as the 3 before it (a ray that leaves the frame first, where
    # the circle is cropped, does not count; the halo beyond a rim can be half as bright).
    idx = np.arange(profile.shape[1])
    after = (idx > best[:, None] + 1) & (idx <= best[:, None] + 7)
    before = (idx <= best[:, None]) & (idx > best[:, None] - 6)
    inside = (best + 7 < profile.shape[1]) & np.isfinite(np.where(after, profile, 0)).all(axis=1)
    with np.errstate(invalid="ignore"):
        dark = inside & (np.where(after, profile, 0).sum(1) / 6 <= DARK_AFTER * (
            np.where(before, profile, 0).sum(1) / before.sum(1).clip(1)))
    usable = np.isfinite(strength) & (strength > 0) & dark
    if usable.sum() < 3:
        raise ValueError("image: no image circle: no edge around the lit area")
    strong = usable & (strength >= 0.25 * np.median(strength[usable]))
    r_edge = radii[best + 1]
    points = np.column_stack([cx + np.cos(angles) * r_edge, cy + np.sin(angles) * r_edge])
    # Trimmed least squares from the first guess: fit the half of the edge points nearest the
    # current circle, three times, then every point within OUTLIER_SHARE of the radius.
    fx, fy, fr = cx, cy, radius
    tolerance = OUTLIER_SHARE * radius
    for trim in (0.5, 0.5, 0.5, None, None):
        off = np.abs(np.hypot(points[:, 0] - fx, points[:, 1] - fy) - fr)
        limit = tolerance if trim is None else np.quantile(off[strong], trim)
        keep = strong & (off <= limit)
        if keep.sum() < 3:
            break
        fx, fy, fr = _fit_circle(points[keep])
    off = np.abs(np.hypot(points[:, 0] - fx, points[:, 1] - fy) - fr)
    keep = strong & (off <= tolerance)
    support = float(keep.mean())
    if support < MIN_SUPPORT or keep.sum() < 3:
        raise ValueError(f"image: no image circle: only {support:.0%} of the rays from the lit "
                         f"area's centre meet one circular edge (at least {MIN_SUPPORT:.0%})")
    fx, fy, fr = _fit_circle(points[keep])
    return ImageCircle(fx, fy, fr, support)


def nominal_camera(circle: ImageCircle, width: int, height: int, *,
                   fov_deg: float = 180.0) -> KannalaBrandt:
    """The equidistant camera whose image circle is ``circle`` and whose field of view across it
    is ``fov_deg`` degrees (module docstring: ``f = R / (fov / 2)``; a guess, not a calibration).

    Parameters
    ----------
    circle : ImageCircle
    width, height : int
        The frames' size in pixels.
    fov_deg : float
        The lens's field of view across the circle, degrees, in (0, 360).
    """
    if not isinstance(circle, ImageCircle):
        raise ValueError(f"circle: expected an ImageCircle, got {type(circle).__name__}")
    if not (isinstance(fov_deg, int | float) and math.isfinite(fov_deg) and 0 < fov_deg < 360):
        raise ValueError(f"fov_deg: expected degrees in (0, 360), got {fov_deg!r}")
    if not (math.isfinite(circle.radius) and circle.radius > 0):
        raise ValueError(f"circle: expected a positive radius, got {circle.radius!r}")
    f = circle.radius / math.radians(fov_deg / 2)
    return KannalaBrandt(fx=f, fy=f, cx=circle.cx, cy=circle.cy, width=width, height=height)
