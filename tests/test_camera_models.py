"""Generic tests run over every registered camera model (basalt-headers style)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from fisheyemotion import calib

from .cameras import ALL_CAMERAS, CAMERA_IDS, MODEL_SAMPLES

RNG_SEED = 1234


def sphere_rays(theta: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    phi = rng.uniform(0, 2 * np.pi, theta.shape)
    return np.stack([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)], -1)


def angle_between(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.arctan2(np.linalg.norm(np.cross(a, b), axis=-1), np.sum(a * b, axis=-1))


def test_every_registered_model_has_samples():
    assert set(MODEL_SAMPLES) == set(calib.MODELS)


def test_samples_include_more_than_180_degrees():
    wide = {name for name, cam in ALL_CAMERAS if np.degrees(cam.theta_max) > 90}
    assert {"kannala_brandt", "double_sphere", "enhanced_unified", "unified"} <= wide


@pytest.mark.parametrize(("name", "cam"), ALL_CAMERAS, ids=CAMERA_IDS)
def test_ray_pixel_ray_round_trip(name, cam):
    rng = np.random.default_rng(RNG_SEED)
    theta = rng.uniform(0, cam.theta_max, 20000)
    rays = sphere_rays(theta, rng)
    pixels, valid = cam.project(rays)
    assert valid.all()
    back, valid2 = cam.unproject(pixels)
    assert valid2.all()
    np.testing.assert_allclose(np.linalg.norm(back, axis=-1), 1.0, atol=1e-12)
    err = angle_between(back, rays)
    # Well-conditioned away from the fold at theta_max, where d(theta)/dr -> infinity.
    inner = theta < cam.theta_max - 0.02
    assert err[inner].max() < 1e-9
    assert err.max() < 1e-5


@pytest.mark.parametrize(("name", "cam"), ALL_CAMERAS, ids=CAMERA_IDS)
def test_pixel_ray_pixel_round_trip(name, cam):
    rng = np.random.default_rng(RNG_SEED)
    fx, fy, cx, cy = cam._affine()
    r_max = min(cam.radius_max, 20.0)
    r = r_max * np.sqrt(rng.uniform(0, 1, 20000))
    phi = rng.uniform(0, 2 * np.pi, r.shape)
    pixels = np.stack([fx * r * np.cos(phi) + cx, fy * r * np.sin(phi) + cy], -1)
    if not cam.radially_symmetric:  # its pixel domain is no disk: pixels of rays inside it
        pixels, _ = cam.project(sphere_rays(rng.uniform(0, 0.99 * cam.theta_max, 20000), rng))
    rays, valid = cam.unproject(pixels)
    assert valid.all()
    np.testing.assert_allclose(np.linalg.norm(rays, axis=-1), 1.0, atol=1e-12)
    back, valid2 = cam.project(rays)
    assert valid2.all()
    np.testing.assert_allclose(back, pixels, atol=1e-9 * max(fx, fy) * max(1.0, r_max))


@pytest.mark.parametrize(("name", "cam"), ALL_CAMERAS, ids=CAMERA_IDS)
def test_every_valid_image_pixel_round_trips(name, cam):
    rays, valid = cam.pixel_rays()
    grid = calib.pixel_grid(cam.width, cam.height)
    assert np.isnan(rays[~valid]).all()
    back, valid2 = cam.project(rays[valid])
    assert valid2.all()
    np.testing.assert_allclose(back, grid[valid], atol=1e-6)


@pytest.mark.parametrize(("name", "cam"), ALL_CAMERAS, ids=CAMERA_IDS)
def test_outside_domain_is_nan_and_invalid(name, cam):
    rng = np.random.default_rng(RNG_SEED)
    if cam.theta_max < np.pi - 1e-9:
        theta = rng.uniform(cam.theta_max + 1e-6, np.pi, 1000)
        pixels, valid = cam.project(sphere_rays(theta, rng))
        assert not valid.any()
        assert np.isnan(pixels).all()
    if np.isfinite(cam.radius_max) and cam.radius_max < 1e6:
        fx, fy, cx, cy = cam._affine()
        # A non-radial model's domain edge departs from the radial one by its small terms.
        margin = 1e-9 if cam.radially_symmetric else 0.05
        r = rng.uniform(cam.radius_max * (1 + margin), 3 * cam.radius_max, 1000)
        phi = rng.uniform(0, 2 * np.pi, r.shape)
        pixels = np.stack([fx * r * np.cos(phi) + cx, fy * r * np.sin(phi) + cy], -1)
        rays, valid = cam.unproject(pixels)
        assert not valid.any()
        assert np.isnan(rays).all()


@pytest.mark.parametrize(("name", "cam"), ALL_CAMERAS, ids=CAMERA_IDS)
def test_domain_edge_is_where_the_radial_map_stops_rising(name, cam):
    """theta_max is a true maximum of r(theta) (or the end of the sphere / model)."""
    t = cam.theta_max
    if t < np.pi - 1e-9:
        before = cam._radius(np.array([t - 1e-5]))[0]
        at = cam._radius(np.array([t]))[0]
        after = cam._radius(np.array([t + 1e-5]))[0]
        assert before < at
        assert not (after > at)  # decreasing, negative, or NaN beyond


@pytest.mark.parametrize(("name", "cam"), ALL_CAMERAS, ids=CAMERA_IDS)
def test_projection_jacobian_matches_central_differences(name, cam):
    rng = np.random.default_rng(RNG_SEED)
    theta = rng.uniform(0, 0.98 * cam.theta_max, 500)
    rays = sphere_rays(theta, rng) * rng.uniform(0.5, 3.0, (500, 1))
    _, jac, valid = cam.project_jacobian(rays)
    assert valid.all()
    h = 1e-6
    num = np.empty_like(jac)
    for k in range(3):
        step = np.zeros(3)
        step[k] = h
        plus, _ = cam.project(rays + step)
        minus, _ = cam.project(rays - step)
        num[..., k] = (plus - minus) / (2 * h)
    scale = np.abs(num).max(axis=(-1, -2), keepdims=True)
    np.testing.assert_allclose(jac / scale, num / scale, atol=2e-6)


@pytest.mark.parametrize(("name", "cam"), ALL_CAMERAS, ids=CAMERA_IDS)
def test_optical_axis(name, cam):
    _, jac, valid = cam.project_jacobian(np.array([[0.0, 0.0, 2.0]]))
    pix, _ = cam.project(np.array([0.0, 0.0, 1.0]))
    fx, fy, cx, cy = cam._affine()
    np.testing.assert_allclose(pix, [cx, cy], atol=1e-12)
    ray, ok = cam.unproject(np.array([cx, cy]))
    assert ok and np.allclose(ray, [0, 0, 1])
    h = 1e-6
    num = (cam.project(np.array([h, 0.0, 2.0]))[0] - cam.project(np.array([-h, 0.0, 2.0]))[0]) / (2 * h)
    np.testing.assert_allclose(jac[0, :, 0], num, rtol=1e-6, atol=1e-9)


@pytest.mark.parametrize(("name", "cam"), ALL_CAMERAS, ids=CAMERA_IDS)
def test_any_leading_shape(name, cam):
    rng = np.random.default_rng(RNG_SEED)
    rays = sphere_rays(rng.uniform(0, 0.9 * cam.theta_max, (2, 3, 4)), rng)
    pixels, valid = cam.project(rays)
    assert pixels.shape == (2, 3, 4, 2) and valid.shape == (2, 3, 4)
    back, valid2 = cam.unproject(pixels)
    assert back.shape == (2, 3, 4, 3) and valid2.shape == (2, 3, 4)
    single, ok = cam.unproject([cam._affine()[2], cam._affine()[3]])
    assert single.shape == (3,) and ok.shape == () and bool(ok)


@pytest.mark.parametrize(("name", "cam"), ALL_CAMERAS, ids=CAMERA_IDS)
def test_zero_and_non_finite_inputs_are_invalid_not_errors(name, cam):
    pixels, valid = cam.project([[0, 0, 0], [np.nan, 0, 1], [np.inf, 0, 1], [0, 0, -1e-300]])
    assert not valid[:3].any() and np.isnan(pixels[:3]).all()
    rays, valid = cam.unproject([[np.nan, 1.0], [np.inf, 0.0]])
    assert not valid.any() and np.isnan(rays).all()


@pytest.mark.parametrize(("name", "cam"), ALL_CAMERAS, ids=CAMERA_IDS)
def test_valid_mask_and_fov(name, cam):
    mask = cam.valid_pixel_mask()
    assert mask.shape == (cam.height, cam.width) and mask.dtype == bool
    assert 0 < cam.fov_deg <= 360
    assert cam.fov_deg <= 2 * np.degrees(cam.theta_max) + 1e-6


@pytest.mark.parametrize("name", sorted(calib.MODELS))
@given(data=st.data())
def test_project_unproject_property(name, data):
    """Any non-zero ray that projects validly comes back as the same direction."""
    cam = MODEL_SAMPLES[name][0]
    v = data.draw(st.lists(st.floats(-1e3, 1e3, allow_nan=False), min_size=3, max_size=3))
    ray = np.array(v)
    n = np.linalg.norm(ray)
    pixel, valid = cam.project(ray)
    if n < 1e-6 or not valid:
        return
    theta = np.arctan2(np.hypot(ray[0], ray[1]), ray[2])
    back, ok = cam.unproject(pixel)
    assert ok
    tol = 1e-9 if theta < cam.theta_max - 0.02 else 1e-5
    assert angle_between(back, ray / n) < tol


# ---- documented closed-form domains (independent of the generic numerical search) ----------

def test_double_sphere_unprojection_domain_matches_paper():
    for cam in MODEL_SAMPLES["double_sphere"]:
        if cam.alpha > 0.5:
            assert cam.radius_max == pytest.approx(1 / np.sqrt(2 * cam.alpha - 1), rel=1e-9)
        else:
            assert cam.radius_max > 1e6 or np.isinf(cam.radius_max)


def test_double_sphere_domain_is_wider_than_papers_w2_check():
    """Usenko's projection test z > -w2 * d1 rejects rays that round-trip exactly."""
    cam = MODEL_SAMPLES["double_sphere"][0]
    a, xi = cam.alpha, cam.xi
    w1 = (1 - a) / a if a > 0.5 else a / (1 - a)
    w2 = (w1 + xi) / np.sqrt(2 * w1 * xi + xi * xi + 1)
    theta_paper = np.arccos(-w2)
    assert cam.theta_max > theta_paper + np.radians(0.5)
    theta = np.linspace(theta_paper + 1e-4, cam.theta_max - 1e-3, 50)
    rays = np.stack([np.sin(theta), np.zeros_like(theta), np.cos(theta)], -1)
    assert (rays[:, 2] <= -w2).all()  # the paper would reject all of them
    pixels, valid = cam.project(rays)
    assert valid.all()
    back, ok = cam.unproject(pixels)
    assert ok.all() and angle_between(back, rays).max() < 1e-7


