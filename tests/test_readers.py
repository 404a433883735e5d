"""Calibration readers and writers, on files other tools wrote (tests/data/calib, as they are)."""

from __future__ import annotations

import numpy as np
import pytest
from fisheyemotion.calib.transforms import invert_transform, quat_to_matrix
from hypothesis import given
from hypothesis import strategies as st

from fisheyemotion import calib

from .cameras import ALL_CAMERAS, CAMERA_IDS, TUMVI_KB
from .conftest import CALIB

FIXTURES = sorted(p for p in CALIB.rglob("*") if p.is_file() and p.suffix in
                  {".json", ".yaml", ".xml", ".txt"} and p.parent.name != "invalid")
TUMVI_KB_FILES = ["opencv/tumvi_cam0_fisheye.yaml", "opencv/tumvi_cam0_fisheye_opencv4.yaml",
                  "opencv/tumvi_cam0_fisheye.xml", "ros/equidistant.yaml",
                  "kalibr/camchain-equidistant.yaml", "colmap/cameras.txt"]


@pytest.mark.parametrize("path", FIXTURES, ids=lambda p: f"{p.parent.name}/{p.name}")
def test_every_fixture_loads(path):
    rig = calib.load_rig(path)
    assert len(rig) >= 1
    for cam in rig.cameras:
        assert isinstance(cam, calib.CameraModel)
        assert cam.valid_pixel_mask().mean() > 0.5


@pytest.mark.parametrize("relpath", TUMVI_KB_FILES)
def test_tumvi_kb_is_the_same_camera_in_every_format(relpath):
    """OpenCV 4/5 YAML, XML, ROS, Kalibr and COLMAP (+0.5 px principal point) agree exactly."""
    cam = calib.load(CALIB / relpath)
    expected = calib.KannalaBrandt(**TUMVI_KB)
    assert isinstance(cam, calib.KannalaBrandt)
    for k, v in expected.to_dict().items():
        if k != "model":
            assert getattr(cam, k) == pytest.approx(v, rel=0, abs=1e-12), k


def test_eucm_in_basalt_kalibr_and_colmap_agree():
    basalt = calib.load(CALIB / "basalt/euroc_eucm_calib.json", camera="cam0")
    kalibr = calib.load(CALIB / "kalibr/camchain-imucam-eucm.yaml")
    colmap = calib.load(CALIB / "colmap/cameras.txt", camera="2")
    for other in (kalibr, colmap):
        assert isinstance(other, calib.EnhancedUnified)
        for k in basalt.param_names:
            assert getattr(other, k) == pytest.approx(getattr(basalt, k), abs=1e-9), k


def test_basalt_models_and_extrinsics():
    rig = calib.load_rig(CALIB / "basalt/euroc_ds_calib.json")
    assert rig.reference == "imu" and rig.names == ("cam0", "cam1")
    cam = rig["cam1"]
    assert isinstance(cam, calib.DoubleSphere)
    assert cam.xi == pytest.approx(-0.21300835384809328) and cam.alpha == pytest.approx(0.5767008625037023)
    t = rig.extrinsic(0)
    expected_r = quat_to_matrix([-0.007239825785317818, 0.007541278561558601,
                                 0.7017845426564943, 0.7123125505904486])
    np.testing.assert_allclose(t[:3, :3], expected_r, atol=1e-12)
    np.testing.assert_allclose(t[:3, 3], [-0.016774788924641534, -0.068938940687127,
                                          0.005139123188382424])
    kb = calib.load(CALIB / "basalt/t265_kb4_calib.json", camera=1)
    assert isinstance(kb, calib.KannalaBrandt) and kb.k4 == pytest.approx(0.009643678532407408)


def test_kalibr_chain_and_imu_extrinsics():
    rig = calib.load_rig(CALIB / "kalibr/camchain-ds.yaml")
    assert rig.reference == "cam0"
    np.testing.assert_allclose(rig.extrinsic(0), np.eye(4))
    t_c1_c0 = np.array([[0.9999681901812315, -0.0010826173214831913, 0.007902313927417923, -0.0989],
                        [0.001099965452852123, 0.999996994120283, -0.0021913070075072053, 0.0004],
                        [-0.007899917827089755, 0.0021999295747461823, 0.9999663752387833, 0.0008],
                        [0, 0, 0, 1.0]])
    np.testing.assert_allclose(rig.extrinsic("cam1") @ t_c1_c0, np.eye(4), atol=1e-12)
    ds = rig["cam0"]
    assert (ds.xi, ds.alpha, ds.fx) == (-0.19963086018860057, 0.5924590037637837, 317.552559595926)
    imu = calib.load_rig(CALIB / "kalibr/camchain-imucam-eucm.yaml")
    assert imu.reference == "imu"
    t_cam_imu = invert_transform(imu.extrinsic(0))
    np.testing.assert_allclose(t_cam_imu[:3, 3], [0.047, -0.047, -0.068])


