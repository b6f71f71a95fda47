"""Bus.poll: holding-register reads on absolute deadlines, against the pymodbus simulator.

Timing checks are generous (the CI machine has two busy cores): they catch drift, bursts and
a wrong clock, not jitter.
"""

from __future__ import annotations

import _thread
import math
import threading
import time
from collections.abc import Callable, Iterator

import pytest
from test_docs import doc_blocks

import benchbus as bb
from benchbus.sim import RegisterDevice, Simulator


@pytest.fixture
def sim() -> Iterator[Simulator[RegisterDevice]]:
    with Simulator({1: RegisterDevice({0x0000: 1000, 0x0001: 7, 0x3006: 1450})}) as s:
        yield s


def ticks_of(ts: list[float], interval: float) -> list[int]:
    """The tick number of each ``t``, checking that ``t`` is ``n * interval``."""
    ns = [round(t / interval) for t in ts]
    for n, t in zip(ns, ts):
        assert t == pytest.approx(n * interval, abs=1e-9), (n, t)
    return ns


def test_values_are_what_the_device_holds(sim: Simulator[RegisterDevice]) -> None:
    registers = sim.devices[1].registers
    with bb.Bus(sim.port, timeout=0.5) as bus:
        poll = bus.poll(1, 0x0000, 2, interval=0.05, duration=0.3)
        samples = []
        for i, (t, values) in enumerate(poll):
            samples.append((t, values))
            registers[0x0000] = 2000 + i  # the next sample reads it
        expected = [[1000, 7]] + [[2000 + i, 7] for i in range(len(samples) - 1)]
        assert [values for _, values in samples] == expected
        assert all(isinstance(v, int) for _, values in samples for v in values)
        # Every tick of 0.3 s at 0.05 s is sampled or missed: 6 of them.
        assert len(samples) + poll.missed == 6
        if poll.missed == 0:
            assert len(samples) == 6
            assert ticks_of([t for t, _ in samples], 0.05) == [0, 1, 2, 3, 4, 5]
        assert bus.stats.transactions == len(samples)
        # Over: it stays over, and sends nothing more.
        assert next(poll, None) is None
        assert bus.stats.transactions == len(samples)
    # The requests are the same 0x03 frames read_holding_registers sends.
    assert set(sim.requests) == {bytes.fromhex("01 03 00 00 00 02 C4 0B")}


def test_default_count_and_a_poll_without_duration(sim: Simulator[RegisterDevice]) -> None:
    with bb.Bus(sim.port, timeout=0.5) as bus:
        poll = bus.poll(1, 0x3006, interval=0.01)
        assert poll.started is None and poll.missed == 0
        assert iter(poll) is poll
        assert "interval=0.01" in repr(poll) and "duration=None" in repr(poll)
        seen = [next(poll) for _ in range(20)]  # no duration: goes on as long as asked
        assert all(values == [1450] for _, values in seen)
        assert seen[0][0] == 0.0
        ns = ticks_of([t for t, _ in seen], 0.01)
        assert ns == sorted(set(ns))
        assert len(seen) + poll.missed == ns[-1] + 1


def test_requests_keep_to_the_grid_without_drift(sim: Simulator[RegisterDevice]) -> None:
    interval = 0.05
    with bb.Bus(sim.port, timeout=0.5) as bus:
        poll = bus.poll(1, 0x3006, interval=interval, duration=0.5)
        time.sleep(0.2)  # the poll starts at the first next(), not at bus.poll()
        ts = []
        for t, _ in poll:
            ts.append(t)
            time.sleep(0.4 * interval)  # a body that takes time: no drift for all that
        started = poll.started
    assert started is not None
    times = sim.request_times
    assert len(times) == len(ts) == 10 - poll.missed
    # Each request reaches the line after its deadline (same clock as time.monotonic()),
    # and not long after it.
    lateness = [at - (started + t) for at, t in zip(times, ts)]
    assert min(lateness) >= 0, lateness
    assert lateness[0] < 0.1, lateness
    # The whole run spans the ticks' span: 18 ms of body per sample did not add up.
    assert times[-1] - times[0] == pytest.approx(ts[-1] - ts[0], abs=0.03)
    if poll.missed == 0:
        assert times[-1] - times[0] == pytest.approx(9 * interval, abs=0.03)
        gaps = [b - a for a, b in zip(times, times[1:])]
        assert sum(gaps) / len(gaps) == pytest.approx(interval, rel=0.2)


