"""A fair line and cancellation, on a simulated line (a pty).

Callers on one Bus take turns one attempt at a time, in the order they asked: an absent
unit's retries never hold the line while other threads wait. A :class:`benchbus.CancelToken`
takes a queued call out of the queue, or stops a call after its attempt in flight, and the
line stays in step: the next call gets its own reply.
"""

from __future__ import annotations

import asyncio
import threading
import time
from collections.abc import Callable, Iterator
from typing import Any

import pytest

import benchbus as bb
from benchbus.sim import RegisterDevice, Simulator

PRESENT = (1, 2, 3, 4)
ABSENT = 9
TIMEOUT = 0.1


@pytest.fixture
def sim() -> Iterator[Simulator[RegisterDevice]]:
    # Register k of unit u holds u * 100 + k.
    devices = {u: RegisterDevice({k: u * 100 + k for k in range(64)}) for u in PRESENT}
    with Simulator(devices, baudrate=115_200) as s:
        yield s


def open_bus(sim: Simulator[RegisterDevice], timeout: float = TIMEOUT, retries: int = 2) -> bb.Bus:
    return bb.Bus(sim.port, baudrate=115_200, timeout=timeout, retries=retries)


def to(unit: int, requests: list[bytes]) -> list[bytes]:
    return [r for r in requests if r[0] == unit]


class Call(threading.Thread):
    """``job`` in a thread under ``token`` (if any): its result or exception, and how long
    it took."""

    def __init__(self, job: Callable[[], Any], token: bb.CancelToken | None = None) -> None:
        super().__init__(daemon=True)
        self.job, self.token = job, token
        self.result: Any = None
        self.error: BaseException | None = None
        self.took = 0.0
        self.start()

    def run(self) -> None:
        start = time.monotonic()
        try:
            if self.token is None:
                self.result = self.job()
            else:
                with self.token:
                    self.result = self.job()
        except BaseException as exc:
            self.error = exc
        self.took = time.monotonic() - start

    def outcome(self) -> BaseException | None:
        self.join(10)
        assert not self.is_alive(), "the call never came back"
        return self.error


def wait_for(condition: Callable[[], bool]) -> None:
    until = time.monotonic() + 5
    while not condition():
        assert time.monotonic() < until, "timed out waiting"
        time.sleep(0.002)


def in_line(jobs: list[Callable[[], Any]]) -> list[Call]:
    """Each of ``jobs`` in a thread of its own, made one after the other: each holds its
    place in the line's queue before the next is made."""
    calls = []
    for job in jobs:
        token = bb.CancelToken()
        calls.append(Call(job, token))
        wait_for(lambda token=token: token.queued)
    return calls


# ---- fairness ----------------------------------------------------------------------------------


def test_an_absent_unit_does_not_hold_the_line_from_present_ones(
    sim: Simulator[RegisterDevice],
) -> None:
    duration = 3.0
    with open_bus(sim, retries=2) as bus:
        bus.read_holding_registers(1, 0, 1)  # the line is up
        stop_at = time.monotonic() + duration
        counts = dict.fromkeys(PRESENT, 0)
        worst = dict.fromkeys(PRESENT, 0.0)
        absent_calls = 0
        errors: list[BaseException] = []

        def poll(unit: int) -> None:
            try:
                while time.monotonic() < stop_at:
                    start = time.monotonic()
                    assert bus.read_holding_registers(unit, unit, 1) == [unit * 101]
                    worst[unit] = max(worst[unit], time.monotonic() - start)
                    counts[unit] += 1
            except BaseException as exc:
                errors.append(exc)

        def absent() -> None:
            nonlocal absent_calls
            while time.monotonic() < stop_at:
                with pytest.raises(bb.ResponseTimeout):
                    bus.read_holding_registers(ABSENT, 0, 1)
                absent_calls += 1

        threads = [threading.Thread(target=poll, args=(u,)) for u in PRESENT]
        threads.append(threading.Thread(target=absent))
        for t in threads:
            t.start()
        for t in threads:
            t.join(duration + 10)
        assert not any(t.is_alive() for t in threads)
        assert not errors, errors
        stats = bus.stats
    mean = sum(counts.values()) / len(counts)
    slowest = max(worst.values())
    print(
        f"\npresent units' calls {list(counts.values())} (mean {mean:.0f}) in {duration} s, "
        f"worst latency {slowest * 1000:.0f} ms with a {TIMEOUT * 1000:.0f} ms timeout; "
        f"the absent unit: {absent_calls} calls of 3 attempts"
    )
    assert absent_calls >= 3
    assert all(abs(n - mean) <= 0.1 * mean for n in counts.values()), counts
    assert len(to(ABSENT, sim.requests)) == 3 * absent_calls
    assert stats.timeouts == 3 * absent_calls, stats
    assert (stats.frame_errors, stats.crc_errors, stats.resyncs) == (0, 0, 0), stats
    # Behind one attempt of the absent unit at most (one timeout), not its three.
    assert slowest < 2 * TIMEOUT, (worst, stats)


