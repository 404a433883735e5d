"""Hostile and careless input: no crash, no silent wrong result, no lost or mixed output.

One test (at least) per promise of docs/reliability.md.
"""

from __future__ import annotations

import json
import threading
import time

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import fisheyemotion as fm
from fisheyemotion import calib, synth
from fisheyemotion.cli import main
from fisheyemotion.poses import Trajectory

from .cameras import tumvi_kb

CAM = tumvi_kb(320, 240, 100.0)
SCENE = synth.parse_scenario({
    "name": "hostile", "frames": 4, "ego": {"speed_kmh": 15},
    "camera": {"position": [2, 0, 1.0], "pitch_deg": 15},
    "objects": [{"id": 1, "kind": "car", "category": "crossing", "start": [8, -4],
                 "heading_deg": 90, "speed_kmh": 15}]})


@pytest.fixture(scope="module")
def frames():
    return synth.render_frames(CAM, SCENE, supersample=1)


@pytest.fixture(scope="module")
def sequence(tmp_path_factory):
    return synth.write_sequence(tmp_path_factory.mktemp("seq") / "seq", CAM, SCENE,
                                progress=False, supersample=1, flow=False)


# ---- 1. threads ------------------------------------------------------------------------------

@pytest.mark.parametrize("flow", ["dis", "farneback"])
def test_detect_from_several_threads_matches_serial_runs(frames, flow):
    params = fm.Params(flow=flow, frame_gap=1)
    f0, f1 = frames[0], frames[1]
    serial = fm.detect(f0.image, f1.image, f0.pose, f1.pose, camera=CAM, params=params)
    out, errors = [None] * 4, []

    def work(i):
        try:
            for _ in range(3):
                out[i] = fm.detect(f0.image, f1.image, f0.pose, f1.pose, camera=CAM,
                                   params=params)
        except Exception as exc:  # noqa: BLE001 - collected and asserted below
            errors.append(exc)

    threads = [threading.Thread(target=work, args=(i,)) for i in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert not errors
    for result in out:
        np.testing.assert_array_equal(result.likelihood, serial.likelihood)


# ---- 2. Farneback settings -------------------------------------------------------------------

@pytest.mark.parametrize("change, field", [
    ({"winsize": -5}, "winsize"), ({"winsize": 0}, "winsize"), ({"pyr_scale": 1.5}, "pyr_scale"),
    ({"pyr_scale": float("nan")}, "pyr_scale"), ({"iterations": -1}, "iterations"),
    ({"poly_n": 0}, "poly_n"), ({"poly_sigma": float("nan")}, "poly_sigma"),
    ({"levels": 2.5}, "levels")])
def test_farneback_settings_are_checked_before_opencv_sees_them(change, field):
    with pytest.raises(ValueError, match=f"farneback.{field}"):
        fm.Params(farneback=change)


def test_cli_params_with_a_bad_farneback_setting_exit_2(tmp_path, sequence, capsys):
    (tmp_path / "p.yaml").write_text("farneback: {winsize: -5}\n")
    code = main(["detect", str(sequence), "--out", str(tmp_path / "o"), "--params",
                 str(tmp_path / "p.yaml"), "--quiet"])
    assert code == 2 and "winsize" in capsys.readouterr().err


# ---- 3. the stream keeps its own copies ------------------------------------------------------

def test_apply_copies_the_callers_frame_and_pose(frames):
    params = fm.Params(flow="dis", frame_gap=1, temporal_decay=0.0, scene_prior=False)
    fresh = fm.MotionDetector(CAM, params=params)
    reused = fm.MotionDetector(CAM, params=params)
    buf, pose = np.empty((240, 320), np.uint8), np.eye(4)
    import cv2

    for f in frames[:3]:
        a = fresh.apply(cv2.cvtColor(f.image, cv2.COLOR_BGR2GRAY), f.pose.copy())
        buf[:] = cv2.cvtColor(f.image, cv2.COLOR_BGR2GRAY)  # one buffer, refilled in place
        pose[:] = f.pose
        b = reused.apply(buf, pose)
    assert not b.static_camera
    np.testing.assert_array_equal(a.mask, b.mask)


# ---- 4. frames and poses ---------------------------------------------------------------------

def test_a_missing_frame_does_not_shift_the_poses(tmp_path, sequence):
    import shutil

    seq = tmp_path / "seq"
    shutil.copytree(sequence, seq)
    (seq / "frames" / "000001.png").unlink()
    (tmp_path / "p.yaml").write_text("frame_gap: 1\n")
    assert main(["detect", str(seq), "--out", str(tmp_path / "o"), "--quiet", "--road", "z0",
                 "--params", str(tmp_path / "p.yaml")]) == 0
    used = fm.poses.read_poses(tmp_path / "o" / "poses.txt").poses
    truth = fm.poses.read_poses(seq / "poses.txt").poses
    np.testing.assert_allclose(used, truth[[0, 2, 3]])
    assert sorted(p.stem for p in (tmp_path / "o" / "likelihood").glob("*.npz")) == [
        "000000", "000002", "000003"]


@pytest.mark.parametrize("corrupt", ["000001.png", "000002.png"])
def test_a_frame_that_cannot_be_read_is_one_error_naming_it(tmp_path, sequence, capsys, corrupt):
    """A corrupt frame of an input is reported by its file, not as the frame before it (or,
    with the frames before it already written, as an IndexError traceback), and no output is
    left behind."""
    import shutil

    seq = tmp_path / "seq"
    shutil.copytree(sequence, seq)
    (seq / "frames" / corrupt).write_bytes(b"not a png")
    (tmp_path / "p.yaml").write_text("frame_gap: 1\n")
    code = main(["detect", str(seq), "--out", str(tmp_path / "o"), "--quiet", "--road", "z0",
                 "--params", str(tmp_path / "p.yaml")])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and err[-1].endswith(f"{corrupt}: cannot be read as an 8-bit image")
    assert "Traceback" not in "\n".join(err) and not (tmp_path / "o").exists()


@pytest.mark.parametrize("value", ["nan", "-1", "inf"])
def test_max_dt_must_be_a_finite_tolerance(tmp_path, sequence, value):
    assert main(["detect", str(sequence), "--out", str(tmp_path / "o"), "--match",
                 "timestamp", f"--max-dt={value}", "--quiet"]) == 2


def test_duplicate_or_unsorted_timestamps_are_refused():
    with pytest.raises(ValueError, match="increase"):
        Trajectory(np.repeat(np.eye(4)[None], 3, 0), [0.0, 0.1, 0.1])
    with pytest.raises(ValueError, match="increase"):
        Trajectory(np.repeat(np.eye(4)[None], 3, 0), [0.0, 0.2, 0.1])


def test_huge_translations_are_not_poses():
    pose = np.eye(4)
    pose[0, 3] = 1e155
    with pytest.raises(ValueError, match="translation"):
        fm.detect(np.zeros((240, 320), np.uint8), np.zeros((240, 320), np.uint8), np.eye(4),
                  pose, camera=CAM)


# ---- 5. outputs whole or not at all ----------------------------------------------------------

def test_interrupted_synth_leaves_the_old_sequence_whole(tmp_path, monkeypatch):
    out = synth.write_sequence(tmp_path / "s", CAM, SCENE, frames=2, progress=False,
                               supersample=1, flow=False)
    before = {p.relative_to(out): p.read_bytes() for p in out.rglob("*") if p.is_file()}
    calls = {"n": 0}
    render = synth.Renderer.render

    def interrupted(self, k):
        calls["n"] += 1
        if calls["n"] == 3:
            raise KeyboardInterrupt
        return render(self, k)

    monkeypatch.setattr(synth.Renderer, "render", interrupted)
    with pytest.raises(KeyboardInterrupt):
        synth.write_sequence(out, CAM, SCENE, frames=4, progress=False, supersample=1,
                             flow=False)
    after = {p.relative_to(out): p.read_bytes() for p in out.rglob("*") if p.is_file()}
    assert after == before
    assert [p.name for p in tmp_path.iterdir()] == ["s"]  # no partial folder left behind


def test_rerunning_into_an_output_folder_replaces_it_whole(tmp_path, sequence):
    out = tmp_path / "o"
    args = ["detect", str(sequence), "--out", str(out), "--quiet", "--road", "z0"]
    assert main(args) == 0
    (out / "stale.txt").write_text("from an earlier run")
    assert main(args) == 2  # not empty
    assert main([*args, "--overwrite"]) == 0
    assert not (out / "stale.txt").exists()


@pytest.mark.parametrize("frames_arg", ["0", "-5", "1"])
def test_synth_refuses_an_empty_sequence(tmp_path, frames_arg, calib_dir):
    assert main(["synth", "--scenario", "crossing", "--calib", str(calib_dir /
                 "opencv/tumvi_cam0_fisheye.yaml"), "--frames", frames_arg, "--out",
                 str(tmp_path / "s"), "--quiet"]) == 2
    assert not (tmp_path / "s").exists()


def test_synth_refuses_nan_noise(tmp_path, calib_dir):
    assert main(["synth", "--scenario", "crossing", "--calib", str(calib_dir /
                 "opencv/tumvi_cam0_fisheye.yaml"), "--noise", "nan", "--out",
                 str(tmp_path / "s"), "--quiet"]) == 2


# ---- 6. sizes, bounded messages --------------------------------------------------------------

def test_billion_laughs_is_refused_fast_with_a_small_message(tmp_path):
    lines = ['a: &a ["lol","lol","lol","lol","lol","lol","lol","lol","lol"]']
    for i in range(1, 9):
        prev = chr(ord("a") + i - 1)
        lines.append(f"{chr(ord('a') + i)}: &{chr(ord('a') + i)} [" + ",".join([f"*{prev}"] * 9)
                     + "]")
    lines.append("cam0: *i")
    bomb = tmp_path / "bomb.yaml"
    bomb.write_text("\n".join(lines) + "\n")
    start = time.perf_counter()
    with pytest.raises(ValueError) as info:
        calib.load(bomb)
    assert time.perf_counter() - start < 5 and len(str(info.value)) < 1000
    (tmp_path / "p.yaml").write_text("\n".join(lines).replace("cam0", "weights") + "\n")
    with pytest.raises(ValueError) as info:
        fm.Params.load(tmp_path / "p.yaml")
    assert len(str(info.value)) < 1000


def test_a_huge_opencv_matrix_or_kalibr_file_is_refused_fast(tmp_path):
    n = 1000
    data = ", ".join(["1."] * (n * n))
    big = tmp_path / "big.yaml"
    big.write_text(f"%YAML:1.0\n---\nimage_width: 640\nimage_height: 480\ncamera_matrix: "
                   f"!!opencv-matrix\n   rows: {n}\n   cols: {n}\n   dt: d\n   data: [ {data} ]\n")
    start = time.perf_counter()
    with pytest.raises(ValueError, match="limit"):
        calib.load(big)
    small = tmp_path / "small.yaml"
    small.write_text("%YAML:1.0\n---\nimage_width: 640\nimage_height: 480\ncamera_matrix: "
                     "!!opencv-matrix\n   rows: 30\n   cols: 30\n   dt: d\n   data: [ "
                     + ", ".join(["1."] * 900) + " ]\n")
    with pytest.raises(ValueError, match="camera_matrix"):
        calib.load(small)
    assert time.perf_counter() - start < 5


# ---- 7. degenerate camera parameters ---------------------------------------------------------

@pytest.mark.parametrize("make", [
    lambda: calib.DoubleSphere(fx=100, fy=100, cx=160, cy=120, xi=-1.0, alpha=0.6, width=320,
                               height=240),
    lambda: calib.DoubleSphere(fx=100, fy=100, cx=160, cy=120, xi=-0.2, alpha=0.0, width=320,
                               height=240),
    lambda: calib.KannalaBrandt(fx=100, fy=100, cx=160, cy=120, k4=1e300, width=320, height=240),
    lambda: calib.KannalaBrandt(fx=100, fy=100, cx=160, cy=120, k4=-1e300, width=320,
                                height=240),
    lambda: calib.KannalaBrandt(fx=1e300, fy=100, cx=160, cy=120, width=320, height=240),
])
def test_degenerate_camera_parameters_are_refused(make):
    with pytest.raises(ValueError):
        make()


def test_a_ray_at_the_edge_of_a_models_domain_is_not_valid():
    for cam in (calib.Unified(fx=400, fy=400, cx=320, cy=240, xi=0.0, width=640, height=480),
                calib.Pinhole(fx=400, fy=400, cx=320, cy=240, width=640, height=480)):
        pix, ok = cam.project(np.array([[1.0, 0.0, 0.0]]))
        assert not ok[0] and np.isnan(pix).all()


# ---- 8. readers ------------------------------------------------------------------------------

OPENCV = ("%YAML:1.0\n---\nimage_width: 640\nimage_height: 480\ncamera_matrix: !!opencv-matrix\n"
          "   rows: 3\n   cols: 3\n   dt: d\n   data: [ {k} ]\nfisheye_model: 1\n"
          "distortion_coefficients: !!opencv-matrix\n   rows: 4\n   cols: 1\n   dt: d\n"
          "   data: [ 0., 0., 0., 0. ]\n")


@pytest.mark.parametrize("k, match", [("200., 2., 320., 0., 200., 240., 0., 0., 1.", "skew"),
                                      ("200., 0., 320., 0., 200., 240., 1., 2., 5.", "form")])
def test_opencv_camera_matrix_form_is_checked(k, match):
    with pytest.raises(ValueError, match=match):
        calib.parse(OPENCV.format(k=k), "c.yaml")


def test_opencv_filestorage_json_is_read():
    import cv2

    fs = cv2.FileStorage(".json", cv2.FILE_STORAGE_WRITE | cv2.FILE_STORAGE_MEMORY)
    fs.write("image_width", 640)
    fs.write("image_height", 480)
    fs.write("camera_matrix", np.array([[200.0, 0, 319.5], [0, 200.0, 239.5], [0, 0, 1]]))
    fs.write("distortion_coefficients", np.zeros((4, 1)))
    fs.write("fisheye_model", 1)
    text = fs.releaseAndGetString()
    cam = calib.parse(text, "c.json")[0]
    assert cam.name == "kannala_brandt" and cam.fx == 200.0


def test_colmap_unsupported_lines_only_fail_when_asked_for(tmp_path):
    text = ("1 FISHEYE 640 480 200 200 320 240\n2 SIMPLE_FISHEYE 640 480 210 320 240\n"
            "3 FOV 640 480 200 200 320 240 0.5\n")
    (tmp_path / "cameras.txt").write_text(text)
    rig = calib.load_rig(tmp_path / "cameras.txt")
    assert rig["1"] == calib.KannalaBrandt(fx=200, fy=200, cx=319.5, cy=239.5, width=640,
                                           height=480)
    assert rig["2"].fx == rig["2"].fy == 210
    with pytest.raises(ValueError, match="line 3.*FOV"):
        rig["3"]


def test_binary_colmap_model_says_how_to_convert(tmp_path):
    (tmp_path / "cameras.bin").write_bytes(b"\x01\x00\x00\x00\x00\x00\x00\x00\x05\x00")
    with pytest.raises(ValueError, match="model_converter"):
        calib.load(tmp_path / "cameras.bin")


# ---- 9. every error a ValueError naming the field ----------------------------------------------

@pytest.mark.parametrize("text, match", [
    ("cam0:\n" + "  " * 0 + "[" * 2000 + "]" * 2000 + "\n", "nested|YAML"),
    ("%YAML:1.0\n---\nimage_width: " + "9" * 400 + "\nimage_height: 480\n", "image_width"),
])
def test_pathological_documents_are_value_errors(text, match):
    with pytest.raises(ValueError, match=match):
        calib.parse(text, "x.yaml")


def test_huge_resolution_is_refused():
    with pytest.raises(ValueError, match="image size"):
        calib.parse(OPENCV.format(k="200., 0., 320., 0., 200., 240., 0., 0., 1.").replace(
            "image_width: 640", "image_width: 100000"), "c.yaml")


@pytest.mark.parametrize("damage", ["mask", "masks_dir", "objects", "mask_size", "roi"])
def test_eval_on_damaged_ground_truth_names_the_file(tmp_path, sequence, damage):
    import shutil

    import cv2

    seq = tmp_path / "seq"
    shutil.copytree(sequence, seq)
    if damage == "mask":
        (seq / "masks" / "000002.png").unlink()
    elif damage == "masks_dir":
        shutil.rmtree(seq / "masks")
    elif damage == "objects":
        (seq / "objects.csv").write_text("frame,id\nx,y\n")
    elif damage == "mask_size":
        cv2.imwrite(str(seq / "masks" / "000002.png"), np.zeros((10, 10), np.uint8))
    else:
        (seq / "roi.png").write_bytes(b"not a png")
    from fisheyemotion.eval.evaluate import evaluate_sequence

    with pytest.raises(ValueError, match=r"masks|objects\.csv|roi\.png"):
        evaluate_sequence(seq, fm.Params(frame_gap=1, flow="dis"), ablation=False)


@pytest.mark.parametrize("workers", [0, -3, 1.5, "2", True])
def test_eval_workers_must_be_a_count_of_processes(sequence, workers):
    evaluate = __import__("importlib").import_module("fisheyemotion.eval.evaluate").evaluate

    with pytest.raises(ValueError, match="workers"):
        evaluate([sequence], fm.Params(), workers=workers, progress=False)


@pytest.mark.parametrize("value", ["0", "-3", "two"])
@pytest.mark.parametrize("command", ["eval", "compare", "demo"])
def test_cli_workers_must_be_a_count_of_processes(tmp_path, sequence, capsys, command, value):
    args = {"eval": ["eval", str(sequence)],
            "compare": ["compare", "--calib", "a.yaml", "--calib", "b.yaml"],
            "demo": ["demo"]}[command]
    with pytest.raises(SystemExit) as exit_:
        main([*args, "--out", str(tmp_path / "o"), "--workers", value, "--quiet"])
    assert exit_.value.code == 2
    assert "--workers: expected a number of processes >= 1" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


def test_eval_on_a_bad_scheduler_address_names_the_argument(tmp_path, sequence, capsys):
    pytest.importorskip("dask.distributed")
    code = main(["eval", str(sequence), "--out", str(tmp_path / "o"), "--scheduler", "nowhere",
                 "--quiet"])
    assert code == 2
    assert "scheduler: cannot use 'nowhere'" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


def test_params_and_road_name_their_field(tmp_path):
    with pytest.raises(ValueError, match="no such parameter file"):
        fm.Params.load(tmp_path / "missing.yaml")
    (tmp_path / "p.yaml").write_bytes(b"\xff\xfe weights")
    with pytest.raises(ValueError, match="UTF-8"):
        fm.Params.load(tmp_path / "p.yaml")
    with pytest.raises(ValueError, match="weights"):
        fm.Params(weights=None)
    with pytest.raises(ValueError, match="offset"):
        fm.Road(offset=None)
    road = fm.Road(normal=(1e300, 1e300, 1e300))
    np.testing.assert_allclose(road.up, np.ones(3) / np.sqrt(3))


def test_compare_with_a_woodscape_camera_does_not_crash():
    from fisheyemotion.eval.compare import fit_table

    ws = calib.load("data/calib/woodscape_front.json")
    kb = calib.load("data/calib/front_kb_640x480.yaml")
    table = fit_table([("ws", ws), ("kb", kb)])
    assert len(table) == 4 and table.rms_px.notna().sum() >= 2


# ---- properties over random input ------------------------------------------------------------

@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.text(max_size=400))
def test_any_text_is_a_calibration_or_a_value_error(text):
    try:
        calib.parse(text, "fuzz")
    except ValueError:
        pass


