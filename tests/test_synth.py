"""The scene renderer against the camera models, and the scenario library."""

from __future__ import annotations

import numpy as np
import pytest
import yaml

import fisheyemotion as fm
from fisheyemotion import synth
from fisheyemotion.sequence import Sequence

from .cameras import tumvi_kb

KB = tumvi_kb(320, 240, 100.0)
DS = fm.calib.DoubleSphere(fx=85, fy=85, cx=159.5, cy=119.5, xi=-0.17, alpha=0.59, width=320,
                           height=240)
EUCM = fm.calib.EnhancedUnified(fx=100, fy=100, cx=159.5, cy=119.5, alpha=0.63, beta=1.04,
                                width=320, height=240)
WIDE_DS = fm.calib.DoubleSphere(fx=70, fy=70, cx=159.5, cy=119.5, xi=0.3, alpha=0.45, width=320,
                                height=240)
CAMERAS = {"kb": KB, "ds": DS, "eucm": EUCM, "ds_wide": WIDE_DS}


@pytest.fixture(scope="module")
def crossing():
    sc = synth.load_scenario("crossing")
    r = synth.Renderer(KB, sc, supersample=1)
    return sc, r, [r.render(k) for k in range(3)]


def _world_points(renderer, index, pixels):
    """Independent check: hit points of chosen pixels from a fresh ray cast."""
    sc = renderer.scenario
    pose = sc.world_from_cam(index)
    rays, ok = renderer.camera.unproject(pixels)
    dirs = rays @ pose[:3, :3].T
    hits = renderer.intersect(pose[:3, 3], dirs, sc.time(index))
    return pose[:3, 3] + hits.t[:, None] * dirs, hits, ok


def test_wide_double_sphere_sees_more_than_180_degrees():
    assert WIDE_DS.fov_deg > 180


def _static_samples(renderer, later, seed):
    """3000 random valid pixels of frame 0 that see static surfaces: the pixels, their 3-D
    points, their (v, u) indices, and where ``camera.project`` puts the points in frame
    ``later`` (pixels, valid)."""
    sc = renderer.scenario
    rng = np.random.default_rng(seed)
    v, u = np.nonzero(KB.valid_pixel_mask())
    pick = rng.choice(len(u), 3000, replace=False)
    pixels = np.stack([u[pick], v[pick]], -1).astype(float)
    x0, hits, _ = _world_points(renderer, 0, pixels)
    static = (hits.obj == 0) | np.isin(hits.obj, [i + 1 for i, b in enumerate(sc.boxes) if not b.moving])
    static &= np.isfinite(hits.t)
    pose = sc.world_from_cam(later)
    projected, ok = KB.project((x0[static] - pose[:3, 3]) @ pose[:3, :3])
    return pixels[static], x0[static], (v[pick][static], u[pick][static]), projected, ok


def test_static_points_land_where_the_camera_model_projects_them(crossing):
    sc, r, frames = crossing
    pixels, x0, vu, projected, ok = _static_samples(r, 1, 0)
    # The renderer's flow says where each pixel goes; it must agree with camera.project.
    flow = frames[1].flow[vu]
    good = ok & np.isfinite(flow).all(axis=1)
    assert good.sum() > 1000
    np.testing.assert_allclose(pixels[good] + flow[good], projected[good], atol=1e-6)
    # And a fresh ray cast at the new pixel finds the same 3-D point (where not occluded).
    x1, hits1, _ = _world_points(r, 1, projected[good])
    same = np.linalg.norm(x1 - x0[good], axis=1) < 1e-6
    body = hits1.obj == len(sc.boxes) + 1  # the ego vehicle's body now hides the point
    assert same[~body].mean() > 0.97


def test_ground_truth_flow_of_moving_points_follows_the_object(crossing):
    sc, r, frames = crossing
    ys, xs = np.nonzero(frames[0].moving)
    pixels = np.stack([xs, ys], -1).astype(float)
    x0, hits, _ = _world_points(r, 0, pixels)
    boxes = [sc.boxes[i - 1] for i in hits.obj]
    t0, t1 = sc.time(0), sc.time(1)
    moved = np.array([b.world_from_box(t1)[:3, :3] @ np.linalg.inv(b.world_from_box(t0)[:3, :3])
                      @ (x - b.world_from_box(t0)[:3, 3]) + b.world_from_box(t1)[:3, 3]
                      for b, x in zip(boxes, x0, strict=True)])
    pose1 = sc.world_from_cam(1)
    projected, ok = KB.project((moved - pose1[:3, 3]) @ pose1[:3, :3])
    flow = frames[1].flow[ys, xs]
    np.testing.assert_allclose((pixels + flow)[ok], projected[ok], atol=1e-6)


