"""Vectorised ray casting of road scenes through any camera model, with exact ground truth.

Every pixel's ray comes from ``camera.unproject`` (the same g(u) the detector uses), is moved
to the world with the camera pose and intersected with the road plane ``z = 0`` and with
textured boxes. Colour is averaged over ``supersample x supersample`` rays per pixel; the ground
truth (ids, range, flow) is exact at pixel centres.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from ..calib.base import CameraModel, pixel_grid
from .scenario import EGO_ID, Box, Scenario
from .textures import sample

SKY, ROAD = -1, 0
_ROAD_TEXEL = 0.005
_BOX_TEXEL = 0.01
_MARK_WIDTH = 0.15
_DASH, _GAP = 3.0, 6.0
# Brightness per face: local +x, -x, +y, -y, +z (top), -z
_FACE_SHADE = np.array([1.0, 0.8, 0.9, 0.7, 1.1, 0.5], dtype=np.float32)


@dataclass(frozen=True, eq=False)
class FrameTruth:
    """One rendered frame and its exact ground truth.

    Attributes
    ----------
    index : int
    image : ndarray of uint8, shape (H, W, 3)
        BGR; black outside the camera's valid region.
    ids : ndarray of uint16, shape (H, W)
        Box id at each pixel centre; 0 for road, sky and invalid pixels; ``EGO_ID`` (65535) for
        the ego vehicle's own body.
    moving : ndarray of uint8, shape (H, W)
        255 where a moving box is seen.
    range : ndarray of float32, shape (H, W)
        Distance from the camera centre to the surface hit (inf for sky, NaN outside the camera).
    flow : ndarray of float32, shape (H, W, 2) or None
        Exact flow from the previous frame's pixels to this frame (None for frame 0); NaN where
        the surface point leaves the camera's domain.
    pose : ndarray, shape (4, 4)
        ``world_from_cam``.
    """

    index: int
    image: NDArray[np.uint8]
    ids: NDArray[np.uint16]
    moving: NDArray[np.uint8]
    range: NDArray[np.float32]
    flow: NDArray[np.float32] | None
    pose: NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class Hits:
    """Nearest intersection per ray: ``obj`` (-1 sky, 0 road, i + 1 for ``boxes[i]``), distance
    ``t``, the hit point in the object's frame (world for road, direction for sky), the face, and
    each box's world rotation at the time of the cast."""

    obj: NDArray[np.int64]
    t: NDArray[np.float64]
    local: NDArray[np.float64]
    face: NDArray[np.int64]
    rotations: tuple[NDArray[np.float64], ...] = ()