JSONISH = st.recursive(st.none() | st.booleans() | st.floats() | st.integers() | st.text(max_size=8),
                       lambda inner: st.lists(inner, max_size=4) | st.dictionaries(
                           st.text(max_size=12), inner, max_size=4), max_leaves=20)


@settings(max_examples=150, deadline=None)
@given(st.dictionaries(st.sampled_from(["weights", "grid", "farneback", "threshold", "flow",
                                        "frame_gap", "temporal_decay", "min_area", "bogus"]),
                       JSONISH, max_size=4))
def test_any_params_mapping_is_params_or_a_value_error(values):
    try:
        fm.Params.from_dict(values)
    except ValueError:
        pass


@settings(max_examples=100, deadline=None)
@given(st.dictionaries(st.sampled_from(["CameraCalibrations", "slam", "value0", "intrinsic"]),
                       JSONISH, max_size=3))
def test_any_json_calibration_is_a_camera_or_a_value_error(doc):
    try:
        calib.parse(json.dumps(doc), "fuzz.json")
    except ValueError:
        pass


def test_double_sphere_at_xi_1_keeps_precision_near_180_degrees():
    # At xi = 1 the radius simplifies exactly to sin(t/2) / (alpha + (1 - alpha) cos(t/2)).
    cam = calib.DoubleSphere(fx=200, fy=200, cx=320, cy=240, xi=1.0, alpha=0.6, width=640,
                             height=480)
    theta = np.radians(np.linspace(170, 179.99, 50))
    exact = np.sin(theta / 2) / (0.6 + 0.4 * np.cos(theta / 2))
    np.testing.assert_allclose(cam._radius(theta), exact, rtol=1e-13)
    rays = np.stack([np.sin(theta), np.zeros_like(theta), np.cos(theta)], -1)
    pixels, ok = cam.project(rays)
    back, ok2 = cam.unproject(pixels)
    again, _ = cam.project(back)
    assert ok.all() and ok2.all() and np.abs(again - pixels).max() < 1e-9


