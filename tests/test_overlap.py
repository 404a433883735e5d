"""Reading ahead and writing behind: order kept, errors delivered, nothing left running."""

from __future__ import annotations

import threading
import time

import pytest

from fisheyemotion.overlap import BackgroundWriter, read_ahead


def test_read_ahead_keeps_order_and_runs_in_another_thread():
    seen = []

    def produce():
        for i in range(20):
            seen.append(threading.current_thread().name)
            yield i

    assert list(read_ahead(produce(), depth=3)) == list(range(20))
    assert set(seen) == {"fisheyemotion-read-ahead"}


def test_read_ahead_raises_the_producers_error_where_it_happened():
    def produce():
        yield 1
        yield 2
        raise ValueError("frame 3: cannot be read")

    got = []
    with pytest.raises(ValueError, match="frame 3"):
        for item in read_ahead(produce()):
            got.append(item)
    assert got == [1, 2]


def test_read_ahead_stops_its_thread_when_the_consumer_stops():
    def endless():
        i = 0
        while True:
            yield i
            i += 1

    for item in read_ahead(endless(), depth=2):
        if item == 5:
            break
    time.sleep(0.1)
    assert not any(t.name == "fisheyemotion-read-ahead" for t in threading.enumerate())


def test_background_writer_runs_jobs_in_order_and_reports_the_first_failure():
    done = []
    with BackgroundWriter(depth=2) as writer:
        for i in range(10):
            writer.submit(lambda i=i: (time.sleep(0.001), done.append(i)))
    assert done == list(range(10))

    def fail():
        raise OSError("disk full")

    writer = BackgroundWriter()
    writer.submit(fail)
    with pytest.raises(OSError, match="disk full"):
        for _ in range(10):
            writer.submit(lambda: None)
        writer.close()