def test_moving_mask_is_the_union_of_moving_ids(crossing):
    sc, _, frames = crossing
    moving_ids = [b.id for b in sc.boxes if b.moving]
    for f in frames:
        np.testing.assert_array_equal(f.moving > 0, np.isin(f.ids, moving_ids))
        assert f.moving.any()


def test_range_map_is_the_intersection_distance(crossing):
    sc, r, frames = crossing
    f = frames[0]
    rays, valid = KB.pixel_rays()
    pose = f.pose
    world = pose[:3, 3] + f.range[..., None] * (rays @ pose[:3, :3].T)
    road = valid & (f.ids == 0) & np.isfinite(f.range)
    # Road points lie on z = 0 (the range map is float32: ~1e-7 relative).
    assert (np.abs(world[road][:, 2]) <= 2e-7 * f.range[road]).all()
    for box in sc.boxes:
        sel = f.ids == box.id
        if not sel.any():
            continue
        p = box.world_from_box(0.0)
        local = (world[sel] - p[:3, 3]) @ p[:3, :3]
        half = np.array(box.size) / 2
        tol = 2e-7 * f.range[sel][:, None]
        on_face = (np.abs(np.abs(local) - half) <= tol).any(axis=1)
        assert on_face.all() and (np.abs(local) <= half + tol).all()
    up = (rays @ pose[:3, :3].T)[..., 2] > 0.5
    assert np.isinf(f.range[valid & up & (f.ids == 0)]).all()  # sky


@pytest.mark.parametrize("scenario", synth.list_scenarios())
@pytest.mark.parametrize("cam", ["kb", "ds", "eucm"])
def test_every_bundled_scenario_renders(scenario, cam):
    sc = synth.load_scenario(scenario)
    camera = CAMERAS[cam]
    small = fm.calib.create(camera.name, **{**camera.params, "fx": camera.params["fx"] / 2,
                                              "fy": camera.params["fy"] / 2, "cx": 79.5,
                                              "cy": 59.5}, width=160, height=120)
    frames = synth.render_frames(small, sc, frames=2, supersample=1)
    assert frames[1].image.shape == (120, 160, 3) and frames[1].flow.shape == (120, 160, 2)
    assert frames[1].image[small.valid_pixel_mask()].std() > 10
    if any(b.moving for b in sc.boxes):
        assert any(f.moving.any() for f in frames) or scenario in ("overtaking", "highway")


def test_wide_camera_renders_with_black_outside():
    sc = synth.load_scenario("static_world")
    f = synth.render_frames(WIDE_DS, sc, frames=2, supersample=1)[1]
    assert np.isfinite(f.flow[WIDE_DS.valid_pixel_mask()]).mean() > 0.9


def test_rendering_is_deterministic_from_the_seed():
    sc = synth.load_scenario("crossing")
    a = synth.Renderer(KB, sc, noise_sigma=2.0, seed=3).render(1).image
    b = synth.Renderer(KB, sc, noise_sigma=2.0, seed=3).render(1).image
    c = synth.Renderer(KB, sc, noise_sigma=2.0, seed=4).render(1).image
    np.testing.assert_array_equal(a, b)
    assert (a != c).any()


BAD_SCENARIOS = [
    ({"frames": 10}, "name"),
    ({"name": "x", "frames": 1}, "frames"),
    ({"name": "x", "ego": {"speed_kmh": -3}}, "ego.speed_kmh"),
    ({"name": "x", "camera": {"position": [0, 0, -1]}}, "camera.position"),
    ({"name": "x", "objects": [{"kind": "car"}]}, r"objects\[0\]\.start: missing"),
    ({"name": "x", "objects": [{"kind": "tank", "start": [0, 0]}]}, r"objects\[0\]\.kind"),
    ({"name": "x", "objects": [{"start": [0, 0], "category": "flying"}]}, r"objects\[0\]\.category"),
    ({"name": "x", "static": [{"center": [0, 0], "size": [1, -1, 1]}]}, r"static\[0\]\.size"),
    ({"name": "x", "static": [{"center": [0, 0], "texture": "marble"}]}, r"static\[0\]\.texture"),
    ({"name": "x", "objects": [{"id": 1, "start": [0, 0]}, {"id": 1, "start": [1, 1]}]}, "duplicate"),
    ({"name": "x", "speed": 3}, "speed: unknown field"),
]


