"""Render a scenario through a camera and write it as a sequence folder."""

from __future__ import annotations

import dataclasses
import os
from pathlib import Path

import cv2
import numpy as np
import pandas as pd
import yaml
from tqdm import tqdm

from ..calib import save_opencv
from ..calib.base import CameraModel
from ..outputs import atomic_folder
from ..poses import write_tum
from ..sequence import OBJECT_COLUMNS, frame_name
from .render import FrameTruth, Renderer
from .scenario import Scenario


def scenario_doc(scenario: Scenario) -> dict:
    """The spec of a scenario as a YAML-ready mapping (readable by ``parse_scenario``)."""
    statics, objects = [], []
    for b in scenario.boxes:
        item = {"id": b.id, "kind": b.kind, "size": list(b.size), "texture": b.texture}
        if b.moving:
            item |= {"category": b.category, "start": list(b.center), "heading_deg": b.yaw_deg,
                     "speed_kmh": b.speed_kmh}
            objects.append(item)
        else:
            item |= {"center": list(b.center), "yaw_deg": b.yaw_deg}
            statics.append(item)
    return {
        "name": scenario.name, "description": scenario.description, "fps": scenario.fps,
        "frames": scenario.frames,
        "ego": {k: (list(v) if isinstance(v, tuple) else v)
                for k, v in dataclasses.asdict(scenario.ego).items()},
        "camera": {k: (list(v) if isinstance(v, tuple) else v)
                   for k, v in dataclasses.asdict(scenario.camera).items()},
        "road": dataclasses.asdict(scenario.road), "static": statics, "objects": objects,
    }


def object_rows(scenario: Scenario, truth: FrameTruth) -> list[dict]:
    """Per object of the frame: category, moving flag, distance and visible pixel count."""
    rows = []
    cam_centre = truth.pose[:3, 3]
    t = scenario.time(truth.index)
    for b in scenario.boxes:
        sel = truth.ids == b.id
        visible = int(sel.sum())
        if visible:
            distance = float(np.nanmin(truth.range[sel]))
        else:
            distance = float(np.linalg.norm(b.world_from_box(t)[:3, 3] - cam_centre))
        rows.append({"frame": truth.index, "id": b.id, "kind": b.kind,
                     "category": "static" if scenario.ego_static and b.moving else b.category,
                     "moving": bool(b.moving), "distance": round(distance, 4),
                     "visible_pixels": visible})
    return rows


def write_sequence(out: str | os.PathLike, camera: CameraModel, scenario: Scenario, *,
                   frames: int | None = None, flow: bool = True, progress: bool = True,
                   overwrite: bool = True, **render_options) -> Path:
    """Render ``scenario`` through ``camera`` into the folder ``out`` (created).

    Parameters
    ----------
    frames : int, optional
        Number of frames (default: the scenario's).
    flow : bool
        Also write ``flow/NNNNNN.npz`` (ground-truth flow and range).
    progress : bool
        Show a progress bar.
    overwrite : bool
        Replace a non-empty ``out`` (as a whole); False refuses it with a ValueError.
    render_options
        Passed to :class:`Renderer` (``supersample``, ``noise_sigma``, ``blur_sigma``, ``seed``).
    """
    out = Path(out)
    if frames is not None and (isinstance(frames, bool) or not isinstance(frames, int)
                               or frames < 2):
        raise ValueError(f"frames: expected an integer >= 2, got {frames!r}")
    n = scenario.frames if frames is None else min(int(frames), scenario.frames)
    renderer = Renderer(camera, scenario, **render_options)
    # Written whole or not at all (Ctrl-C included), replacing any earlier sequence there.
    with atomic_folder(out, overwrite=overwrite) as tmp:
        _write(tmp, renderer, camera, scenario, n, flow, progress)
    return out


def _write(out: Path, renderer: Renderer, camera: CameraModel, scenario: Scenario, n: int,
           flow: bool, progress: bool) -> None:
    for sub in ("frames", "masks", "ids") + (("flow",) if flow else ()):
        (out / sub).mkdir(parents=True, exist_ok=True)
    poses, rows = [], []
    for k in tqdm(range(n), desc=f"synth {scenario.name}", disable=not progress, leave=False):
        truth = renderer.render(k)
        name = frame_name(k)
        cv2.imwrite(str(out / "frames" / name), truth.image)
        cv2.imwrite(str(out / "masks" / name), truth.moving)
        cv2.imwrite(str(out / "ids" / name), truth.ids)
        if flow:
            np.savez_compressed(out / "flow" / name.replace(".png", ".npz"),
                                flow=truth.flow if truth.flow is not None else np.zeros(0),
                                range=truth.range)
        poses.append(truth.pose)
        rows.extend(object_rows(scenario, truth))
    write_tum(out / "poses.txt", [scenario.time(k) for k in range(n)], poses)
    save_opencv(camera, out / "calib.yaml")
    cv2.imwrite(str(out / "roi.png"), renderer.roi())
    pd.DataFrame(rows, columns=list(OBJECT_COLUMNS)).to_csv(out / "objects.csv", index=False)
    (out / "scenario.yaml").write_text(yaml.safe_dump(scenario_doc(scenario), sort_keys=False))