def test_woodscape_front_camera_looks_forward_and_down():
    rig = calib.load_rig(CALIB / "woodscape/front.json")
    cam, t = rig["FV"], rig.extrinsic("FV")
    assert isinstance(cam, calib.RadialPoly) and rig.reference == "vehicle"
    optical_axis = t[:3, :3] @ [0, 0, 1.0]  # in ISO 8855: x forward, y left, z up
    assert optical_axis[0] > 0.9 and optical_axis[2] < -0.3
    right = t[:3, :3] @ [1.0, 0, 0]
    assert right[1] < -0.99
    np.testing.assert_allclose(t[:3, 3], [3.7484, 0.0, 0.66017])
    # WoodScape's principal point: image centre + offset - 0.5.
    assert cam._affine()[2:] == (640 + 3.942 - 0.5, 483 - 3.093 - 0.5)


def test_ros_fisheye_naming_of_older_files():
    cam = calib.load(CALIB / "ros/fisheye-melodic.yaml")
    assert isinstance(cam, calib.KannalaBrandt)
    assert (cam.width, cam.height, cam.k1) == (1640, 1232, 0.175653)


def test_camera_selection_by_index_and_name():
    path = CALIB / "basalt/tumvi_512_eucm_calib.json"
    assert calib.load(path, camera=1) == calib.load(path, camera="cam1")
    with pytest.raises(ValueError, match="camera"):
        calib.load(path, camera=5)
    with pytest.raises(ValueError, match="camera.*cam7"):
        calib.load(path, camera="cam7")


# ---- files that must be refused, or whose outer pixels have no ray --------------------------

def test_missing_field_names_file_and_field():
    path = CALIB / "invalid/ds-missing-alpha-basalt.json"
    with pytest.raises(calib.CalibrationError, match=r"ds-missing-alpha-basalt\.json.*alpha.*missing"):
        calib.load(path)


def test_unknown_model_names_file_field_and_model():
    path = CALIB / "invalid/unknown-model-kalibr.yaml"
    with pytest.raises(ValueError, match=r"unknown-model-kalibr\.yaml: cam0\.camera_model.*fisheye624"):
        calib.load(path)


def test_non_monotonic_kb_outer_pixels_invalid_inner_round_trip():
    cam = calib.load(CALIB / "invalid/non-monotonic-equidistant.yaml")
    assert np.degrees(cam.theta_max) == pytest.approx(48.65, abs=0.01)
    rays, valid = cam.pixel_rays()
    grid = calib.pixel_grid(cam.width, cam.height)
    r = np.hypot((grid[..., 0] - cam.cx) / cam.fx, (grid[..., 1] - cam.cy) / cam.fy)
    np.testing.assert_array_equal(valid, r <= cam.radius_max)
    assert not valid[0, 0] and valid[600, 960]
    back, ok = cam.project(rays[valid])
    assert ok.all()
    np.testing.assert_allclose(back, grid[valid], atol=1e-6)


