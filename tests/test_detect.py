"""detect(), MotionDetector, drawing and the detect CLI on rendered scenes with exact truth."""

from __future__ import annotations

import os

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import fisheyemotion as fm
from fisheyemotion import draw, synth
from fisheyemotion.cli import main

from .cameras import tumvi_kb

CAM = tumvi_kb(640, 480, 200.0)
PAIR = synth.parse_scenario({
    "name": "pair", "frames": 3, "ego": {"speed_kmh": 5},
    "camera": {"position": [2, 0, 1.0], "pitch_deg": 15},
    "objects": [{"id": 1, "kind": "car", "category": "crossing", "start": [9, -5],
                 "heading_deg": 90, "speed_kmh": 15}],
})


@pytest.fixture(scope="module")
def pair():
    return synth.render_frames(CAM, PAIR)


def test_detect_finds_the_crossing_box_and_little_else(pair):
    f0, f1 = pair[0], pair[1]
    likelihood, mask = fm.detect(f0.image, f1.image, f0.pose, f1.pose, camera=CAM)
    assert likelihood.dtype == np.float32 and likelihood.shape == (480, 640)
    assert mask.dtype == np.uint8 and set(np.unique(mask)) <= {0, 255}
    moving = f0.moving > 0
    static = ~moving & CAM.valid_pixel_mask()
    assert (mask[moving] > 0).mean() > 0.8
    assert (mask[static] > 0).mean() < 0.05
    assert np.median(likelihood[moving]) > 5 * np.median(likelihood[static])


def test_detection_carries_maps_flow_grid_and_regions(pair):
    f0, f1 = pair[0], pair[1]
    det = fm.detect(f0.image, f1.image, f0.pose, f1.pose, camera=CAM)
    assert set(det.maps) == {"epipolar", "depth", "height", "antiparallel"}
    assert det.flow.shape == (480, 640, 2) and det.grid.size == 5
    assert det.grid.centres.shape == (96, 128, 2)
    big = det.regions[0]
    x, y, w, h = big.bbox
    ys, xs = np.nonzero(f0.moving)
    assert x <= np.median(xs) <= x + w and y <= np.median(ys) <= y + h
    # The crossing car is seen by the epipolar constraint.
    static = (f0.moving == 0) & CAM.valid_pixel_mask()
    epi = det.maps["epipolar"]
    assert np.median(epi[f0.moving > 0]) > 10 * np.median(epi[static])
    likelihood, mask = det
    assert likelihood is det.likelihood and det[1] is mask and len(det) == 2


def test_outside_the_valid_circle_is_zero():
    # Double sphere with alpha > 0.5: the valid region is a disk of radius fx / sqrt(2 alpha - 1).
    wide = fm.calib.DoubleSphere(fx=60, fy=60, cx=159.5, cy=119.5, xi=-0.2, alpha=0.7,
                                 width=320, height=240)
    frames = synth.render_frames(wide, PAIR, frames=2, supersample=1)
    assert not wide.valid_pixel_mask().all()
    lik, mask = fm.detect(frames[0].image, frames[1].image, frames[0].pose, frames[1].pose,
                          camera=wide)
    outside = ~wide.valid_pixel_mask()
    assert np.all(lik[outside] == 0) and np.all(mask[outside] == 0)
    assert np.all(frames[1].image[outside] == 0)


def test_ground_truth_flow_gives_a_clean_static_scene(pair):
    f0, f1 = pair[0], pair[1]
    roi = synth.Renderer(CAM, PAIR).roi()
    assert 0 < (roi == 0).mean() < 0.5  # the vehicle's own body is outside the ROI
    det = fm.MotionDetector(CAM, roi=roi).detect_flow(np.nan_to_num(f1.flow), f0.pose, f1.pose)
    assert np.all(det.likelihood[roi == 0] == 0) and np.all(det.mask[roi == 0] == 0)
    static = (f0.moving == 0) & (roi > 0)
    assert np.percentile(det.likelihood[static], 99) < 1e-3
    assert (det.mask[f0.moving > 0] > 0).mean() > 0.9


