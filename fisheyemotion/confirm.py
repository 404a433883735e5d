"""Region test over consecutive results of a stream: a region is confirmed by the frame before.

A false region on static structure is a flow error, and many flow errors do not repeat at the
same place in the next frame: on the rendered streets 47-82 % of the frames with a false region
have one that no false region of the frame before came near (``docs/evaluation.md``,
*Confirmed by the frame before*). A moving object is flagged again and again where it is.

This is the track confirmation of a radar or lidar tracker (a track is reported once it has
been seen twice), on the detector's own regions: the regions of a result (the cells the
segmentation keeps, :func:`fisheyemotion.segment.segment_cells`, before their growth to the
objects' extent) are reported only where they come within ``reach`` cells of a region of the
stream's previous result (its candidates, reported or not: confirmation does not feed on
itself). Between two consecutive results an object moves by about ``flow / frame_gap``;
``reach`` bounds that, and the change of a region's outline, without carrying the previous
regions by the flow, whose errors are what the test is against.

The price is one result per object: the first frame an object is flagged in (and the first
after a frame it was missed in) is not reported. A stream's first result has nothing before it
and is reported as measured: an object already moving when the stream starts is not hidden for
a frame (suppressing that result too cost the open road's preceding, approaching and
static-ego objects one object-frame of 13 each, and removed no false-positive frame). A single
pair (:func:`fisheyemotion.detect`) is not confirmed.
"""

from __future__ import annotations

import cv2
import numpy as np
from numpy.typing import NDArray

from .segment import Region

__all__ = ["confirmed_regions"]


def confirmed_regions(labels: NDArray[np.int32], regions: list[Region],
                      before: NDArray[np.bool_] | None, reach: int
                      ) -> tuple[NDArray[np.int32], list[Region]]:
    """The regions that come within ``reach`` cells of a cell of ``before``.

    Parameters
    ----------
    labels : ndarray of int32, shape (rows, cols)
        Each region's cells by its ``label`` (0 elsewhere), on the current frame's cells.
    regions : list of Region
        Their properties (``label`` 1..n), as :func:`fisheyemotion.segment.segment_cells`
        gives them.
    before : ndarray of bool, shape (rows, cols), or None
        The cells of the previous result's regions (on that frame's cells); None: there is no
        previous result (a stream's first), and every region is reported as it is.
    reach : int
        Cells (Chebyshev distance) a region's cells may be from one of ``before``'s.

    Returns
    -------
    labels : ndarray of int32, shape (rows, cols)
        The confirmed regions' cells, relabelled ``1..m`` in the order of ``regions``.
    regions : list of Region
        The confirmed regions, in their order, with their new labels.
    """
    if before is None or not regions:
        return labels, regions
    if before.shape != labels.shape:
        raise ValueError(f"before: expected cells of shape {labels.shape}, got {before.shape}")
    size = 2 * max(int(reach), 0) + 1
    near = cv2.dilate(before.astype(np.uint8), np.ones((size, size), np.uint8)) > 0
    hit = np.zeros(len(regions) + 1, bool)
    hit[labels[near]] = True
    hit[0] = False
    relabel = np.zeros(len(regions) + 1, np.int32)
    kept = [r for r in regions if hit[r.label]]
    for i, r in enumerate(kept, start=1):
        relabel[r.label] = i
    return relabel[labels], [r._replace(label=i) for i, r in enumerate(kept, start=1)]
