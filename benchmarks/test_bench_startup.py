"""Start-up as a new process sees it: ``import fisheyemotion`` and the first ``detect()`` after it,
with the numba cache warm, cold (an empty ``NUMBA_CACHE_DIR``, as a fresh clone or install
finds it) and cold without the warm-up's second process (``FISHEYEMOTION_WARMUP=0``); beside
them numba's own start in a new process, the floor of any first result that runs a numba kernel:
``import numba`` and the first call of one trivial kernel loaded from its warm cache.

Each round is a new interpreter that times itself (``extra_info``: medians over the rounds, in
seconds); the benchmark's own time is the whole process. One frame pair of the ``crossing``
scene, rendered once by the parent, OpenCV at one thread.
"""

from __future__ import annotations

import json
import os
import statistics
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import fisheyemotion as fm
from fisheyemotion import synth

ROOT = Path(__file__).resolve().parents[1]
CALIB = ROOT / "data" / "calib" / "front_kb_640x480.yaml"

CHILD = """
import sys, time
t0 = time.perf_counter()
import cv2, numpy as np
cv2.setNumThreads(1)
t1 = time.perf_counter()
import fisheyemotion as fm
t2 = time.perf_counter()
pair = np.load(sys.argv[2])
cam = fm.calib.load(sys.argv[1])
t3 = time.perf_counter()
fm.detect(pair["prev"], pair["curr"], pair["pose0"], pair["pose1"], camera=cam)
t4 = time.perf_counter()
print(t2 - t1, t4 - t3)
"""


@pytest.fixture(scope="module")
def pair(tmp_path_factory):
    cam = fm.calib.load(CALIB)
    renderer = synth.Renderer(cam, synth.load_scenario("crossing"))
    f0, f1 = renderer.render(0), renderer.render(3)
    gray = [np.ascontiguousarray(f.image.mean(axis=-1).astype(np.uint8)) for f in (f0, f1)]
    path = tmp_path_factory.mktemp("startup") / "pair.npz"
    np.savez(path, prev=gray[0], curr=gray[1], pose0=f0.pose, pose1=f1.pose)
    return path


@pytest.mark.parametrize("cache", ["warm", "cold", "cold-no-warmup"])
def test_first_result(benchmark, pair, cache, tmp_path):
    benchmark.group = "startup"
    env = dict(os.environ)
    if cache == "warm":  # the repository's own cache, filled by an untimed first run
        subprocess.run([sys.executable, "-c", CHILD, str(CALIB), str(pair)], env=env,
                       check=True, capture_output=True)
    times = []
    rounds = iter(range(100))

    def run():
        if cache != "warm":
            cold = tmp_path / f"numba-{next(rounds)}"  # empty each round
            cold.mkdir()
            env["NUMBA_CACHE_DIR"] = str(cold)
            env["FISHEYEMOTION_WARMUP"] = "0" if cache == "cold-no-warmup" else "1"
        out = subprocess.run([sys.executable, "-c", CHILD, str(CALIB), str(pair)], env=env,
                             check=True, capture_output=True, text=True)
        times.append([float(x) for x in out.stdout.split()])

    benchmark.pedantic(run, rounds=5 if cache == "warm" else 3, warmup_rounds=0)
    benchmark.extra_info["import_s"] = statistics.median(t[0] for t in times)
    benchmark.extra_info["first_s"] = statistics.median(t[1] for t in times)
    benchmark.extra_info["import_and_first_s"] = statistics.median(t[0] + t[1] for t in times)
    print(json.dumps({cache: benchmark.extra_info}))


FLOOR_KERNEL = """
import numba


@numba.njit(cache=True)
def total(x):
    return x.sum()
"""

FLOOR = """
import sys, time
sys.path.insert(0, sys.argv[1])
import numpy as np
t1 = time.perf_counter()
import floor_kernel
floor_kernel.total(np.ones(3))
t2 = time.perf_counter()
print(0.0, t2 - t1)
"""


def test_numba_floor(benchmark, tmp_path):
    """numba's import and its first cached kernel call in a new process (``first_s``), the
    part of the warm first result that is numba's own."""
    benchmark.group = "startup"
    (tmp_path / "floor_kernel.py").write_text(FLOOR_KERNEL)
    command = [sys.executable, "-c", FLOOR, str(tmp_path)]
    subprocess.run(command, check=True, capture_output=True)  # fills the kernel's cache
    times = []

    def run():
        out = subprocess.run(command, check=True, capture_output=True, text=True)
        times.append([float(x) for x in out.stdout.split()])

    benchmark.pedantic(run, rounds=5, warmup_rounds=0)
    benchmark.extra_info["first_s"] = statistics.median(t[1] for t in times)
    print(json.dumps({"numba floor": benchmark.extra_info}))
