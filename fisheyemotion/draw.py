"""Drawing for people: flow arrows, heat maps, the likelihood map, the segmentation overlay
(all BGR uint8, as cv2 apps show them) and the paper's Fig. 6 layout (matplotlib)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import cv2
import numpy as np
from numpy.typing import NDArray

from .detect import CONSTRAINT_NAMES, Detection

if TYPE_CHECKING:  # matplotlib is imported when a figure is drawn, not with the package
    from matplotlib.figure import Figure


def _bgr(frame: NDArray[np.uint8]) -> NDArray[np.uint8]:
    if frame.dtype != np.uint8:
        raise ValueError(f"frame: expected dtype uint8, got {frame.dtype}")
    if frame.ndim == 2:
        return cv2.cvtColor(frame, cv2.COLOR_GRAY2BGR)
    if frame.ndim == 3 and frame.shape[2] == 3:
        return frame.copy()
    raise ValueError(f"frame: expected shape (H, W) or (H, W, 3), got {frame.shape}")


def flow_arrows(frame: NDArray[np.uint8], detection: Detection, *, step: int = 4,
                scale: float = 1.0, color: tuple[int, int, int] = (0, 255, 255)) -> NDArray[np.uint8]:
    """Grid-averaged flow as arrows (every ``step``-th cell) on a copy of ``frame``."""
    out = _bgr(frame)
    g = detection.grid
    for r in range(0, g.centres.shape[0], step):
        for c in range(0, g.centres.shape[1], step):
            if not g.valid[r, c]:
                continue
            u = g.centres[r, c]
            v = u + scale * g.flow[r, c]
            cv2.arrowedLine(out, (int(round(u[0])), int(round(u[1]))),
                            (int(round(v[0])), int(round(v[1]))), color, 1, cv2.LINE_AA,
                            tipLength=0.3)
    return out


def heatmap(values: NDArray, *, vmax: float, colormap: int = cv2.COLORMAP_INFERNO,
            valid: NDArray[np.bool_] | None = None) -> NDArray[np.uint8]:
    """``values`` in ``[0, vmax]`` as a colour map (saturated above ``vmax``); black where not
    ``valid``."""
    if vmax <= 0:
        raise ValueError(f"vmax: expected > 0, got {vmax}")
    scaled = np.clip(np.nan_to_num(values, nan=0.0) / vmax, 0, 1)
    out = cv2.applyColorMap((scaled * 255).astype(np.uint8), colormap)
    if valid is not None:
        out[~valid] = 0
    return out


def likelihood_map(detection: Detection, *, saturation: float = 0.02) -> NDArray[np.uint8]:
    """The motion likelihood, saturated at ``saturation`` (paper: 0.02)."""
    return heatmap(detection.likelihood, vmax=saturation)


def overlay_mask(frame: NDArray[np.uint8], mask: NDArray[np.uint8], *,
                 color: tuple[int, int, int] = (0, 255, 0), alpha: float = 0.5) -> NDArray[np.uint8]:
    """``mask`` (uint8 0/255) blended in ``color`` over a copy of ``frame``."""
    out = _bgr(frame)
    sel = mask > 0
    out[sel] = (out[sel] * (1 - alpha) + np.array(color) * alpha).astype(np.uint8)
    return out


def annotate(frame: NDArray[np.uint8], detection: Detection) -> NDArray[np.uint8]:
    """Segmentation overlay with region boxes and their mean likelihood."""
    out = overlay_mask(frame, detection.mask)
    for r in detection.regions:
        x, y, w, h = r.bbox
        cv2.rectangle(out, (x, y), (x + w - 1, y + h - 1), (0, 255, 0), 1)
        cv2.putText(out, f"{r.mean_likelihood:.3f}", (x, max(10, y - 3)),
                    cv2.FONT_HERSHEY_SIMPLEX, 0.35, (0, 255, 0), 1, cv2.LINE_AA)
    return out


ROW_TITLES = ("I flow", "II epipolar", "III positive depth", "IV positive height",
              "V anti-parallel", "VI likelihood", "VII segmentation")


def fig6(columns: Sequence[tuple[NDArray[np.uint8], Detection, str]], *,
         saturation: float = 0.02) -> Figure:
    """The paper's Fig. 6: rows I-VII (flow, the four deviations, likelihood, segmentation) for
    one or more frame pairs ``(frame, detection, title)``."""
    n = len(columns)
    from matplotlib.figure import Figure

    fig = Figure(figsize=(3.2 * n, 2.4 * 7), layout="constrained")
    axes = fig.subplots(7, n, squeeze=False)
    for c, (frame, det, title) in enumerate(columns):
        rows = [flow_arrows(frame, det)]
        rows += [heatmap(det.maps[name], vmax=saturation) for name in CONSTRAINT_NAMES]
        rows += [likelihood_map(det, saturation=saturation), overlay_mask(frame, det.mask)]
        for r, img in enumerate(rows):
            ax = axes[r, c]
            ax.imshow(cv2.cvtColor(img, cv2.COLOR_BGR2RGB))
            ax.set_xticks([])
            ax.set_yticks([])
            if c == 0:
                ax.set_ylabel(ROW_TITLES[r], fontsize=9)
            if r == 0:
                ax.set_title(title, fontsize=10)
    return fig