def test_a_slow_consumer_misses_deadlines_without_a_burst(
    sim: Simulator[RegisterDevice],
) -> None:
    interval = 0.04
    with bb.Bus(sim.port, timeout=0.5) as bus:
        poll = bus.poll(1, 0x3006, interval=interval, duration=0.6)
        ts = []
        for t, values in poll:
            assert values == [1450]
            ts.append(t)
            time.sleep(2.5 * interval)
        missed = poll.missed
    assert missed > 0
    assert len(ts) + missed == 15  # every tick of 0.6 s at 0.04 s: sampled or missed
    ns = ticks_of(ts, interval)
    assert ns[0] == 0
    steps = [b - a for a, b in zip(ns, ns[1:])]
    assert min(steps) >= 2, ns  # each 2.5-interval body skipped at least one deadline
    assert all(b - a >= interval - 1e-9 for a, b in zip(ts, ts[1:])), ts
    # One request per sample, none fired in a hurry to catch up.
    times = sim.request_times
    assert len(times) == len(ts)
    assert min(b - a for a, b in zip(times, times[1:])) > interval


def test_bad_arguments_are_refused_by_poll_itself(sim: Simulator[RegisterDevice]) -> None:
    with bb.Bus(sim.port) as bus:
        bad_calls: list[tuple[type[Exception], Callable[[], object]]] = [
            (ValueError, lambda: bus.poll(0, 0, interval=0.1)),
            (ValueError, lambda: bus.poll(256, 0, interval=0.1)),
            (ValueError, lambda: bus.poll(1, -1, interval=0.1)),
            (ValueError, lambda: bus.poll(1, 0x10000, interval=0.1)),
            (ValueError, lambda: bus.poll(1, 0, 0, interval=0.1)),
            (ValueError, lambda: bus.poll(1, 0, 126, interval=0.1)),
            (ValueError, lambda: bus.poll(1, 0xFFFF, 2, interval=0.1)),
            (ValueError, lambda: bus.poll(1, 0, interval=0)),
            (ValueError, lambda: bus.poll(1, 0, interval=-0.1)),
            (ValueError, lambda: bus.poll(1, 0, interval=math.nan)),
            (ValueError, lambda: bus.poll(1, 0, interval=math.inf)),
            (ValueError, lambda: bus.poll(1, 0, interval=3600.5)),
            (ValueError, lambda: bus.poll(1, 0, interval=0.1, duration=-1)),
            (ValueError, lambda: bus.poll(1, 0, interval=0.1, duration=math.nan)),
            (ValueError, lambda: bus.poll(1, 0, interval=0.1, duration=math.inf)),
            (ValueError, lambda: bus.poll(1, 0, interval=0.1, duration=2**2000)),
            (TypeError, lambda: bus.poll(True, 0, interval=0.1)),
            (TypeError, lambda: bus.poll("1", 0, interval=0.1)),  # type: ignore[arg-type]
            (TypeError, lambda: bus.poll(1, 0, 1.0, interval=0.1)),  # type: ignore[arg-type]
            (TypeError, lambda: bus.poll(1, 0, True, interval=0.1)),
            (TypeError, lambda: bus.poll(1, 0, interval=True)),
            (TypeError, lambda: bus.poll(1, 0, interval="0.1")),  # type: ignore[arg-type]
            (TypeError, lambda: bus.poll(1, 0, interval=None)),  # type: ignore[arg-type]
            (TypeError, lambda: bus.poll(1, 0, interval=0.1, duration=False)),
            (TypeError, lambda: bus.poll(1, 0, interval=0.1, duration="1")),  # type: ignore[arg-type]
            (TypeError, lambda: bus.poll(1, 0)),  # type: ignore[call-arg]
            (TypeError, lambda: bus.poll(1, 0, 1, 0.1)),  # type: ignore[call-arg]
        ]
        for exc, call in bad_calls:
            with pytest.raises(exc):
                call()
        with pytest.raises(ValueError, match="interval"):
            bus.poll(1, 0, interval=0)
        with pytest.raises(ValueError, match="duration"):
            bus.poll(1, 0, interval=1, duration=-1)
        # Ints are seconds too; a duration of 0 has no deadline at all.
        assert list(bus.poll(1, 0, interval=1, duration=0)) == []
        assert bus.stats.transactions == 0
    assert sim.requests == []


