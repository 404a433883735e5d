"""Per-frame metrics against exact ground truth, as the paper defines them (Table 2).

Definitions
-----------
- An object counts in a frame if it is moving, visible, and within ``range_limit`` metres
  (paper: 8 m) of the camera.
- **detected**: the predicted mask covers any of its pixels (the paper's "any coverage"), or at
  least ``min_coverage`` of them when that is set above 0.
- **coverage**: the covered fraction of its pixels.
- **detection rate** (per category): the share of counted object-frames in which the object is
  detected. **coverage rate**: the mean coverage over the detected object-frames.
- **false-positive frame**: a frame with a predicted region (8-connected component of the mask)
  that touches no moving object. **static flagged**: the fraction of valid static pixels
  predicted moving. The paper reports 13 % and 2 %. Those pixels lie either in false regions
  (``fp_px_alone``) or around a detected object, in a region that touches it (the rest of
  ``fp_px``): a false alarm, or an object's mask reaching beyond it.
- Pixel **IoU**, **precision**, **recall** of the moving class (WoodScape's convention).
"""

from __future__ import annotations

import numpy as np
import pandas as pd
from numpy.typing import NDArray
from skimage.measure import label

PAPER_TABLE2 = pd.DataFrame(
    [("crossing", 3848, 0.72, 0.64), ("overtaking", 2757, 0.98, 0.81),
     ("preceding", 789, 0.48, 0.30), ("approaching", 224, 0.89, 0.42),
     ("static", 475, 0.95, 0.78), ("false positives", 5000, 0.13, 0.02)],
    columns=["category", "frames", "detection_rate", "coverage_rate"],
)
CATEGORY_ORDER = ("crossing", "overtaking", "preceding", "approaching", "static")


def object_metrics(pred: NDArray, ids: NDArray, objects: pd.DataFrame, *,
                   range_limit: float = 8.0, min_coverage: float = 0.0) -> list[dict]:
    """One row per counted object of a frame.

    Parameters
    ----------
    pred : ndarray, shape (H, W)
        Predicted mask (non-zero = moving).
    ids : ndarray of int, shape (H, W)
        Ground-truth object ids.
    objects : DataFrame
        The frame's rows of ``objects.csv`` (id, category, moving, distance, visible_pixels).
    """
    rows = []
    moving = pred > 0
    for obj in objects.itertuples(index=False):
        if not bool(obj.moving) or obj.visible_pixels <= 0 or obj.distance > range_limit:
            continue
        pix = ids == obj.id
        n = int(pix.sum())
        if n == 0:
            continue
        covered = int(moving[pix].sum())
        coverage = covered / n
        detected = coverage >= min_coverage if min_coverage > 0 else covered > 0
        rows.append({"id": int(obj.id), "category": obj.category, "distance": float(obj.distance),
                     "pixels": n, "covered": covered, "coverage": coverage,
                     "detected": bool(detected)})
    return rows


def frame_metrics(pred: NDArray, moving_gt: NDArray, valid: NDArray) -> dict:
    """False-positive and pixel metrics of one frame (see the module docstring)."""
    p = (pred > 0) & valid
    g = (moving_gt > 0) & valid
    static = valid & ~g
    labels = label(p, connectivity=2)
    n_regions = int(labels.max())
    touching = np.unique(labels[p & g])
    touching = touching[touching > 0]
    fp_regions = n_regions - len(touching)
    tp, fp, fn = int((p & g).sum()), int((p & ~g).sum()), int((~p & g).sum())
    alone = int((p & ~np.isin(labels, touching)).sum())  # static: no region there touches g
    return {
        "regions": n_regions,
        "fp_regions": fp_regions,
        "fp_frame": fp_regions > 0,
        "static_flagged": fp / max(int(static.sum()), 1),
        "tp_px": tp, "fp_px": fp, "fn_px": fn, "fp_px_alone": alone,
        "iou": tp / (tp + fp + fn) if tp + fp + fn else np.nan,
        "precision": tp / (tp + fp) if tp + fp else np.nan,
        "recall": tp / (tp + fn) if tp + fn else np.nan,
    }


