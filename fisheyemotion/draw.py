"""Drawing for people: flow arrows, heat maps, the likelihood map, the segmentation overlay
(all BGR uint8, as cv2 apps show them) and the paper's Fig. 6 layout (matplotlib)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, NamedTuple

import cv2
import numpy as np
from numpy.typing import NDArray

from .detection import CONSTRAINT_NAMES, Detection

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


def truth_overlay(frame: NDArray[np.uint8], mask: NDArray[np.uint8],
                  truth: NDArray[np.bool_], *, alpha: float = 0.55) -> NDArray[np.uint8]:
    """Detections judged against ground truth on a copy of ``frame``: green where the mask is on
    a moving object (true), red where it is on static scene (false), blue where a moving object
    is missed.

    Parameters
    ----------
    frame : ndarray of uint8, shape (H, W) or (H, W, 3)
    mask : ndarray of uint8, shape (H, W)
        The detection mask (0/255).
    truth : ndarray of bool, shape (H, W)
        True on moving objects.
    """
    out = _bgr(frame)
    if mask.shape != out.shape[:2] or truth.shape != out.shape[:2]:
        raise ValueError(f"mask, truth: expected shape {out.shape[:2]}, got {mask.shape} and "
                         f"{truth.shape}")
    found = mask > 0
    for sel, color in ((found & truth, (0, 200, 0)), (found & ~truth, (0, 0, 255)),
                       (~found & truth, (255, 120, 0))):
        out[sel] = (out[sel] * (1 - alpha) + np.array(color) * alpha).astype(np.uint8)
    return out


class Fig6Column(NamedTuple):
    """One column of :func:`fig6`: the current frame, its detection, a title and, when known,
    the ground-truth moving pixels (bool, shape (H, W))."""

    frame: NDArray[np.uint8]
    detection: Detection
    title: str
    truth: NDArray[np.bool_] | None = None


ROW_TITLES = ("I flow", "II epipolar", "III positive\ndepth", "IV positive\nheight",
              "V anti-\nparallel", "VI likelihood", "VII detected")
TRUTH_TITLE = "ground\ntruth"
STILL_NOTE = "camera still:\nterm not used;\nVI is |p\u2032\u00d7p|"


def fig6(columns: Sequence[Fig6Column | tuple], *, saturation: float = 0.02,
         arrows: int = 14) -> Figure:
    """The paper's Fig. 6 for one or more frame pairs.

    Rows: I the grid-averaged flow (about ``arrows`` arrows across, from where each cell was in
    the previous frame to where it is now), II-V the four deviations and VI the likelihood (one
    colour scale, saturated at ``saturation`` like the paper's), VII the segmentation; with
    ground truth, a row of the moving objects before VII, and VII colours true detections green,
    false ones red and missed object pixels blue. Columns whose camera stood still say that rows
    II-V are not used there.

    Parameters
    ----------
    columns : sequence of Fig6Column or tuples (frame, detection, title[, truth])
    saturation : float
        Top of the colour scale, radians.
    arrows : int
        Arrows across the image in row I.
    """
    from matplotlib import colormaps
    from matplotlib.cm import ScalarMappable
    from matplotlib.colors import Normalize
    from matplotlib.figure import Figure

    cols = [Fig6Column(*c) for c in columns]
    n = len(cols)
    truth_row = any(col.truth is not None for col in cols)
    titles = ROW_TITLES[:6] + ((TRUTH_TITLE,) if truth_row else ()) + ROW_TITLES[6:]
    fig = Figure(figsize=(2.9 * n + 1.6, 2.3 * len(titles)), layout="constrained")
    axes = fig.subplots(len(titles), n, squeeze=False)
    for c, col in enumerate(cols):
        det = col.detection
        step = max(1, det.grid.centres.shape[1] // arrows)
        rows = [flow_arrows(col.frame, det, step=step)]
        rows += [heatmap(det.maps[name], vmax=saturation) for name in CONSTRAINT_NAMES]
        rows.append(likelihood_map(det, saturation=saturation))
        if truth_row:
            truth = np.zeros(det.mask.shape, bool) if col.truth is None else col.truth
            rows.append(overlay_mask(col.frame, truth.astype(np.uint8) * 255,
                                     color=(255, 120, 0)))
        rows.append(overlay_mask(col.frame, det.mask) if col.truth is None
                    else truth_overlay(col.frame, det.mask, col.truth))
        for r, img in enumerate(rows):
            ax = axes[r, c]
            ax.imshow(cv2.cvtColor(img, cv2.COLOR_BGR2RGB))
            ax.set_xticks([])
            ax.set_yticks([])
            if det.static_camera and 1 <= r <= 4:
                ax.text(0.5, 0.5, STILL_NOTE, transform=ax.transAxes, ha="center", va="center",
                        color="white", fontsize=11)
            if c == 0:
                ax.set_ylabel(titles[r], fontsize=14, rotation=0, ha="right", va="center")
            if r == 0:
                ax.set_title(col.title, fontsize=13)
    colorbar = fig.colorbar(ScalarMappable(Normalize(0, saturation), colormaps["inferno"]),
                            ax=axes[1:6, :].ravel().tolist(), shrink=0.6, aspect=40, pad=0.01)
    colorbar.set_label(f"deviation / likelihood (rad), saturated at {saturation:g}", fontsize=13)
    if any(col.truth is not None for col in cols):
        fig.supxlabel("ground truth: moving objects in blue; VII: green = detected on a moving "
                      "object, red = false detection on static scene, blue = missed object pixels",
                      fontsize=13)
    return fig
