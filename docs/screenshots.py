"""Screenshots of the HTML report in headless Chromium, as a reader sees it at 100 % zoom.

``make screenshots`` (after ``make demo``), or ``python docs/screenshots.py [report.html]``:
renders the page in a 1280-pixel-wide window and writes it, cut into screen-high tiles, to
``docs/img/report_<n>.png``, and copies the report's figures that docs/ shows
(``docs/img/eval_*.png``, ``docs/img/real_aria.png``, ``docs/img/real_pairs.png``). Needs
Debian's ``chromium`` (``apt-get install chromium``).
"""

from __future__ import annotations

import argparse
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import cv2
import numpy as np

OUT = Path(__file__).parent / "img"
WIDTH, TILE = 1280, 1600
#: The report's figures shown in docs/, by their name there.
FIGURES = {"table2.png": "eval_table2.png", "pr.png": "eval_pr.png",
           "scenes.png": "eval_scenes.png", "fig6.png": "eval_fig6.png", "real.png": "real_aria.png",
           "real_pairs.png": "real_pairs.png"}
# Flags for a machine with no network and no display; --no-sandbox because CI runs as root.
FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
         "--disable-background-networking", "--disable-component-update", "--disable-sync",
         "--hide-scrollbars", "--force-device-scale-factor=1"]


def render(page: Path, height: int) -> np.ndarray:
    """The page rendered in a ``WIDTH x height`` window, as a BGR image."""
    chromium = shutil.which("chromium") or shutil.which("chromium-browser")
    if chromium is None:
        raise SystemExit("screenshots: chromium not found (apt-get install chromium)")
    with tempfile.TemporaryDirectory() as tmp:
        shot = Path(tmp) / "page.png"
        subprocess.run([chromium, *FLAGS, f"--user-data-dir={tmp}/profile",
                        f"--window-size={WIDTH},{height}", f"--screenshot={shot}",
                        page.resolve().as_uri()], check=True, capture_output=True, timeout=120)
        return cv2.imread(str(shot))


def content_height(img: np.ndarray) -> int:
    """Rows down to the last one that is not plain background."""
    rows = np.flatnonzero((img != img[-1:, :, :]).any(axis=(1, 2)))
    return int(rows[-1]) + 1 if len(rows) else 0


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("report", nargs="?", default="data/generated/demo/report/report.html",
                    help="the HTML report (default: %(default)s, written by make demo)")
    ap.add_argument("--out", default=str(OUT), help="folder of the tiles (default: docs/img)")
    args = ap.parse_args(argv)
    page = Path(args.report)
    if not page.is_file():
        raise SystemExit(f"screenshots: {page} not found (run make demo first)")
    img = render(page, 30000)
    height = content_height(img)
    if height >= img.shape[0] - 1:
        raise SystemExit("screenshots: the page is taller than 30000 px")
    out = Path(args.out)
    for old in out.glob("report_*.png"):
        old.unlink()
    tiles = range(0, height, TILE)
    for n, top in enumerate(tiles, 1):
        cv2.imwrite(str(out / f"report_{n}.png"), img[top:min(top + TILE, height)])
    copied = [shutil.copyfile(page.parent / src, out / dst) for src, dst in FIGURES.items()
              if (page.parent / src).exists()]
    print(f"{len(tiles)} tiles of {WIDTH} px width and {len(copied)} figures in {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