class Renderer:
    """Renders the frames of a scenario through a camera.

    Parameters
    ----------
    camera : CameraModel
    scenario : Scenario
    supersample : int, default 2
        Rays per pixel side for the colour image (>= 1; at least 2 keeps flow free of aliasing).
    noise_sigma : float, default 0
        Standard deviation of Gaussian sensor noise (grey levels).
    blur_sigma : float, default 0
        Gaussian blur (pixels) before noise.
    seed : int, default 0
        Seed of the sensor noise.
    """

    def __init__(self, camera: CameraModel, scenario: Scenario, *, supersample: int = 2,
                 noise_sigma: float = 0.0, blur_sigma: float = 0.0, seed: int = 0) -> None:
        if not isinstance(supersample, int) or supersample < 1:
            raise ValueError(f"supersample: expected an integer >= 1, got {supersample!r}")
        self.camera, self.scenario = camera, scenario
        self.ss, self.noise_sigma, self.blur_sigma, self.seed = supersample, noise_sigma, blur_sigma, seed
        w, h = camera.width, camera.height
        self._rays, self._valid = camera.pixel_rays()
        offsets = (np.arange(supersample) + 0.5) / supersample - 0.5
        ou, ov = np.meshgrid(offsets, offsets)
        sub = pixel_grid(w, h)[:, :, None, :] + np.stack([ou.ravel(), ov.ravel()], -1)
        self._sub_rays, self._sub_valid = camera.unproject(sub)  # (H, W, ss*ss, 3)
        # Angle between neighbouring samples, at the image centre (1 / focal length).
        fx, fy, _, _ = camera._affine()
        self._sample_angle = 1.0 / (max(fx, fy) * supersample)
        self._prev_hits: tuple[int, Hits] | None = None
        self._body_sub = self._body_hits(self._sub_rays[self._sub_valid])
        self._body_centre = self._body_hits(self._rays[self._valid])

    # ---- geometry -----------------------------------------------------------------------
    def _boxes_at(self, t: float) -> list[tuple[Box, np.ndarray]]:
        out = [(b, b.world_from_box(t)) for b in self.scenario.boxes]
        body = self.scenario.ego_body()
        if body is not None:  # rigidly attached to the vehicle
            out.append((body, self.scenario.ego.world_from_vehicle(t) @ body.world_from_box(0.0)))
        return out

    @property
    def _all_boxes(self) -> list[Box]:
        body = self.scenario.ego_body()
        return list(self.scenario.boxes) + ([body] if body is not None else [])

    def intersect(self, origin: NDArray, dirs: NDArray, time: float, *,
                  body: tuple[NDArray, NDArray, NDArray] | None = None) -> Hits:
        """Nearest hits of world rays ``dirs`` (N, 3) from ``origin`` at scenario time ``time``.

        ``body``: precomputed ``(t, local, face)`` of the ego vehicle's body for these rays
        (rigid with the camera, so the same in every frame); cast here when None.
        """
        return self._cast(origin, dirs, self._boxes_at(time), body=body,
                          n_scene=len(self.scenario.boxes))

    def _cast(self, origin: NDArray, dirs: NDArray, boxes: list[tuple[Box, NDArray]], *,
              body: tuple[NDArray, NDArray, NDArray] | None, n_scene: int) -> Hits:
        """Road plane and ``boxes`` (box, world_from_box); ``body`` stands for ``boxes[n_scene]``."""
        n = dirs.shape[0]
        best_t = np.full(n, np.inf)
        obj = np.full(n, SKY, dtype=np.int64)
        face = np.full(n, -1, dtype=np.int64)
        local = dirs.copy()
        with np.errstate(divide="ignore", invalid="ignore"):
            t_road = np.where(dirs[:, 2] < -1e-12, -origin[2] / dirs[:, 2], np.inf)
        hit = t_road < best_t
        best_t[hit], obj[hit] = t_road[hit], ROAD
        cast = boxes if body is None else boxes[:n_scene]
        if body is not None and len(boxes) > n_scene:
            t_b, local_b, face_b = body
            sel = np.flatnonzero(t_b < best_t)
            best_t[sel], obj[sel] = t_b[sel], n_scene + 1
            local[sel], face[sel] = local_b[sel], face_b[sel]
        if cast:
            # Cone cull of every box at once: rays within the angle its bounding sphere subtends.
            centres = np.array([p[:3, 3] for _, p in cast]) - origin
            dist = np.linalg.norm(centres, axis=1)
            radius = np.array([0.5 * float(np.linalg.norm(b.size)) for b, _ in cast])
            with np.errstate(invalid="ignore"):
                cos_cone = np.where(dist > radius, np.sqrt(np.maximum(dist**2 - radius**2, 0)), -np.inf)
            near = dirs @ centres.T > cos_cone  # d . oc > |oc| cos(alpha)
        for i, (box, pose) in enumerate(cast):
            idx = np.flatnonzero(near[:, i])
            if idx.size == 0:
                continue
            rot, centre = pose[:3, :3], pose[:3, 3]
            half = np.array(box.size) / 2
            o_l = rot.T @ (origin - centre)
            d_l = dirs[idx] @ rot
            with np.errstate(divide="ignore", invalid="ignore"):
                inv = 1.0 / d_l
                t1 = (-half - o_l) * inv
                t2 = (half - o_l) * inv
            t_near = np.fmin(t1, t2)
            t_far = np.fmax(t1, t2)
            t_in = np.fmax(np.fmax(t_near[:, 0], t_near[:, 1]), t_near[:, 2])
            t_out = np.fmin(np.fmin(t_far[:, 0], t_far[:, 1]), t_far[:, 2])
            ok = (t_in <= t_out) & (t_in > 0) & (t_in < best_t[idx])
            sel = idx[ok]
            if sel.size == 0:
                continue
            t_hit = t_in[ok]
            axis = np.argmax(np.where(np.isnan(t_near[ok]), -np.inf, t_near[ok]), axis=1)
            p_l = o_l + t_hit[:, None] * d_l[ok]
            sign = (p_l[np.arange(sel.size), axis] > 0).astype(np.int64)
            best_t[sel], obj[sel] = t_hit, i + 1
            local[sel] = p_l
            face[sel] = axis * 2 + (1 - sign)
        road = np.flatnonzero(obj == ROAD)
        local[road] = origin + best_t[road, None] * dirs[road]
        return Hits(obj, best_t, local, face, tuple(p[:3, :3] for _, p in boxes))

    def _body_hits(self, rays_cam: NDArray) -> tuple[NDArray, NDArray, NDArray] | None:
        """The ego body's hits for camera-frame rays (the same in every frame)."""
        body = self.scenario.ego_body()
        if body is None:
            return None
        vehicle_from_cam = self.scenario.camera.vehicle_from_cam()
        pose = body.world_from_box(0.0)  # in the vehicle frame
        hits = self._cast(vehicle_from_cam[:3, 3], rays_cam @ vehicle_from_cam[:3, :3].T,
                          [(body, pose)], body=None, n_scene=1)
        t = np.where(hits.obj == 1, hits.t, np.inf)
        return t, hits.local, hits.face

    # ---- shading ------------------------------------------------------------------------
    def _footprint(self, t: NDArray, cos_incidence: NDArray) -> NDArray[np.float64]:
        """Metres of surface one sample covers: distance x sample angle / cos(incidence)."""
        return t * self._sample_angle / np.maximum(np.abs(cos_incidence), 0.05)

    def _shade(self, hits: Hits, dirs: NDArray) -> NDArray[np.float32]:
        colour = np.empty((hits.obj.size, 3), dtype=np.float32)
        sky = hits.obj == SKY
        el = np.clip(dirs[sky, 2], 0, 1)[:, None]
        colour[sky] = (np.array([235, 205, 175], np.float32) * (1 - el)
                       + np.array([200, 140, 90], np.float32) * el)
        road = hits.obj == ROAD
        if road.any():
            colour[road] = self._road_colour(hits.local[road],
                                             self._footprint(hits.t[road], dirs[road, 2]))
        for i, box in enumerate(self._all_boxes):
            sel = np.flatnonzero(hits.obj == i + 1)
            if sel.size == 0:
                continue
            p, f = hits.local[sel], hits.face[sel]
            axis = f // 2
            normal_cos = (dirs[sel] @ hits.rotations[i])[np.arange(axis.size), axis]
            footprint = self._footprint(hits.t[sel], normal_cos)
            # Face coordinates: horizontal along the face, vertical up (top: x, y).
            u = np.where(axis == 0, p[:, 1], p[:, 0]) + 7.3 * i
            v = np.where(axis == 2, p[:, 1], p[:, 2])
            colour[sel] = sample(box.texture, u, v, _BOX_TEXEL, footprint) * _FACE_SHADE[f][:, None]
        return colour

    def _road_colour(self, points: NDArray, footprint: NDArray) -> NDArray[np.float32]:
        x, y = points[:, 0], points[:, 1]
        spec = self.scenario.road
        half = spec.lanes * spec.lane_width / 2
        colour = sample("gravel", x, y, _ROAD_TEXEL, footprint)
        verge = np.abs(y) > half + _MARK_WIDTH
        if verge.any():
            colour[verge] = sample("grass", x[verge], y[verge], _ROAD_TEXEL * 2, footprint[verge])
        lines = [(-half, False), (half, False)] + [
            (-half + k * spec.lane_width, True) for k in range(1, spec.lanes)]
        for offset, dashed in lines:
            mark = np.abs(y - offset) < _MARK_WIDTH / 2
            if dashed:
                mark &= np.mod(x, _DASH + _GAP) < _DASH
            colour[mark] = colour[mark] * 0.25 + np.float32(200)
        return colour

    # ---- frames -------------------------------------------------------------------------
    def hits(self, index: int) -> Hits:
        """Ground-truth hits at the pixel centres of frame ``index`` (valid pixels only)."""
        if self._prev_hits is not None and self._prev_hits[0] == index:
            return self._prev_hits[1]
        pose = self.scenario.world_from_cam(index)
        dirs = self._rays[self._valid] @ pose[:3, :3].T
        return self.intersect(pose[:3, 3], dirs, self.scenario.time(index), body=self._body_centre)

    def roi(self) -> NDArray[np.uint8]:
        """255 where the camera sees the scene, 0 where it sees its own vehicle or nothing."""
        ids = np.zeros((self.camera.height, self.camera.width), np.uint16)
        hits = self.hits(0)
        box_ids = np.array([0] + [b.id for b in self._all_boxes], dtype=np.uint16)
        ids[self._valid] = box_ids[np.maximum(hits.obj, 0)]
        return np.where(self._valid & (ids != EGO_ID), 255, 0).astype(np.uint8)

    def render(self, index: int) -> FrameTruth:
        """Frame ``index`` with its ground truth (flow from frame ``index - 1``)."""
        cam, sc = self.camera, self.scenario
        h, w = cam.height, cam.width
        pose = sc.world_from_cam(index)
        time = sc.time(index)
        # Colour: supersampled.
        valid_sub = self._sub_valid
        dirs = self._sub_rays[valid_sub] @ pose[:3, :3].T
        colour = np.zeros(valid_sub.shape + (3,), dtype=np.float32)
        colour[valid_sub] = self._shade(
            self.intersect(pose[:3, 3], dirs, time, body=self._body_sub), dirs)
        image = colour.mean(axis=2)
        if self.blur_sigma > 0:
            image = cv2.GaussianBlur(image, (0, 0), self.blur_sigma)
        if self.noise_sigma > 0:
            rng = np.random.default_rng([self.seed, index])
            image = image + rng.normal(0, self.noise_sigma, image.shape).astype(np.float32)
        image = np.clip(np.rint(image), 0, 255).astype(np.uint8)
        image[~self._valid] = 0
        # Ground truth at pixel centres.
        hits = self.hits(index)
        ids = np.zeros((h, w), np.uint16)
        box_ids = np.array([0] + [b.id for b in self._all_boxes], dtype=np.uint16)
        ids[self._valid] = box_ids[np.maximum(hits.obj, 0)]
        moving_ids = [b.id for b in sc.boxes if b.moving]
        moving = np.where(np.isin(ids, moving_ids) & (ids > 0), 255, 0).astype(np.uint8)
        rng_map = np.full((h, w), np.nan, np.float32)
        rng_map[self._valid] = hits.t
        flow = None if index == 0 else self._flow(index)
        self._prev_hits = (index, hits)
        return FrameTruth(index, image, ids, moving, rng_map, flow, pose)

    def _flow(self, index: int) -> NDArray[np.float32]:
        """Where each pixel's surface point of frame ``index - 1`` is seen in frame ``index``."""
        sc, cam = self.scenario, self.camera
        prev = self.hits(index - 1)
        t1 = sc.time(index)
        pose1 = sc.world_from_cam(index)
        world = np.empty_like(prev.local)
        sky = prev.obj == SKY
        road = prev.obj == ROAD
        world[road] = prev.local[road]
        for i, (_, p) in enumerate(self._boxes_at(t1)):
            sel = prev.obj == i + 1
            if sel.any():
                world[sel] = prev.local[sel] @ p[:3, :3].T + p[:3, 3]
        rays = np.empty_like(world)
        rays[~sky] = (world[~sky] - pose1[:3, 3]) @ pose1[:3, :3]
        rays[sky] = prev.local[sky] @ pose1[:3, :3]  # directions: rotation only
        pixels, ok = cam.project(rays)
        grid = pixel_grid(cam.width, cam.height)[self._valid]
        flow = np.full((cam.height, cam.width, 2), np.nan, np.float32)
        flow[self._valid] = np.where(ok[:, None], pixels - grid, np.nan)
        return flow


def render_frames(camera: CameraModel, scenario: Scenario, *, frames: int | None = None,
                  **kwargs) -> list[FrameTruth]:
    """All frames (or the first ``frames``) of a scenario, in order."""
    r = Renderer(camera, scenario, **kwargs)
    n = scenario.frames if frames is None else min(frames, scenario.frames)
    return [r.render(k) for k in range(n)]