def test_a_camera_under_the_given_road_warns(frames):
    det = fm.MotionDetector(CAM, fm.Road(normal=(0, 0, -1), offset=0.0),
                            fm.Params(frame_gap=1, flow="dis"))
    with pytest.warns(UserWarning, match="on or under"):
        det.detect(frames[0].image, frames[1].image, frames[0].pose, frames[1].pose)


def test_cli_version_and_calib_reporting_every_file(capsys, calib_dir):
    with pytest.raises(SystemExit) as info:
        main(["--version"])
    assert info.value.code == 0 and "fisheyemotion" in capsys.readouterr().out
    code = main(["calib", str(calib_dir / "invalid" / "unknown-model-kalibr.yaml"),
                 str(calib_dir / "opencv" / "tumvi_cam0_fisheye.yaml")])
    out, err = capsys.readouterr()
    assert code == 2 and "kannala_brandt" in out and "unknown-model-kalibr.yaml" in err


@pytest.mark.parametrize(("text", "mode"), [("on", "on"), ("off", "off"), ("auto", "auto"),
                                            ("'on'", "on"), ("yes", "on"), ("no", "off")])
def test_a_yaml_on_or_off_pose_refinement_is_the_mode_not_a_boolean(tmp_path, text, mode):
    # YAML 1.1 (PyYAML) reads an unquoted on / off / yes / no as a boolean.
    (tmp_path / "p.yaml").write_text(f"pose_refinement: {text}\n")
    assert fm.Params.load(tmp_path / "p.yaml").pose_refinement == mode
    with pytest.raises(ValueError, match="pose_refinement"):
        fm.Params(pose_refinement=True)  # in Python, a mode is a string
