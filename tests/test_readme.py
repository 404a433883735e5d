"""The README's code runs as written (on a bundled scene's frame pair)."""

from __future__ import annotations

import os
import re
from pathlib import Path

import cv2
import numpy as np

import fisheyemotion as fm
from fisheyemotion import synth

README = Path(__file__).resolve().parents[1] / "README.md"


def test_the_readme_python_block_runs_as_written(tmp_path):
    block = re.search(r"```python\n(.*?)```", README.read_text(), re.S).group(1)
    cam = fm.calib.load(Path(__file__).resolve().parents[1] / "data" / "calib"
                        / "front_kb_640x480.yaml")
    fm.calib.save_opencv(cam, tmp_path / "calib.yaml")
    f0, f1 = synth.render_frames(cam, synth.load_scenario("crossing"), frames=2, supersample=1)
    namespace = {"prev": f0.image, "curr": f1.image, "pose0": f0.pose, "pose1": f1.pose}
    cwd = os.getcwd()
    os.chdir(tmp_path)
    try:
        exec(compile(block, "README.md", "exec"), namespace)  # noqa: S102 - the README's code
    finally:
        os.chdir(cwd)
    written = cv2.imread(str(tmp_path / "moving.png"))
    assert written is not None and written.shape == (480, 640, 3)
    assert namespace["mask"].dtype == np.uint8 and namespace["mask"].any()