@pytest.mark.parametrize(
    ("name", "text", "match"),
    [
        ("nonrigid.yaml", "cam0:\n  camera_model: pinhole\n  intrinsics: [1, 1, 1, 1]\n"
         "  resolution: [10, 10]\ncam1:\n  camera_model: pinhole\n  intrinsics: [1, 1, 1, 1]\n"
         "  resolution: [10, 10]\n  T_cn_cnm1: [[2, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]\n",
         r"nonrigid\.yaml: cam1\.T_cn_cnm1: .*not rigid"),
        ("type.yaml", "cam0:\n  camera_model: pinhole\n  intrinsics: [1, one, 1, 1]\n"
         "  resolution: [10, 10]\n", r"type\.yaml: cam0\.intrinsics\[1\]: expected a number"),
        ("count.yaml", "cam0:\n  camera_model: ds\n  intrinsics: [1, 1, 1, 1]\n  resolution: [10, 10]\n",
         r"cam0\.intrinsics: expected 6 numbers"),
        ("range.yaml", "cam0:\n  camera_model: ds\n  intrinsics: [3, 0.5, 1, 1, 1, 1]\n"
         "  resolution: [10, 10]\n", r"cam0\.intrinsics: .*xi"),
        ("res.yaml", "cam0:\n  camera_model: pinhole\n  intrinsics: [1, 1, 1, 1]\n  resolution: [0, 10]\n",
         r"cam0\.resolution\[0\]"),
        ("cameras.txt", "1 FOV 640 480 300 300 320 240 0.9\n", r"cameras\.txt: line 1\.MODEL.*FOV"),
        ("quat.json", '{"value0": {"T_imu_cam": [{"px": 0, "py": 0, "pz": 0, "qx": 0, "qy": 0, '
         '"qz": 0, "qw": 2}], "intrinsics": [{"camera_type": "pinhole", "intrinsics": {"fx": 1, '
         '"fy": 1, "cx": 1, "cy": 1}}], "resolution": [[10, 10]]}}', r"T_imu_cam\[0\].*norm"),
        ("ws.json", '{"intrinsic": {"model": "radial_poly", "k1": 1, "k2": 0, "k3": 0, '
         '"cx_offset": 0, "cy_offset": 0, "width": 10, "height": 10}}', r"ws\.json: intrinsic\.k4: missing"),
        ("cv.yaml", "%YAML:1.0\n---\nimage_width: 10\ncamera_matrix: !!opencv-matrix\n   rows: 3\n"
         "   cols: 3\n   dt: d\n   data: [1., 0., 1., 0., 1., 1., 0., 0., 1.]\n",
         r"cv\.yaml: image_height: missing"),
        ("x.yaml", "foo: 1\n", r"x\.yaml: .*unrecognised"),
        ("ros.yaml", "image_width: 10\nimage_height: 10\ncamera_matrix: {data: [1, 0, 1, 0, 1, 1, 0, 0, 1]}\n"
         "distortion_model: plumb_bob\ndistortion_coefficients: {data: [0.1, 0, 0, 0, 0]}\n",
         r"ros\.yaml: distortion_model: unsupported"),
    ],
)
def test_malformed_files_name_file_and_field(tmp_path, name, text, match):
    path = tmp_path / name
    path.write_text(text)
    with pytest.raises(calib.CalibrationError, match=match):
        calib.load(path)


def test_missing_file():
    with pytest.raises(ValueError, match="no such file"):
        calib.load("/nonexistent/calib.yaml")


# ---- writers: read(write(x)) == x -----------------------------------------------------------

@pytest.mark.parametrize(("name", "cam"), ALL_CAMERAS, ids=CAMERA_IDS)
@pytest.mark.parametrize("suffix", [".yaml", ".xml"])
def test_opencv_write_read_round_trip(tmp_path, name, cam, suffix):
    path = tmp_path / f"calib{suffix}"
    calib.save_opencv(cam, path)
    assert calib.load(path) == cam


def test_opencv_written_kb_is_readable_as_cv2_fisheye(tmp_path):
    import cv2

    cam = calib.KannalaBrandt(**TUMVI_KB)
    calib.save_opencv(cam, tmp_path / "c.yaml")
    fs = cv2.FileStorage(str(tmp_path / "c.yaml"), cv2.FILE_STORAGE_READ)
    k, d = fs.getNode("camera_matrix").mat(), fs.getNode("distortion_coefficients").mat()
    assert k[0, 0] == cam.fx and d.ravel()[3] == cam.k4 and fs.getNode("fisheye_model").real() == 1


# Kalibr has no form for WoodScape's polynomial or Aria's FISHEYE624 (writing one is an error).
KALIBR_CAMERAS = [(n, c) for n, c in ALL_CAMERAS if n not in ("radial_poly", "fisheye624")]


@pytest.mark.parametrize(("name", "cam"), KALIBR_CAMERAS, ids=[n for n, _ in KALIBR_CAMERAS])
def test_kalibr_write_read_round_trip(tmp_path, name, cam):
    calib.save_kalibr(cam, tmp_path / "camchain.yaml")
    assert calib.load(tmp_path / "camchain.yaml") == cam


