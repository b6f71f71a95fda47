"""The steady clock of the periodic loops written in Python (``record``, the keepalive, the
CLI): ``benchbus._core._Ticks``, the deadlines of the Rust ``timing::Schedule`` that
``Bus.poll`` uses too.

On a fake clock and sleep every deadline is known exactly; on the real clock the deadlines
are checked against ``time.monotonic()`` and the wait is shown to release the GIL.
"""

from __future__ import annotations

import itertools
import math
import threading
import time
from typing import Any

import pytest
from test_record import FakeTime

from benchbus._core import _Ticks as ticks

# ---- on a fake clock ---------------------------------------------------------------------------


def test_ticks_keep_absolute_deadlines_whatever_the_loop_costs() -> None:
    """Each pass takes 0.1 s and every sleep overshoots by 1/16 s: a loop that slept one
    interval after its body would be 3.25 s late after 20 passes; the ticks are not."""
    fake = FakeTime(oversleep=0.0625)
    seen = []
    for n, deadline, missed in ticks(0.25, 5.0, clock=fake.clock, sleep=fake.sleep):
        seen.append((n, deadline, missed, fake.now))
        fake.now += 0.1  # the loop body
    assert [s[0] for s in seen] == list(range(20))
    assert [s[1] for s in seen] == [1024.0 + n * 0.25 for n in range(20)]
    assert all(s[2] == 0 for s in seen)
    # Every pass starts one oversleep after its deadline, the first on time: no drift.
    assert [s[3] - s[1] for s in seen] == [0.0] + [0.0625] * 19


def test_ticks_skip_the_deadlines_an_overrun_passed_and_count_them() -> None:
    fake = FakeTime()
    body = {4: 0.875}  # the pass at deadline 1.0 takes until 1.875: 1.25 and 1.5 are gone
    seen = []
    for n, deadline, missed in ticks(0.25, 3.0, clock=fake.clock, sleep=fake.sleep):
        seen.append((n, deadline - 1024.0, missed, fake.now - 1024.0))
        fake.now += body.get(n, 0.0625)
    assert [s[0] for s in seen] == [0, 1, 2, 3, 4, 7, 8, 9, 10, 11]
    assert seen[5] == (7, 1.75, 2, 1.875)  # the latest deadline past, at once
    assert seen[6] == (8, 2.0, 0, 2.0)  # then on the grid again
    assert sum(s[2] for s in seen) == 2


def test_ticks_without_duration_go_on_and_with_zero_duration_never_start() -> None:
    fake = FakeTime()
    first = list(itertools.islice(ticks(0.5, clock=fake.clock, sleep=fake.sleep), 100))
    assert [d for _, d, _ in first] == [1024.0 + n * 0.5 for n in range(100)]
    assert list(ticks(0.5, 0, clock=fake.clock, sleep=fake.sleep)) == []
    # An interval longer than the duration: one tick, at the start.
    assert [n for n, _, _ in ticks(2.0, 0.5, clock=fake.clock, sleep=fake.sleep)] == [0]


@pytest.mark.parametrize(
    ("interval", "duration"),
    [
        *[(bad, 1.0) for bad in (0, -0.1, math.nan, math.inf, "0.1")],
        *[(0.1, bad) for bad in (-1.0, math.nan, math.inf)],
    ],
)
def test_ticks_refuse_bad_arguments(interval: Any, duration: Any) -> None:
    with pytest.raises(ValueError):
        next(ticks(interval, duration))


def test_tick_count_does_not_depend_on_where_the_clock_starts() -> None:
    for start in (0.0, 1000.0, 123456.7):
        for interval, duration in ((0.3, 0.9), (0.7, 2.1), (0.1, 1.0)):
            now = [start]

            def advance(d: float, now: list[float] = now) -> None:
                now[0] += d

            got = list(ticks(interval, duration, clock=lambda now=now: now[0], sleep=advance))
            assert len(got) == round(duration / interval), (start, interval, duration)


# ---- on the real clock -------------------------------------------------------------------------


def test_real_deadlines_are_monotonic_seconds_and_absolute() -> None:
    """Deadlines are ``time.monotonic()`` seconds on a grid from the first ``next()``; a
    body that costs part of each period does not push them, and no tick comes early."""
    before = time.monotonic()
    seen = []
    for n, deadline, missed in ticks(0.02, 0.2):
        seen.append((n, deadline, missed, time.monotonic()))
        time.sleep(0.005)  # the loop body
    start = seen[0][1]
    assert before <= start <= seen[0][3]
    ns = [s[0] for s in seen]
    assert ns == sorted(set(ns)) and len(ns) + sum(s[2] for s in seen) == 10
    assert [s[1] for s in seen] == [start + s[0] * 0.02 for s in seen]
    assert all(s[3] >= s[1] for s in seen), "a tick came before its deadline"
    assert seen[-1][0] == 9  # the last tick of 0.2 s at 0.02 s, however late


def test_an_overrun_on_the_real_clock_is_skipped_and_counted() -> None:
    got = []
    for n, _deadline, missed in ticks(0.02, 0.3):
        got.append((n, missed))
        if n == 2:
            time.sleep(0.07)  # passes at least three deadlines
    assert [n for n, _ in got][:3] == [0, 1, 2]
    assert got[3][0] >= 5 and got[3][1] == got[3][0] - 3
    assert sum(m for _, m in got) + len(got) == 15


def test_the_wait_releases_the_gil() -> None:
    """A Python thread keeps counting while the main thread waits for a tick 0.2 s away."""
    counts = [0]
    stop = threading.Event()

    def count() -> None:
        while not stop.is_set():
            counts[0] += 1

    it = ticks(0.2, 0.3)
    next(it)  # tick 0: at once
    worker = threading.Thread(target=count)
    worker.start()
    try:
        time.sleep(0.01)
        start = counts[0]
        next(it)  # tick 1, 0.2 s after tick 0
        during = counts[0] - start
    finally:
        stop.set()
        worker.join()
    assert during > 1000, during


def test_an_injected_sleep_is_called_with_what_is_left_on_the_real_clock() -> None:
    """The keepalive's form: the real clock, and a sleep that a stop request cuts short."""
    waits: list[float] = []
    event = threading.Event()

    def wait(seconds: float) -> None:
        waits.append(seconds)
        event.wait(seconds)

    it = ticks(0.05, sleep=wait)
    got = [next(it) for _ in range(3)]
    assert [n for n, _, _ in got] == [0, 1, 2]
    assert waits and all(0 < w <= 0.05 for w in waits)
