"""Command line: ``fisheyemotion {demo,calib}``."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pandas as pd

from . import calib

REPO_DATA = Path(__file__).resolve().parents[1] / "data"


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


def _calib_files(data: Path) -> list[Path]:
    return sorted(p for p in (data / "calib").iterdir()
                  if p.suffix in {".yaml", ".yml", ".json", ".xml", ".txt"})


def cmd_calib(args: argparse.Namespace) -> int:
    print(calibration_table([Path(p) for p in args.files]).to_string(index=False))
    return 0


def cmd_demo(args: argparse.Namespace) -> int:
    data = Path(args.data)
    print(f"Bundled calibrations in {data / 'calib'}:")
    print(calibration_table(_calib_files(data)).to_string(index=False))
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="fisheyemotion", description=__doc__)
    sub = parser.add_subparsers(dest="command", required=True)
    p = sub.add_parser("demo", help="run the main job on the bundled data")
    p.add_argument("--data", default=str(REPO_DATA), help="the data/ folder (default: bundled)")
    p.set_defaults(func=cmd_demo)
    p = sub.add_parser("calib", help="print model, size and FOV of calibration files")
    p.add_argument("files", nargs="+")
    p.set_defaults(func=cmd_calib)
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
