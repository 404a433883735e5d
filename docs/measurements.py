"""The supporting measurements quoted in docs/geometry.md and docs/evaluation.md, from the demo's
sequences.

    make demo                       # renders data/generated/demo/sequences
    .venv/bin/python docs/measurements.py

Prints: the flow error on static structure with and without the static-scene model, the share
of cells above 3 sigma in the height term per surface, how fast and how well the road is
estimated in the first camera's frame, what the false regions of the default pipeline are, how
far the prior and the flow are off there, why the scene model's ranges are wrong there, how
far the scene model's ranges are off on the tuning street's brick wall, what the ground-contact
test's scene-agreement veto and the arc test cost and buy with the exact flow, whether one
region statistic could drop the false regions, which ranges the ground-contact test fails
on, how far Table 2 moves under negligible, noisy
and refined poses over several draws, and with the scene model off, how far a warp prior
from the true depth, with and without occlusions handled, would go, how far off a stream's
first pair's prior is with and without the scene-model bootstrap, the share of pairs with a
false region by the frame they end at, the streets' Table 2 with the ground-contact test
given the true ranges, where a moving object's coverage is lost step by step, the crossing
pedestrians' cells flagged by their elevation from the plane through the epipole, how far
the flow departs from the prior it was warped by, and the photometric search's reach and the
share a carried cell needs (``Params.carry_share``) and the receding test (``Params.receding``)
over five runs, how far beyond the road the exact flow reads each moving object's base, what
the two-span test leaves against the true ranges and visibility, and how much of a crossing
pedestrian two views show given the exact flow and Farneback's.

    .venv/bin/python docs/measurements.py true_depth_prior_bounds   # one of them, by name
"""

from __future__ import annotations

import sys
import warnings
from pathlib import Path

import cv2
import numpy as np

import fisheyemotion as fm
from fisheyemotion.frames import to_gray
from fisheyemotion.sequence import Sequence
from fisheyemotion.significance import cell_sigma, pixel_angle
from fisheyemotion.synth import Renderer, load_scenario

SEQUENCES = Path(__file__).resolve().parents[1] / "data" / "generated" / "demo" / "sequences"


def _grays(seq: Sequence) -> list[np.ndarray]:
    return [to_gray(seq.frame(k), "frame") for k in range(len(seq))]


def scene_prior_flow_error(name: str = "street_kb", frames: int = 30) -> None:
    """Median flow error (px) on static boxes (buildings, walls, parked cars, poles) against
    the exact flow, with the road/far-field prior alone and with the static-scene model."""
    seq = Sequence(SEQUENCES / name)
    renderer = Renderer(seq.camera, load_scenario(seq.path / "scenario.yaml"), supersample=1)
    grays = _grays(seq)
    for scene_prior in (False, True):
        det = fm.MotionDetector(seq.camera, params=fm.Params(scene_prior=scene_prior),
                                roi=seq.roi())
        errors = []
        for k in range(3, frames):
            flow = det.flow(grays[k - 3], grays[k], seq.poses[k - 3], seq.poses[k])
            det.detect_flow(flow, seq.poses[k - 3], seq.poses[k], prev=grays[k - 3], stream=True)
            exact = renderer.flow(k, gap=3)
            ids = seq.ids(k - 3)
            static = (ids > 0) & (ids < 65535) & (seq.mask(k - 3) == 0) & np.isfinite(exact).all(-1)
            errors.append(np.median(np.linalg.norm(flow - exact, axis=-1)[static]))
        print(f"{name}: flow error on static structure, scene model {'on ' if scene_prior else 'off'}:"
              f" median per frame {np.percentile(errors, 10):.2f}-{np.percentile(errors, 90):.2f} px "
              f"(10th-90th percentile), last 10 frames {np.median(errors[-10:]):.2f} px")


def height_significance(name: str = "street_kb", preceding_id: int = 2) -> None:
    """Share of cells whose height deviation exceeds 3 flow-error sigmas, per surface."""
    seq = Sequence(SEQUENCES / name)
    cam = seq.camera
    det = fm.MotionDetector(cam, roi=seq.roi())
    angle = pixel_angle(cam, det._centres)
    grays = _grays(seq)
    counts = {"preceding car": [0, 0], "static objects": [0, 0], "road": [0, 0]}
    for k in range(3, len(seq)):
        flow = det.flow(grays[k - 3], grays[k], seq.poses[k - 3], seq.poses[k])
        result = det.detect_flow(flow, seq.poses[k - 3], seq.poses[k], prev=grays[k - 3],
                                 stream=True)
        rays1, _ = cam.unproject(det._centres + result.grid.flow)
        res = fm.constraints(det._rays0, rays1, seq.poses[k - 3], seq.poses[k], params=det.params)
        with np.errstate(invalid="ignore", divide="ignore"):
            z = res.height / cell_sigma(flow, det.params.grid, angle, floor=det.params.flow_sigma)
        ids = seq.ids(k - 3)[2::5, 2::5][: z.shape[0], : z.shape[1]]
        valid = result.grid.valid
        for key, sel in (("preceding car", ids == preceding_id),
                         ("static objects", (ids >= 20) & (ids < 65535)), ("road", ids == 0)):
            m = valid & sel
            counts[key][0] += int((z[m] > 3).sum())
            counts[key][1] += int(m.sum())
    for key, (above, total) in counts.items():
        print(f"{name}: height deviation above 3 sigma: {key} {100 * above / max(total, 1):.2f} % "
              f"of {total} cells")


def road_estimates(names=("preceding", "street_kb", "highway", "crossing", "street_heldout_ds",
                          "overtaking"), frames: int = 12) -> None:
    """Frame at which the road is found, and its tilt and height errors over the first
    ``frames`` frames, with the poses in the first camera's frame (no height given) and in the
    raised, turned frame with the camera height given (``eval --world``)."""
    from fisheyemotion.eval.evaluate import world_transform

    from fisheyemotion.frames import to_gray
    from fisheyemotion.ground import GroundEstimator

    tilts, heights, found = [], [], []
    for name in names:
        seq = Sequence(SEQUENCES / name)
        for world, height in (("first_camera", None), ("raised", float(seq.poses[0][2, 3]))):
            moved, truth = world_transform(world, seq.poses[0])
            ground = GroundEstimator(camera_height=height)
            first = None
            for k in range(min(len(seq), frames)):
                pose = moved @ seq.poses[k]
                ground.observe(seq.camera, to_gray(seq.frame(k), "frame"), pose,
                               mask=seq.camera.valid_pixel_mask())
                if ground.road is None:
                    continue
                first = k if first is None else first
                tilts.append(np.degrees(np.arccos(np.clip(ground.road.up @ truth.up, -1, 1))))
                heights.append(abs(ground.road.height(pose[:3, 3]) - truth.height(pose[:3, 3])))
            found.append(first)
    print(f"road found at frame {sorted(set(found))}; over the first {frames} frames: tilt "
          f"median {np.median(tilts):.3f} deg, 90th percentile {np.percentile(tilts, 90):.3f} "
          f"deg; height error median {100 * np.median(heights):.1f} cm, max "
          f"{100 * np.max(heights):.1f} cm")


def false_regions(names=("street_kb", "street_ds", "crossing", "highway", "overtaking",
                         "preceding", "approaching", "curve", "parking_lot",
                         "static_world")) -> None:
    """The regions of ``Params()`` (Farneback, streamed) that touch no moving object, against
    those that do: size, distance to the nearest moving object, mean likelihood."""
    from scipy import ndimage
    from skimage.measure import label, regionprops

    false, true = [], []
    for name in names:
        seq = Sequence(SEQUENCES / name)
        valid = seq.camera.valid_pixel_mask() & (seq.roi() > 0 if seq.roi() is not None else True)
        det = fm.MotionDetector(seq.camera, params=fm.Params(), roi=seq.roi())
        for k in range(len(seq)):
            result = det.apply(seq.frame(k), seq.poses[k])
            if result is None:
                continue
            moving = (seq.mask(k) > 0) & valid
            far = ndimage.distance_transform_edt(~moving) if moving.any() else None
            for region in regionprops(label((result.mask > 0) & valid, connectivity=2)):
                pix = tuple(region.coords.T)
                row = (region.area, result.likelihood[pix].mean(),
                       far[pix].min() if far is not None else np.inf)
                (true if moving[pix].any() else false).append(row)
    f, t = np.array(false), np.array(true)
    print(f"false regions: {len(f)}, area median {np.median(f[:, 0]):.0f} px (true "
          f"{np.median(t[:, 0]):.0f}), half of them at most {np.percentile(f[:, 0], 50):.0f} px; "
          f"distance to the nearest moving object median {np.median(f[:, 2]):.0f} px; mean "
          f"likelihood median {np.median(f[:, 1]):.4f} (true {np.median(t[:, 1]):.4f})")


def prior_error_at_false_regions(names=("street_kb", "street_heldout_ds")) -> None:
    """Median error (pixels, against the renderer's exact flow) of the ego prior the flow was
    warped by and of the measured flow, at the cells of false regions led by the epipolar and by
    the anti-parallel term and at the static cells the detector left unflagged (``Params()``,
    Farneback, streamed)."""
    from skimage.measure import label

    from fisheyemotion.constraints import constraints
    from fisheyemotion.detection import CONSTRAINT_NAMES
    from fisheyemotion.flow import grid_average

    p = fm.Params()
    g, gap = p.grid, p.frame_gap
    weights = dict(zip(CONSTRAINT_NAMES, p.weights, strict=True))
    quiet = {"prior": [], "flow": []}
    false = {lead: {"prior": [], "flow": []} for lead in ("epipolar", "antiparallel")}
    for name in names:
        seq = Sequence(SEQUENCES / name)
        det = fm.MotionDetector(seq.camera, params=p, roi=seq.roi())
        renderer = Renderer(seq.camera, load_scenario(seq.path / "scenario.yaml"), supersample=1)
        for k in range(len(seq)):
            if k >= gap:
                t0, t1 = seq.poses[k - gap], seq.poses[k]
                prior, _ = det._prior(t0, t1, det._prior_road(t0, t1), view=det._pixel_valid,
                                      scene=det.scene)
            result = det.apply(seq.frame(k), seq.poses[k])
            if result is None:
                continue
            exact = renderer.flow(k, gap=gap)
            cells = result.grid
            known = grid_average(np.isfinite(exact[..., 0]).astype(np.float32), g) > 0.99
            exact = grid_average(np.nan_to_num(exact), g)
            errors = {"prior": np.linalg.norm(grid_average(prior, g) - exact, axis=-1),
                      "flow": np.linalg.norm(cells.flow - exact, axis=-1)}
            moving = np.where(cells.valid, cells.likelihood, 0) > p.threshold
            truth = grid_average((seq.mask(k - gap) > 0).astype(np.float32), g) > 0
            ok = cells.valid & known
            for key in errors:
                quiet[key].append(errors[key][ok & ~truth & ~moving])
            rays1, _ = seq.camera.unproject(cells.centres + cells.flow)
            res = constraints(det._rays0, rays1, t0, t1, road=det.road, params=p)
            labels = label(moving, connectivity=2)
            for i in range(1, labels.max() + 1):
                region = labels == i
                if region.sum() * g * g < p.min_area or truth[region].any():
                    continue
                lead = max(weights, key=lambda t: np.nanmean(weights[t] * getattr(res, t)[region]))
                if lead in false and (region & ok).any():
                    for key in errors:
                        false[lead][key].append(np.median(errors[key][region & ok]))
    med = {k: np.median(np.concatenate(quiet[k])) for k in quiet}
    print(f"prior / flow error against the exact flow ({', '.join(names)}): static cells not "
          f"flagged {med['prior']:.2f} / {med['flow']:.2f} px (median over cells)")
    for lead, e in false.items():
        flow = np.array(e["flow"])
        print(f"  false regions led by the {lead} term: {np.median(e['prior']):.1f} / "
              f"{np.median(flow):.1f} px (median over {len(flow)} regions of each region's "
              f"median; flow within 0.5 px in {100 * np.mean(flow < 0.5):.0f} % of them)")