def test_enhanced_unified_unprojection_domain():
    cam = MODEL_SAMPLES["enhanced_unified"][0]
    assert cam.radius_max == pytest.approx(1 / np.sqrt(cam.beta * (2 * cam.alpha - 1)), rel=1e-9)
    wide = MODEL_SAMPLES["enhanced_unified"][1]
    assert np.degrees(wide.theta_max) > 90


def test_unified_domain_closed_form():
    cam = MODEL_SAMPLES["unified"][1]
    assert np.cos(cam.theta_max) == pytest.approx(-1 / cam.xi, abs=1e-9)
    assert cam.radius_max == pytest.approx(1 / np.sqrt(cam.xi**2 - 1), rel=1e-9)
    narrow = MODEL_SAMPLES["unified"][0]  # xi < 1: denominator cos(theta) + xi vanishes
    assert np.cos(narrow.theta_max) == pytest.approx(-narrow.xi, abs=1e-9)
    assert np.isinf(narrow.radius_max) or narrow.radius_max > 1e6


def test_kannala_brandt_theta_max_is_first_root_of_derivative():
    cam = MODEL_SAMPLES["kannala_brandt"][2]
    # d'(theta) = 1 + 3k1 t^2 + 5k2 t^4 + 7k3 t^6 + 9k4 t^8, as a polynomial in s = t^2.
    roots = np.roots([9 * cam.k4, 7 * cam.k3, 5 * cam.k2, 3 * cam.k1, 1.0])
    s = min(r.real for r in roots if abs(r.imag) < 1e-12 and r.real > 0)
    assert cam.theta_max == pytest.approx(np.sqrt(s), abs=1e-12)
    assert np.degrees(cam.theta_max) == pytest.approx(48.65, abs=0.01)