def test_a_late_reply_coming_while_another_caller_has_the_line_is_dropped_there(
    sim: Simulator[RegisterDevice],
) -> None:
    """Unit 1 answers later than the timeout; unit 2's calls, served between unit 1's
    attempts, drop its late replies and get their own answers."""
    sim.devices[1].reply_delay = 1.6 * TIMEOUT
    with open_bus(sim, retries=1) as bus:
        stop_at = time.monotonic() + 1.5
        slow_results: list[list[int] | BaseException] = []

        def slow() -> None:
            while time.monotonic() < stop_at:
                try:
                    slow_results.append(bus.read_holding_registers(1, 10, 1))
                except bb.ResponseTimeout as exc:
                    slow_results.append(exc)

        thread = threading.Thread(target=slow)
        thread.start()
        calls = 0
        while time.monotonic() < stop_at:
            assert bus.read_holding_registers(2, 3, 1) == [203]
            calls += 1
        thread.join(10)
        stats = bus.stats
    # The line is fair: unit 2 is served between any two of unit 1's attempts, each of which
    # waits a timeout (the simulator answers one request at a time, so the slow unit's
    # answers hold unit 2's up).
    unit_1_attempts = sum(1 for frame in sim.requests if frame[0] == 1)
    assert calls >= unit_1_attempts - 1 >= 5, (calls, unit_1_attempts)
    # Unit 1's retries may take its own late reply (the same request), never another's.
    assert all(r == [110] for r in slow_results if not isinstance(r, BaseException))
    assert (stats.frame_errors, stats.crc_errors) == (0, 0)
    assert stats.stale_bytes >= 7


def test_a_write_sent_again_is_not_overtaken_by_a_later_write_to_its_unit(
    sim: Simulator[RegisterDevice],
) -> None:
    """The first of four writes to one register, made one after the other from four threads,
    gets a garbled reply: the device has carried it out, and it is sent again at the back of
    the queue. The later writes to that unit wait for it, so the device takes them in the
    order they were made and keeps the last value; a read of another unit, made after them,
    goes on meanwhile."""
    sim.devices[1].reply_delay = 0.2  # the others are made while the first write is out
    sim.corrupt_next(1)
    with open_bus(sim, timeout=0.5) as bus:
        jobs: list[Callable[[], Any]] = [
            *(lambda value=value: bus.write_register(1, 40, value) for value in range(100, 104)),
            lambda: bus.read_holding_registers(2, 3, 1),
        ]
        calls = in_line(jobs)
        assert sim.replies == []  # all made while the first write was still out
        assert [call.outcome() for call in calls] == [None] * 5
        assert calls[-1].result == [203]
        assert bus.stats.crc_errors == 1
    order = [(r[0], r[4:6]) for r in sim.requests]
    writes = [int.from_bytes(value, "big") for unit, value in order if unit == 1]
    assert writes == [100, 100, 101, 102, 103]
    assert sim.peek(1, 40) == [103]
    # The read did not wait for the writes: it went out before the first one's second try.
    assert [unit for unit, _ in order[:3]] == [1, 2, 1]


