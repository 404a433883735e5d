"""A cold numba cache compiled on two cores: part of the pipeline's camera-independent kernels
in a second process while this one compiles the rest.

The first detection in a process whose numba cache is empty (a fresh clone, CI, a new
install) spends most of its time compiling kernels, one after the other: numba compiles under a
process-wide lock. When the cache of the kernels of :data:`CHILD` is missing and the machine has
a second core, :func:`start` (called by the first :class:`~fisheyemotion.MotionDetector`)
compiles them in a child process, which writes them to the same cache, while this process
compiles :data:`HERE` at once and then the camera's projection kernels and the first flow, as
before. :func:`wait`, called before a kernel of :data:`CHILD` is first run, waits for the
child; the kernel is then loaded from the cache. Nothing changes where the cache is warm, on
one core, with ``FISHEYEMOTION_WARMUP=0``, in a frozen application (PyInstaller and the like:
its executable is not a Python interpreter), where numba cannot cache or where the child fails:
the kernels are then compiled where they are first run, as before.
"""


from __future__ import annotations

import os
import subprocess
import sys
import threading

__all__ = ["CHILD", "HERE", "start", "wait"]

#: ``(module, kernel)`` compiled by the child: the constraint kernel and the transfer of results
#: to the current frame (1.7 s of a 4.6 s cold first detection, timed per kernel with numba's
#: compile events; the child's own start-up and numba's first-compilation set-up add 0.9 s).
CHILD = (("fisheyemotion._engine_kernel", "constraint_kernel"),
         ("fisheyemotion._grid_kernels", "transfer"))
#: Compiled by :func:`start` in this process while the child runs: the photometric check's
#: residuals, the cells' flow variance (0.8 s) and the pixels' landing cells of the transfer to
#: the current frame (0.16 s), which the first detection would compile later. (A stream's own
#: kernels, e.g. the three views' z-buffer, compile at its first pair: 0.4 s more here would
#: delay every first detect().)
HERE = (("fisheyemotion._grid_kernels", "block_residuals"),
        ("fisheyemotion._grid_kernels", "cell_variance"),
        ("fisheyemotion._grid_kernels", "landed_pixels"))

_TIMEOUT = 120.0  # seconds; after that this process compiles the kernels itself
_lock = threading.Lock()
_child: subprocess.Popen | None = None
_started = False


def _cold() -> bool:
    """True if a kernel of :data:`CHILD` has no cache index yet (and numba can cache it)."""
    import importlib

    for module, name in CHILD:
        try:
            kernel = getattr(importlib.import_module(module), name)
            index = kernel._cache._cache_file._index_path  # numba's cache locator
        except AttributeError:  # NUMBA_DISABLE_JIT, or a numba without these internals
            return False
        if not os.path.exists(index):
            return True
    return False


def start() -> None:
    """Compile :data:`CHILD` in a child process and :data:`HERE` in this one if the cache is
    cold (once per process)."""
    global _child, _started
    with _lock:
        if _started:
            return
        _started = True
        if (os.cpu_count() or 1) < 2 or os.environ.get("FISHEYEMOTION_WARMUP") == "0" \
                or not sys.executable or getattr(sys, "frozen", False) or not _cold():
            return  # (a frozen application's executable is not a Python interpreter)
        try:
            _child = subprocess.Popen(
                [sys.executable, "-c", "from fisheyemotion import _warmup; _warmup.compile(_warmup.CHILD)"],
                stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        except OSError:
            _child = None
            return
    try:
        compile(HERE)
    except Exception:  # ahead of time only: where they first run they compile (or fail) as before
        pass


def wait() -> None:
    """Wait for the child of :func:`start`, if one is running (a cheap check otherwise)."""
    global _child
    if _child is None:
        return
    with _lock:
        if _child is None:
            return
        try:
            _child.wait(timeout=_TIMEOUT)
        except subprocess.TimeoutExpired:
            _child.kill()
        _child = None


def compile(kernels) -> None:
    """Run each of ``kernels`` (of :data:`CHILD` and :data:`HERE`) once through the wrapper the
    pipeline calls it by, on tiny inputs of the pipeline's types, so that the cache holds the
    signatures the pipeline will ask for (``tests/test_warmup.py`` checks that it does)."""
    import numpy as np

    names = {name for _, name in kernels}
    frame = np.zeros((10, 10), np.uint8)
    flow = np.zeros((10, 10, 2), np.float32)
    if "constraint_kernel" in names:
        from .constraints import constraints
        from .params import Params
        from .road import Road

        rays = np.array([[0.0, 0.0, 1.0], [0.0, 0.6, 0.8]])
        pose0, pose1 = np.eye(4), np.eye(4)
        pose1[2, 3] = 1.0
        constraints(rays, rays, pose0, pose1, road=Road(offset=-1.0), params=Params())
    if "transfer" in names:
        from .flow import grid_transfer

        grid_transfer(np.zeros((2, 2, 2), np.float32), np.zeros((2, 2)), 5)
    if "block_residuals" in names:
        from .photometric import cell_residual

        cell_residual(frame, frame, flow, 5)
    if "cell_variance" in names:
        from .significance import cell_sigma

        cell_sigma(flow, 5, np.ones((2, 2)), floor=0.5, mean=np.zeros((2, 2, 2), np.float32))
    if "landed_pixels" in names:
        from .flow import pixel_transfer

        pixel_transfer(np.full((2, 2), -1, np.intp), flow, np.zeros((2, 2)),
                       np.ones((2, 2), bool), 5, share=0.5)