def test_streaming_apply_matches_detect_and_starts_with_none(pair):
    params = fm.Params(flow="dis", dis_preset="fast", frame_gap=1)
    det = fm.MotionDetector(CAM, params=params)
    assert det.apply(pair[0].image, pair[0].pose) is None
    streamed = det.apply(pair[1].image, pair[1].pose)
    direct = fm.MotionDetector(CAM, params=params).detect(
        pair[0].image, pair[1].image, pair[0].pose, pair[1].pose)
    np.testing.assert_array_equal(streamed.mask, direct.mask)


def test_gray_and_bgr_frames_give_the_same_result(pair):
    f0, f1 = pair[0], pair[1]
    g0, g1 = (cv2.cvtColor(f.image, cv2.COLOR_BGR2GRAY) for f in (f0, f1))
    a = fm.detect(f0.image, f1.image, f0.pose, f1.pose, camera=CAM)
    b = fm.detect(g0, g1, f0.pose, f1.pose, camera=CAM)
    np.testing.assert_array_equal(a.likelihood, b.likelihood)


def _rss_bytes() -> int:
    with open("/proc/self/statm") as fh:
        return int(fh.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")


# Identity-like poses put the camera on the default road z = 0: the warning is right, and not
# what this test is about.
@pytest.mark.filterwarnings("ignore:road. the camera is:UserWarning")
@pytest.mark.skipif(not os.path.exists("/proc/self/statm"), reason="needs Linux /proc")
def test_memory_stays_flat_over_a_long_stream():
    """10,000 frames through apply(): resident memory after frame 1,000 and frame 10,000 agree.

    A detector keeping anything per frame (even a 64x48 float32 map, 12 kB) would grow by
    over 100 MB here."""
    cam = fm.calib.KannalaBrandt(fx=40, fy=40, cx=31.5, cy=23.5, width=64, height=48)
    det = fm.MotionDetector(cam, params=fm.Params(flow="dis", dis_preset="ultrafast", grid=4,
                                                  frame_gap=1))
    rng = np.random.default_rng(0)
    frames = [rng.integers(0, 255, (48, 64), dtype=np.uint8) for _ in range(4)]
    pose = np.eye(4)
    rss = {}
    for i in range(10_000):
        pose = pose.copy()
        pose[0, 3] += 0.01
        assert (det.apply(frames[i % 4], pose) is None) == (i == 0)
        if i in (1000, 9999):
            rss[i] = _rss_bytes()
    assert rss[9999] - rss[1000] < 16 * 1024 * 1024


@pytest.mark.parametrize(
    ("change", "match"),
    [
        (dict(prev=np.zeros((480, 640), np.float32)), "prev.*uint8"),
        (dict(curr=np.zeros((240, 320), np.uint8)), "curr.*640x480"),
        (dict(curr=np.zeros((480, 640, 2), np.uint8)), "curr.*shape"),
        (dict(pose0=np.eye(3)), "pose0"),
        (dict(pose1=np.full((4, 4), np.inf)), "pose1"),
        (dict(pose1=np.diag([1.0, 1.0, -1.0, 1.0])), "pose1"),
    ],
)
def test_bad_inputs_name_the_argument(pair, change, match):
    args = dict(prev=pair[0].image, curr=pair[1].image, pose0=pair[0].pose, pose1=pair[1].pose)
    args.update(change)
    with pytest.raises(ValueError, match=match):
        fm.detect(args["prev"], args["curr"], args["pose0"], args["pose1"], camera=CAM)


def test_bad_camera_and_params():
    with pytest.raises(ValueError, match="camera"):
        fm.MotionDetector("kb")
    with pytest.raises(ValueError, match="grid"):
        fm.Params(grid=0)
    with pytest.raises(ValueError, match=r"unknown key.*gird.*did you mean \['grid'\]"):
        fm.Params.from_dict({"gird": 5})
    with pytest.raises(ValueError, match="flow"):
        fm.Params(flow="raft")
    p = fm.Params(threshold=0.01, flow="dis")
    assert fm.Params.from_dict(p.to_dict()) == p


def test_drawing_returns_bgr_images_and_the_fig6_layout(pair):
    f0, f1 = pair[0], pair[1]
    det = fm.detect(f0.image, f1.image, f0.pose, f1.pose, camera=CAM)
    for img in (draw.flow_arrows(f0.image, det), draw.likelihood_map(det),
                draw.overlay_mask(f0.image, det.mask), draw.annotate(f0.image, det),
                draw.heatmap(det.maps["epipolar"], vmax=0.02)):
        assert img.dtype == np.uint8 and img.shape == (480, 640, 3)
    overlay = draw.overlay_mask(f0.image, det.mask)
    sel = det.mask > 0
    assert (overlay[sel][:, 1].astype(int) >= f0.image[sel][:, 1]).all()  # greener
    fig = draw.fig6([(f0.image, det, "crossing")])
    assert len(fig.axes) == 7 + 1  # seven rows and the colour bar
    # Against ground truth: green on true detections, red on false ones, blue on missed pixels.
    truth = np.zeros(det.mask.shape, bool)
    truth[:, :320] = True
    judged = draw.truth_overlay(f0.image, det.mask, truth).astype(int) - f0.image
    found = det.mask > 0
    for sel, channel in ((found & truth, 1), (found & ~truth, 2), (~found & truth, 0)):
        assert sel.any()
        assert (judged[sel].argmax(axis=1) == channel).mean() > 0.95
    assert (judged[~found & ~truth] == 0).all()
    fig = draw.fig6([draw.Fig6Column(f0.image, det, "crossing", truth)] * 2)
    assert len(fig.axes) == 2 * 8 + 1 and "green" in fig._supxlabel.get_text()  # + truth row


def test_detect_cli_on_a_sequence_folder(tmp_path, pair, capsys):
    seq = synth.write_sequence(tmp_path / "seq", CAM, PAIR, frames=3, progress=False)
    out = tmp_path / "out"
    assert main(["detect", str(seq), "--out", str(out), "--quiet", "--road", "z0"]) == 0
    # Three frames, fewer than the frame gap (3) needs: compared at a gap of 2, said so. One
    # output per input frame, named like it; empty masks while that gap fills.
    assert "the input has 3 frames: frame gap 2 instead of 3" in capsys.readouterr().err
    assert sorted(p.name for p in (out / "annotated").glob("*.png")) == [
        "000000.png", "000001.png", "000002.png"]
    for name, moving in (("000001", False), ("000002", True)):
        with np.load(out / "likelihood" / f"{name}.npz") as z:
            assert z["mask"].any() == moving
    (tmp_path / "p.yaml").write_text("frame_gap: 1\nflow: dis\n")
    args = ["detect", str(seq), "--out", str(out), "--quiet", "--road", "z0", "--params",
            str(tmp_path / "p.yaml")]
    assert main(args) == 2  # --out is not empty
    assert main([*args, "--overwrite"]) == 0
    assert len(list((out / "annotated").glob("*.png"))) == 3
    with np.load(out / "likelihood" / "000002.npz") as z:
        assert z["likelihood"].shape == (480, 640) and z["mask"].any()
    import pandas as pd

    regions = pd.read_csv(out / "regions.csv")
    assert (regions.frame >= 1).all() and len(regions) >= 1
    assert {"timestamp", "azimuth_deg", "elevation_deg", "ground_distance_m"} <= set(regions)
    assert regions.timestamp.notna().all() and regions.ground_distance_m.notna().any()
    assert len(pd.read_json(out / "regions.jsonl", lines=True)) == len(regions)
    # --frame-gap overrides the params' gap: at 1 the second frame is compared with the first
    # (a result at frame 1, where the default gap of 2 here has none); 0 is an argument error.
    out1 = tmp_path / "gap1"
    assert main(["detect", str(seq), "--out", str(out1), "--quiet", "--road", "z0",
                 "--frame-gap", "1"]) == 0
    assert "instead of" not in capsys.readouterr().err
    assert set(pd.read_csv(out1 / "regions.csv").frame) >= {1, 2}
    with pytest.raises(SystemExit) as exit_:
        main(["detect", str(seq), "--out", str(tmp_path / "gap0"), "--frame-gap", "0"])
    assert exit_.value.code == 2 and "--frame-gap: expected a number of frames >= 1" in (
        capsys.readouterr().err)
    assert not (tmp_path / "gap0").exists()


def test_detect_cli_on_a_video_with_explicit_files(tmp_path, pair):
    video = tmp_path / "in.avi"
    writer = cv2.VideoWriter(str(video), cv2.VideoWriter_fourcc(*"MJPG"), 15, (640, 480))
    for f in pair:
        writer.write(f.image)
    writer.release()
    fm.poses.write_tum(tmp_path / "poses.txt", [0, 1 / 15, 2 / 15], [f.pose for f in pair])
    fm.calib.save_opencv(CAM, tmp_path / "calib.yaml")
    out = tmp_path / "out"
    (tmp_path / "p.json").write_text('{"frame_gap": 1}')
    code = main(["detect", str(video), "--calib", str(tmp_path / "calib.yaml"), "--poses",
                 str(tmp_path / "poses.txt"), "--out", str(out), "--quiet", "--params",
                 str(tmp_path / "p.json")])
    assert code == 0 and (out / "annotated.mp4").stat().st_size > 0
    assert len(list((out / "likelihood").glob("*.npz"))) == 3
    cap = cv2.VideoCapture(str(out / "annotated.mp4"))
    assert cap.get(cv2.CAP_PROP_FPS) == pytest.approx(15) and cap.get(
        cv2.CAP_PROP_FRAME_COUNT) == 3  # the input's rate and frame count
    cap.release()


def test_detect_cli_errors_are_one_line_and_exit_2(tmp_path, capsys):
    assert main(["detect", str(tmp_path / "missing.mp4"), "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "missing.mp4" in err


def test_hysteresis_keeps_only_regions_with_a_strong_cell():
    from fisheyemotion.segment import segment_cells

    cells = np.zeros((10, 12))
    cells[1:4, 1:4] = 0.006            # weak region
    cells[6:9, 6:10] = 0.006           # region with one strong cell
    cells[7, 8] = 0.05
    plain, regions = segment_cells(cells, threshold=0.004, grid=5, min_area=0)
    assert len(regions) == 2
    mask, regions = segment_cells(cells, threshold=0.004, grid=5, min_area=0, seed_threshold=0.01)
    assert len(regions) == 1 and regions[0].area == 12 * 25
    assert mask[6:9, 6:10].all() and not mask[1:4, 1:4].any()
    same, _ = segment_cells(cells, threshold=0.004, grid=5, min_area=0, seed_threshold=0.004)
    np.testing.assert_array_equal(same, plain)
    # A region is 8-connected: a weak cell diagonal to the strong region belongs to it.
    cells[9, 10] = 0.006
    mask, regions = segment_cells(cells, threshold=0.004, grid=5, min_area=0, seed_threshold=0.01)
    assert mask[9, 10] and len(regions) == 1 and regions[0].area == 13 * 25


@pytest.mark.parametrize("seed", range(6))
def test_extension_is_scikit_images_hysteresis_seeded_by_the_kept_regions(seed):
    """With no ``min_area`` the extension is a hysteresis threshold (low: ``extend_threshold``,
    high: ``threshold``) over 8-connected components, here from scikit-image's labelling."""
    from skimage.measure import label

    from fisheyemotion.segment import segment_cells

    rng = np.random.default_rng(seed)
    cells = rng.uniform(0, 0.006, size=(24, 32))
    cells[rng.random(cells.shape) < 0.05] = np.nan
    values = np.nan_to_num(cells)
    plain, _ = segment_cells(cells, threshold=0.004, grid=5, min_area=0)
    mask, regions = segment_cells(cells, threshold=0.004, grid=5, min_area=0,
                                  extend_threshold=0.002)
    strong = values > 0.004
    want = np.isin(label(values > 0.002, connectivity=2),
                   np.unique(label(values > 0.002, connectivity=2)[strong]))
    np.testing.assert_array_equal(mask, want)
    assert mask[plain].all() and mask.sum() >= plain.sum()
    assert sum(r.area for r in regions) == mask.sum() * 25
    # At or above the threshold, or 0: no extension.
    for off in (0.0, 0.004, 0.005):
        same, _ = segment_cells(cells, threshold=0.004, grid=5, min_area=0,
                                extend_threshold=off)
        np.testing.assert_array_equal(same, plain)


def test_seeds_keep_whole_regions_that_hold_one_and_drop_the_rest():
    from fisheyemotion.segment import segment_cells

    cells = np.zeros((10, 12))
    cells[1:4, 1:4] = 0.006            # a region without a seed
    cells[6:9, 6:10] = 0.006           # a region with one seed cell
    seeds = np.zeros(cells.shape, bool)
    seeds[7, 8] = True
    seeds[0, 11] = True                # a seed outside every region changes nothing
    mask, regions = segment_cells(cells, threshold=0.004, grid=5, min_area=0, seeds=seeds)
    assert mask[6:9, 6:10].all() and mask.sum() == 12 and len(regions) == 1
    plain, _ = segment_cells(cells, threshold=0.004, grid=5, min_area=0)
    every, _ = segment_cells(cells, threshold=0.004, grid=5, min_area=0, seeds=cells > 0)
    np.testing.assert_array_equal(every, plain)


def test_a_kept_region_takes_the_pieces_within_its_gap_and_closes_over_them():
    """``gap``: a seeded region is closed with the unseeded pieces that face it (or a piece
    joined to it) across at most 2 gap cells of a row or column, the cells between them filled;
    pieces farther off, or only diagonal, are dropped as before; gap 0 is the old
    segmentation."""
    from fisheyemotion.segment import segment_cells

    cells = np.zeros((14, 20))
    cells[4:8, 2:5] = 0.006            # the seeded region
    cells[4:8, 7:9] = 0.006            # a piece 2 cells to its right (no seed)
    cells[4:8, 11:12] = 0.006          # a piece 2 cells to the right of that one
    cells[4:8, 15:17] = 0.006          # 3 cells farther: not taken
    cells[10:12, 7:9] = 0.006          # 2 cells below and 2 across from a corner: diagonal only
    seeds = np.zeros(cells.shape, bool)
    seeds[5, 3] = True
    mask, regions = segment_cells(cells, threshold=0.004, grid=5, min_area=0, seeds=seeds,
                                  gap=1)
    assert len(regions) == 1
    pieces = cells > 0
    assert mask[:9, :12][pieces[:9, :12]].all()        # the region and both pieces, whole
    assert mask[5:7, 2:12].all()                       # the cells between them where they face
    assert not mask[4, 5:7].any() and not mask[7, 9:11].any()   # not the corners (a plus)
    assert not mask[:, 13:].any() and not mask[9:].any()
    assert regions[0].bbox == (2 * 5, 4 * 5, 10 * 5, 4 * 5)
    old, _ = segment_cells(cells, threshold=0.004, grid=5, min_area=0, seeds=seeds)
    zero, _ = segment_cells(cells, threshold=0.004, grid=5, min_area=0, seeds=seeds, gap=0)
    np.testing.assert_array_equal(zero, old)
    assert old.sum() == 12 and old[4:8, 2:5].all()     # only the seeded region
    # Without seeds the regions of min_area are what take pieces (here the seeded region's
    # size: 12 cells = 300 px; the pieces are smaller and, alone, dropped).
    unseeded, _ = segment_cells(cells, threshold=0.004, grid=5, min_area=300, gap=1)
    np.testing.assert_array_equal(unseeded, mask)


def test_a_region_led_by_the_anti_parallel_term_needs_led_seeds():
    """``led``/``led_seeds``: a region whose mean share (NaN as 0) reaches LED needs
    ``led_seeds`` seed cells; one below it needs one; 1 is the old rule."""
    from fisheyemotion.segment import LED, segment_cells

    cells = np.zeros((10, 16))
    cells[2:6, 1:5] = 0.006            # region A
    cells[2:6, 10:14] = 0.006          # region B
    share = np.zeros(cells.shape)
    share[2:6, 1:5] = LED + 0.05       # A led by the term (on average) ...
    share[2, 1] = np.nan               # ... a NaN counts 0: mean still above LED
    share[2:6, 10:14] = LED - 0.05     # B not
    seeds = np.zeros(cells.shape, bool)
    seeds[3, 2] = seeds[3, 11] = True
    kw = dict(threshold=0.004, grid=5, min_area=0, seeds=seeds, led=share)
    old, _ = segment_cells(cells, threshold=0.004, grid=5, min_area=0, seeds=seeds)
    one, _ = segment_cells(cells, **kw, led_seeds=1)
    np.testing.assert_array_equal(one, old)
    two, regions = segment_cells(cells, **kw, led_seeds=2)
    assert not two[:, :8].any() and two[2:6, 10:14].all() and len(regions) == 1
    seeds[4, 3] = True                 # a second seed in A
    both, _ = segment_cells(cells, **kw, led_seeds=2)
    np.testing.assert_array_equal(both, old)
    share[2:6, 1:5] = LED - 0.05       # A no longer led: one seed is enough
    seeds[4, 3] = False
    np.testing.assert_array_equal(segment_cells(cells, **kw, led_seeds=2)[0], old)


def test_a_speck_under_min_area_does_not_take_pieces_through_the_gap():
    from fisheyemotion.segment import segment_cells

    cells = np.zeros((8, 12))
    cells[2:5, 2:4] = 0.006            # a seeded speck of 6 cells (150 px) ...
    cells[2:5, 6:8] = 0.006            # ... 2 cells from another of 6 without a seed
    seeds = np.zeros(cells.shape, bool)
    seeds[2, 2] = True
    mask, _ = segment_cells(cells, threshold=0.004, grid=5, min_area=175, seeds=seeds, gap=1)
    assert not mask.any()              # joined they would pass min_area: the speck did not
    kept, _ = segment_cells(cells, threshold=0.004, grid=5, min_area=150, seeds=seeds, gap=1)
    assert kept[2:5, 2:4].all() and kept[2:5, 6:8].all() and kept[3, 4:6].all()
    assert kept.sum() == 14            # and the middle row between them


@given(st.integers(0, 2**31 - 1), st.integers(1, 2))
@settings(max_examples=25, deadline=None)
def test_the_gap_only_adds_cells_around_the_regions_kept_without_it(seed, gap):
    """Every region kept without the gap is kept with it, whole; every cell the closing adds
    is within gap cells (along rows and columns) of a flagged cell it kept; no region appears
    that holds none of the regions kept without it."""
    from fisheyemotion.segment import segment_cells

    rng = np.random.default_rng(seed)
    cells = np.where(rng.random((16, 20)) < 0.3, 0.006, 0.0)
    seeds = rng.random(cells.shape) < 0.05
    old, _ = segment_cells(cells, threshold=0.004, grid=5, min_area=50, seeds=seeds)
    new, regions = segment_cells(cells, threshold=0.004, grid=5, min_area=50, seeds=seeds,
                                 gap=gap)
    assert new[old].all()
    if not old.any():
        assert not new.any() and regions == []
        return
    moving = cells > 0.004
    plus = cv2.getStructuringElement(cv2.MORPH_CROSS, (2 * gap + 1,) * 2)
    near = cv2.dilate((new & moving).astype(np.uint8), plus) > 0
    assert not (new & ~moving & ~near).any()
    n, labels = cv2.connectedComponents(new.astype(np.uint8), connectivity=8)
    assert all(old[labels == i].any() for i in range(1, n))


def test_a_speck_under_min_area_does_not_grow_into_a_detection():
    from fisheyemotion.segment import segment_cells

    cells = np.zeros((12, 12))
    cells[1:5, 1:5] = 0.003             # weak cells ...
    cells[2, 2] = 0.01                  # ... around one strong cell: 25 px, under min_area
    cells[7:10, 7:10] = 0.01            # a region of 9 cells: 225 px
    cells[6:11, 6:11] = np.where(cells[6:11, 6:11] > 0, cells[6:11, 6:11], 0.003)
    mask, regions = segment_cells(cells, threshold=0.004, grid=5, min_area=100,
                                  extend_threshold=0.002)
    assert not mask[:6, :6].any()       # the speck neither grew nor survived
    alone, _ = segment_cells(cells, threshold=0.004, grid=5, min_area=0, extend_threshold=0.002)
    assert alone[1:5, 1:5].all()        # (without min_area it is a region and grows)
    assert mask[6:11, 6:11].all() and mask.sum() == 25 and len(regions) == 1


@pytest.mark.parametrize("seed", range(4))
def test_region_properties_match_scikit_image_regionprops(seed):
    """The vectorised region properties equal scikit-image's regionprops, region by region."""
    from skimage.measure import label, regionprops

    from fisheyemotion.segment import segment_cells

    rng = np.random.default_rng(seed)
    cells = rng.random((40, 50)) * 0.008
    cells[rng.random(cells.shape) < 0.1] = np.nan
    age = rng.integers(0, 4, cells.shape)
    grid, threshold, min_area, persistence = 4, 0.004, 3 * 16, 2
    mask, regions = segment_cells(cells, threshold=threshold, grid=grid, min_area=min_area,
                                  age=age, persistence=persistence)
    values = np.nan_to_num(cells, nan=0.0)
    labels = label(values > threshold, connectivity=2)
    expected = []
    for prop in regionprops(labels, intensity_image=values):
        sel = labels == prop.label
        if prop.area * grid * grid < min_area or age[sel].max() < persistence:
            continue
        r0, c0, r1, c1 = prop.bbox
        cy, cx = prop.centroid
        expected.append((int(prop.area) * grid * grid,
                         (c0 * grid, r0 * grid, (c1 - c0) * grid, (r1 - r0) * grid),
                         prop.intensity_mean, cx * grid + (grid - 1) / 2,
                         cy * grid + (grid - 1) / 2, sel))
    assert len(regions) == len(expected) > 5
    expected.sort(key=lambda e: (-e[0], e[1]))
    got = sorted(regions, key=lambda r: (-r.area, r.bbox))
    for r, (area, bbox, mean, cx, cy, _) in zip(got, expected, strict=True):
        assert (r.area, r.bbox) == (area, bbox)
        assert r.mean_likelihood == pytest.approx(mean, rel=1e-12)
        assert r.centroid == pytest.approx((cx, cy), rel=1e-12)
    np.testing.assert_array_equal(mask, np.any([e[5] for e in expected], axis=0))
    assert [r.label for r in regions] == list(range(1, len(regions) + 1))
    assert [r.area for r in regions] == sorted((r.area for r in regions), reverse=True)