#: Surfaces false-positive pixels are broken down by (``objects.csv`` kinds; id 0 is the road and
#: the ground beside it, anything else static is ``other``).
SURFACES = ("road", "building", "wall", "parked_car", "pole", "other")


def false_positive_surfaces(pred: NDArray, moving_gt: NDArray, valid: NDArray, ids: NDArray,
                            kinds: dict[int, str]) -> dict[str, int]:
    """False-positive pixels of one frame per surface they lie on (:data:`SURFACES`)."""
    fp = (pred > 0) & valid & ~(moving_gt > 0)
    counts = np.bincount(ids[fp].ravel().astype(np.int64))
    out = dict.fromkeys(SURFACES, 0)
    for i in np.flatnonzero(counts):
        kind = "road" if i == 0 else kinds.get(int(i), "other")
        out[kind if kind in out else "other"] += int(counts[i])
    return out


def table2(objects: pd.DataFrame, frames: pd.DataFrame) -> pd.DataFrame:
    """Table 2 of the paper from the tidy per-object and per-frame tables.

    ``frames`` for a category is the number of counted object-frames; the last row gives the
    false-positive frame share and the mean static flagged fraction over all frames.
    """
    rows = []
    for cat in CATEGORY_ORDER:
        sel = objects[objects.category == cat] if len(objects) else objects
        n = len(sel)
        det = sel[sel.detected] if n else sel
        rows.append({"category": cat, "frames": n,
                     "detection_rate": float(sel.detected.mean()) if n else np.nan,
                     "coverage_rate": float(det.coverage.mean()) if len(det) else np.nan})
    n = len(frames)
    rows.append({"category": "false positives", "frames": n,
                 "detection_rate": float(frames.fp_frame.mean()) if n else np.nan,
                 "coverage_rate": float(frames.static_flagged.mean()) if n else np.nan})
    return pd.DataFrame(rows)


def pixel_scores(frames: pd.DataFrame) -> dict:
    """IoU, precision and recall of the moving class over all pixels of all frames."""
    tp, fp, fn = (int(frames[c].sum()) for c in ("tp_px", "fp_px", "fn_px"))
    return {"iou": tp / (tp + fp + fn) if tp + fp + fn else np.nan,
            "precision": tp / (tp + fp) if tp + fp else np.nan,
            "recall": tp / (tp + fn) if tp + fn else np.nan}


#: Likelihood thresholds for the PR/ROC sweep (log-spaced).
SWEEP_THRESHOLDS = np.concatenate([[0.0], np.logspace(-5, 0, 101)])


def likelihood_histograms(likelihood: NDArray, moving_gt: NDArray,
                          valid: NDArray) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Counts of moving and static valid pixels above each of :data:`SWEEP_THRESHOLDS`."""
    lik = likelihood[valid]
    g = moving_gt[valid] > 0
    edges = SWEEP_THRESHOLDS

    def above(values):
        srt = np.sort(values)
        return len(srt) - np.searchsorted(srt, edges, side="right")

    return above(lik[g]), above(lik[~g])


def sweep(moving_above: NDArray, static_above: NDArray, n_moving: int,
          n_static: int) -> pd.DataFrame:
    """PR and ROC points from accumulated counts above each threshold."""
    tp = moving_above.astype(float)
    fp = static_above.astype(float)
    with np.errstate(invalid="ignore", divide="ignore"):
        precision = np.where(tp + fp > 0, tp / (tp + fp), np.nan)
        recall = tp / max(n_moving, 1)
        fpr = fp / max(n_static, 1)
    return pd.DataFrame({"threshold": SWEEP_THRESHOLDS, "precision": precision, "recall": recall,
                         "fpr": fpr})