@pytest.mark.parametrize(("doc", "match"), BAD_SCENARIOS)
def test_bad_scenarios_name_the_field(tmp_path, doc, match):
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump(doc))
    with pytest.raises(ValueError, match=match):
        synth.load_scenario(path)


def test_unknown_bundled_scenario_lists_the_known_ones():
    with pytest.raises(ValueError, match="crossing"):
        synth.load_scenario("nope")


def test_sequence_folder_round_trip(tmp_path):
    sc = synth.load_scenario("preceding")
    out = synth.write_sequence(tmp_path / "seq", KB, sc, frames=3, progress=False, supersample=1)
    seq = Sequence(out)
    assert len(seq) == 3 and seq.camera == KB
    np.testing.assert_allclose(seq.poses[2], sc.world_from_cam(2), atol=1e-12)
    np.testing.assert_allclose(seq.timestamps, [0, 1 / 15, 2 / 15])
    assert seq.frame(1).shape == (240, 320, 3) and seq.ids(1).dtype == np.uint16
    assert set(np.unique(seq.mask(1))) <= {0, 255}
    assert seq.flow(1)["flow"].shape == (240, 320, 2)
    assert synth.parse_scenario(seq.scenario) == sc
    objects = seq.objects
    assert list(objects.columns) == ["frame", "id", "kind", "category", "moving", "distance",
                                     "visible_pixels"]
    car = objects[(objects.id == 1)]
    assert (car.category == "preceding").all() and car.moving.all()
    assert (car.distance.diff().dropna() < 0).all()  # the ego vehicle closes in


def _slab_distance(origin, dirs, pose, size):
    """Independent reference: entry distance of rays into a box (inf when missed), no culling."""
    half = np.asarray(size, float) / 2
    o = (origin - pose[:3, 3]) @ pose[:3, :3]
    d = dirs @ pose[:3, :3]
    with np.errstate(divide="ignore", invalid="ignore"):
        t1, t2 = (-half - o) / d, (half - o) / d
    t_in = np.nanmax(np.minimum(t1, t2), axis=1)
    t_out = np.nanmin(np.maximum(t1, t2), axis=1)
    return np.where((t_in <= t_out) & (t_in > 0), t_in, np.inf)


@pytest.mark.parametrize("name", ["crossing", "parking_lot", "highway"])
def test_cast_finds_the_nearest_surface_of_every_ray(name):
    """The kernel's culled cast equals a brute-force cast over all boxes and the road."""
    sc = synth.load_scenario(name)
    r = synth.Renderer(KB, sc, supersample=1)
    rng = np.random.default_rng(3)
    dirs = rng.normal(size=(20_000, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    time = sc.time(5)
    origin = sc.world_from_cam(5)[:3, 3]
    hits = r.intersect(origin, dirs, time)
    boxes = r._boxes_at(time)
    t_all = np.stack([np.where(dirs[:, 2] < 0, -origin[2] / dirs[:, 2], np.inf)]
                     + [_slab_distance(origin, dirs, p, b.size) for b, p in boxes], axis=1)
    nearest = t_all.min(axis=1)
    np.testing.assert_allclose(hits.t, nearest, rtol=1e-12)
    expected_obj = np.where(np.isinf(nearest), -1, np.argmin(t_all, axis=1))
    assert (hits.obj == expected_obj).mean() > 0.9999  # ties at edges may go either way
    assert (hits.obj > 0).sum() > 100  # the test does hit boxes


@pytest.mark.parametrize("gap", [2, 3])
def test_flow_over_a_gap_lands_where_the_camera_model_projects_static_points(crossing, gap):
    _, r, _ = crossing
    pixels, _, vu, projected, ok = _static_samples(r, gap, gap)
    flow = r.flow(gap, gap=gap)[vu]
    good = ok & np.isfinite(flow).all(axis=1)
    assert good.sum() > 1000
    np.testing.assert_allclose(pixels[good] + flow[good], projected[good], atol=1e-6)


def test_flow_gap_is_checked(crossing):
    _, r, _ = crossing
    with pytest.raises(ValueError, match="gap"):
        r.flow(2, gap=3)
    with pytest.raises(ValueError, match="gap"):
        r.flow(2, gap=0)
