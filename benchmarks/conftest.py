"""Benchmarks: every figure is measured beside its peer in the same run (see docs/performance.md).

cv2's threads are pinned for every benchmark: one thread unless a benchmark is parametrised by
``threads`` (its id ends in ``-1t`` or ``-2t``), so that no figure depends on what OpenCV chose.
"""

from __future__ import annotations

import cv2
import pytest


@pytest.fixture(autouse=True)
def cv2_threads(request):
    """Pin cv2's thread count (the ``threads`` parameter, else 1) and record it."""
    threads = getattr(request.node, "callspec", None)
    threads = threads.params.get("threads", 1) if threads is not None else 1
    before = cv2.getNumThreads()
    cv2.setNumThreads(threads)
    if "benchmark" in request.fixturenames:
        request.getfixturevalue("benchmark").extra_info["cv2_threads"] = threads
    yield threads
    cv2.setNumThreads(before)
