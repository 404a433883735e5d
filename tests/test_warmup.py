"""The cold-cache warm-up (``fisheyemotion._warmup``): the kernels it compiles ahead are the ones
the pipeline then runs, loaded from the cache, not compiled again."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from fisheyemotion import _warmup

ROOT = Path(__file__).resolve().parents[1]
CALIB = str(ROOT / "data" / "calib" / "front_kb_640x480.yaml")

# A first detection in a new process: which kernels of the warm-up's groups ran, and whether
# each came from the cache (numba's dispatcher statistics).
FIRST_DETECTION = """
import json, sys
import numpy as np
import fisheyemotion as fm
from fisheyemotion import _warmup
cam = fm.calib.load(sys.argv[1])
rng = np.random.default_rng(0)
prev = rng.integers(0, 256, (cam.height, cam.width), dtype=np.uint8)
curr = np.roll(prev, 3, axis=1)
pose0, pose1 = np.eye(4), np.eye(4)
pose0[:3, 3] = [0.0, -1.0, 0.0]
pose1[:3, 3] = [0.0, -1.0, 0.5]
fm.detect(prev, curr, pose0, pose1, camera=cam, road=fm.Road(normal=(0, -1, 0), offset=0.0))
stats = {}
for module, name in _warmup.CHILD + _warmup.HERE:
    kernel = getattr(sys.modules[module], name)
    stats[name] = [len(kernel.signatures), sum(kernel.stats.cache_hits.values()),
                   sum(kernel.stats.cache_misses.values())]
print(json.dumps({"stats": stats}))
"""


def _run(code: str, cache: Path, *args: str, warmup: str = "1") -> str:
    env = dict(os.environ, NUMBA_CACHE_DIR=str(cache), FISHEYEMOTION_WARMUP=warmup)
    out = subprocess.run([sys.executable, "-c", code, *args], env=env, cwd=ROOT,
                         capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    return out.stdout


def test_compiled_ahead_is_what_the_pipeline_loads(tmp_path):
    """compile() writes the signatures a real first detection asks for: run in a cold cache,
    then a detection (warm-up off) loads every one of them and compiles none."""
    _run("from fisheyemotion import _warmup; _warmup.compile(_warmup.CHILD + _warmup.HERE)",
         tmp_path)
    result = json.loads(_run(FIRST_DETECTION, tmp_path, CALIB, warmup="0").splitlines()[-1])
    for name, (signatures, hits, misses) in result["stats"].items():
        assert signatures == 1, name  # the kernel ran, with one signature
        assert (hits, misses) == (1, 0), name


def test_without_the_warm_up_the_kernels_compile_where_they_run(tmp_path):
    """The check above can fail: in a cold cache without compile(), the same detection
    compiles every kernel itself (misses, no hits)."""
    result = json.loads(_run(FIRST_DETECTION, tmp_path, CALIB, warmup="0").splitlines()[-1])
    for name, (signatures, hits, misses) in result["stats"].items():
        assert (signatures, hits, misses) == (1, 0, 1), name


def test_a_cold_first_detection_with_the_child(tmp_path):
    """With the warm-up on (a cold cache, two cores) CHILD comes from the cache, which only the
    child process can have written by then; HERE is compiled in this process (ahead, by
    start())."""
    if (os.cpu_count() or 1) < 2:
        pytest.skip("the warm-up needs a second core")
    result = json.loads(_run(FIRST_DETECTION, tmp_path, CALIB).splitlines()[-1])
    for _, name in _warmup.CHILD:
        assert result["stats"][name] == [1, 1, 0], name
    for _, name in _warmup.HERE:
        assert result["stats"][name] == [1, 0, 1], name


@pytest.mark.parametrize("setting", ["one core", "off", "frozen"])
def test_no_child_where_it_cannot_help_or_cannot_run(monkeypatch, setting):
    """start() spawns nothing on one core, with FISHEYEMOTION_WARMUP=0 or in a frozen
    application (whose executable is not a Python interpreter), even with a cold cache."""
    monkeypatch.setattr(_warmup, "_started", False)
    monkeypatch.setattr(_warmup, "_child", None)
    monkeypatch.setattr(_warmup, "_cold", lambda: True)
    spawned = []
    monkeypatch.setattr(_warmup.subprocess, "Popen", lambda *a, **k: spawned.append(a))
    monkeypatch.setattr(_warmup, "compile", lambda kernels: None)
    monkeypatch.setattr(_warmup.os, "cpu_count", lambda: 1 if setting == "one core" else 2)
    if setting == "off":
        monkeypatch.setenv("FISHEYEMOTION_WARMUP", "0")
    elif setting == "frozen":
        monkeypatch.setattr(_warmup.sys, "frozen", True, raising=False)
    _warmup.start()
    assert spawned == []
    # ... and the same cold cache on two cores, warm-up on, spawns the child.
    monkeypatch.setattr(_warmup, "_started", False)
    monkeypatch.delenv("FISHEYEMOTION_WARMUP", raising=False)
    monkeypatch.setattr(_warmup.sys, "frozen", False, raising=False)
    monkeypatch.setattr(_warmup.os, "cpu_count", lambda: 2)
    _warmup.start()  # (Popen is the stub above: nothing is started)
    assert len(spawned) == 1
    monkeypatch.setattr(_warmup, "_child", None)


def test_a_failing_child_is_waited_for_and_forgotten(monkeypatch):
    """wait() returns once the child has ended, however it ended, and only waits once: the
    kernels are then compiled where they run, as without the warm-up."""
    child = subprocess.Popen([sys.executable, "-c", "raise SystemExit(3)"])
    monkeypatch.setattr(_warmup, "_child", child)
    _warmup.wait()
    assert child.returncode == 3 and _warmup._child is None
    _warmup.wait()  # nothing left to wait for


def test_a_failure_compiling_ahead_does_not_reach_the_caller(monkeypatch):
    """start() runs in MotionDetector's constructor: an error while compiling HERE ahead is
    left to the kernels' own first call, not raised there."""
    monkeypatch.setattr(_warmup, "_started", False)
    monkeypatch.setattr(_warmup, "_child", None)
    monkeypatch.setattr(_warmup, "_cold", lambda: True)
    monkeypatch.setattr(_warmup.os, "cpu_count", lambda: 2)
    monkeypatch.delenv("FISHEYEMOTION_WARMUP", raising=False)
    monkeypatch.setattr(_warmup.subprocess, "Popen", lambda *a, **k: None)

    def failing(kernels):
        raise RuntimeError("numba could not compile")

    monkeypatch.setattr(_warmup, "compile", failing)
    _warmup.start()  # no exception
    monkeypatch.setattr(_warmup, "_child", None)