def test_a_failed_read_is_raised_and_the_poll_goes_on(sim: Simulator[RegisterDevice]) -> None:
    with bb.Bus(sim.port, timeout=0.05, retries=0) as bus:
        poll = bus.poll(1, 0x3006, interval=0.02)
        sim.answer_exception(2)
        with pytest.raises(bb.ModbusException) as e:
            next(poll)
        assert (e.value.unit, e.value.function, e.value.code) == (1, 3, 2)
        assert e.value.meaning == "illegal data address"
        t, values = next(poll)
        assert values == [1450] and t > 0
        sim.set_silent(1)
        with pytest.raises(bb.ResponseTimeout):
            next(poll)
        sim.set_silent(1, False)
        assert next(poll)[1] == [1450]
        assert bus.stats.exceptions == 1 and bus.stats.timeouts == 1


def test_a_closed_bus_raises_port_error(sim: Simulator[RegisterDevice]) -> None:
    bus = bb.Bus(sim.port)
    poll = bus.poll(1, 0x3006, interval=0.01)
    assert next(poll)[1] == [1450]
    bus.close()
    with pytest.raises(bb.PortError, match="closed"):
        next(poll)
    with pytest.raises(bb.PortError, match="closed"):
        bus.poll(1, 0x3006, interval=0.01)
    assert len(sim.requests) == 1


def test_the_gil_is_released_while_a_poll_waits(sim: Simulator[RegisterDevice]) -> None:
    spins = 0
    done = threading.Event()

    def spin() -> None:
        nonlocal spins
        while not done.is_set():
            spins += 1

    with bb.Bus(sim.port, timeout=0.5) as bus:
        poll = bus.poll(1, 0x3006, interval=0.3)
        next(poll)
        worker = threading.Thread(target=spin)
        worker.start()
        try:
            next(poll)  # waits about 0.3 s, meanwhile the other thread runs
        finally:
            done.set()
            worker.join(5)
    assert spins > 10_000


def test_ctrl_c_interrupts_a_long_wait(sim: Simulator[RegisterDevice]) -> None:
    with bb.Bus(sim.port, timeout=0.5) as bus:
        poll = bus.poll(1, 0x3006, interval=30.0)
        next(poll)
        timer = threading.Timer(0.2, _thread.interrupt_main)
        start = time.monotonic()
        timer.start()
        with pytest.raises(KeyboardInterrupt):
            next(poll)
        took = time.monotonic() - start
        timer.join(5)
    assert took < 5, took
    assert len(sim.requests) == 1


def test_readme_poll_example(
    sim: Simulator[RegisterDevice], capsys: pytest.CaptureFixture[str]
) -> None:
    (block,) = [b for b in doc_blocks() if "bus.poll(" in b]
    with bb.Bus(sim.port, timeout=0.5) as bus:
        exec(block.replace("duration=10.0", "duration=0.3"), {"bus": bus})
    lines = capsys.readouterr().out.splitlines()
    assert 1 <= len(lines) <= 3
    assert lines[0] == " 0.0 s  1450"
    assert all(line.endswith(" s  1450") for line in lines)