def test_the_writes_made_before_a_broadcast_do_not_go_out_after_it(
    sim: Simulator[RegisterDevice],
) -> None:
    """A write whose reply comes garbled, and another to its unit waiting for it, both made
    before a broadcast to the same register: neither goes out after the broadcast (which
    they would undo on their unit). The first fails with its garbled reply, the second is
    cancelled unsent, and every unit keeps the broadcast's value."""
    sim.devices[1].reply_delay = 0.2
    sim.corrupt_next(1)
    with open_bus(sim, timeout=0.5) as bus:
        jobs: list[Callable[[], Any]] = [
            lambda: bus.write_register(1, 40, 100),
            lambda: bus.write_register(1, 40, 101),
            lambda: bus.broadcast_write_register(40, 7),
        ]
        calls = in_line(jobs)
        assert sim.replies == []  # all made while the first write was still out
        first, second, broadcast = (call.outcome() for call in calls)
        assert isinstance(first, bb.CrcError)
        assert isinstance(second, bb.Cancelled)
        assert broadcast is None
        assert bus.stats.retries == 0
    assert [r[0] for r in sim.requests] == [1, 0]
    assert [sim.peek(u, 40) for u in PRESENT] == [[7]] * len(PRESENT)


# ---- cancellation ------------------------------------------------------------------------------


def test_a_cancelled_token_raises_at_once_and_sends_nothing(
    sim: Simulator[RegisterDevice],
) -> None:
    token = bb.CancelToken()
    assert not token.cancelled
    assert repr(token) == "CancelToken(cancelled=False)"
    token.cancel()
    token.cancel()  # harmless
    assert token.cancelled and repr(token) == "CancelToken(cancelled=True)"
    with open_bus(sim) as bus:
        for _ in range(2):  # a token used again is still cancelled
            with token:
                start = time.monotonic()
                with pytest.raises(bb.Cancelled, match="cancelled before it was sent") as e:
                    bus.read_holding_registers(1, 5, 1)
                assert time.monotonic() - start < TIMEOUT / 2
                with pytest.raises(bb.Cancelled):
                    bus.broadcast_write_register(0, 1)
        assert isinstance(e.value, bb.BenchbusError)
        assert (e.value.unit, e.value.function, e.value.frame) == (1, 3, None)
        assert sim.requests == []
        # Outside the block, and in other threads, calls go on.
        assert bus.read_holding_registers(1, 5, 1) == [105]
        with token:
            other = Call(lambda: bus.read_holding_registers(2, 5, 1))
            assert other.outcome() is None and other.result == [205]
        # Nested blocks: the call stops if any token in force is cancelled.
        with bb.CancelToken(), token, pytest.raises(bb.Cancelled):
            bus.read_holding_registers(1, 5, 1)
        with bb.CancelToken():
            assert bus.read_holding_registers(1, 6, 1) == [106]


def test_a_queued_call_cancelled_leaves_without_touching_the_line(
    sim: Simulator[RegisterDevice],
) -> None:
    with open_bus(sim, timeout=0.4, retries=0) as bus:
        holder = Call(lambda: bus.read_holding_registers(ABSENT, 0, 1))
        wait_for(lambda: len(sim.requests) == 1)
        token = bb.CancelToken()
        queued = Call(lambda: bus.read_holding_registers(1, 5, 1), token)
        time.sleep(0.05)
        assert queued.is_alive()  # waiting for its turn
        token.cancel()
        error = queued.outcome()
        assert isinstance(error, bb.Cancelled), error
        assert "before it was sent" in str(error)
        assert queued.took < 0.3  # left while the absent unit still held the line
        assert isinstance(holder.outcome(), bb.ResponseTimeout)
        assert to(1, sim.requests) == []
        assert bus.read_holding_registers(1, 7, 1) == [107]