def test_unified_from_basalt_alpha_matches_alpha_form():
    alpha, f = 0.6, 250.0
    cam = calib.Unified.from_alpha(fx=f, fy=f, cx=320, cy=240, alpha=alpha, width=640, height=480)
    rng = np.random.default_rng(RNG_SEED)
    rays = sphere_rays(rng.uniform(0, 1.5, 100), rng)
    d = np.linalg.norm(rays, axis=-1)
    u = f * rays[:, 0] / (alpha * d + (1 - alpha) * rays[:, 2]) + 320
    np.testing.assert_allclose(cam.project(rays)[0][:, 0], u, rtol=1e-12)


# ---- parameter and input validation ---------------------------------------------------------

BAD_PARAMS = [
    ("double_sphere", "xi", 1.5),
    ("double_sphere", "alpha", -0.1),
    ("enhanced_unified", "alpha", 1.2),
    ("enhanced_unified", "beta", 0.0),
    ("unified", "xi", -0.5),
    ("radial_poly", "k1", -3.0),
    ("kannala_brandt", "fx", -1.0),
    ("pinhole", "fy", 0.0),
    ("kannala_brandt", "k1", float("nan")),
    ("pinhole", "width", 0),
    ("pinhole", "height", 10.5),
    ("kannala_brandt", "cx", "320"),
]