@pytest.mark.parametrize("fixture", ["kalibr/camchain-ds.yaml", "kalibr/camchain-imucam-eucm.yaml",
                                     "basalt/tumvi_512_ds_calib.json"])
def test_kalibr_rig_round_trip_keeps_extrinsics(tmp_path, fixture):
    rig = calib.load_rig(CALIB / fixture)
    calib.save_kalibr(rig, tmp_path / "camchain.yaml")
    back = calib.load_rig(tmp_path / "camchain.yaml")
    assert back.cameras == rig.cameras and back.reference == rig.reference
    for a, b in zip(back.extrinsics, rig.extrinsics, strict=True):
        np.testing.assert_allclose(a, b, atol=1e-12)


def test_kalibr_refuses_models_it_cannot_hold(tmp_path):
    cam = calib.load(CALIB / "woodscape/front.json")
    with pytest.raises(ValueError, match="radial_poly"):
        calib.save_kalibr(cam, tmp_path / "x.yaml")


# ---- fuzzing: only ValueError ever escapes ---------------------------------------------------

FUZZ_TEXTS = {p.name: p.read_text() for p in FIXTURES if p.stat().st_size < 20000}
FUZZ_TEXTS.update({p.name: p.read_text()[:6000] for p in FIXTURES if p.stat().st_size >= 20000})
PIECES = ["", " ", "-", "0", "1e9", "nan", "[", "]", "{", "}", ":", ",", "\n", '"', "x", "-1",
          "!!opencv-matrix", "<", ">", "null", "  ", "\t"]


@st.composite
def mutated(draw):
    name = draw(st.sampled_from(sorted(FUZZ_TEXTS)))
    text = FUZZ_TEXTS[name]
    for _ in range(draw(st.integers(1, 4))):
        i = draw(st.integers(0, len(text)))
        j = draw(st.integers(i, min(len(text), i + 12)))
        text = text[:i] + draw(st.sampled_from(PIECES)) + text[j:]
    return name, text


@given(case=mutated())
def test_fuzzed_fixtures_raise_only_value_error(case):
    name, text = case
    try:
        rig = calib.parse(text, name)
    except ValueError:
        return
    for cam in rig.cameras:
        assert isinstance(cam, calib.CameraModel)


MALFORMED_MATRIX = (
    "%YAML 1.2\n---\nimage_width: 512\nimage_height: 512\nfisheye_model: 1\n"
    "camera_matrix: !!opencv-matrix\n   rows: 3\n   cx: 3\n   dt: d\n"
    "   data: [ 190.9, 0., 254.9, 0., 190.9, 256.8, 0., 0., 1. ]\n"
)


def test_malformed_opencv_matrix_is_an_error_not_a_crash():
    """OpenCV 5.0's FileNode.mat() corrupts the heap on this input; we never call it."""
    with pytest.raises(calib.CalibrationError, match="camera_matrix: expected .*opencv-matrix"):
        calib.parse(MALFORMED_MATRIX, "m.yaml")


def test_malformed_opencv_matrix_repeatedly_does_not_abort_the_process():
    import subprocess
    import sys

    code = (
        "from fisheyemotion import calib\n"
        f"text = {MALFORMED_MATRIX!r}\n"
        "for _ in range(500):\n"
        "    try:\n        calib.parse(text, 'm.yaml')\n"
        "    except ValueError:\n        pass\n"
        "print('ok')\n"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0 and done.stdout.strip() == "ok"


def test_basalt_ucm_becomes_meis_unified(tmp_path):
    doc = ('{"value0": {"intrinsics": [{"camera_type": "ucm", "intrinsics": {"fx": 200.0, '
           '"fy": 201.0, "cx": 320.0, "cy": 240.0, "alpha": 0.6}}], "resolution": [[640, 480]]}}')
    (tmp_path / "ucm.json").write_text(doc)
    cam = calib.load(tmp_path / "ucm.json")
    assert isinstance(cam, calib.Unified)
    assert cam.xi == pytest.approx(1.5) and cam.fx == pytest.approx(500.0)
    ray = np.array([0.3, -0.2, 0.5])
    d = np.linalg.norm(ray)
    expected_u = 200.0 * ray[0] / (0.6 * d + 0.4 * ray[2]) + 320.0
    assert cam.project(ray)[0][0] == pytest.approx(expected_u, rel=1e-12)
