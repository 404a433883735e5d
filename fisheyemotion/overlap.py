"""Work that overlaps the detection on the second core: frames read ahead and outputs written
behind, each in one thread (OpenCV's decoders and encoders and zlib release the GIL), in order.

The detection itself stays in the caller's thread: each frame pair's flow prior depends on the
scene model that the previous pair's detection updated, so pairs cannot run side by side without
changing the results.
"""

from __future__ import annotations

import queue
import threading
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import Future, ThreadPoolExecutor
from typing import TypeVar

__all__ = ["BackgroundWriter", "read_ahead"]

T = TypeVar("T")
_DONE = object()


def read_ahead(items: Iterable[T], depth: int = 2) -> Iterator[T]:
    """``items`` produced by a thread up to ``depth`` ahead of the consumer; an exception in the
    producer is raised in the consumer, at the item where it happened."""
    buffer: queue.Queue = queue.Queue(maxsize=depth)
    stop = threading.Event()

    def produce() -> None:
        try:
            for item in items:
                if stop.is_set():
                    return
                buffer.put((item, None))
        except BaseException as exc:  # handed to the consumer
            buffer.put((_DONE, exc))
            return
        buffer.put((_DONE, None))

    thread = threading.Thread(target=produce, name="fisheyemotion-read-ahead", daemon=True)
    thread.start()
    try:
        while True:
            item, exc = buffer.get()
            if exc is not None:
                raise exc
            if item is _DONE:
                return
            yield item
    finally:
        stop.set()
        while thread.is_alive():  # unblock a producer waiting on a full buffer
            try:
                buffer.get(timeout=0.05)
            except queue.Empty:
                pass


class BackgroundWriter:
    """Run output jobs in one thread, in the order submitted; at most ``depth`` wait. The first
    failure is raised by the next :meth:`submit` or by :meth:`close`.

    Use as a context manager: leaving the block waits for every job."""

    def __init__(self, depth: int = 4) -> None:
        self._pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="fisheyemotion-write")
        self._pending: list[Future] = []
        self._depth = depth

    def submit(self, job: Callable[..., object], *args, **kwargs) -> None:
        # Jobs finish in order: collect the finished ones (raising their errors) and wait for
        # the oldest while too many are queued.
        while self._pending and (self._pending[0].done() or len(self._pending) >= self._depth):
            self._pending.pop(0).result()
        self._pending.append(self._pool.submit(job, *args, **kwargs))

    def close(self) -> None:
        try:
            for f in self._pending:
                f.result()
        finally:
            self._pending = []
            self._pool.shutdown(wait=True)

    def __enter__(self) -> BackgroundWriter:
        return self

    def __exit__(self, *exc) -> None:
        if exc[0] is not None:  # already failing: wait, but do not mask the first error
            self._pool.shutdown(wait=True, cancel_futures=True)
            return
        self.close()
