"""What a detection returns: :class:`Detection` (unpacks as ``likelihood, mask``, as cv2's
results do), its cell-level :class:`Grid` and the constraint names of its per-term maps."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from .segment import Region

__all__ = ["CONSTRAINT_NAMES", "Detection", "Grid", "LazyMaps"]

#: The four constraints, in the order of ``Params.weights`` and of :attr:`Detection.maps`.
CONSTRAINT_NAMES = ("epipolar", "depth", "height", "antiparallel")


class Grid(NamedTuple):
    """Cell-level measurement of one detection (``rows x cols`` cells of ``size`` pixels) on the
    *previous* frame, where the flow starts.

    Attributes
    ----------
    size : int
    centres : ndarray, shape (rows, cols, 2)
        Pixel ``u`` of each cell centre in the previous frame.
    flow : ndarray, shape (rows, cols, 2)
        Mean flow of each cell; ``u' = u + flow``.
    likelihood : ndarray, shape (rows, cols)
        The frame pair's own likelihood (before any temporal filtering); NaN where the cell is
        not valid.
    valid : ndarray of bool, shape (rows, cols)
    """

    size: int
    centres: NDArray[np.float64]
    flow: NDArray[np.float64]
    likelihood: NDArray[np.float64]
    valid: NDArray[np.bool_]


class LazyMaps(Mapping):
    """Per-constraint full-resolution maps, made (``make(name)``) on first access: most callers
    never look at them."""

    def __init__(self, names: tuple[str, ...], make) -> None:
        self._names, self._make, self._done = names, make, {}

    def __getitem__(self, name: str) -> NDArray[np.float32]:
        if name not in self._names:
            raise KeyError(name)
        if name not in self._done:
            self._done[name] = self._make(name)
        return self._done[name]

    def __iter__(self):
        return iter(self._names)

    def __len__(self) -> int:
        return len(self._names)


@dataclass(frozen=True, eq=False)
class Detection:
    """Result of :func:`detect`; unpacks as ``likelihood, mask``.

    ``likelihood``, ``mask``, ``maps`` and ``regions`` are on the pixels of the *current* frame
    (``curr``, or the frame just passed to :meth:`MotionDetector.apply`), as with cv2's
    background subtractors: the flow is measured from the previous frame's cells and every cell
    is carried along its flow to where it lands now. ``flow`` and ``grid`` stay on the previous
    frame, where they were measured.

    Attributes
    ----------
    likelihood : ndarray of float32, shape (H, W)
        Motion likelihood; 0 outside the camera's valid region and at invalid cells.
    mask : ndarray of uint8, shape (H, W)
        255 on moving regions, else 0.
    maps : mapping of str to ndarray of float32, shape (H, W)
        Per-constraint deviations ``epipolar``, ``depth``, ``height``, ``antiparallel``
        (upsampled from the grid when first read).
    flow : ndarray of float32, shape (H, W, 2)
        The dense flow.
    grid : Grid
    regions : list of Region
    static_camera : bool
    cell_mask : ndarray of uint8, shape (H, W)
        255 on the regions' cells that the constraints flagged: without the cells the closing
        over small gaps filled in (``Params.region_gap``) and before the growth to the objects'
        extent (``Params.extent_reach``; :mod:`fisheyemotion.extent`), with the regions not yet
        confirmed by the frame before (``Params.confirm_reach``). The same as ``mask`` without
        the three. Pose estimation and refinement exclude it.
    """

    likelihood: NDArray[np.float32]
    mask: NDArray[np.uint8]
    maps: Mapping[str, NDArray[np.float32]] = field(repr=False)
    flow: NDArray[np.float32] = field(repr=False)
    grid: Grid = field(repr=False)
    regions: list[Region] = field(default_factory=list)
    static_camera: bool = False
    cell_mask: NDArray[np.uint8] | None = field(default=None, repr=False)

    def __post_init__(self) -> None:
        if self.cell_mask is None:
            object.__setattr__(self, "cell_mask", self.mask)

    def __iter__(self):
        return iter((self.likelihood, self.mask))

    def __len__(self) -> int:
        return 2

    def __getitem__(self, index: int):
        return (self.likelihood, self.mask)[index]