def scene_model_at_false_cells(names=("street_kb", "street_heldout_ds")) -> None:
    """Why the prior is wrong where false cells are: the static cells of the false regions of
    ``Params()`` (Farneback, streamed) whose prior is more than 2 px off the exact flow, the
    share of them whose scene-model range (the 8-px sample the prior used) is more than 10 % off
    the true range, and how many of those samples hold no stored point within 10 % of it; and
    the parked-car cells whose prior is right but which are flagged (the anti-parallel term):
    the measured ranges of the unflagged cells of the same car below them, over the true ones."""
    for name in names:
        _scene_model_at_false_cells(name)


def _scene_model_at_false_cells(name: str) -> None:
    from fisheyemotion.flow import grid_average
    from fisheyemotion.static_scene import triangulate_range

    p = fm.Params()
    g, gap = p.grid, p.frame_gap
    seq = Sequence(SEQUENCES / name)
    scenario = load_scenario(seq.path / "scenario.yaml")
    kinds = {b.id: b.kind for b in scenario.boxes}
    det = fm.MotionDetector(seq.camera, params=p, roi=seq.roi())
    renderer = Renderer(seq.camera, scenario, supersample=1)
    step = det._prior.step
    prior_off, scene_off, no_right_point, below = 0, 0, 0, []
    flagged_total = 0
    for k in range(len(seq)):
        if k >= gap:
            t0, t1 = seq.poses[k - gap], seq.poses[k]
            prior, _ = det._prior(t0, t1, det._prior_road(t0, t1), view=det._pixel_valid,
                                  scene=det.scene)
            scene = det._scene_ranges_at_cells(t0) if len(det.scene) else None
            points = det.scene.points()
        result = det.apply(seq.frame(k), seq.poses[k])
        if result is None or result.static_camera or scene is None:
            continue
        cells = result.grid
        rows, cols = cells.valid.shape
        c = (g - 1) // 2
        truth = renderer.render(k - gap)
        true_range = truth.range[c:rows * g:g, c:cols * g:g].astype(np.float64)
        ids = truth.ids[c:rows * g:g, c:cols * g:g]
        exact = renderer.flow(k, gap=gap)
        known = grid_average(np.isfinite(exact[..., 0]).astype(np.float32), g) > 0.99
        exact = grid_average(np.nan_to_num(exact), g)
        prior_error = np.linalg.norm(grid_average(prior, g) - exact, axis=-1)
        moving = grid_average((seq.mask(k - gap) > 0).astype(np.float32), g) > 0
        flagged = cells.valid & known & (np.where(cells.valid, cells.likelihood, 0) > p.threshold)
        false = flagged & ~moving & np.isfinite(true_range)
        flagged_total += int(false.sum())
        bad = false & (prior_error > 2)
        prior_off += int(bad.sum())
        wrong = bad & (np.abs(scene / true_range - 1) > 0.1)
        scene_off += int(wrong.sum())
        local = (points - t0[:3, 3]) @ t0[:3, :3]
        pix, ok = seq.camera.project(local)
        reach = np.linalg.norm(local, axis=-1)
        sample = np.where(ok, np.floor(pix[:, 1] / step) * 10000 + np.floor(pix[:, 0] / step), -1)
        for r, cc in zip(*np.nonzero(wrong), strict=True):
            centre = cells.centres[r, cc]
            here = sample == (centre[1] // step) * 10000 + centre[0] // step
            if not (np.abs(reach[here] / true_range[r, cc] - 1) <= 0.1).any():
                no_right_point += 1
        # Parked-car cells flagged with a right prior: the same car's unflagged cells below them.
        rays1, _ = seq.camera.unproject(cells.centres + cells.flow)
        ranges, _ = triangulate_range(det._rays0, rays1, t0, t1, far=p.prior_distance)
        for r, cc in zip(*np.nonzero(false & (prior_error <= 2)), strict=True):
            if kinds.get(int(ids[r, cc])) != "parked_car":
                continue
            for d in range(1, 5):
                if r + d < rows and ids[r + d, cc] == ids[r, cc] and not flagged[r + d, cc]:
                    below.append(ranges[r + d, cc] / true_range[r + d, cc])
    below = np.array(below)
    below = below[np.isfinite(below)]
    q = np.percentile(below, [25, 50, 75])
    print(f"{name}: of {flagged_total} false cells {100 * prior_off / flagged_total:.0f} % have a "
          f"prior more than 2 px off; of those {100 * scene_off / max(prior_off, 1):.0f} % read a "
          f"scene-model range more than 10 % off the true one, and in "
          f"{100 * no_right_point / max(scene_off, 1):.0f} % of these the sample holds no stored "
          f"point within 10 % of it; the unflagged cells below flagged parked-car cells (right "
          f"prior) are measured at {q[0]:.2f} / {q[1]:.2f} / {q[2]:.2f} of their true range "
          f"(quartiles)")


def wall_ranges(name: str = "street_kb", frame: int = 30) -> None:
    """The scene model's ranges against the true ones on the upper right of the tuning street
    (the brick wall), after streaming to ``frame``."""
    seq = Sequence(SEQUENCES / name)
    det = fm.MotionDetector(seq.camera, params=fm.Params(), roi=seq.roi())
    for k in range(frame + 1):
        det.apply(seq.frame(k), seq.poses[k])
    gap = det.params.frame_gap
    truth = Renderer(seq.camera, load_scenario(seq.path / "scenario.yaml"),
                     supersample=1).render(frame - gap).range
    ranges = det._scene_ranges_at_cells(seq.poses[frame - gap])
    import cv2

    h, w = truth.shape
    full = cv2.resize(np.nan_to_num(ranges, nan=0), (w, h), interpolation=cv2.INTER_NEAREST)
    region = (slice(60, 140), slice(450, 620))
    rel = np.where(full[region] > 0, full[region] / truth[region] - 1, np.nan)
    print(f"{name} frame {frame}: scene-model range on the wall's upper band "
          f"{100 * np.nanmedian(rel):+.0f} % of the true one (median)")


def pose_steps(names=("crossing", "highway", "street_kb", "street_ds", "curve", "preceding",
                      "overtaking", "approaching", "parking_lot", "street_heldout_kb",
                      "street_heldout_ds", "static_world")) -> None:
    """Length of each step estimated from the images and the camera height, against the true
    one (median and range of the ratio per sequence), and the rotation error between
    consecutive frames."""
    from fisheyemotion.eval.pose_sources import pose_errors

    from fisheyemotion.egomotion import PoseTracker

    medians, lo, hi, rotations = [], [], [], []
    for name in names:
        seq = Sequence(SEQUENCES / name)
        roi = seq.roi()
        tracker = PoseTracker(seq.camera, mask=None if roi is None else roi > 0,
                              camera_height=float(fm.Road().height(seq.poses[0, :3, 3])))
        est = np.stack([tracker(gray) for gray in _grays(seq)])
        ratio = (np.linalg.norm(np.diff(est[:, :3, 3], axis=0), axis=-1)
                 / np.linalg.norm(np.diff(seq.poses[:, :3, 3], axis=0), axis=-1))
        medians.append(np.median(ratio))
        lo.append(ratio.min())
        hi.append(ratio.max())
        rotations += list(pose_errors(est, seq.poses, 1).rotation_error_deg)
    print(f"estimated steps / true steps: medians per sequence {min(medians):.3f}-"
          f"{max(medians):.3f}, single steps {min(lo):.2f}-{max(hi):.2f}; rotation error between "
          f"consecutive frames median {np.median(rotations):.3f} deg")


def _table2_all_scenes(params, **options) -> dict[str, float]:
    """Table 2 over every demo sequence, in per cent: ``{"<category> det.|cov.": value}``
    (``options``: :func:`fisheyemotion.eval.evaluate.evaluate_sequence`'s)."""
    from fisheyemotion.eval.evaluate import combine, evaluate, sequence_paths
    from fisheyemotion.eval.metrics import table2

    tables = combine(evaluate(sequence_paths([SEQUENCES]), params, ablation=False,
                              progress=False, **options))
    t = table2(tables["objects"], tables["frames"]).set_index("category")
    return {f"{c} {k}": 100 * float(t.loc[c, m]) for c in t.index
            for k, m in (("det.", "detection_rate"), ("cov.", "coverage_rate"))}


def _negligible(seed: int):
    """Every pose turned by 0.001 deg about a random axis, nothing else: a perturbation that
    changes nothing that matters (a few thousandths of a pixel)."""
    from fisheyemotion.eval.pose_sources import Perturbation

    return Perturbation(rotation_deg=0.001, translation=0.0, time_offset_s=0.0, seed=seed)


def pose_noise_draws(draws: int = 8) -> None:
    """Table 2 over all scenes with the true poses, beside its spread under a negligible
    perturbation (:func:`_negligible`, ``draws`` draws: how far the figures move when nothing
    that matters changes) and over the same draws of the default noise (0.3 deg, 3 % of the
    step, 5 ms), given as they are and refined (``pose_refinement='on'``): each row's mean and
    range over the draws, and each mean's difference from the true poses' figure and from the
    negligible perturbation's mean."""
    from fisheyemotion.eval.pose_sources import Perturbation

    true = _table2_all_scenes(fm.Params())
    sources = {
        "negligible (0.001 deg)": (fm.Params(), _negligible),
        "perturbed": (fm.Params(), lambda s: Perturbation(seed=s)),
        "perturbed, refined": (fm.Params(pose_refinement="on"), lambda s: Perturbation(seed=s)),
    }
    runs = {name: [_table2_all_scenes(params, poses="perturbed", noise=noise(s))
                   for s in range(draws)]
            for name, (params, noise) in sources.items()}
    floor = {key: np.mean([r[key] for r in runs["negligible (0.001 deg)"]]) for key in true}
    print(f"Table 2 over all scenes, {draws} draws each: mean [min-max]")
    for key in true:
        cells = [f"true {true[key]:.1f}"]
        for name, draw in runs.items():
            values = np.array([r[key] for r in draw])
            cells.append(f"{name} {values.mean():.1f} [{values.min():.1f}-{values.max():.1f}]")
        print(f"  {key}: " + ", ".join(cells))
    for name, draw in runs.items():
        means = {key: np.mean([r[key] for r in draw]) for key in true}
        print(f"  {name}: largest difference of the means from the true poses' "
              f"{max(abs(means[k] - true[k]) for k in true):.1f}, from the negligible "
              f"perturbation's {max(abs(means[k] - floor[k]) for k in true):.1f}; single draws "
              "from the true poses' " + ", ".join(
                  f"{max(abs(r[k] - true[k]) for k in true):.1f}" for r in draw))


def scene_model_amplification(draws: int = 4) -> None:
    """The same negligible perturbation as :func:`pose_noise_draws` with the static-scene model
    off (``scene_prior=False``): the largest difference of each draw's Table 2 from the
    unperturbed run's, which says whether the scene model's feedback (each pair's result in the
    next pair's prior) is what amplifies it."""
    params = fm.Params(scene_prior=False)
    base = _table2_all_scenes(params)
    moved = [np.nanmax([abs(row[k] - base[k]) for k in base])
             for row in (_table2_all_scenes(params, poses="perturbed", noise=_negligible(s))
                         for s in range(draws))]
    print("without the scene model, 0.001 deg per frame moves Table 2 by at most "
          + ", ".join(f"{m:.1f}" for m in moved) + " points (one value per draw)")


def scene_agreement_tradeoff() -> None:
    """The ground-contact test's scene-agreement veto alone (``contact_arc=0``), with the arc
    test of standing cells (the defaults) and off, with the renderer's exact flow over all the
    demo sequences: false-positive frames and crossing detection per scene group."""
    import importlib

    from fisheyemotion.eval.evaluate import evaluate, sequence_paths
    from fisheyemotion.eval.report import groups_table

    detect_module = importlib.import_module("fisheyemotion.detector")
    rows = {}
    saved = detect_module.SCENE_AGREEMENT
    variants = (("veto alone", saved, fm.Params(contact_arc=0.0)),
                ("veto and arc test (defaults)", saved, fm.Params()),
                ("no veto", np.inf, fm.Params(contact_arc=0.0)))
    try:
        for name, tolerance, params in variants:
            detect_module.SCENE_AGREEMENT = tolerance  # inf: no range ever disagrees
            result = evaluate(sequence_paths([SEQUENCES]), params, workers=1,
                              progress=False, ablation=False, exact_flow=True)
            rows[name] = groups_table(result).set_index("scenes")
    finally:
        detect_module.SCENE_AGREEMENT = saved
    for name, table in rows.items():
        cells = ", ".join(f"{scenes} {100 * r['FP frames']:.0f} % / {100 * r['crossing det.']:.0f} %"
                          for scenes, r in table.iterrows())
        print(f"exact flow, {name}: false-positive frames / crossing detected: {cells}")


def ground_contact_ranges(names=("street_kb", "street_heldout_kb")) -> None:
    """Which ranges the ground-contact test fails on: the cells of the regions it tests (led by
    the anti-parallel term, ``Params()``, Farneback, streamed) that it finds standing, with the
    ranges it was given (the measured flow's), with the exact flow's static readings, and with
    the measured ones inside the region but the exact ones around it, and the other way round;
    regions that touch no moving object (static structure) and those mostly on a moving one."""
    from fisheyemotion import detector as detector_module
    from fisheyemotion.flow import grid_average
    from fisheyemotion.static_scene import triangulate_range

    standing = detector_module.standing_regions
    seen: dict = {}

    def capture(moving, share, ranges, *args, **kwargs):
        seen.update(moving=moving.copy(), share=share.copy(), ranges=ranges.copy(), args=args,
                    kwargs=kwargs)
        return standing(moving, share, ranges, *args, **kwargs)

    p = fm.Params()
    g, gap = p.grid, p.frame_gap
    totals = {kind: np.zeros(5) for kind in ("static", "moving")}
    detector_module.standing_regions = capture
    try:
        for name in names:
            seq = Sequence(SEQUENCES / name)
            renderer = Renderer(seq.camera, load_scenario(seq.path / "scenario.yaml"),
                                supersample=1)
            det = fm.MotionDetector(seq.camera, params=p, roi=seq.roi())
            for k in range(len(seq)):
                seen.clear()
                det.apply(seq.frame(k), seq.poses[k])
                if not seen:
                    continue
                t0, t1 = seq.poses[k - gap], seq.poses[k]
                exact = grid_average(np.nan_to_num(renderer.flow(k, gap=gap), nan=1e5), g)
                rays1, _ = seq.camera.unproject(det._centres + exact)
                true = triangulate_range(det._rays0, rays1, t0, t1, far=p.prior_distance)[0]
                rows, cols = true.shape
                c = (g - 1) // 2
                moving_px = seq.mask(k - gap)[c:rows * g:g, c:cols * g:g] > 0
                n, labels = cv2.connectedComponents(seen["moving"].astype(np.uint8),
                                                    connectivity=8)
                for i in range(1, n):
                    cells = labels == i
                    if seen["share"][cells].mean() < 0.5:  # not tested
                        continue
                    measured = seen["ranges"]
                    row = [cells.sum()]
                    for ranges in (measured, true, np.where(cells, measured, true),
                                   np.where(cells, true, measured)):
                        stands = standing(cells, seen["share"], ranges, *seen["args"],
                                          **seen["kwargs"])
                        row.append(stands[cells].sum())
                    totals["moving" if moving_px[cells].mean() > 0.5 else "static"] += row
    finally:
        detector_module.standing_regions = standing
    for kind, (cells, *stand) in totals.items():
        print(f"{', '.join(names)}: {int(cells)} cells of tested regions on {kind} objects; "
              "standing with the measured ranges / the exact ones / measured in the region and "
              "exact around it / exact in the region and measured around it: "
              + " / ".join(f"{100 * s / max(cells, 1):.0f} %" for s in stand))


def false_region_rules() -> None:
    """Could one region statistic drop the false regions of ``Params()`` (Farneback, streamed,
    every demo sequence)? False-positive frames per scene group with the regions that a rule
    names dropped, beside the share of true regions (touching a moving object) it drops too."""
    import cv2
    import pandas as pd

    groups = {"open road": ("approaching", "crossing", "curve", "highway", "overtaking",
                            "parking_lot", "preceding", "static_ego", "static_world"),
              "street (tuning)": ("street_kb", "street_ds"),
              "street (held out)": ("street_heldout_kb", "street_heldout_ds")}
    weights = dict(zip(("epipolar", "depth", "height", "antiparallel"), fm.Params().weights,
                       strict=True))
    rows, frames = [], {g: 0 for g in groups}
    for group, names in groups.items():
        for name in names:
            seq = Sequence(SEQUENCES / name)
            cam = seq.camera
            h, w = cam.height, cam.width
            rays, _ = cam.unproject(np.stack(np.meshgrid(np.arange(w), np.arange(h)), -1)
                                    .astype(float))
            off_axis = np.degrees(np.arccos(np.clip(rays[..., 2], -1, 1)))
            valid = cam.valid_pixel_mask() & (seq.roi() > 0 if seq.roi() is not None else True)
            det = fm.MotionDetector(cam, params=fm.Params(), roi=seq.roi())
            before = None
            items = ((seq.frame(i), seq.poses[i]) for i in range(len(seq)))
            for k, result in enumerate(det.stream(items)):
                if result is None:
                    continue
                frames[group] += 1
                mask = (result.mask > 0) & valid
                moving = (seq.mask(k) > 0) & valid
                n, labels = cv2.connectedComponents(mask.astype(np.uint8), connectivity=8)
                for i in range(1, n):
                    region = labels == i
                    lead = max(weights, key=lambda t: weights[t] * result.maps[t][region].mean())
                    rows.append({"group": group, "sequence": name, "frame": k,
                                 "true": bool(moving[region].any()), "area": int(region.sum()),
                                 "off_axis": float(off_axis[region].mean()), "lead": lead,
                                 "before": bool(before is not None and before[region].any())})
                before = mask
    df = pd.DataFrame(rows)
    rules = {"none": np.zeros(len(df), bool),
             "anti-parallel-led beyond 60 deg": (df.lead == "antiparallel") & (df.off_axis > 60),
             "every region beyond 60 deg": df.off_axis > 60,
             "every anti-parallel-led region": df.lead == "antiparallel",
             "not flagged in the frame before": ~df.before,
             "smaller than 400 px": df.area < 400}
    print(f"false regions {int((~df.true).sum())}, of which beyond 60 deg off axis "
          f"{100 * (df.off_axis[~df.true] > 60).mean():.0f} % (true regions "
          f"{100 * (df.off_axis[df.true] > 60).mean():.0f} %)")
    for rule, drop in rules.items():
        cells = []
        for group in groups:
            kept = df[(df.group == group) & ~drop & ~df.true]
            fp = len(kept.groupby(["sequence", "frame"])) / frames[group]
            lost = drop[(df.group == group) & df.true].mean()
            cells.append(f"{group} {100 * fp:.0f} % ({100 * lost:.0f} % of true regions dropped)")
        print(f"  drop {rule}: false-positive frames " + ", ".join(cells))


def stored_point_errors(name: str = "street_kb", params: fm.Params | None = None) -> None:
    """The points the static-scene model stores, against the true range at their cells, per
    surface: how many are more than 10 % off, how many of those were stored where the model
    already held a range that was itself more than 10 % off, and how many of those repeat the
    model's range within 5 % (the flow warped by the model's prior read it back). ``params``:
    the detector's (default ``Params()``; e.g. ``Params(scene_sweep=15.0)``)."""
    import collections
    import importlib

    scene_module = importlib.import_module("fisheyemotion.static_scene")
    seq = Sequence(SEQUENCES / name)
    renderer = Renderer(seq.camera, load_scenario(seq.path / "scenario.yaml"), supersample=1)
    det = fm.MotionDetector(seq.camera, params=params or fm.Params(), roi=seq.roi())
    gap = det.params.frame_gap
    kinds = {int(k): str(v) for k, v in zip(seq.objects.id, seq.objects.kind, strict=True)}
    stored = {}
    original = scene_module.StaticScene.add

    def add(self, rays, ranges, pose, static):
        stored["cells"] = (ranges.copy(), static.copy())
        return original(self, rays, ranges, pose, static)

    counts = collections.defaultdict(lambda: np.zeros(4, int))
    centres = det._centres.round().astype(int)
    rows = np.clip(centres[..., 1], 0, seq.camera.height - 1)
    cols = np.clip(centres[..., 0], 0, seq.camera.width - 1)
    grays = _grays(seq)
    scene_module.StaticScene.add = add
    try:
        for k in range(gap, len(seq)):
            pose0, pose1 = seq.poses[k - gap], seq.poses[k]
            before = det._scene_ranges_at_cells(pose0) if len(det.scene) else None
            flow = det.flow(grays[k - gap], grays[k], pose0, pose1)
            det.detect_flow(flow, pose0, pose1, prev=grays[k - gap], curr=grays[k], stream=True)
            ranges, static = stored.pop("cells")
            frame = renderer.render(k - gap)
            truth, ids = frame.range[rows, cols], frame.ids[rows, cols]
            with np.errstate(invalid="ignore", divide="ignore"):
                off = static & np.isfinite(ranges) & (np.abs(ranges / truth - 1) > 0.1)
                model_off = off & (np.abs(before / truth - 1) > 0.1) if before is not None \
                    else np.zeros_like(off)
                repeated = model_off & (np.abs(ranges / before - 1) < 0.05) \
                    if before is not None else np.zeros_like(off)
            for kind in np.unique(ids[static]):
                cells = static & np.isfinite(ranges) & (ids == kind)
                label = "road, sky" if kind == 0 else kinds.get(int(kind), "ego body")
                counts[label] += [cells.sum(), (cells & off).sum(), (cells & model_off).sum(),
                                  (cells & repeated).sum()]
    finally:
        scene_module.StaticScene.add = original
    for label, (n, off, model_off, repeated) in sorted(counts.items(), key=lambda kv: -kv[1][0]):
        print(f"{name}, {label}: {n} points stored, {off} ({100 * off / max(n, 1):.0f} %) more "
              f"than 10 % off; of those {model_off} where the model's range was as far off, "
              f"{repeated} repeating it within 5 %")


def _true_depth_prior(path, mode: str):
    """A :class:`~fisheyemotion.MotionDetector` whose warp prior is the static scene's flow
    from the renderer's true ranges of the pair's previous frame (per pixel, sharp; moving
    objects read as static at their own range, as any static prior reads them), filled where
    the point leaves the camera's domain and seen only where it lands on the valid pixels, as
    :class:`~fisheyemotion.prior.EgoFlowPrior` does. ``mode``: ``"prior"`` that alone;
    ``"occlusion"`` also with the pixels whose static point is hidden in the current frame
    behind a nearer static surface (true ranges, 5 %) left out of the warp and their cells
    (30 % of their pixels) not scored; ``"occlusion only"`` that occlusion with the detector's
    own prior; ``"coarse"`` the true ranges read at the detector's prior's own samples (every
    8 px, as the scene model's are, the flow between them bilinear) and ``"coarse, occlusion"``
    that with the occlusions handled; ``"coarse, estimated occlusion"`` and ``"estimated
    occlusion"`` the occlusions estimated from the prior itself (``_estimated_occlusion``)
    instead of the truth, with the true ranges at the prior's samples and with the detector's
    own prior."""
    from fisheyemotion.calib.base import pixel_grid
    from scipy import ndimage

    from fisheyemotion.detector import MotionDetector
    from fisheyemotion.flow import grid_average
    from fisheyemotion.prior import lands_on, static_scene_targets

    seq = Sequence(path)
    renderer = Renderer(seq.camera, load_scenario(seq.path / "scenario.yaml"), supersample=1)
    index = {pose.tobytes(): k for k, pose in enumerate(seq.poses)}
    ranges, static_ranges = {}, {}

    def truth(k):
        if k not in ranges:
            frame = renderer.render(k)
            ranges[k] = np.where(np.isfinite(frame.range), frame.range, 1e3).astype(np.float64)
            static_ranges[k] = np.where(frame.moving > 0, np.inf, frame.range)
        return ranges[k], static_ranges[k]

    class TrueDepthDetector(MotionDetector):
        def _static_prior(self, pose_a, pose_b):
            a, b = index.get(pose_a.tobytes()), index.get(pose_b.tobytes())
            if a is None or b is None:  # not a pair of the sequence's own poses
                return super()._static_prior(pose_a, pose_b)
            cam = self.camera
            if not hasattr(self, "_pixels"):
                self._pixels = pixel_grid(cam.width, cam.height).astype(np.float64)
                self._pixel_rays = cam.unproject(self._pixels)[0]
                self._cells_before = self._cell_valid.copy()
            depth = truth(a)[0]
            targets, ok = static_scene_targets(cam, self._pixel_rays, pose_a, pose_b,
                                               fm.Road.unknown(), 1e3, depth)
            flow = np.where(ok[..., None], targets - self._pixels, 0.0).astype(np.float32)
            if ok.any() and not ok.all():
                _, (r, c) = ndimage.distance_transform_edt(~ok, return_indices=True)
                flow = flow[r, c]
            seen = lands_on(targets, ok, self._pixel_valid, cam.width, cam.height)
            if mode == "occlusion only":
                flow, seen_prior = super()._static_prior(pose_a, pose_b)
            if mode.startswith("coarse"):  # the true ranges at the prior's own samples
                step = self._prior.step
                rows, cols = -(-cam.height // step), -(-cam.width // step)
                at = np.minimum(np.arange(rows) * step + (step - 1) // 2, cam.height - 1)
                across = np.minimum(np.arange(cols) * step + (step - 1) // 2, cam.width - 1)
                sampled = depth[np.ix_(at, across)]

                class Truth:
                    def ranges(self, pose, step, shape):
                        return sampled

                flow, seen_prior = self._prior(pose_a, pose_b, self._prior_road(pose_a, pose_b),
                                               view=self._pixel_valid, scene=Truth())
                if mode == "coarse":
                    return flow, seen_prior
                if mode == "coarse, estimated occlusion":
                    return self._estimated_occlusion(flow, seen_prior, pose_a, pose_b, sampled)
            if mode == "estimated occlusion":
                flow, seen_prior = super()._static_prior(pose_a, pose_b)
                step = self._prior.step
                rows, cols = -(-cam.height // step), -(-cam.width // step)
                return self._estimated_occlusion(flow, seen_prior, pose_a, pose_b,
                                                 self.scene.ranges(pose_a, step, (rows, cols)))
            if mode != "prior":
                points = pose_a[:3, 3] + depth[..., None] * (self._pixel_rays @ pose_a[:3, :3].T)
                expected = np.linalg.norm(points - pose_b[:3, 3], axis=-1)
                u = np.clip(np.rint(np.nan_to_num(targets[..., 0])), 0, cam.width - 1)
                v = np.clip(np.rint(np.nan_to_num(targets[..., 1])), 0, cam.height - 1)
                there = np.nan_to_num(truth(b)[1][v.astype(int), u.astype(int)], nan=np.inf)
                hidden = seen & (there < 0.95 * expected)
                seen = (seen if mode == "occlusion" else seen_prior) & ~hidden
                cells = grid_average(hidden.astype(np.float32), self.params.grid) > 0.3
                self._cell_valid = self._cells_before & ~cells
            return flow, seen

        def _estimated_occlusion(self, flow, seen, pose_a, pose_b, sample_ranges):
            """Occlusions estimated from the prior itself: each pixel's range as the prior
            chose it (the road, the far field or ``sample_ranges`` at its 8-px sample),
            splatted along the prior's flow into a z-buffer of the current frame; a pixel whose
            point lies 5 % behind what lands on its target is hidden."""
            from fisheyemotion import prior
            from fisheyemotion.flow import grid_upsample

            cam, step = self.camera, self._prior.step
            if not hasattr(self, "_pixels"):
                self._pixels = pixel_grid(cam.width, cam.height).astype(np.float64)
                self._pixel_rays = cam.unproject(self._pixels)[0]
                self._cells_before = self._cell_valid.copy()
            dirs = self._pixel_rays @ pose_a[:3, :3].T
            road = self._prior_road(pose_a, pose_b)
            # The depth static_scene_targets chooses (road or far field, unless the model holds
            # something clearly nearer), per pixel.
            depth = np.minimum(road.ray_range(pose_a[:3, 3], dirs, min_down=prior._HORIZON_SIN),
                               self.params.prior_distance)
            known = grid_upsample(sample_ranges, step, cam.width, cam.height)
            with np.errstate(invalid="ignore"):
                depth = np.where(known < prior.OCCLUDER_RATIO * depth, known, depth)
            points = pose_a[:3, 3] + depth[..., None] * dirs
            far = np.linalg.norm(points - pose_b[:3, 3], axis=-1)
            target = np.rint(self._pixels + flow)
            inside = seen & np.isfinite(far)
            u, v = target[..., 0].astype(np.intp), target[..., 1].astype(np.intp)
            inside &= (u >= 0) & (u < cam.width) & (v >= 0) & (v < cam.height)
            index = np.where(inside, v * cam.width + u, 0)
            zbuf = np.full(cam.width * cam.height, np.inf)
            np.minimum.at(zbuf, index[inside], far[inside])
            hidden = inside & (far > 1.05 * zbuf[index])
            cells = grid_average(hidden.astype(np.float32), self.params.grid) > 0.3
            self._cell_valid = self._cells_before & ~cells
            return flow, seen & ~hidden

    return TrueDepthDetector


def true_depth_prior_bounds(modes=(None, "prior", "occlusion", "occlusion only", "coarse",
                                   "coarse, occlusion", "coarse, estimated occlusion",
                                   "estimated occlusion"), params: fm.Params | None = None) -> None:
    """How far a better static prior could go: ``Params()`` with Farneback over every demo
    sequence, its warp prior replaced by the static scene's flow from the true ranges
    (:func:`_true_depth_prior`), then also with the occlusions by static surfaces handled, that
    occlusion handling with the detector's own prior, and the true ranges at the resolution of
    the detector's prior with and without it. ``params``: the detector's (default ``Params()``;
    e.g. ``Params(scene_sweep=15.0)``)."""
    import importlib

    from fisheyemotion.eval.evaluate import evaluate, sequence_paths
    from fisheyemotion.eval.report import groups_table

    module = importlib.import_module("fisheyemotion.eval.evaluate")
    original, detector = module.evaluate_sequence, module.MotionDetector
    columns = ("FP frames", "crossing det.", "preceding det.", "approaching det.", "IoU")
    try:
        for mode in modes:
            def run(path, *args, mode=mode, **kwargs):  # in the pool's forked workers too
                module.MotionDetector = detector if mode is None else _true_depth_prior(path, mode)
                return original(path, *args, **kwargs)
            module.evaluate_sequence = run
            table = groups_table(evaluate(sequence_paths([SEQUENCES]), params or fm.Params(),
                                          workers=2, progress=False, ablation=False)
                                 ).set_index("scenes")
            cells = "; ".join(f"{scenes}: " + ", ".join(
                f"{name} {100 * row[name] if name != 'IoU' else row[name]:.{2 if name == 'IoU' else 0}f}"
                for name in columns) for scenes, row in table.iterrows())
            print(f"warp prior {mode or 'of the detector (the defaults)'}: {cells}")
    finally:
        module.evaluate_sequence, module.MotionDetector = original, detector


def first_pair_prior_error(name: str = "static_world", frames=(3, 4, 5, 6),
                           bootstrap: bool = False) -> None:
    """The warp prior's error against the renderer's exact flow, median per surface, for the
    pairs ending at ``frames`` of a stream with ``Params(scene_bootstrap=bootstrap)``: how far
    off the prior is for structure already near when the stream starts, and how fast the scene
    model learns it (docs/evaluation.md, *Scene-model bootstrap*)."""
    seq = Sequence(SEQUENCES / name)
    renderer = Renderer(seq.camera, load_scenario(seq.path / "scenario.yaml"), supersample=1)
    kinds = {int(i): str(k) for i, k in zip(seq.objects.id, seq.objects.kind, strict=True)}
    grays = _grays(seq)
    det = fm.MotionDetector(seq.camera, fm.Road(), params=fm.Params(scene_bootstrap=bootstrap),
                            roi=seq.roi())
    gap = det.params.frame_gap
    priors = {}
    static_prior = det._static_prior

    def recorded(a, b):
        out = static_prior(a, b)
        priors[(a.tobytes(), b.tobytes())] = out[0]
        return out
    det._static_prior = recorded
    for k in range(max(frames) + 1):  # one stream; each pair's prior as its flow used it
        det.apply(grays[k], seq.poses[k])
    for end in frames:
        prior = priors[(seq.poses[end - gap].tobytes(), seq.poses[end].tobytes())]
        error = np.linalg.norm(prior - renderer.flow(end, gap=gap), axis=-1)
        ids = renderer.render(end - gap).ids
        cells = []
        for i in np.unique(ids):
            surface = (ids == i) & np.isfinite(error)
            if 0 < i < 65535 and surface.sum() >= 200:
                cells.append(f"{kinds.get(int(i), 'static')} {i} {np.median(error[surface]):.1f} px")
        print(f"{name}, pair ending at frame {end}, bootstrap {bootstrap}: " + ", ".join(cells))


def false_positive_frames_by_frame(report: Path = SEQUENCES.parent / "report") -> None:
    """The share of pairs with a false region by the frame they end at (3-6, 7-10, 11-15, then
    by eights), open road and streets, from an evaluation's ``frames.csv`` (default: ``make
    demo``'s; Farneback)."""
    import pandas as pd

    frames = pd.read_csv(Path(report) / "frames.csv")
    frames = frames[frames.flow == "farneback"]
    streets = frames.sequence.str.startswith("street")
    bins = pd.cut(frames.frame, [2, 6, 10, 15, 24, 32, 40, 48])
    table = frames.assign(group=np.where(streets, "streets", "open road"), bins=bins).pivot_table(
        index="group", columns="bins", values="fp_frame", aggfunc="mean", observed=True)
    print(f"{report}: pairs with a false region by the frame they end at\n"
          + (100 * table).round(0).to_string())



def epipolar_significance_real(ks=(0.0, 2.0, 3.0, 4.0), position_sigmas=(0.0, 0.002)) -> None:
    """The real Aria clips with ``Params(frame_gap=1, epipolar_significance=k,
    position_sigma=s)``: the kitchen's static background and utensils flagged, the office's
    share outside the largest region; and the spread of the kitchen's static cells' epipolar
    deviation in sigmas of their error, with and without the poses' (docs/evaluation.md,
    *Epipolar significance*)."""
    import cv2
    from fisheyemotion.eval.real import TOLERANCE_PX, find_clips, run_real

    from fisheyemotion import calib
    from fisheyemotion.inputs import ImageFolder
    from fisheyemotion.poses import PoseMatcher, read_poses

    data = SEQUENCES.parents[2]
    for k, s in ((k, s) for s in position_sigmas for k in ks):
        table, _ = run_real(data, fm.Params(frame_gap=1, epipolar_significance=k,
                                            position_sigma=s))
        for _, row in table.iterrows():
            moving = row["ground truth: moving objects' pixels flagged %"]
            print(f"k = {k}, position_sigma = {s}: {row['clip']} / {row['camera']}: "
                  "outside the largest region "
                  f"{row['outside the largest region %']:.2f} %, ground truth static / moving "
                  f"{row['ground truth: static flagged %']:.2f} / "
                  f"{moving:.0f} %")
    seen = {}
    with_significance = fm.MotionDetector._with_significance

    def recorded(self, res, sigma, likelihood):
        if sigma.ndim == 2:
            seen["z"] = res.epipolar / sigma
        return with_significance(self, res, sigma, likelihood)
    fm.MotionDetector._with_significance = recorded
    try:
        for clip, s in ((c, s) for s in position_sigmas for c in find_clips(data)):
            truth_dir = clip.folder.parent / "ground_truth" / "moving" / clip.camera
            if not truth_dir.is_dir():
                continue
            cam = calib.load(clip.calibration, clip.camera)
            params = fm.Params(frame_gap=1, position_sigma=s).for_camera(cam)
            det = fm.MotionDetector(cam, fm.Road.unknown(), params)
            poses = PoseMatcher(read_poses(clip.poses))
            for f in ImageFolder(clip.folder):
                seen.clear()
                det.apply(f.image, poses(f.index, f.name, f.stamp)[1])
                if not (truth_dir / f.name).is_file() or "z" not in seen:
                    continue
                truth = cv2.imread(str(truth_dir / f.name), cv2.IMREAD_GRAYSCALE)
                size = 2 * TOLERANCE_PX + 1
                near = cv2.dilate((truth == 255).astype(np.uint8), np.ones((size, size), np.uint8))
                g = params.grid
                rows, cols = seen["z"].shape
                static = ((truth == 0) & (near == 0))[:rows * g, :cols * g]
                static = static.reshape(rows, g, cols, g).all(axis=(1, 3))
                z = seen["z"][static & np.isfinite(seen["z"])]
                print(f"{clip.camera} {f.name}, position_sigma = {s}: static cells' "
                      "epipolar deviation / sigma, "
                      f"percentiles 50 / 90 / 99: "
                      + " / ".join(f"{q:.2f}" for q in np.percentile(z, [50, 90, 99])))
    finally:
        fm.MotionDetector._with_significance = with_significance


def contact_with_true_ranges(names=("street_kb", "street_ds", "street_heldout_kb",
                                    "street_heldout_ds")) -> None:
    """Table 2 per street group with the ground-contact test given the renderer's true range
    at every cell centre (the static range the test reads, exact, below and inside each region;
    inf and beyond ``prior_distance`` clipped to it) and everything else the detector's own
    (``Params()``, Farneback): how far right ranges in the test alone would take the streets."""
    from fisheyemotion.eval.evaluate import evaluate_sequence
    from fisheyemotion.eval.report import groups_table

    from fisheyemotion import detector as detector_module

    standing = detector_module.standing_regions
    p = fm.Params()
    g, c = p.grid, (p.grid - 1) // 2

    def given_true_ranges(seq: Sequence):
        renderer = Renderer(seq.camera, load_scenario(seq.path / "scenario.yaml"), supersample=1)
        frame_of = {pose.tobytes(): k for k, pose in enumerate(seq.poses)}

        def test(moving, share, ranges, rays, pose, *args, **kwargs):
            k = frame_of.get(np.asarray(pose).tobytes())
            if k is not None:
                rows, cols = ranges.shape
                true = renderer.render(k).range[c:rows * g:g, c:cols * g:g].astype(float)
                ranges = np.where(np.isfinite(true), np.minimum(true, p.prior_distance),
                                  p.prior_distance)
            return standing(moving, share, ranges, rays, pose, *args, **kwargs)
        return test

    results = []
    try:
        for name in names:
            seq = Sequence(SEQUENCES / name)
            detector_module.standing_regions = given_true_ranges(seq)
            results.append(evaluate_sequence(seq.path, p, ablation=False))
    finally:
        detector_module.standing_regions = standing
    table = groups_table(results).set_index("scenes")
    columns = ["crossing det.", "preceding det.", "approaching det.", "approaching cov.",
               "FP frames", "static flagged"]
    print("The ground-contact test given the true ranges (per cent):")
    print((100 * table[columns]).round(1).to_string())



def _traced_pairs(path: Path, params: fm.Params, *, exact_flow: bool = False):
    """``evaluate_sequence``'s stream of a sequence, each pair with what the detector computed
    on the way (a list of dicts, one a pair): ``frame`` (the current one), ``pose0``,
    ``valid`` and ``flagged`` (the pair's cells on the previous frame: scored, and above the
    threshold), ``carried`` and ``filtered`` (cells above the threshold on the current frame's
    cells before and after the temporal filter), ``result`` (the Detection) and ``res``
    (the constraints)."""
    from fisheyemotion.eval.evaluate import evaluate_sequence

    from fisheyemotion import detector as detector_module

    cls = detector_module.MotionDetector
    originals = {name: getattr(cls, name)
                 for name in ("_measure", "_temporal_filter", "_assemble", "detect_flow")}
    seq = Sequence(path)
    frame_of = {pose.tobytes(): k for k, pose in enumerate(seq.poses)}
    pairs: list[dict] = []
    now: dict = {}

    def measure(self, flow, t0, t1, *args, **kwargs):
        now.update(frame=frame_of.get(np.asarray(t1).tobytes()), pose0=t0)
        return originals["_measure"](self, flow, t0, t1, *args, **kwargs)

    def temporal_filter(self, cell_likelihood, carrier, source):
        out = originals["_temporal_filter"](self, cell_likelihood, carrier, source)
        now.update(carried=np.nan_to_num(cell_likelihood) > self.params.threshold,
                   filtered=np.nan_to_num(out[0]) > self.params.threshold)
        return out

    def assemble(self, flow, cell_flow, res, likelihood, valid, **kwargs):
        now.update(valid=valid, res=res,
                   flagged=valid & (np.nan_to_num(likelihood) > self.params.threshold))
        return originals["_assemble"](self, flow, cell_flow, res, likelihood, valid, **kwargs)

    def detect_flow(self, *args, **kwargs):
        result = originals["detect_flow"](self, *args, **kwargs)
        if kwargs.get("stream") and now.get("frame") is not None:
            pairs.append({**now, "result": result})
        now.clear()
        return result

    try:
        cls._measure, cls._temporal_filter = measure, temporal_filter
        cls._assemble, cls.detect_flow = assemble, detect_flow
        evaluate_sequence(path, params, ablation=False, exact_flow=exact_flow)
    finally:
        for name, function in originals.items():
            setattr(cls, name, function)
    return seq, pairs


def coverage_by_step(names=("crossing", "street_kb", "street_heldout_kb", "preceding"),
                     exact_flow: bool = False, params: fm.Params | None = None) -> None:
    """Where a moving object's coverage is lost, step by step (``Params()``, Farneback or the
    exact flow, streamed as the evaluation does): the share of each object (the object-frames
    with a cell above the threshold) covered by its cells above the threshold on the previous
    frame (*measured*), the same carried to the current frame (*carried*), after the temporal
    filter (*filtered*), in the regions kept, without the closing's cells (*kept*:
    ``Detection.cell_mask``), and in the final mask (*mask*: closed and grown); *scored* is the
    share of its cells on the previous frame that were scored at all. ``params``: other than
    ``Params()`` (``Params(region_gap=0)``: 0.8.11's regions)."""
    import pandas as pd

    from fisheyemotion.flow import grid_upsample

    p = fm.Params() if params is None else params
    g = p.grid
    rows = []
    for name in names:
        seq, pairs = _traced_pairs(SEQUENCES / name, p, exact_flow=exact_flow)
        objects = seq.objects
        category = dict(zip(objects.id.astype(int), objects.category, strict=True))
        moving = set(objects[objects.moving.astype(bool)].id.astype(int))
        h, w = seq.camera.height, seq.camera.width

        def up(cells, w=w, h=h):
            return grid_upsample(cells.astype(np.uint8), g, w, h) > 0

        for pair in pairs:
            k = pair["frame"]
            ids0, ids1 = seq.ids(k - p.frame_gap), seq.ids(k)
            masks = {"measured": up(pair["flagged"]), "carried": up(pair["carried"]),
                     "filtered": up(pair["filtered"]),
                     "kept": pair["result"].cell_mask > 0, "mask": pair["result"].mask > 0}
            for i in moving:
                before, after = ids0 == i, ids1 == i
                if not before.any() or not after.any() or not (masks["measured"] & before).any():
                    continue
                row = {"sequence": name, "category": category[i],
                       "scored": (up(pair["valid"]) & before).sum() / before.sum()}
                for step, mask in masks.items():
                    on = before if step == "measured" else after
                    row[step] = (mask & on).sum() / on.sum()
                rows.append(row)
    table = pd.DataFrame(rows).groupby(["sequence", "category"]).mean(numeric_only=True)
    print(f"Share of each moving object covered, step by step ({'exact' if exact_flow else 'Farneback'}"
          " flow, per cent):")
    print((100 * table).round(1).to_string())


def crossing_cells_by_elevation(names=("crossing", "street_kb", "street_heldout_kb")) -> None:
    """The crossing pedestrians' scored cells given the exact flow, by their elevation from the
    horizontal plane through the epipole (the plane of the baseline and the road's normal):
    how many, the share above the threshold and the median epipolar deviation. Lateral motion
    seen near that plane runs along the epipolar arcs."""
    import pandas as pd

    p = fm.Params()
    g, c = p.grid, (p.grid - 1) // 2
    rows = []
    for name in names:
        seq, pairs = _traced_pairs(SEQUENCES / name, p, exact_flow=True)
        objects = seq.objects
        crossing = set(objects[objects.category == "crossing"].id.astype(int))
        cam = seq.camera
        rcount, ccount = pairs[0]["valid"].shape
        u, v = np.meshgrid(np.arange(ccount) * g + c, np.arange(rcount) * g + c)
        rays, _ = cam.unproject(np.stack([u, v], -1).astype(float))
        up_world = fm.Road().up
        for pair in pairs:
            k, pose0 = pair["frame"], pair["pose0"]
            baseline = seq.poses[k][:3, 3] - pose0[:3, 3]
            side = np.cross(baseline, up_world)
            normal = np.cross(side, baseline)  # in the baseline's vertical plane, upwards
            normal /= np.linalg.norm(normal)
            elevation = np.degrees(np.arcsin(np.clip(rays @ pose0[:3, :3].T @ normal, -1, 1)))
            ids = seq.ids(k - p.frame_gap)[c:rcount * g:g, c:ccount * g:g]
            cells = np.isin(ids, list(crossing)) & pair["valid"]
            rows.append(pd.DataFrame({"elevation": np.abs(elevation[cells]),
                                      "flagged": pair["flagged"][cells],
                                      "epipolar": pair["res"].epipolar[cells]}))
    df = pd.concat(rows)
    df["band"] = pd.cut(df.elevation, [0, 1, 2, 4, 8, 16, 90])
    table = df.groupby("band", observed=True).agg(
        cells=("flagged", "size"), flagged=("flagged", "mean"), epipolar=("epipolar", "median"))
    print("Crossing pedestrians' scored cells given the exact flow, by elevation (deg) from the "
          "horizontal plane through the epipole:")
    print(table.round(4).to_string())


def flow_follows_prior(name: str = "street_kb", frame: int = 30) -> None:
    """How far the flow departs from the prior it was warped by (``Params()``, Farneback, the
    stream run up to ``frame``; textured static pixels of finite range whose predicted point
    stays in view): by the prior's error against the exact flow, the share of pixels whose flow
    is within 2 px of the exact one and how far it moved off its prior; then the same frame
    warped by the prior plus a uniform horizontal offset, where it is right to within 1 px,
    and the median error of the flow after one, two and three passes (each warped back by the
    one before)."""
    from fisheyemotion.eval.evaluate import world_transform

    from fisheyemotion.flow import FlowEstimator, warp_by

    seq = Sequence(SEQUENCES / name)
    renderer = Renderer(seq.camera, load_scenario(seq.path / "scenario.yaml"), supersample=1)
    grays, poses = _grays(seq), seq.poses
    p = fm.Params()
    gap = p.frame_gap
    _, road = world_transform("scene", poses[0])
    det = fm.MotionDetector(seq.camera, road, params=p, roi=seq.roi())
    for i in range(gap):
        det._observe_ground(grays[i], poses[i])
    for k in range(gap, frame + 1):
        g0, g1, t0, t1 = grays[k - gap], grays[k], poses[k - gap], poses[k]
        if k == gap:
            det._bootstrap_scene([(grays[i], poses[i]) for i in range(gap + 1)], None)
        if k == frame:
            prior, seen = det._static_prior(t0, t1)
        flow = det.flow(g0, g1, t0, t1)
        det.detect_flow(flow, t0, t1, prev=g0, curr=g1, stream=True)
    exact = renderer.flow(frame, gap=gap)
    laplacian = cv2.Laplacian(cv2.GaussianBlur(g0, (3, 3), 0), cv2.CV_32F)
    textured = cv2.blur(np.abs(laplacian), (5, 5)) > 4
    static = ((seq.mask(frame) == 0) & seq.camera.valid_pixel_mask() & seen & textured
              & np.isfinite(exact).all(-1) & np.isfinite(renderer.render(frame - gap).range))
    prior_error = np.linalg.norm(prior - exact, axis=-1)
    flow_error = np.linalg.norm(flow - exact, axis=-1)
    moved = np.linalg.norm(flow - prior, axis=-1)
    print(f"{name}, pair {frame - gap}-{frame}: the flow against the prior it was warped by "
          "(textured static pixels)")
    for lo, hi in ((0, 2), (2, 5), (5, 20), (20, np.inf)):
        band = static & (prior_error >= lo) & (prior_error < hi)
        print(f"  prior {lo}-{hi} px off: {band.sum():6d} px, flow within 2 px "
              f"{np.mean(flow_error[band] < 2):.0%}, moved off the prior {np.median(moved[band]):.2f}"
              " px (median)")
    right = static & (prior_error < 1)
    farneback = FlowEstimator(p)  # the detector's flow method, without a prior

    print("  the prior plus a uniform offset, where it was within 1 px: median error after "
          "1 / 2 / 3 passes")
    for offset in (0, 2, 5, 10, 20):
        current = prior + np.float32([offset, 0])
        errors = []
        for _ in range(3):
            warped = warp_by(g1, current)
            np.copyto(warped, g0, where=~seen)
            current = current + farneback(g0, warped)
            errors.append(np.median(np.linalg.norm(current - exact, axis=-1)[right]))
        print(f"  {offset:2d} px: " + " / ".join(f"{e:.2f}" for e in errors) + " px")


def base_ratios(names=("crossing", "preceding", "approaching", "street_kb", "street_ds",
                        "street_heldout_kb", "street_heldout_ds")) -> None:
    """How far beyond the road the exact flow reads each moving object's base
    (``fisheyemotion.receding``): per object-frame (pair ``k - 3 -> k``, on frame ``k - 3``'s
    pixels, objects of at least 50 px), the median static range of the lowest quarter of its
    pixels over the road plane's range at its base (the pixel 2 below each of its columns'
    lowest pixel, the median over columns); per category, the object-frames' minimum, median
    and maximum. Above 1: the base reads under the road (receding); below: it floats."""
    import pandas as pd

    from fisheyemotion.receding import road_ranges
    from fisheyemotion.static_scene import triangulate_range

    rows = []
    for name in names:
        seq = Sequence(SEQUENCES / name)
        renderer = Renderer(seq.camera, load_scenario(seq.path / "scenario.yaml"), supersample=1)
        h, w = seq.mask(0).shape
        vv, uu = np.mgrid[0:h, 0:w]
        pixels = np.stack([uu, vv], axis=-1).astype(np.float64)
        rays0, _ = seq.camera.unproject(pixels)
        objects = seq.objects[seq.objects.category.isin(["crossing", "preceding", "approaching"])]
        for k in range(3, len(seq)):
            rays1, _ = seq.camera.unproject(pixels + renderer.flow(k, gap=3))
            pose0 = seq.poses[k - 3]
            ranges = triangulate_range(rays0, rays1, pose0, seq.poses[k], far=1000.0)[0]
            ids = seq.ids(k - 3)
            for obj in objects[objects.frame == k - 3].itertuples():
                v, u = np.nonzero(ids == obj.id)
                if len(v) < 50:
                    continue
                lowest = np.full(w, -1)
                np.maximum.at(lowest, u, v)
                cols = np.flatnonzero(lowest >= 0)
                below = np.minimum(lowest[cols] + 2, h - 1)
                base_rays = rays0[below, cols]
                rho = np.nanmedian(road_ranges(base_rays, pose0, fm.Road()))
                quarter = v >= np.percentile(v, 75)
                lam = np.nanmedian(ranges[v[quarter], u[quarter]])
                rows.append({"sequence": name, "category": obj.category, "ratio": lam / rho})
    table = pd.DataFrame(rows).groupby(["sequence", "category"]).ratio
    print(table.describe()[["count", "min", "50%", "max"]].round(2).to_string())


def false_seed_predictions(names=("street_kb", "street_heldout_ds"),
                           params: fm.Params | None = None, false_regions: bool = False) -> None:
    """Where the photometric check's static prediction is at the seeds (cells above the
    threshold that it does not explain) of ``params`` (default: ``Params()`` with the fixed
    tolerance only, ``photometric_range_error=0``; Farneback, streamed with ``apply()``), by
    the surface under each (the renderer's ids on the previous frame): how many, the median
    error of the static prediction and of the measured flow against the exact flow (pixels),
    the median parallax (the prediction's distance from the image of its point at infinity),
    the quartiles of the prediction's error along the epipolar curve as a share of that
    parallax (positive: the static point is nearer than predicted), the median error across
    the curve (pixels), and the median photometric residuals (grey levels, the cell's mean
    absolute difference) of the measured flow, the static prediction and the exact flow. With
    ``false_regions``, only the seeds that land (by their flow) in a region of the result that
    touches no moving object."""
    import pandas as pd

    from fisheyemotion import detector as detector_module
    from fisheyemotion.flow import grid_average
    from fisheyemotion.photometric import cell_residual

    p = params if params is not None else fm.Params(photometric_range_error=0.0)
    g, gap = p.grid, p.frame_gap
    cls = detector_module.MotionDetector
    original = cls._assemble
    seen: dict = {}

    def assemble(self, *args, seeds=None, static_flow=None, **kwargs):
        seen.update(seeds=seeds, static_flow=static_flow)
        return original(self, *args, seeds=seeds, static_flow=static_flow, **kwargs)

    rows = []
    try:
        cls._assemble = assemble
        for name in names:
            seq = Sequence(SEQUENCES / name)
            kinds = dict(zip(seq.objects.id.astype(int), seq.objects.kind.astype(str),
                             strict=True))
            renderer = Renderer(seq.camera, load_scenario(seq.path / "scenario.yaml"),
                                supersample=1)
            det = fm.MotionDetector(seq.camera, params=p, roi=seq.roi())
            for k in range(len(seq)):
                seen.clear()
                result = det.apply(seq.frame(k), seq.poses[k])
                if result is None or seen.get("seeds") is None:
                    continue
                exact_px = np.nan_to_num(renderer.flow(k, gap=gap), nan=1e4).astype(np.float32)
                exact = grid_average(exact_px, g)
                static = grid_average(seen["static_flow"], g)
                measured = result.grid.flow
                t0, t1 = seq.poses[k - gap], seq.poses[k]
                at_infinity = det._at_infinity(t0, t1)
                ids = seq.ids(k - gap)[g // 2::g, g // 2::g]
                prev, curr = (to_gray(seq.frame(i), "frame") for i in (k - gap, k))
                residual = {name: cell_residual(prev, curr, flow, g, seen["seeds"]) for name, flow
                            in (("measured", result.flow), ("static", seen["static_flow"]),
                                ("exact", exact_px))}
                count, regions = cv2.connectedComponents((result.mask > 0).astype(np.uint8))
                moving = np.bincount(regions[seq.mask(k) > 0], minlength=count) > 0
                for r, c in zip(*np.nonzero(seen["seeds"]), strict=True):
                    u, v = np.round(det._centres[r, c] + measured[r, c]).astype(int)
                    inside = 0 <= v < regions.shape[0] and 0 <= u < regions.shape[1]
                    if false_regions and not (inside and regions[v, u] and not
                                              moving[regions[v, u]]):
                        continue
                    along = det._centres[r, c] + static[r, c] - at_infinity[r, c]
                    parallax = float(np.linalg.norm(along))
                    error = exact[r, c] - static[r, c]
                    rows.append({
                        "surface": kinds.get(int(ids[r, c]), "road"), "parallax": parallax,
                        "static": float(np.linalg.norm(error)),
                        "flow": float(np.linalg.norm(exact[r, c] - measured[r, c])),
                        "along": float(error @ along) / parallax ** 2,
                        "across": abs(float(np.cross(along / parallax, error))),
                        **{f"r_{name}": float(x[r, c]) for name, x in residual.items()}})
    finally:
        cls._assemble = original
    table = pd.DataFrame(rows).groupby("surface").agg(
        seeds=("static", "size"), static_px=("static", "median"), flow_px=("flow", "median"),
        parallax_px=("parallax", "median"), along_q1=("along", lambda x: x.quantile(0.25)),
        along_median=("along", "median"), along_q3=("along", lambda x: x.quantile(0.75)),
        across_px=("across", "median"), r_measured=("r_measured", "median"),
        r_static=("r_static", "median"), r_exact=("r_exact", "median"))
    print(f"{'false regions' if false_regions else 'all'} seeds of {', '.join(names)} "
          f"({p.flow}):")
    print(table.round(3).to_string())


def _draw_groups(params: fm.Params, draws: int) -> tuple[list, list]:
    """Every demo sequence evaluated under ``params``, with the true poses and
    ``draws`` negligible perturbations (:func:`_negligible`): the runs' results and their
    scene-group tables (``groups_table``, indexed by scene group), one a run."""
    from fisheyemotion.eval.evaluate import evaluate, sequence_paths
    from fisheyemotion.eval.report import groups_table

    paths = sequence_paths([SEQUENCES])
    runs = [evaluate(paths, params, ablation=False, progress=False)]
    runs += [evaluate(paths, params, ablation=False, progress=False, poses="perturbed",
                      noise=_negligible(seed)) for seed in range(draws)]
    return runs, [groups_table(r).set_index("scenes") for r in runs]


def photometric_search_draws(reaches=(4.0, 16.0), draws: int = 4) -> None:
    """``Params(photometric_search=r)`` for each reach over every demo sequence (Farneback),
    with the true poses and ``draws`` negligible perturbations (:func:`_draw_groups`): the
    false-positive frames per scene group (mean and SD of the runs), crossing detection over
    all scenes and the held-out streets' approaching detection (means)."""
    from fisheyemotion.eval.evaluate import combine
    from fisheyemotion.eval.metrics import table2

    for reach in reaches:
        runs, groups = _draw_groups(fm.Params(photometric_search=reach), draws)
        cells = []
        for scenes in groups[0].index:
            fp = np.array([100 * g.loc[scenes, "FP frames"] for g in groups])
            cells.append(f"{scenes} {fp.mean():.1f} +- {fp.std(ddof=1):.1f} %")
        crossing = np.mean([100 * table2(*(combine(r)[t] for t in ("objects", "frames")))
                            .set_index("category").loc["crossing", "detection_rate"]
                            for r in runs])
        approaching = np.mean([100 * g.loc["street, held out", "approaching det."]
                               for g in groups])
        print(f"photometric_search {reach:g} px, {len(groups)} runs: false-positive frames "
              + ", ".join(cells) + f"; crossing detection (all) {crossing:.1f} %, held-out "
              f"approaching {approaching:.1f} %")


def _setting_draws(name: str, values, draws: int, *, flow: str = "farneback") -> None:
    """``Params(name=v)`` for each value over every demo sequence (``flow``), with the true
    poses and ``draws`` negligible perturbations (:func:`_draw_groups`): each scene group's
    detection and coverage per category, false-positive frames, static pixels flagged and IoU,
    the runs' means (per cent), and the false-positive frames' SD."""
    for value in values:
        shown = value if isinstance(value, str) else f"{value:g}"
        _params_draws(f"{name} {shown}", {name: value}, draws, flow=flow)


def _params_draws(title: str, changes: dict, draws: int, *, flow: str = "farneback") -> None:
    """``Params(**changes)`` over every demo sequence (``flow``) as :func:`_setting_draws`
    runs one value: the runs' means per scene group and category, and the false-positive
    frames' SD, printed under ``title``."""
    import pandas as pd

    columns = ["crossing det.", "crossing cov.", "preceding det.", "preceding cov.",
               "approaching det.", "approaching cov.", "overtaking det.", "overtaking cov.",
               "static cov.", "FP frames", "static flagged", "IoU"]
    with pd.option_context("display.width", 250, "display.max_columns", 40):
        _, groups = _draw_groups(fm.Params(**changes, flow=flow), draws)
        numbers = [g[[c for c in columns if c in g]].astype(float) for g in groups]
        mean = sum(numbers) / len(numbers)
        sd = np.sqrt(sum((n - mean) ** 2 for n in numbers) / (len(numbers) - 1))
        print(f"{title}, {flow}, {len(groups)} runs (means, per cent):")
        print((100 * mean).round(1).to_string())
        print("false-positive frames SD: "
              + ", ".join(f"{s} {100 * v:.1f}" for s, v in sd["FP frames"].items()))


def confirm_draws(settings=({"confirm_reach": 0, "range_consistency": 0.0}, {},
                            {"range_consistency": 0.0}, {"range_consistency_alone": 1.5}),
                  draws: int = 4, flows=("farneback", "dis")) -> None:
    """:func:`_params_draws` of region confirmation by the frame before
    (``Params.confirm_reach``, cells; :mod:`fisheyemotion.confirm`) and the three-view test
    with it: each of ``settings`` (``Params`` changes: ``data/params/unconfirmed.yaml``, the
    defaults, ``no_three_views.yaml``, ``three_views_unchecked.yaml``) with each of ``flows``."""
    for flow in flows:
        for changes in settings:
            title = ", ".join(f"{k} {v:g}" for k, v in changes.items()) or "defaults"
            _params_draws(title, changes, draws, flow=flow)


def road_spill_draws(values=(0.0, 15.0), draws: int = 4, flows=("farneback", "dis")) -> None:
    """:func:`_setting_draws` of ``Params.road_spill`` (grey levels; 0: no trim;
    :mod:`fisheyemotion.spill`) with each of ``flows``."""
    for flow in flows:
        _setting_draws("road_spill", values, draws, flow=flow)


def carry_share_draws(shares=(0.0, 0.4, 0.5, 0.6), draws: int = 4) -> None:
    """:func:`_setting_draws` of ``Params.carry_share``."""
    _setting_draws("carry_share", shares, draws)


def receding_draws(values=(0.0, 2.0), draws: int = 4) -> None:
    """:func:`_setting_draws` of ``Params.receding`` (0: off)."""
    _setting_draws("receding", values, draws)


def range_tolerance_draws(values=(0.0, 0.03), draws: int = 4) -> None:
    """:func:`_setting_draws` of ``Params.photometric_range_error`` (0: the fixed tolerance
    only), with Farneback and with DIS."""
    for flow in ("farneback", "dis"):
        _setting_draws("photometric_range_error", values, draws, flow=flow)


def edge_draws(values=(0.0, 0.1), draws: int = 4) -> None:
    """:func:`_setting_draws` of ``Params.photometric_edge`` (0: off), with Farneback and with
    DIS."""
    for flow in ("farneback", "dis"):
        _setting_draws("photometric_edge", values, draws, flow=flow)


def span_draws(values=(0.0, 0.2, 0.35), draws: int = 4) -> None:
    """:func:`_setting_draws` of ``Params.photometric_span`` (0: off), with Farneback and with
    DIS medium."""
    for flow in ("farneback", "dis"):
        _setting_draws("photometric_span", values, draws, flow=flow)


def grow_draws(values=(0, 4), draws: int = 4) -> None:
    """:func:`_setting_draws` of ``Params.grow`` (cells of growth to the flow boundary; 0: off),
    with Farneback and with DIS medium."""
    for flow in ("farneback", "dis"):
        _setting_draws("grow", values, draws, flow=flow)


def second_pass_flow_draws(values=("same", "dis-ultrafast", "dis-fast", "dis-medium"),
                           draws: int = 4) -> None:
    """:func:`_setting_draws` of ``Params.second_pass_flow``, with Farneback and with DIS."""
    for flow in ("farneback", "dis"):
        _setting_draws("second_pass_flow", values, draws, flow=flow)


def span_at_true_ranges(names=("street_kb", "street_ds", "street_heldout_kb",
                               "street_heldout_ds")) -> None:
    """What the two-span test (``Params.photometric_span``) leaves, against the truth
    (``Params()``, Farneback, streamed as the evaluation does): every seed it tests, on a static
    surface or a moving object (the renderer's ids at the cell centre on the pair's previous
    frame), explained by the test or not, then explained by the same test with the single
    candidate at the renderer's true range of the cell centre, and whether that true point is
    seen in the pair's current frame and in the frame a span before (the range seen where it
    projects within 5 % of its own, no moving object there; or behind a moving object) and
    whether the cell straddles a depth edge (its pixels' true ranges more than 10 % apart).
    Static seeds the true range does not explain are those a rigidly moved cell cannot
    explain, whatever range the model held.
    ``names``: the sequences."""
    import pandas as pd
    from fisheyemotion.eval.evaluate import evaluate_sequence

    from fisheyemotion import detector as detector_module
    from fisheyemotion.photometric import span_explained
    from fisheyemotion.static_scene import world_points

    cls = detector_module.MotionDetector
    original = cls._span_explained
    rows = []
    for name in names:
        seq = Sequence(SEQUENCES / name)
        renderer = Renderer(seq.camera, load_scenario(seq.path / "scenario.yaml"),
                            supersample=1)
        frame_of = {pose.tobytes(): k for k, pose in enumerate(seq.poses)}
        truth: dict = {}

        def rendered(k, renderer=renderer, truth=truth):
            if k not in truth:
                frame = renderer.render(k)
                truth[k] = (np.where(np.isfinite(frame.range), frame.range, np.inf),
                            frame.moving > 0)
            return truth[k]

        def spy(self, m, seeds, measured, name=name, frame_of=frame_of, rendered=rendered):
            out = original(self, m, seeds, measured)
            (pose_before, before), model = m.span_before, m.scene_ranges
            cells = seeds & np.isfinite(model)
            if m.along_travel is not None:
                cells &= ~m.along_travel
            k0, k1 = frame_of.get(m.t0.tobytes()), frame_of.get(m.t1.tobytes())
            kb = frame_of.get(pose_before.tobytes())
            if not cells.any() or None in (k0, k1, kb):
                return out
            r, c = np.nonzero(cells)
            g = self.params.grid
            ranges0, moving0 = rendered(k0)
            centre = self._centres[r, c]
            u, v = centre[:, 0].astype(int), centre[:, 1].astype(int)
            block = np.stack([ranges0[rr * g:rr * g + g, cc * g:cc * g + g] for rr, cc in
                              zip(r, c, strict=True)])
            with np.errstate(invalid="ignore"):
                straddles = block.max(axis=(1, 2)) > 1.1 * block.min(axis=(1, 2))
            points = world_points(self._rays0[r, c], ranges0[v, u], m.t0)
            moves, seen, behind_moving = [], [], []
            for k, pose in ((k1, m.t1), (kb, pose_before)):
                pixels, ok = self.camera.project((points - pose[:3, 3]) @ pose[:3, :3])
                ok &= np.isfinite(ranges0[v, u])
                moves.append(np.where(ok[:, None], pixels - centre, np.nan)[None])
                ranges, moving = rendered(k)
                pu = np.clip(np.rint(np.nan_to_num(pixels[:, 0])), 0, ranges.shape[1] - 1)
                pv = np.clip(np.rint(np.nan_to_num(pixels[:, 1])), 0, ranges.shape[0] - 1)
                pu, pv = pu.astype(int), pv.astype(int)
                expected = np.linalg.norm(points - pose[:3, 3], axis=-1)
                with np.errstate(invalid="ignore"):
                    seen.append(ok & (np.abs(ranges[pv, pu] / expected - 1) < 0.05)
                                & ~moving[pv, pu])
                    behind_moving.append(ok & moving[pv, pu]
                                         & (ranges[pv, pu] < 0.95 * expected))
            true = span_explained(m.gray, m.curr, before, g, cells, measured, *moves)
            rows.append(pd.DataFrame({
                "scene": name, "moving": moving0[v, u], "explained": out[r, c],
                "true explains": true[r, c], "seen now": seen[0], "seen in both": seen[0] & seen[1],
                "behind a moving object now": behind_moving[0],
                "straddles": straddles}))
            return out

        cls._span_explained = spy
        try:
            evaluate_sequence(seq.path, fm.Params(), ablation=False)
        finally:
            cls._span_explained = original
    df = pd.concat(rows)
    df["surface"] = np.where(df.moving, "moving object", "static")
    static = df[~df.moving]
    print("Seeds the two-span test tested (Farneback, Params()): share explained by the test, "
          "by the true range alone, seen in the current frame, seen there and in the frame a span "
          "before, straddling a depth edge (%):")
    print((100 * df.groupby(["scene", "surface"]).mean(numeric_only=True).drop(
        columns="moving")).round(0).join(df.groupby(["scene", "surface"]).size().rename(
            "seeds")).to_string())
    alone = static[~static["behind a moving object now"]]
    unexplained = alone[~alone["true explains"]]
    hidden = ~unexplained["seen now"]
    before = unexplained["seen now"] & ~unexplained["seen in both"]
    neither = unexplained["seen in both"] & ~unexplained.straddles
    print(f"Static seeds not behind a moving object in the current frame: {len(alone)} of "
          f"{len(static)}; the true range explains {100 * alone['true explains'].mean():.0f} %. "
          f"Of the {len(unexplained)} it does not: {100 * hidden.mean():.0f} % hidden in the "
          f"current frame behind a static surface, {100 * before.mean():.0f} % hidden only in "
          f"the frame a span before, {100 * unexplained.straddles.mean():.0f} % straddling a "
          f"depth edge, {100 * neither.mean():.0f} % seen in both and not straddling")


def crossing_evidence(factors=(0.5, 1.0, 2.0), flows=("exact", "farneback")) -> None:
    """How much of a crossing pedestrian two views show (``Params()``, every demo sequence with
    one, streamed as the evaluation does, given each of ``flows``: ``"exact"``, the rendered
    scene's, or ``"farneback"``): the share of its object-frames (the evaluation's: within 8 m)
    with a scored cell above ``factors`` times the threshold in the pair's constraints as the
    paper scores them (raw angles), then above the threshold after the pair's measurement
    (significance, region tests), and detected."""
    for flow in flows:
        _crossing_evidence(factors, exact_flow=flow == "exact")


def _crossing_evidence(factors, *, exact_flow: bool) -> None:
    import pandas as pd
    from fisheyemotion.eval.evaluate import evaluate_sequence
    from fisheyemotion.eval.report import scene_group

    from fisheyemotion import detector as detector_module

    cls = detector_module.MotionDetector
    original = cls._measure
    p = fm.Params()
    g, c = p.grid, (p.grid - 1) // 2
    rows = []
    for path in sorted(SEQUENCES.iterdir()):
        seq = Sequence(path)
        if not (seq.objects.category == "crossing").any():
            continue
        frame_of = {pose.tobytes(): k for k, pose in enumerate(seq.poses)}
        measured: dict = {}

        def spy(self, flow, t0, t1, *args, frame_of=frame_of, measured=measured, **kwargs):
            m = original(self, flow, t0, t1, *args, **kwargs)
            measured[frame_of.get(np.asarray(t1).tobytes())] = m
            return m

        cls._measure = spy
        try:
            result = evaluate_sequence(path, p, ablation=False, exact_flow=exact_flow)
        finally:
            cls._measure = original
        objects = result.objects[result.objects.category == "crossing"]
        for row in objects.itertuples():
            m = measured.get(row.frame)
            rcount, ccount = m.likelihood.shape
            ids = seq.ids(row.frame - p.frame_gap)[c:rcount * g:g, c:ccount * g:g]
            cells = (ids == row.id) & m.valid
            raw = np.nanmax(m.res.likelihood[cells]) if cells.any() else 0.0
            after = np.nanmax(m.likelihood[cells]) if cells.any() else 0.0
            rows.append({"scenes": scene_group(path.name), "raw": raw,
                         "after": after, "detected": row.detected})
    df = pd.DataFrame(rows)
    table = pd.DataFrame({
        **{f"raw > {f:g} thr.": df.raw > f * p.threshold for f in factors},
        "after the measurement": df.after > p.threshold, "detected": df.detected,
        "scenes": df.scenes}).groupby("scenes")
    print(f"Crossing pedestrians' object-frames, {'the exact' if exact_flow else 'Farneback'} "
          "flow: a cell above the threshold (%), and their count:")
    print((100 * table.mean()).round(0).join(table.size().rename("object-frames")).to_string())


if __name__ == "__main__":
    if not SEQUENCES.is_dir():
        sys.exit(f"{SEQUENCES}: run 'make demo' first")
    warnings.simplefilter("ignore")
    if sys.argv[1:]:  # only these, by name
        for name in sys.argv[1:]:
            globals()[name]()
        sys.exit()
    scene_prior_flow_error()
    height_significance()
    road_estimates()
    false_regions()
    prior_error_at_false_regions()
    scene_model_at_false_cells()
    wall_ranges()
    pose_steps()
    pose_noise_draws()
    scene_model_amplification()
    scene_agreement_tradeoff()
    false_region_rules()
    ground_contact_ranges()
    stored_point_errors()
    true_depth_prior_bounds()
    contact_with_true_ranges()
    coverage_by_step()
    crossing_cells_by_elevation()
    crossing_evidence()
    flow_follows_prior()
    photometric_search_draws()
    carry_share_draws()