def test_a_cancel_mid_attempt_lets_it_finish_and_the_next_call_gets_its_own_reply(
    sim: Simulator[RegisterDevice],
) -> None:
    slow = sim.devices[1]
    slow.reply_delay = 1.5 * TIMEOUT  # its replies come after the timeout
    with open_bus(sim, retries=3) as bus:
        token = bb.CancelToken()
        call = Call(lambda: bus.read_holding_registers(1, 10, 1), token)
        wait_for(lambda: len(sim.requests) == 1)
        token.cancel()
        error = call.outcome()
        assert isinstance(error, bb.Cancelled), error
        assert "after 1 attempt" in str(error)
        assert call.took >= TIMEOUT  # the attempt ran its timeout out
        time.sleep(TIMEOUT)
        assert len(sim.requests) == 1  # no retry
        assert (bus.stats.timeouts, bus.stats.retries) == (1, 0)
        # The late reply (110) to the cancelled call comes; the next call to the unit, of
        # the same shape, is answered by its own reply (111), not that one.
        slow.reply_delay = 0.0
        assert bus.read_holding_registers(1, 11, 1) == [111]
        assert bus.stats.stale_bytes == 7  # the late reply, dropped


def test_a_cancel_between_the_requests_of_a_split_read_stops_it(
    sim: Simulator[RegisterDevice],
) -> None:
    sim.devices[1].reply_delay = 0.05
    with open_bus(sim, timeout=0.5, retries=0) as bus:
        meter = bb.Instrument(bus, unit=1, max_read=10)
        token = bb.CancelToken()
        call = Call(lambda: meter.read_registers(0, 40), token)  # four requests
        wait_for(lambda: len(sim.requests) == 1)
        token.cancel()
        error = call.outcome()
        assert isinstance(error, bb.Cancelled), error
        assert "before it was sent" in str(error)  # the second request
        time.sleep(0.1)
        # The first request was answered; no other went out.
        assert len(sim.requests) == len(sim.replies) == 1
        assert bus.stats.transactions == 1
        sim.devices[1].reply_delay = 0.0
        assert meter.read_registers(0, 40) == [100 + k for k in range(40)]


def test_cancel_from_an_event_loop_while_a_worker_thread_makes_the_call(
    sim: Simulator[RegisterDevice],
) -> None:
    sim.devices[1].reply_delay = 1.5 * TIMEOUT

    async def main(bus: bb.Bus) -> None:
        token = bb.CancelToken()

        def work() -> list[int]:
            with token:
                return bus.read_holding_registers(1, 3, 1)

        loop = asyncio.get_running_loop()
        future = loop.run_in_executor(None, work)
        while not sim.requests:
            await asyncio.sleep(0.002)
        token.cancel()  # from the loop's thread, while the worker waits for the reply
        with pytest.raises(bb.Cancelled):
            await future

    with open_bus(sim, retries=5) as bus:
        asyncio.run(main(bus))
        assert len(sim.requests) == 1


def test_a_cancel_while_waiting_out_a_late_reply_window_sends_nothing(
    sim: Simulator[RegisterDevice],
) -> None:
    """After a timeout, the next request to that unit waits out the late reply's window
    (two timeouts) before its turn: cancelled then, it leaves with nothing sent, and the
    other units' calls went on meanwhile."""
    sim.set_silent(1)
    with open_bus(sim, retries=0) as bus:
        with pytest.raises(bb.ResponseTimeout):
            bus.read_holding_registers(1, 10, 1)
        token = bb.CancelToken()
        waiting = Call(lambda: bus.read_holding_registers(1, 11, 1), token)
        start = time.monotonic()
        assert bus.read_holding_registers(2, 4, 1) == [204]
        assert time.monotonic() - start < TIMEOUT  # unit 2 is not held up
        assert waiting.is_alive()
        token.cancel()
        error = waiting.outcome()
        assert isinstance(error, bb.Cancelled) and "before it was sent" in str(error)
        assert waiting.took < 1.5 * TIMEOUT  # well within its window of two timeouts
        assert len(to(1, sim.requests)) == 1
