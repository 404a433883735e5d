"""Metrics on hand-made masks with known answers, and end-to-end runs on rendered sequences."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from fisheyemotion.eval import (
    combine,
    evaluate,
    evaluate_sequence,
    frame_metrics,
    object_metrics,
    table2,
    write_report,
)
from fisheyemotion.eval.cli import run_eval

import fisheyemotion as fm
from fisheyemotion import synth

from .cameras import tumvi_kb


def _objects(rows):
    return pd.DataFrame(rows, columns=["frame", "id", "kind", "category", "moving", "distance",
                                       "visible_pixels"])


def _scene():
    ids = np.zeros((20, 30), np.uint16)
    ids[2:6, 2:6] = 1  # 16 px, moving, near
    ids[10:14, 10:20] = 2  # 40 px, moving, near
    ids[15:19, 25:29] = 3  # 16 px, moving, far (beyond the range limit)
    ids[0:2, 20:30] = 7  # static building
    objects = _objects([
        (0, 1, "pedestrian", "crossing", True, 5.0, 16),
        (0, 2, "car", "overtaking", True, 7.9, 40),
        (0, 3, "car", "approaching", True, 12.0, 16),
        (0, 7, "building", "static", False, 15.0, 20),
        (0, 9, "car", "preceding", True, 4.0, 0),  # off-image this frame
    ])
    return ids, objects


def test_detected_missed_coverage_and_range_filter():
    ids, objects = _scene()
    pred = np.zeros_like(ids, np.uint8)
    pred[2:4, 2:6] = 255  # half of object 1
    pred[18, 28] = 255  # one pixel of the far object 3
    rows = {r["id"]: r for r in object_metrics(pred, ids, objects)}
    assert set(rows) == {1, 2}  # 3 is beyond 8 m, 9 is not visible, 7 is static
    assert rows[1]["detected"] and rows[1]["coverage"] == 0.5
    assert not rows[2]["detected"] and rows[2]["coverage"] == 0.0
    strict = {r["id"]: r for r in object_metrics(pred, ids, objects, min_coverage=0.6)}
    assert not strict[1]["detected"]
    far = {r["id"]: r for r in object_metrics(pred, ids, objects, range_limit=20)}
    assert far[3]["detected"] and far[3]["coverage"] == 1 / 16


def test_false_positive_frame_and_pixel_scores():
    ids, _ = _scene()
    moving = np.isin(ids, [1, 2, 3]).astype(np.uint8) * 255
    valid = np.ones(ids.shape, bool)
    pred = np.zeros_like(moving)
    pred[2:6, 2:8] = 255  # object 1 plus 8 static pixels, touching it: not a FP region
    m = frame_metrics(pred, moving, valid)
    assert m["regions"] == 1 and not m["fp_frame"]
    assert m["tp_px"] == 16 and m["fp_px"] == 8 and m["fn_px"] == 56
    assert m["iou"] == pytest.approx(16 / 80) and m["precision"] == pytest.approx(16 / 24)
    assert m["static_flagged"] == pytest.approx(8 / (600 - 72))
    assert m["fp_px_alone"] == 0  # its 8 static pixels lie around the object it touches
    pred[8, 0] = 255  # a region touching no moving object
    m = frame_metrics(pred, moving, valid)
    assert m["fp_frame"] and m["fp_regions"] == 1
    assert m["fp_px"] == 9 and m["fp_px_alone"] == 1


def test_edge_cases_empty_and_invalid():
    ids, objects = _scene()
    empty = np.zeros_like(ids, np.uint8)
    rows = object_metrics(empty, ids, objects)
    assert all(not r["detected"] for r in rows)
    m = frame_metrics(empty, np.zeros_like(empty), np.ones(ids.shape, bool))
    assert m["regions"] == 0 and not m["fp_frame"] and np.isnan(m["iou"])
    none_valid = frame_metrics(np.full_like(empty, 255), empty, np.zeros(ids.shape, bool))
    assert none_valid["regions"] == 0 and none_valid["static_flagged"] == 0
    assert object_metrics(empty, ids, objects.iloc[0:0]) == []
    t = table2(pd.DataFrame(columns=["category", "detected", "coverage"]),
               pd.DataFrame({"fp_frame": [True, False], "static_flagged": [0.1, 0.0]}))
    assert np.isnan(t.set_index("category").loc["crossing", "detection_rate"])
    assert t.set_index("category").loc["false positives", "detection_rate"] == 0.5


def test_table2_definitions():
    objs = pd.DataFrame({"category": ["crossing"] * 4 + ["static"],
                         "detected": [True, True, False, True, False],
                         "coverage": [0.5, 0.7, 0.0, 0.3, 0.0]})
    frames = pd.DataFrame({"fp_frame": [False, True, False, False],
                           "static_flagged": [0.0, 0.04, 0.0, 0.0]})
    t = table2(objs, frames).set_index("category")
    assert t.loc["crossing", "frames"] == 4
    assert t.loc["crossing", "detection_rate"] == 0.75
    assert t.loc["crossing", "coverage_rate"] == pytest.approx(0.5)  # over detections only
    assert t.loc["static", "detection_rate"] == 0.0
    assert t.loc["false positives", "coverage_rate"] == pytest.approx(0.01)


CAM = tumvi_kb(320, 240, 100.0)
FAST = fm.Params(flow="dis", dis_preset="fast", flow_prior="ego", fb_check=True, frame_gap=2,
                 grid=4, min_area=48)


@pytest.fixture(scope="module")
def sequences(tmp_path_factory):
    root = tmp_path_factory.mktemp("seqs")
    crossing = synth.parse_scenario({
        "name": "near_crossing", "frames": 8, "ego": {"speed_kmh": 10},
        "camera": {"position": [2, 0, 0.9], "pitch_deg": 15},
        "objects": [{"id": 1, "kind": "car", "category": "crossing", "start": [8, -4],
                     "heading_deg": 90, "speed_kmh": 15}]})
    world = synth.load_scenario("static_world")
    return [synth.write_sequence(root / sc.name, CAM, sc, frames=8, flow=False, progress=False,
                                 supersample=1) for sc in (crossing, world)]


def assert_well_formed(page: str) -> None:
    """Every element closed in order (void elements excepted), one html/head/body."""
    from html.parser import HTMLParser

    void = {"meta", "img", "br", "hr", "link", "input"}

    class Checker(HTMLParser):
        def __init__(self):
            super().__init__()
            self.stack, self.seen = [], []

        def handle_starttag(self, tag, attrs):
            self.seen.append(tag)
            if tag not in void:
                self.stack.append(tag)

        def handle_endtag(self, tag):
            assert self.stack and self.stack[-1] == tag, f"</{tag}> closes <{self.stack[-1:]}>"
            self.stack.pop()

    checker = Checker()
    checker.feed(page)
    checker.close()
    assert page.startswith("<!doctype html>") and checker.stack == []
    assert [checker.seen.count(t) for t in ("html", "head", "body", "title")] == [1, 1, 1, 1]


def test_end_to_end_report(sequences, tmp_path):
    results, report = run_eval(sequences, FAST, ["dis", "farneback"], tmp_path / "report",
                               workers=1, scheduler=None, progress=False)
    assert report.exists() and (tmp_path / "report" / "report.md").exists()
    for name in ("table2.csv", "objects.csv", "frames.csv", "ablation.csv", "pr.csv",
                 "table2.png", "pr.png", "scenes.png", "fig6.png"):
        assert (tmp_path / "report" / name).exists(), name
    html = report.read_text()
    assert "data:image/png;base64," in html and "<img src=\"" not in html
    assert_well_formed(html)
    # The HTML says everything report.md says: every heading, every table, every figure.
    md = (tmp_path / "report" / "report.md").read_text()
    import re

    for heading in re.findall(r"^#+ (.+)$", md, re.M):
        assert heading in html, heading
    assert html.count("<table") == len(re.findall(r"^\|[-:| ]+\|$", md, re.M))
    table_rows = [ln for ln in md.splitlines() if ln.startswith("|")]
    separators = [ln for ln in table_rows if re.fullmatch(r"\|[-:| ]+\|", ln)]
    assert html.count("<tr>") == len(table_rows) - len(separators)  # one <tr> per row
    figures = re.findall(r"^!\[(.+)\]\(([^)]+)\)$", md, re.M)
    assert len(figures) >= 4 and html.count("<figcaption>") == len(figures)
    for caption, name in figures:  # every figure exists, is embedded and has its caption
        assert f'alt="{name}"' in html and (tmp_path / "report" / name).exists()
        assert caption.split(".")[0] in html and caption.split(".")[0].startswith("Figure")
    assert "src=\"http" not in html and "href=\"http" not in html  # self-contained
    wide = pd.read_csv(tmp_path / "report" / "table2.csv")
    assert list(wide.category) == ["crossing", "overtaking", "preceding", "approaching",
                                   "static", "false positives"]
    crossing = wide.set_index("category").loc["crossing"]
    assert crossing.dis_frames >= 4 and crossing.dis_detection > 0.5
    assert wide.set_index("category").loc["false positives", "dis_frames"] == 12
    abl = pd.read_csv(tmp_path / "report" / "ablation.csv")
    assert {"epipolar only", "depth only", "height only", "antiparallel only"} <= set(abl.variant)
    # Detection by visible size: every counted object-frame in exactly one size class, and each
    # class's share detected as the object rows say.
    objs = pd.read_csv(tmp_path / "report" / "objects.csv")
    sizes = pd.read_csv(tmp_path / "report" / "sizes.csv")
    counted = sizes.groupby(["flow", "category"])["object-frames"].sum()
    assert counted[counted > 0].to_dict() == objs.groupby(["flow", "category"]).size().to_dict()
    for r in sizes[sizes["object-frames"] > 0].itertuples(index=False):
        lo, hi = (int(v) for v in re.findall(r"\d+", r.size)) if "-" in r.size else (
            int(re.findall(r"\d+", r.size)[0]), np.inf)
        hi = hi + 1 if np.isfinite(hi) else hi
        here = objs[(objs.flow == r.flow) & (objs.category == r.category)
                    & (objs.pixels >= lo) & (objs.pixels < hi)]
        assert len(here) == r[3] and here.detected.mean() == pytest.approx(r.detected)
    assert "## Detection by visible size" in md


def test_the_exact_flow_is_reported_beside_a_flow_method(sequences, tmp_path):
    """``--flow farneback,exact``: the rendered scenes' exact flow is one more row of every
    table, labelled ``exact``, with the figures of ``evaluate(..., exact_flow=True)``."""
    results, _ = run_eval(sequences, FAST, ["farneback", "exact"], tmp_path / "report",
                          workers=1, scheduler=None, progress=False)
    assert [r.flow for r in results] == ["farneback", "farneback", "exact", "exact"]
    direct = evaluate(sequences, FAST, workers=1, progress=False, exact_flow=True)
    for ours, theirs in zip(results[2:], direct, strict=True):
        pd.testing.assert_frame_equal(ours.frames, theirs.frames)
        pd.testing.assert_frame_equal(ours.objects, theirs.objects)
    assert not results[0].frames.equals(results[2].frames)  # not the flow method's run again
    for name in ("groups.csv", "false_positives.csv"):  # in the order asked, group by group
        flows = pd.read_csv(tmp_path / "report" / name).flow
        assert list(flows) == ["farneback", "exact"] * (len(flows) // 2)
    wide = pd.read_csv(tmp_path / "report" / "table2.csv")
    assert {"farneback_detection", "exact_detection"} <= set(wide.columns)


def test_the_exact_flow_of_a_sequence_without_its_scenario_is_one_clear_error(
        sequences, tmp_path, capsys):
    import shutil

    from fisheyemotion.cli import main

    seq = tmp_path / "no_scenario"
    shutil.copytree(sequences[0], seq)
    (seq / "scenario.yaml").unlink()
    out = tmp_path / "report"
    assert main(["eval", str(seq), "--flow", "exact", "--out", str(out), "--workers", "1",
                 "--quiet"]) != 0
    err = capsys.readouterr().err
    assert "scenario.yaml" in err and "Traceback" not in err
    assert not out.exists()  # no half-written report
    assert main(["eval", str(seq), "--flow", "farneback,optical", "--out", str(out),
                 "--quiet"]) != 0
    assert "--flow: expected a comma-separated list of farneback, dis, exact" in \
        capsys.readouterr().err


@pytest.mark.parametrize("params", [FAST, fm.Params(flow="dis", dis_preset="fast", grid=4,
                                                     min_area=48)],
                         ids=["gap2-fb", "defaults-gap3"])
def test_the_evaluation_scores_the_masks_a_users_stream_returns(sequences, params, monkeypatch):
    """``evaluate_sequence`` runs the detector as ``MotionDetector.apply`` does (the scene
    model's bootstrap from the frames between the first pair's included): the masks it scores
    are, to the bit, those a user streaming the same frames and poses gets."""
    import importlib

    from fisheyemotion.sequence import Sequence

    module = importlib.import_module("fisheyemotion.eval.evaluate")
    scored = []
    metrics = module.object_metrics

    def recording(mask, *args, **kwargs):
        scored.append(mask.copy())
        return metrics(mask, *args, **kwargs)

    monkeypatch.setattr(module, "object_metrics", recording)
    path = sequences[1]  # parked cars and poles beside the road from the first frame
    evaluate_sequence(path, params, ablation=False)
    seq = Sequence(path)
    det = fm.MotionDetector(seq.camera, fm.Road(), params=params, roi=seq.roi())
    streamed = [r.mask for r in (det.apply(seq.frame(k), seq.poses[k]) for k in range(len(seq)))
                if r is not None]
    assert len(scored) == len(streamed) == len(seq) - params.frame_gap
    for a, b in zip(scored, streamed, strict=True):
        np.testing.assert_array_equal(a, b)


def test_process_pool_equals_serial(sequences):
    serial = evaluate(sequences, FAST, workers=1, progress=False, ablation=False)
    pooled = evaluate(sequences, FAST, workers=2, progress=False, ablation=False)
    for a, b in zip(serial, pooled, strict=True):
        pd.testing.assert_frame_equal(a.objects, b.objects)
        pd.testing.assert_frame_equal(a.frames, b.frames)


def test_dask_local_cluster_equals_serial(sequences):
    distributed = pytest.importorskip("dask.distributed")
    serial = evaluate(sequences, FAST, workers=1, progress=False, ablation=False)
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  host="127.0.0.1", dashboard_address=None) as cluster:
        remote = evaluate(sequences, FAST, scheduler=cluster.scheduler_address, progress=False,
                          ablation=False)
    for a, b in zip(serial, remote, strict=True):
        pd.testing.assert_frame_equal(a.objects, b.objects)
        pd.testing.assert_frame_equal(a.frames, b.frames)
        np.testing.assert_array_equal(a.moving_above, b.moving_above)


def test_missing_sequence_folder_is_a_value_error(tmp_path):
    from fisheyemotion.eval.evaluate import sequence_paths

    with pytest.raises(ValueError, match="no such sequence"):
        sequence_paths([tmp_path / "nope"])
    with pytest.raises(ValueError, match="frames"):
        evaluate_sequence(tmp_path)


def test_combine_adds_the_flow_column(sequences):
    res = evaluate(sequences[:1], FAST, workers=1, progress=False, ablation=False)
    tables = combine(res)
    assert (tables["frames"].flow == "dis").all()
    write_report(res, sequences[0].parent / "r", FAST)


def test_compare_models_side_by_side(tmp_path):
    from fisheyemotion.calib.fit import fit_model
    from fisheyemotion.eval.compare import compare

    kb = tumvi_kb(160, 120, 50.0)
    ds, rms = fit_model(kb, "double_sphere")
    assert rms < 1.0 and ds.width == 160
    params = fm.Params(flow="dis", dis_preset="fast", frame_gap=1, grid=4, min_area=16)
    out = compare([("kb", kb), ("ds", ds)], ["crossing"], tmp_path, params=params, frames=3,
                  workers=1, progress=False)
    table = pd.read_csv(tmp_path / "compare.csv")
    assert set(table.camera) == {"kb", "ds"} and (table.round_trip_px < 1e-6).all()
    fits = pd.read_csv(tmp_path / "fits.csv")
    assert set(fits.fitted_model) == {"kannala_brandt", "double_sphere"}
    assert (fits.rms_px < 1.0).all()
    assert out.exists() and "base64" in out.read_text()


# Some additions alone (the frame gap without the warp) flood the image: the warning is right.
@pytest.mark.filterwarnings("ignore:detection. more than:UserWarning")
def test_additions_table_has_each_addition_and_the_defaults(sequences):
    from fisheyemotion.eval.evaluate import ADDITIONS, additions_table

    table, scenes = additions_table(sequences[:1], ["dis"], workers=1, progress=False,
                                    by_sequence=True)
    assert len(scenes) == len(table) and set(scenes.sequence) == {Path(sequences[0]).name}
    # One sequence: its row is the aggregate row.
    np.testing.assert_allclose(scenes.fp_frames, table["false positives det"])
    np.testing.assert_allclose(scenes.iou, table.iou)
    assert list(table.variant) == list(ADDITIONS) + ["all (defaults)", "all, exact flow"]
    assert list(table.flow) == ["dis"] * (len(ADDITIONS) + 1) + ["exact"]
    assert {"crossing det", "false positives cov", "iou"} <= set(table.columns)
    # With exact correspondences no static road pixel is flagged: what remains is geometry.
    exact = table.set_index("variant").loc["all, exact flow"]
    assert exact["iou"] >= table.set_index("variant").loc["all (defaults)", "iou"]
    paper = table.set_index("variant").loc["paper"]
    defaults = table.set_index("variant").loc["all (defaults)"]
    assert defaults["false positives cov"] <= paper["false positives cov"]


def test_dask_workers_get_glibc_malloc_thresholds_back():
    import platform

    from fisheyemotion.eval.evaluate import restore_malloc_thresholds

    if platform.libc_ver()[0] != "glibc":
        pytest.skip("not glibc")
    assert restore_malloc_thresholds() is True


def test_size_table_and_the_shortfall_notes_count_small_objects():
    """Hand-made object rows: the size classes split them at 500 / 1000 / 2000 pixels, and the
    note on a category below the paper's rate counts its missed object-frames under 1000 px."""
    from fisheyemotion.eval.evaluate import SequenceResult
    from fisheyemotion.eval.report import diagnose, size_table

    pixels = [100, 499, 500, 999, 1000, 1999, 2000, 5000]
    detected = [False, False, True, False, False, True, True, True]
    objects = pd.DataFrame({"id": 1, "category": "crossing", "distance": 5.0, "pixels": pixels,
                            "covered": 0, "coverage": 0.5, "detected": detected,
                            "sequence": "s", "frame": range(8), "c_epipolar": 0.001,
                            "c_depth": 0.0, "c_height": 0.0, "c_antiparallel": 0.0})
    frames = pd.DataFrame({"fp_frame": [False] * 8, "static_flagged": [0.0] * 8,
                           "sequence": "s", "frame": range(8)})
    result = SequenceResult("s", "farneback", objects, frames, np.zeros(10), np.zeros(10), 1, 1)
    sizes = size_table([result]).set_index(["category", "size"])
    crossing = sizes.loc["crossing"]
    assert list(crossing["object-frames"]) == [2, 2, 2, 2]
    assert list(crossing.detected) == [0.0, 0.5, 0.5, 1.0]
    assert sizes.loc["preceding", "object-frames"].sum() == 0
    notes = diagnose([result], fm.Params())
    crossing_note = [n for n in notes if "crossing objects" in n]
    assert len(crossing_note) == 1 and "3 of its 4 missed object-frames are under 1000" in (
        crossing_note[0])