@pytest.mark.parametrize(("name", "param", "value"), BAD_PARAMS)
def test_bad_parameters_name_the_parameter(name, param, value):
    base = MODEL_SAMPLES[name][0].to_dict()
    base.pop("model")
    base[param] = value
    with pytest.raises(ValueError, match=param):
        calib.create(name, **base)


def test_unknown_model_lists_known_ones():
    with pytest.raises(ValueError, match="double_sphere"):
        calib.create("fisheye62", fx=1)
    with pytest.raises(ValueError, match=r"fisheye624.*fx.*expected.*\bf\b"):
        calib.create("fisheye624", fx=1, width=10, height=10)


def test_models_are_frozen_and_keyword_only():
    cam = MODEL_SAMPLES["double_sphere"][0]
    with pytest.raises(AttributeError):
        cam.xi = 0.0
    with pytest.raises(TypeError):
        calib.Pinhole(300, 300, 320, 240, 640, 480)


@pytest.mark.parametrize(
    ("method", "value", "match"),
    [
        ("project", np.zeros((4, 2)), r"rays.*\(\.\.\., 3\)"),
        ("unproject", np.zeros((4, 3)), r"pixels.*\(\.\.\., 2\)"),
        ("unproject", np.array(["a", "b"]), "pixels"),
        ("project", np.zeros(3, dtype=complex), "rays"),
        ("project", 1.0, "rays"),
    ],
)
def test_bad_arrays_name_the_argument(method, value, match):
    cam = MODEL_SAMPLES["pinhole"][0]
    with pytest.raises(ValueError, match=match):
        getattr(cam, method)(value)


def test_integer_pixels_are_accepted():
    cam = MODEL_SAMPLES["kannala_brandt"][0]
    rays, valid = cam.unproject(np.array([[10, 20], [255, 256]], dtype=np.int32))
    assert valid.all() and rays.dtype == np.float64
