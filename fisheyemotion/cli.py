"""Command line: ``fisheyemotion {detect,synth,calib}`` (+ ``eval``, ``compare``, ``demo`` from
:mod:`fisheyemotion.eval`).

Errors are one line on stderr and exit code 2.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Iterator, Sequence
from importlib.metadata import entry_points
from pathlib import Path

import cv2
import numpy as np
import pandas as pd
from tqdm import tqdm

from . import calib
from .detect import MotionDetector
from .params import Params
from .poses import read_tum
from .road import Road

REPO_DATA = Path(__file__).resolve().parents[1] / "data"
IMAGE_SUFFIXES = {".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff"}


class CliError(ValueError):
    """A user error reported as one line."""


# ---- calibrations ---------------------------------------------------------------------------

def calibration_table(paths: Sequence[Path]) -> pd.DataFrame:
    """One row per camera of each calibration file: file, camera, model, size, FOV."""
    rows = []
    for path in paths:
        rig = calib.load_rig(path)
        for name, cam in zip(rig.names, rig.cameras, strict=True):
            rows.append({
                "file": path.name, "camera": name, "model": cam.name,
                "size": f"{cam.width}x{cam.height}", "fov_deg": round(cam.fov_deg, 1),
                "theta_max_deg": round(float(np.degrees(cam.theta_max)), 1),
                "valid_px_%": round(100 * float(cam.valid_pixel_mask().mean()), 1),
            })
    return pd.DataFrame(rows)


def calib_files(data: Path) -> list[Path]:
    """Calibration files in ``data/calib``."""
    return sorted(p for p in (data / "calib").iterdir()
                  if p.suffix in {".yaml", ".yml", ".json", ".xml", ".txt"})


def cmd_calib(args: argparse.Namespace) -> int:
    print(calibration_table([Path(p) for p in args.files]).to_string(index=False))
    return 0


# ---- detect ---------------------------------------------------------------------------------

def _parse_road(text: str | None) -> Road:
    if not text:
        return Road()
    try:
        v = [float(x) for x in text.split(",")]
    except ValueError:
        raise CliError(f"--road: expected 'nx,ny,nz,offset' numbers, got {text!r}") from None
    if len(v) != 4:
        raise CliError(f"--road: expected 4 numbers 'nx,ny,nz,offset', got {len(v)}")
    try:
        return Road(normal=tuple(v[:3]), offset=v[3])
    except ValueError as exc:
        raise CliError(f"--road: {exc}") from None


def _stamp_of(path: Path) -> float | None:
    try:
        v = float(path.stem)
    except ValueError:
        return None
    return v / 1e9 if len(path.stem.split(".")[0]) >= 16 else v  # nanoseconds (EuRoC, TUM VI)


def iter_frames(source: Path) -> Iterator[tuple[int, float | None, np.ndarray]]:
    """``(index, timestamp or None, BGR frame)`` from a video, an image folder or a sequence."""
    if source.is_dir():
        folder = source / "frames" if (source / "frames").is_dir() else source
        paths = sorted(p for p in folder.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES)
        if not paths:
            raise CliError(f"{source}: no images")
        for i, p in enumerate(paths):
            img = cv2.imread(str(p), cv2.IMREAD_COLOR)
            if img is None:
                raise CliError(f"{p}: cannot be read as an image")
            yield i, _stamp_of(p), img
        return
    if not source.exists():
        raise CliError(f"{source}: no such file or folder")
    cap = cv2.VideoCapture(str(source))
    if not cap.isOpened():
        raise CliError(f"{source}: cannot be opened as a video")
    i = 0
    try:
        while True:
            ok, img = cap.read()
            if not ok:
                break
            yield i, cap.get(cv2.CAP_PROP_POS_MSEC) / 1000.0, img
            i += 1
    finally:
        cap.release()


class PoseLookup:
    """Poses for frames, by frame index or by the nearest timestamp (within ``max_dt`` s)."""

    def __init__(self, path: Path, match: str, max_dt: float) -> None:
        self.stamps, self.poses = read_tum(path)
        self.path, self.match, self.max_dt = path, match, max_dt

    def __call__(self, index: int, stamp: float | None) -> tuple[float, np.ndarray]:
        """``(pose timestamp, world_from_cam)`` for a frame."""
        if self.match == "index":
            if index >= len(self.poses):
                raise CliError(f"{self.path}: {len(self.poses)} poses, but the input has more frames")
            return float(self.stamps[index]), self.poses[index]
        if stamp is None:
            raise CliError("--match timestamp: frame names are not timestamps; use --match index")
        j = int(np.argmin(np.abs(self.stamps - stamp)))
        if abs(self.stamps[j] - stamp) > self.max_dt:
            raise CliError(f"{self.path}: no pose within {self.max_dt} s of frame {index} (t={stamp})")
        return float(self.stamps[j]), self.poses[j]


def run_detect(source: Path, camera: calib.CameraModel, poses: PoseLookup, out: Path, *,
               road: Road, params: Params, write_video: bool, progress: bool = True,
               roi: np.ndarray | None = None) -> pd.DataFrame:
    """Detect over a whole input; writes annotations, likelihood maps and regions.csv."""
    from .draw import annotate

    out.mkdir(parents=True, exist_ok=True)
    (out / "likelihood").mkdir(exist_ok=True)
    if not write_video:
        (out / "annotated").mkdir(exist_ok=True)
    detector = MotionDetector(camera, road, params, roi=roi)
    writer = None
    rows = []
    frames = iter_frames(source)
    for index, stamp, frame in tqdm(frames, desc="detect", disable=not progress, leave=False):
        stamp, pose = poses(index, stamp)
        try:
            result = detector.apply(frame, pose)
        except ValueError as exc:
            raise CliError(f"frame {index}: {exc}") from None
        if result is None:
            continue
        name = f"{index:06d}"
        np.savez_compressed(out / "likelihood" / f"{name}.npz", likelihood=result.likelihood,
                            mask=result.mask)
        shown = annotate(frame, result)
        if write_video:
            if writer is None:
                writer = cv2.VideoWriter(str(out / "annotated.mp4"),
                                         cv2.VideoWriter_fourcc(*"mp4v"), 15.0,
                                         (shown.shape[1], shown.shape[0]))
            writer.write(shown)
        else:
            cv2.imwrite(str(out / "annotated" / f"{name}.png"), shown)
        for r in result.regions:
            rows.append({"frame": index, "timestamp": stamp, "label": r.label, "x": r.bbox[0],
                         "y": r.bbox[1], "w": r.bbox[2], "h": r.bbox[3], "area": r.area,
                         "mean_likelihood": r.mean_likelihood, "u": r.centroid[0],
                         "v": r.centroid[1]})
    if writer is not None:
        writer.release()
    table = pd.DataFrame(rows, columns=["frame", "timestamp", "label", "x", "y", "w", "h", "area",
                                        "mean_likelihood", "u", "v"])
    table.to_csv(out / "regions.csv", index=False)
    return table


def cmd_detect(args: argparse.Namespace) -> int:
    source = Path(args.input)
    if not source.exists():
        raise CliError(f"{source}: no such file or folder")
    is_sequence = (source / "frames").is_dir()
    calib_path = Path(args.calib) if args.calib else (source / "calib.yaml" if is_sequence else None)
    poses_path = Path(args.poses) if args.poses else (source / "poses.txt" if is_sequence else None)
    if calib_path is None or poses_path is None:
        raise CliError("--calib and --poses are required unless INPUT is a sequence folder")
    camera = calib.load(calib_path, camera=args.camera)
    params = Params.load(args.params) if args.params else Params()
    if args.flow:
        params = params.replace(flow=args.flow)
    lookup = PoseLookup(poses_path, args.match, args.max_dt)
    roi_path = Path(args.roi) if args.roi else (source / "roi.png" if is_sequence else None)
    roi = None
    if roi_path is not None and (args.roi or roi_path.exists()):
        roi = cv2.imread(str(roi_path), cv2.IMREAD_GRAYSCALE)
        if roi is None:
            raise CliError(f"{roi_path}: cannot be read as an image")
    write_video = not source.is_dir()
    table = run_detect(source, camera, lookup, Path(args.out), road=_parse_road(args.road),
                       params=params, write_video=write_video, progress=not args.quiet, roi=roi)
    print(f"{len(table)} regions in {table['frame'].nunique()} frames; written to {args.out}")
    return 0


# ---- synth ----------------------------------------------------------------------------------

def cmd_synth(args: argparse.Namespace) -> int:
    from . import synth

    if args.list:
        for name in synth.list_scenarios():
            sc = synth.load_scenario(name)
            print(f"{name:16s} {sc.frames:4d} frames  {sc.description}")
        return 0
    if not args.scenario or not args.calib or not args.out:
        raise CliError("--scenario, --calib and --out are required (or --list)")
    scenario = synth.load_scenario(args.scenario)
    camera = calib.load(args.calib, camera=args.camera)
    out = synth.write_sequence(args.out, camera, scenario, frames=args.frames, seed=args.seed,
                               supersample=args.supersample, noise_sigma=args.noise,
                               progress=not args.quiet)
    print(f"wrote {out}")
    return 0


def _camera_arg(text: str) -> int | str:
    return int(text) if text.isdigit() else text


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="fisheyemotion", description=__doc__)
    sub = parser.add_subparsers(dest="command", required=True)

    p = sub.add_parser("detect", help="detect moving objects in a video, image folder or sequence")
    p.add_argument("input", help="video file, folder of frames, or sequence folder")
    p.add_argument("--calib", help="calibration file (default: INPUT/calib.yaml)")
    p.add_argument("--camera", type=_camera_arg, default=0, help="camera index or name in --calib")
    p.add_argument("--poses", help="TUM pose file, world_from_cam (default: INPUT/poses.txt)")
    p.add_argument("--match", choices=("index", "timestamp"), default="index",
                   help="pair frames and poses by index (default) or by timestamp")
    p.add_argument("--max-dt", type=float, default=0.02, help="timestamp tolerance, seconds")
    p.add_argument("--road", help="road plane 'nx,ny,nz,offset' in the world frame (default 0,0,1,0)")
    p.add_argument("--params", help="YAML/JSON file of Params")
    p.add_argument("--roi", help="mask image of pixels to use (default: INPUT/roi.png if present)")
    p.add_argument("--flow", choices=("farneback", "dis"), help="override the flow method")
    p.add_argument("--out", required=True, help="output folder")
    p.add_argument("--quiet", action="store_true")
    p.set_defaults(func=cmd_detect)

    p = sub.add_parser("synth", help="render a scenario to a sequence folder")
    p.add_argument("--scenario", help="bundled scenario name or YAML file")
    p.add_argument("--calib", help="calibration file of the camera")
    p.add_argument("--camera", type=_camera_arg, default=0)
    p.add_argument("--frames", type=int, help="number of frames (default: the scenario's)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--supersample", type=int, default=2)
    p.add_argument("--noise", type=float, default=0.0, help="sensor noise sigma, grey levels")
    p.add_argument("--out", help="output sequence folder")
    p.add_argument("--list", action="store_true", help="list the bundled scenarios")
    p.add_argument("--quiet", action="store_true")
    p.set_defaults(func=cmd_synth)

    p = sub.add_parser("calib", help="print model, size and FOV of calibration files")
    p.add_argument("files", nargs="+")
    p.set_defaults(func=cmd_calib)

    # Commands of packages built on the core (fisheyemotion.eval: eval, compare, demo) register
    # through entry points, so that the core never imports them.
    for ep in entry_points(group="fisheyemotion.commands"):
        ep.load()(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except (ValueError, OSError) as exc:
        print(f"fisheyemotion {args.command}: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
