"""Evaluation: metrics against exact ground truth, Table 2, sweeps, ablation and reports."""

from .evaluate import ABLATION_WEIGHTS, SequenceResult, combine, evaluate, evaluate_sequence
from .metrics import PAPER_TABLE2, frame_metrics, object_metrics, pixel_scores, sweep, table2
from .report import write_report

__all__ = ["ABLATION_WEIGHTS", "PAPER_TABLE2", "SequenceResult", "combine", "evaluate",
           "evaluate_sequence", "frame_metrics", "object_metrics", "pixel_scores", "sweep",
           "table2", "write_report"]
