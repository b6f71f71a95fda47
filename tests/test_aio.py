"""benchbus.aio: the Bus and the devices awaited on an event loop, against the simulators.

Each test is a plain function that runs its coroutine with ``asyncio.run`` (no plugin).
"""

from __future__ import annotations

import asyncio
import contextlib
import inspect
import os
import select
import selectors
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Awaitable, Callable, Iterator
from pathlib import Path
from typing import Any, TypeVar

import nbformat
import pytest
from nbclient import NotebookClient

import benchbus as bb
from benchbus import aio
from benchbus.sim import (
    DriveDevice,
    J2Device,
    PblDevice,
    ProfileDevice,
    RegisterDevice,
    Simulator,
    TaisongDevice,
)
from conftest import ScriptedSlave, read_up_to, rtu

ROOT = Path(__file__).resolve().parent.parent
T = TypeVar("T")


def run(coro: Callable[[], Awaitable[T]], limit: float = 20.0) -> T:
    """``coro()`` in a fresh loop, failing the test rather than hanging."""

    async def bounded() -> T:
        return await asyncio.wait_for(coro(), limit)

    return asyncio.run(bounded())


def aio_threads() -> list[threading.Thread]:
    """The worker threads of benchbus.aio alive now."""
    return [t for t in threading.enumerate() if t.name.startswith("benchbus.aio")]


@pytest.fixture(autouse=True)
def no_threads_left() -> Iterator[None]:
    """Every test leaves no worker thread running."""
    yield
    deadline = time.monotonic() + 2
    while aio_threads() and time.monotonic() < deadline:
        time.sleep(0.01)
    assert aio_threads() == []


@pytest.fixture
def sim() -> Iterator[Simulator[RegisterDevice]]:
    device = RegisterDevice(
        {0: 7, 1: 8, 2: 9, 4: 0x12},
        input_registers={3: 1003, 4: 1004},
        coils={1, 3},
        discrete_inputs={2},
        identity={0: "ACME", 1: "M-1", 2: "1.0"},
    )
    with Simulator({1: device, 2: RegisterDevice()}) as simulator:
        yield simulator


def device_of(sim: Simulator[Any], unit: int = 1) -> Any:
    return sim.devices[unit]


# ---- the bus ----------------------------------------------------------------------------------


#: Bus members that are not wire calls made awaitable.
NOT_CALLS = {"poll", "close", "stats", "closed", "__enter__", "__exit__"}


def bus_calls() -> list[str]:
    return [
        n
        for n in dir(bb.Bus)
        if not n.startswith("_") and n not in NOT_CALLS and callable(getattr(bb.Bus, n))
    ]


def test_every_bus_method_is_a_coroutine_with_its_signature_and_doc() -> None:
    names = bus_calls()
    assert "read_holding_registers" in names and "scan" in names and "reopen" in names
    for name in names:
        method = getattr(aio.AsyncBus, name)
        assert inspect.iscoroutinefunction(method), name
        assert method.__doc__ == getattr(bb.Bus, name).__doc__, name
        assert inspect.signature(method) == inspect.signature(getattr(bb.Bus, name)), name
    for name in ("port", "baudrate", "parity", "timeout", "retries", "stats", "t3_5"):
        assert getattr(aio.AsyncBus, name).__doc__ == getattr(bb.Bus, name).__doc__


def test_every_awaitable_method_against_the_simulator(sim: Simulator[RegisterDevice]) -> None:
    device = device_of(sim)

    async def main() -> None:
        async with aio.AsyncBus(sim.port, timeout=0.3, retries=1) as bus:
            assert await bus.read_holding_registers(1, 0, 3) == [7, 8, 9]
            assert await bus.read_input_registers(1, 3, 2) == [1003, 1004]
            assert await bus.read_coils(1, 0, 4) == [False, True, False, True]
            assert await bus.read_discrete_inputs(1, 1, 3) == [False, True, False]
            await bus.write_register(1, 10, 1500)
            await bus.write_registers(1, 11, [1, 2, 3])
            await bus.write_coil(1, 5, True)
            await bus.write_coils(1, 6, [True, False, True])
            # The specification's mask write: 0x12 AND 0xF2 OR (0x25 AND NOT 0xF2) = 0x17.
            await bus.mask_write_register(1, 4, 0xF2, 0x25)
            assert await bus.read_write_registers(1, 11, 3, 20, [5, 6]) == [1, 2, 3]
            assert await bus.read_exception_status(1) == device.exception_status
            assert await bus.diagnostics(1, 0, b"\xa5\x37") == b"\xa5\x37"
            assert isinstance(await bus.report_server_id(1), bytes)
            # The unit counted the 13 requests above (and whatever the module's other tests
            # sent it); the 0x0B between the two: a message, not an event, logged.
            counter = await bus.get_comm_event_counter(1)
            assert counter.status == 0 and counter.event_count >= 13
            log = await bus.get_comm_event_log(1)
            assert log.event_count == counter.event_count and log.events[:2] == b"\x40\x80"
            await bus.write_file_record(1, [(7, 100, [11, 12])])
            assert await bus.read_file_record(1, [(7, 101, 1), (7, 100, 2)]) == [[12], [11, 12]]
            assert await bus.read_fifo_queue(1, 11) == [2]  # 11..13 hold 1, 2, 3: one value
            assert await bus.request(1, 3, b"\x00\x00\x00\x02", reply_length=5) == (
                b"\x04\x00\x07\x00\x08"
            )
            assert await bus.read_device_identification(1) == {0: "ACME", 1: "M-1", 2: "1.0"}
            await bus.broadcast_write_register(30, 42)
            await bus.broadcast_write_registers(31, [43, 44])
            await bus.broadcast_write_coil(40, True)
            await bus.broadcast_write_coils(41, [True, True])
            assert await bus.scan(range(1, 4), timeout=0.05) == [1, 2]
            await bus.reopen()
            assert await bus.read_holding_registers(1, 10, 1) == [1500]
            # Properties are the Bus's.
            assert (bus.port, bus.baudrate, bus.parity, bus.stopbits) == (sim.port, 19200, "N", 1)
            assert (bus.timeout, bus.retries, bus.framing, bus.bytesize) == (0.3, 1, "rtu", 8)
            assert bus.t3_5 == bus.bus.t3_5 and bus.char_time == bus.bus.char_time
            assert not (bus.echo or bus.rs485 or bus.reconnect) and bus.turnaround == 0.1
            assert bus.silence == 0.0 and bus.stats.reopens == 1
            assert bus.stats.transactions == bus.bus.stats.transactions > 15
            assert not bus.closed
        assert bus.closed and bus.bus.closed

    run(main)
    assert device.registers[10:14] == [1500, 1, 2, 3]
    assert device.registers[4] == 0x17 and device.registers[20:22] == [5, 6]
    assert device.coils[5:9] == [True, True, False, True]
    for unit in (1, 2):
        assert device_of(sim, unit).registers[30:33] == [42, 43, 44]
        assert device_of(sim, unit).coils[40:43] == [True, True, True]


def test_errors_come_through_and_bad_input_is_refused_before_sending(
    sim: Simulator[RegisterDevice],
) -> None:
    async def main() -> None:
        async with aio.AsyncBus(sim.port, timeout=0.05, retries=0) as bus:
            with pytest.raises(ValueError):
                await bus.read_holding_registers(1, 0, 126)
            with pytest.raises(TypeError):
                await bus.write_coil(1, 0, 1)  # type: ignore[arg-type]
            assert sim.requests == []
            with pytest.raises(bb.ResponseTimeout):
                await bus.read_holding_registers(9, 0, 1)
            sim.answer_exception(2)
            with pytest.raises(bb.ModbusException) as caught:
                await bus.read_holding_registers(1, 0, 1)
            assert caught.value.code == 2

    run(main)


def test_a_sync_bus_and_an_async_bus_cannot_hold_one_port(
    sim: Simulator[RegisterDevice],
) -> None:
    async def main() -> None:
        with bb.Bus(sim.port), pytest.raises(bb.PortError, match="in use"):
            aio.AsyncBus(sim.port)
        async with aio.AsyncBus(sim.port) as bus:
            with pytest.raises(bb.PortError, match="in use"):
                bb.Bus(sim.port)
            assert await bus.read_holding_registers(1, 0, 1) == [7]
        with bb.Bus(sim.port) as sync:  # released by aclose
            assert sync.read_holding_registers(1, 0, 1) == [7]

    run(main)


def test_calls_run_at_once_in_several_threads_and_leave_in_arrival_order(
    sim: Simulator[RegisterDevice],
) -> None:
    sim.reply_delay = 0.02

    async def main() -> list[int]:
        async with aio.AsyncBus(sim.port, timeout=0.5, workers=4) as bus:
            order: list[int] = []

            async def one(i: int) -> None:
                await bus.write_register(1, 100, i)
                order.append(i)

            started = time.monotonic()
            await asyncio.gather(*(one(i) for i in range(12)))
            assert time.monotonic() - started < 2
            assert len({t.name for t in bus._pool.threads()}) == 4
            return order

    order = run(main)
    assert sorted(order) == list(range(12))
    # Every request reached the line, each one whole.
    assert len(sim.requests) == 12


def test_one_thread_sends_the_calls_in_the_order_they_were_made(
    sim: Simulator[RegisterDevice],
) -> None:
    async def main() -> None:
        async with aio.AsyncBus(sim.port, workers=1) as bus:
            await asyncio.gather(*(bus.write_register(1, 100, i) for i in range(10)))

    run(main)
    # 0x06 requests: unit, function, address (2), value (2), CRC: the value is bytes 4..5.
    assert [int.from_bytes(f[4:6], "big") for f in sim.requests] == list(range(10))


def test_the_bus_options_are_the_buses() -> None:
    device = RegisterDevice({0: 7})
    with Simulator({1: device}, framing="ascii") as sim:

        async def main() -> None:
            async with aio.AsyncBus(sim.port, framing="ascii", turnaround=0.05) as bus:
                assert (bus.framing, bus.bytesize, bus.parity, bus.turnaround) == (
                    "ascii",
                    7,
                    "E",
                    0.05,
                )
                assert await bus.read_holding_registers(1, 0, 1) == [7]

        run(main)


def test_the_loop_runs_while_a_call_waits_for_the_line(sim: Simulator[RegisterDevice]) -> None:
    sim.set_silent(1)

    async def main() -> int:
        async with aio.AsyncBus(sim.port, timeout=0.3, retries=0) as bus:
            ticks = 0

            async def ticker() -> None:
                nonlocal ticks
                while True:
                    await asyncio.sleep(0.01)
                    ticks += 1

            task = asyncio.create_task(ticker())
            with pytest.raises(bb.ResponseTimeout):
                await bus.read_holding_registers(1, 0, 1)
            task.cancel()
            return ticks

    assert run(main) >= 15  # ~30 in 0.3 s; a blocked loop gives 0


# ---- cancellation and closing -------------------------------------------------------------


@pytest.mark.parametrize("workers", [1, 2], ids=["in-the-aio-queue", "in-the-core"])
def test_a_call_cancelled_while_it_waits_for_the_line_is_never_sent(
    sim: Simulator[RegisterDevice], workers: int
) -> None:
    """With one thread the write waits in this layer's queue; with two, a thread takes it
    and it waits its turn in the core (the core's CancelToken takes it out)."""
    sim.set_silent(2)  # unit 2 never answers: its read holds the line

    async def main() -> None:
        async with aio.AsyncBus(sim.port, timeout=0.3, retries=0, workers=workers) as bus:
            busy = asyncio.create_task(bus.read_holding_registers(2, 0, 1))
            await asyncio.sleep(0.05)
            waiting = asyncio.create_task(bus.write_register(1, 50, 1234))
            await asyncio.sleep(0.05)
            assert len(bus._pool._queue) == 2 - workers
            waiting.cancel()
            with pytest.raises(asyncio.CancelledError):
                await waiting
            assert len(bus._pool._queue) == 0
            with pytest.raises(bb.ResponseTimeout):
                await busy
            # The threads are free again and the line in order.
            assert await bus.read_holding_registers(1, 0, 1) == [7]

    run(main)
    assert [frame[0] for frame in sim.requests] == [2, 1], "the write was never sent"
    assert device_of(sim).registers[50] == 0


def test_wait_for_running_out_cancels_a_queued_call_unsent(
    sim: Simulator[RegisterDevice],
) -> None:
    sim.set_silent(2)

    async def main() -> None:
        async with aio.AsyncBus(sim.port, timeout=0.3, retries=0, workers=1) as bus:
            busy = asyncio.create_task(bus.read_holding_registers(2, 0, 1))
            await asyncio.sleep(0.05)
            with pytest.raises(asyncio.TimeoutError):
                await asyncio.wait_for(bus.write_register(1, 51, 99), 0.05)
            with pytest.raises(bb.ResponseTimeout):
                await busy

    run(main)
    assert [frame[0] for frame in sim.requests] == [2]
    assert device_of(sim).registers[51] == 0


def test_a_call_cancelled_in_its_thread_returns_at_once_and_the_line_stays_in_sync(
    sim: Simulator[RegisterDevice],
) -> None:
    sim.reply_delay = 0.2

    async def main() -> None:
        async with aio.AsyncBus(sim.port, timeout=0.5, retries=0) as bus:
            first = asyncio.create_task(bus.read_holding_registers(1, 0, 1))
            await asyncio.sleep(0.05)  # its request is on the line
            assert len(sim.requests) == 1
            started = time.monotonic()
            first.cancel()
            with pytest.raises(asyncio.CancelledError):
                await first
            assert time.monotonic() - started < 0.05, "CancelledError at once"
            # The next call is answered by its own reply, not the cancelled one's.
            assert await bus.read_holding_registers(1, 1, 1) == [8]
            assert bus.stats.stale_bytes == 0

    run(main)


def test_a_call_cancelled_mid_reply_leaves_the_line_in_step(slave: ScriptedSlave) -> None:
    """Half the reply is on the line when the task is cancelled: the attempt reads the rest
    (not left for the next call to find), and no retry follows."""
    first = rtu("01 03 02 00 07")
    second = rtu("01 03 02 00 08")

    def serve() -> None:
        slave.received.append(read_up_to(slave.master, 8, 2.0))
        os.write(slave.master, first[:3])
        time.sleep(0.2)
        os.write(slave.master, first[3:])
        slave.received.append(read_up_to(slave.master, 8, 2.0))
        os.write(slave.master, second)

    server = threading.Thread(target=serve, daemon=True)
    server.start()

    async def main() -> None:
        async with aio.AsyncBus(slave.port, timeout=0.5, retries=2) as bus:
            call = asyncio.create_task(bus.read_holding_registers(1, 0, 1))
            await asyncio.sleep(0.1)  # the reply's first bytes have come
            call.cancel()
            with pytest.raises(asyncio.CancelledError):
                await call
            assert await bus.read_holding_registers(1, 1, 1) == [8]
            assert (bus.stats.retries, bus.stats.stale_bytes, bus.stats.crc_errors) == (0, 0, 0)

    run(main)
    server.join(2)
    assert slave.received == [rtu("01 03 00 00 00 01"), rtu("01 03 00 01 00 01")]


def test_a_call_cancelled_while_it_waits_out_its_write_interval_is_never_sent(
    sim: Simulator[RegisterDevice],
) -> None:
    """Before it is sent: the write waits in the core for the unit's write interval."""

    async def main() -> None:
        async with aio.AsyncBus(sim.port) as bus:
            await bus.write_register(1, 80, 1, write_interval=0.5)
            paced = asyncio.create_task(bus.write_register(1, 81, 2, write_interval=0.5))
            await asyncio.sleep(0.1)
            assert len(bus._pool._queue) == 0  # in its thread, waiting out the interval
            paced.cancel()
            with pytest.raises(asyncio.CancelledError):
                await paced
            await asyncio.sleep(0.6)

    run(main)
    assert len(sim.requests) == 1
    assert device_of(sim).registers[80:82] == [1, 0]


def test_aclose_lets_calls_in_threads_finish_and_fails_the_queued_ones_unsent(
    sim: Simulator[RegisterDevice],
) -> None:
    sim.reply_delay = 0.1

    async def main() -> None:
        bus = aio.AsyncBus(sim.port, timeout=0.5, workers=1)
        running = asyncio.create_task(bus.read_holding_registers(1, 0, 1))
        await asyncio.sleep(0.02)
        queued = asyncio.create_task(bus.write_register(1, 60, 5))
        await asyncio.sleep(0.02)
        await bus.aclose()
        assert await running == [7]
        with pytest.raises(bb.PortError, match="closed before it was sent"):
            await queued
        assert bus.closed and bus.bus.closed
        with pytest.raises(bb.PortError, match="closed"):
            await bus.read_holding_registers(1, 0, 1)
        with pytest.raises(bb.PortError):
            bus.poll(1, 0, interval=0.1)
        await bus.aclose()  # twice is harmless
        assert aio_threads() == []

    run(main)
    assert len(sim.requests) == 1
    assert device_of(sim).registers[60] == 0


def test_idle_threads_end_by_themselves(
    sim: Simulator[RegisterDevice], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(aio, "IDLE_END", 0.05)

    async def main() -> None:
        bus = aio.AsyncBus(sim.port)
        await asyncio.gather(*(bus.read_holding_registers(1, 0, 1) for _ in range(3)))
        assert aio_threads()
        await asyncio.sleep(0.3)
        assert aio_threads() == []  # even on a bus not closed
        assert await bus.read_holding_registers(1, 1, 1) == [8]  # a new thread takes it
        await bus.aclose()

    run(main)


def test_workers_are_checked() -> None:
    with pytest.raises(ValueError, match="workers"):
        aio.AsyncBus("/dev/null", workers=0)
    with pytest.raises(TypeError, match="workers"):
        aio.AsyncBus("/dev/null", workers=1.5)  # type: ignore[arg-type]


# ---- the poll ----------------------------------------------------------------------------------


def test_poll_on_absolute_deadlines(sim: Simulator[RegisterDevice]) -> None:
    async def main() -> None:
        async with aio.AsyncBus(sim.port) as bus:
            with pytest.raises(ValueError):
                bus.poll(1, 0, 126, interval=0.05)
            with pytest.raises(ValueError):
                bus.poll(1, 0, interval=0)
            assert sim.requests == []
            poll = bus.poll(1, 0, 2, interval=0.05, duration=0.3)
            assert poll.started is None
            samples: list[tuple[float, list[int], float]] = []
            async for t, values in poll:
                assert poll.started is not None
                samples.append((t, values, time.monotonic() - (poll.started + t)))
            assert [round(t, 3) for t, _, _ in samples] == [0.0, 0.05, 0.1, 0.15, 0.2, 0.25]
            assert all(values == [7, 8] for _, values, _ in samples)
            # Each read was made at its deadline, not before.
            assert all(0 <= late < 0.03 for _, _, late in samples), samples
            assert poll.missed == 0
            # A slow body skips the deadlines already past.
            slow = bus.poll(1, 0, interval=0.02, duration=0.2)
            count = 0
            async for _ in slow:
                count += 1
                await asyncio.sleep(0.05)
            assert slow.missed > 0 and count + slow.missed <= 10

    run(main)


def p99(values: list[float]) -> float:
    return sorted(values)[int(len(values) * 0.99)]


#: Samples of the 100 that show the poll ran at its rate: a loaded machine skips a few
#: deadlines (the poll skips what is past, it does not bunch them), a poll that stalls most.
MOST_OF_A_POLL = 80


async def lag_during_a_poll(port: str) -> tuple[float, float, int]:
    """A 1 ms ticker's p99 lag before and after a 1 s poll at 100 Hz, and during it; and
    how many samples the poll took."""
    async with aio.AsyncBus(port, timeout=0.25) as bus:
        window: list[float] = []
        idle: list[float] = []
        busy: list[float] = []
        samples = 0

        async def ticker(seconds: float) -> None:
            end = time.monotonic() + seconds
            while time.monotonic() < end:
                before = time.monotonic()
                await asyncio.sleep(0.001)
                lag = time.monotonic() - before - 0.001
                (busy if len(window) == 1 else idle).append(lag)

        ticks = asyncio.create_task(ticker(1.8))
        await asyncio.sleep(0.4)
        window.append(time.monotonic())
        async for _ in bus.poll(1, 0x3006, interval=0.01, duration=1.0):
            samples += 1
        window.append(time.monotonic())
        await ticks
        return p99(idle), p99(busy), samples


@pytest.fixture(scope="module")
def drive_in_another_process() -> Iterator[str]:
    """The port of a simulated drive served by another process (``benchbus sim drive``)."""
    env = {**os.environ, "PYTHONPATH": str(ROOT / "python")}
    proc = subprocess.Popen(
        [sys.executable, "-m", "benchbus", "sim", "drive", "--seconds", "120"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
    )
    try:
        assert proc.stdout is not None
        assert select.select([proc.stdout], [], [], 10)[0], "the simulator did not start"
        yield proc.stdout.readline().strip()
    finally:
        proc.terminate()
        proc.communicate(timeout=10)


@pytest.mark.timing
def test_loop_lag_during_a_100hz_poll_of_another_process(drive_in_another_process: str) -> None:
    """A 1 ms ticker's p99 lag during a 100 Hz poll stays within 0.5 ms of its idle p99.

    The loop runs on ``select()``, whose timeout has microseconds: with epoll (asyncio's
    default on Linux) any wake-up between two ticks, whoever causes it, rounds the next
    timeout up to a whole millisecond, which measures epoll, not what holds the loop up
    (the next test holds benchbus to one wake-up a call there).
    The machine is shared with other work: a run is tried up to three times, and one
    within the bound passes (a loop that benchbus blocks fails them all).
    """
    runs = []
    for _ in range(3):
        loop = asyncio.SelectorEventLoop(selectors.SelectSelector())
        try:
            idle, busy, samples = loop.run_until_complete(
                lag_during_a_poll(drive_in_another_process)
            )
        finally:
            loop.close()
        assert samples >= MOST_OF_A_POLL
        runs.append(f"p99 lag {busy * 1e3:.3f} ms, idle {idle * 1e3:.3f} ms")
        if busy <= idle + 0.0005:
            break
    else:
        pytest.fail("; ".join(runs))


class CountingSelector(selectors.DefaultSelector):
    """asyncio's default selector, counting the times I/O woke the loop."""

    def __init__(self) -> None:
        super().__init__()
        self.woken = 0

    def select(self, timeout: float | None = None) -> list[tuple[Any, int]]:
        events: list[tuple[Any, int]] = super().select(timeout)
        self.woken += bool(events)
        return events


@pytest.mark.timing
def test_on_the_default_loop_each_call_wakes_the_loop_once(drive_in_another_process: str) -> None:
    """On asyncio's default loop (epoll on Linux) each wake-up between two timers costs the
    next timer up to a millisecond, so what benchbus can do for the loop's lag there is to
    wake it as seldom as possible: once a call, to hand over its result (a pure-asyncio
    client is woken at least as often, by the reply's bytes). The poll's deadlines are
    timers, and the threads' hand-overs do not touch the loop."""
    selector = CountingSelector()
    loop = asyncio.SelectorEventLoop(selector)
    try:
        _, _, samples = loop.run_until_complete(lag_during_a_poll(drive_in_another_process))
    finally:
        loop.close()
    assert samples >= MOST_OF_A_POLL
    # The samples' results, and the opening and closing of the bus.
    assert samples <= selector.woken <= samples + 3, (selector.woken, samples)


# ---- the devices -------------------------------------------------------------------------------


def test_drive_on_an_async_bus() -> None:
    device = DriveDevice()

    async def main() -> None:
        async with aio.AsyncBus(Simulator(device).start().port, timeout=0.25) as bus:
            async with aio.Drive(bus, unit=1) as drive:
                assert drive.bus is bus and drive.unit == 1 and drive.family == "BLD"
                assert drive.units()["speed"] == "rpm"  # known without asking
                await drive.set("speed_setpoint", 1500)
                assert await drive.get("speed_setpoint") == 1500
                assert await drive.speed_setpoint == 1500  # a property, awaited
                with pytest.raises(AttributeError, match=r"await device\.assign"):
                    drive.comm_loss_timeout = 2.0
                await drive.assign("comm_loss_timeout", 2.0)  # a setting, not a register
                assert await drive.comm_loss_timeout == 2.0
                await drive.forward()
                telemetry = await drive.telemetry()
                assert isinstance(telemetry, bb.DriveTelemetry)
                assert telemetry.speed_reference == 1500
                assert (await drive.status()).state == bb.DriveState.FORWARD
                assert isinstance(drive.sync, bb.Drive)
                with pytest.raises(AttributeError, match=r"await device\.set"):
                    drive.speed_setpoint = 10
                with pytest.raises(AttributeError, match="did you mean 'speed_setpoint'"):
                    drive.speed_setpoin  # noqa: B018
                with pytest.raises(ValueError):
                    await drive.set("speed_setpoint", 99999)
                await drive.assign("speed_setpoint", 1200)  # a register's property
                assert await drive.get("speed_setpoint") == 1200
                with pytest.raises(AttributeError, match="did you mean 'comm_loss_timeout'"):
                    await drive.assign("comm_loss_timeuot", 1.0)
            assert device.commands == [1, 5]  # stopped on leaving
            assert not bus.closed  # the shared bus stays open
            assert await bus.read_holding_registers(1, 0x2001, 1) == [1200]

    run(main)


def stop_on_leaving(body: Callable[[aio.Drive], Awaitable[None]]) -> list[int]:
    """The drive's commands after ``async with`` around ``body`` on its own port."""
    device = DriveDevice()
    with Simulator(device) as sim:

        async def main() -> None:
            async with aio.Drive(sim.port) as drive:
                await body(drive)

        with pytest.raises(BaseException) as caught:
            run(main)
        assert not isinstance(caught.value, AssertionError), caught.value
    return device.commands


def test_leaving_the_block_stops_the_motor_on_exception_and_on_cancellation() -> None:
    async def fails(drive: aio.Drive) -> None:
        await drive.forward()
        raise RuntimeError("bench failed")

    assert stop_on_leaving(fails) == [1, 5]

    async def cancelled(drive: aio.Drive) -> None:
        await drive.forward()
        task = asyncio.current_task()
        assert task is not None
        asyncio.get_running_loop().call_later(0.05, task.cancel)
        await asyncio.sleep(10)

    assert stop_on_leaving(cancelled) == [1, 5]

    async def times_out(drive: aio.Drive) -> None:
        await drive.reverse()
        await asyncio.wait_for(asyncio.sleep(10), 0.05)

    assert stop_on_leaving(times_out) == [2, 5]


def test_the_stop_is_sent_even_when_the_task_is_cancelled_again_while_leaving() -> None:
    device = DriveDevice()
    with Simulator(device) as sim:
        sim.reply_delay = 0.1

        async def main() -> None:
            async def spin() -> None:
                async with aio.Drive(sim.port) as drive:
                    await drive.forward()
                    await asyncio.sleep(10)

            task = asyncio.create_task(spin())
            await asyncio.sleep(0.3)
            task.cancel()
            await asyncio.sleep(0.02)  # leaving the block: the stop is on its way
            task.cancel()
            with pytest.raises(asyncio.CancelledError):
                await task
            await asyncio.sleep(0.3)

        run(main)
        assert device.commands == [1, 5]


CTRL_C = """
import asyncio, sys
import benchbus as bb

async def main(port):
    async with bb.aio.Drive(port) as drive:
        await drive.forward()
        print("running", flush=True)
        await asyncio.sleep(30)

asyncio.run(main(sys.argv[1]))
"""


@contextlib.contextmanager
def running(script: str, port: str) -> Iterator[subprocess.Popen[str]]:
    """``script`` run on ``port`` in a process of its own, once it printed "running";
    killed on leaving if it has not ended."""
    proc = subprocess.Popen(
        [sys.executable, "-c", script, port],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env={**os.environ, "PYTHONPATH": str(ROOT / "python")},
    )
    try:
        assert proc.stdout is not None
        assert select.select([proc.stdout], [], [], 20)[0], "the script did not start"
        assert proc.stdout.readline() == "running\n"
        yield proc
    finally:
        proc.kill()


def test_ctrl_c_in_asyncio_run_stops_the_motor() -> None:
    device = DriveDevice()
    with Simulator(device) as sim, running(CTRL_C, sim.port) as proc:
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=20)
    assert "KeyboardInterrupt" in err
    assert device.commands == [1, 5]


def test_a_device_on_its_own_port_closes_it_and_its_threads() -> None:
    device = DriveDevice()
    with Simulator(device) as sim:

        async def main() -> None:
            drive = aio.Drive(sim.port, unit=1, timeout=0.2)
            assert drive.bus.timeout == 0.2 and drive.bus.baudrate == 19200
            assert await drive.get("speed") == 0
            await drive.aclose()
            assert drive.bus.bus.closed
            await drive.aclose()  # twice is harmless
            with pytest.raises(bb.PortError):
                await drive.get("speed")

        run(main)
        assert device.commands == []  # aclose closes, it does not stop


def test_pbl_drive() -> None:
    device = PblDevice()
    with Simulator({0x11: device}) as sim:

        async def main() -> None:
            async with aio.AsyncBus(sim.port, 115200, "E", timeout=0.2) as bus:
                async with aio.PblDrive(bus, unit=0x11) as pbl:
                    await pbl.set("internal_speed", 1200)
                    await pbl.start()
                    assert device.peek(0) & 1  # the control word's run bit
                    assert (await pbl.parameters())["internal_speed"] == 1200
                    assert set(await pbl.sample()) >= {"speed", "current"}
                assert device.peek(0) & 1 == 0  # stopped on leaving

        run(main)
        assert device.peek(201) == 1200


def test_j2_controller() -> None:
    device = J2Device()
    with Simulator({1: device}, baudrate=9600) as sim:

        async def main() -> None:
            async with aio.J2Controller(sim.port, 1) as j2:
                await j2.set("SV", 120.5)
                assert await j2.get("SV") == 120.5
                assert await j2.sv == 120.5
                assert set(await j2.sample()) == {"pv", "sv", "mv"}
                assert j2.table()[0].name  # static: plain

        run(main)


def test_instrument() -> None:
    device = TaisongDevice()
    with Simulator({1: device}) as sim:

        async def main() -> None:
            async with aio.AsyncBus(sim.port) as bus:
                meter = aio.Instrument(bus, unit=1)
                assert meter.max_read == 37
                await meter.write_register(0x0005, 100)
                assert await meter.read_register(0x0005) == 100
                assert len(await meter.read_registers(0x0000, 50)) == 50

        run(main)
        assert device.registers[0x0005] == 100


def test_instrument_counters_files_and_fifo(sim: Simulator[RegisterDevice]) -> None:
    async def main() -> None:
        async with aio.AsyncBus(sim.port) as bus:
            unit = aio.Instrument(bus, unit=2)
            counter = await unit.get_comm_event_counter()
            log = await unit.get_comm_event_log()
            # The 0x0B between them: a message and not an event, logged (sent 40, received 80).
            assert counter.status == log.status == 0
            assert log.event_count == counter.event_count and log.events[:2] == b"\x40\x80"
            await unit.write_file_record([(1, 0, [5, 6])])
            assert await unit.read_file_record([(1, 1, 1)]) == [[6]]
            assert await unit.read_fifo_queue(0) == []

    run(main)


def test_device_from_profile() -> None:
    path = ROOT / "examples" / "profiles" / "xy_md02.toml"
    sensor = ProfileDevice(path, values={"temperature": 23.4})
    with Simulator({1: sensor}) as sim:

        async def main() -> None:
            async with aio.AsyncBus(sim.port, 9600, timeout=0.5) as bus:
                dev = aio.Device.from_profile(path, bus, unit=1)
                assert dev.profile.name == "XY-MD02"
                assert await dev.temperature == 23.4  # a register, awaited
                assert await dev.read("temperature") == 23.4
                assert set(await dev.read_many(["temperature", "humidity"])) == {
                    "temperature",
                    "humidity",
                }
                sent = len(sim.requests)
                with pytest.raises(AttributeError, match="did you mean 'temperature'"):
                    dev.temperatur  # noqa: B018
                assert len(sim.requests) == sent  # nothing read to say so
                await dev.aclose()
                assert not bus.closed

        run(main)


# ---- loops -------------------------------------------------------------------------------------


def test_nothing_runs_a_loop_of_its_own() -> None:
    """In a loop that is already running (as a notebook's), and without asyncio.run."""
    source = (ROOT / "python" / "benchbus" / "aio.py").read_text("utf-8")
    assert "asyncio.run(" not in source and "run_until_complete" not in source
    device = RegisterDevice({0: 5})
    with Simulator({1: device}) as sim:
        loop = asyncio.new_event_loop()
        got: list[Any] = []

        async def cell() -> None:
            async with aio.AsyncBus(sim.port) as bus:
                got.append(await bus.read_holding_registers(1, 0, 1))
            loop.stop()

        loop.call_soon(lambda: loop.create_task(cell()))
        loop.run_forever()
        loop.close()
        assert got == [[5]]


def test_the_async_poll_example_runs() -> None:
    done = subprocess.run(
        [sys.executable, str(ROOT / "examples" / "async_poll.py")],
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
        env={**os.environ, "PYTHONPATH": str(ROOT / "python")},
    )
    assert done.returncode == 0, done.stderr
    out = done.stdout.splitlines()
    assert out[0].endswith(" rpm") and out[4] == "0.80 s  1200 rpm"
    assert out[5] == "20 samples, 0 missed"
    ticked = out[6].split()
    assert int(ticked[3]) >= 60  # ~100 in the second polled: the loop ran meanwhile
    assert out[7] == "commands the drive received: [1, 5]"


@pytest.mark.timeout(120)
def test_top_level_await_in_a_jupyter_kernel() -> None:
    """In the loop a Jupyter kernel runs, cells await the bus and a drive directly."""
    cells = [
        "import threading\n"
        "import benchbus as bb\n"
        "from benchbus.sim import DriveDevice, Simulator\n"
        "sim = Simulator({1: DriveDevice()}).start()\n"
        "bus = bb.aio.AsyncBus(sim.port)",
        "print(await bus.read_holding_registers(1, 0x2001, 1))",
        "async with bb.aio.Drive(bus, 1) as drive:\n"
        "    await drive.set('speed_setpoint', 900)\n"
        "    await drive.forward()\n"
        "    print(await drive.get('speed_setpoint'))\n"
        "print(sim.devices[1].commands)",
        "await bus.aclose()\n"
        "sim.stop()\n"
        "print([t.name for t in threading.enumerate() if t.name.startswith('benchbus.aio')])",
    ]
    notebook = nbformat.v4.new_notebook(cells=[nbformat.v4.new_code_cell(c) for c in cells])
    NotebookClient(notebook, timeout=60, kernel_name="python3").execute()
    printed = ["".join(o.get("text", "") for o in cell.outputs) for cell in notebook.cells]
    assert printed == ["", "[0]\n", "900\n[1, 5]\n", "[]\n"]


# ---- cancellation inside the core (its CancelToken) -------------------------------------------


def test_a_call_cancelled_mid_attempt_makes_no_further_attempt(
    sim: Simulator[RegisterDevice],
) -> None:
    sim.set_silent(1)

    async def main() -> None:
        async with aio.AsyncBus(sim.port, timeout=0.3, retries=3) as bus:
            call = asyncio.create_task(bus.read_holding_registers(1, 0, 1))
            await asyncio.sleep(0.1)  # its first attempt waits for a reply
            assert len(sim.requests) == 1
            call.cancel()
            with pytest.raises(asyncio.CancelledError):
                await call
            await asyncio.sleep(1.0)  # three more attempts would be on the line by now
            assert len(sim.requests) == 1
            assert bus.stats.retries == 0
            sim.set_silent(1, False)
            # The thread is free and the line in step: the next call gets its own reply.
            assert await bus.read_holding_registers(1, 1, 1) == [8]

    run(main)


def test_a_cancelled_device_method_sends_nothing_more(sim: Simulator[RegisterDevice]) -> None:
    """A device method of several requests stops at the one on the wire when cancelled."""
    sim.reply_delay = 0.1

    async def main() -> None:
        async with aio.AsyncBus(sim.port, timeout=0.5) as bus:
            meter = aio.Instrument(bus, unit=1, max_read=10)
            read = asyncio.create_task(meter.read_registers(0, 100))  # ten requests
            await asyncio.sleep(0.25)
            read.cancel()
            with pytest.raises(asyncio.CancelledError):
                await read
            await asyncio.sleep(0.3)
            assert 2 <= len(sim.requests) <= 4

    run(main)


@pytest.mark.timing  # the absent unit's 50 ms timeout, and equal shares measured in 2 s
def test_four_present_units_are_served_alike_beside_an_absent_one() -> None:
    """4 tasks polling 4 present units, a fifth an absent one (retried): the present units'
    completed calls per second are within 10 % of their mean."""
    with Simulator({u: RegisterDevice({0: u}) for u in range(1, 5)}) as sim:

        async def main() -> dict[int, int]:
            async with aio.AsyncBus(sim.port, timeout=0.05, retries=2) as bus:
                done = {u: 0 for u in range(1, 5)}
                end = time.monotonic() + 2.0

                async def present(unit: int) -> None:
                    while time.monotonic() < end:
                        assert await bus.read_holding_registers(unit, 0, 1) == [unit]
                        done[unit] += 1

                async def absent() -> None:
                    while time.monotonic() < end:
                        with pytest.raises(bb.ResponseTimeout):
                            await bus.read_holding_registers(9, 0, 1)

                await asyncio.gather(absent(), *(present(u) for u in range(1, 5)))
                return done

        done = run(main)
    mean = sum(done.values()) / len(done)
    assert mean > 20, done
    assert all(abs(n - mean) <= 0.1 * mean for n in done.values()), done


# ---- what a review found: each a test that hung, sent or lost something before ----------------


STATS_UNDER_LOAD = """
import asyncio, sys, time
from benchbus import aio

async def main(port):
    # A timeout long enough that a loaded machine's slow reply is not one: a hang is.
    async with aio.AsyncBus(port, timeout=1.0, retries=0) as bus:
        end = time.monotonic() + 1.5
        async def hammer():
            while time.monotonic() < end:
                await bus.read_holding_registers(1, 0, 1)
        tasks = [asyncio.create_task(hammer()) for _ in range(4)]
        reads = 0
        while time.monotonic() < end:
            bus.stats, bus.closed, repr(bus.bus)  # on the loop, while calls hold the line
            reads += 1
            await asyncio.sleep(0)
        await asyncio.gather(*tasks)
        print(reads, bus.stats.transactions)

asyncio.run(main(sys.argv[1]))
"""


def test_reading_the_stats_on_the_loop_while_calls_run_neither_blocks_nor_deadlocks(
    sim: Simulator[RegisterDevice],
) -> None:
    """A call on the line holds the Bus's state and logs into Python; the stats read on the
    loop (holding the GIL) used to wait for that state: the process hung."""
    done = subprocess.run(
        [sys.executable, "-c", STATS_UNDER_LOAD, sim.port],
        capture_output=True,
        text=True,
        timeout=30,
        check=False,
    )
    assert done.returncode == 0, done.stderr
    reads, transactions = map(int, done.stdout.split())
    assert transactions > 20 and reads > transactions


def test_a_call_cancelled_in_the_queue_is_not_sent_even_before_its_callback_runs(
    sim: Simulator[RegisterDevice],
) -> None:
    """The task is cancelled, then the loop is busy before the done-callback that takes the
    call out of the queue runs: a free thread must still not send it."""
    sim.reply_delay = 0.1

    async def main() -> None:
        async with aio.AsyncBus(sim.port, timeout=0.5, retries=0, workers=1) as bus:
            busy = asyncio.create_task(bus.read_holding_registers(1, 0, 1))
            await asyncio.sleep(0.05)
            queued = asyncio.create_task(bus.write_register(1, 50, 1234))
            await asyncio.sleep(0.01)
            queued.cancel()
            time.sleep(0.2)  # the loop is busy: the thread is free before the callback runs
            with pytest.raises(asyncio.CancelledError):
                await queued
            await busy
            await asyncio.sleep(0.2)

    run(main)
    assert len(sim.requests) == 1 and sim.requests[0][1] == 0x03
    assert device_of(sim).registers[50] != 1234


def test_a_call_raising_stop_iteration_reaches_its_task() -> None:
    async def main() -> None:
        pool = aio._Pool(1, "test")

        def stops() -> None:
            raise StopIteration("done")

        with pytest.raises(RuntimeError, match="StopIteration"):
            await asyncio.wait_for(pool.submit(stops), 5)
        await pool.close()

    run(main)


CANCELLED_WHILE_THE_STOP_WAITS = """
import asyncio, sys
import benchbus as bb

async def main(port):
    async with bb.aio.Drive(port, timeout=2.0) as drive:
        await drive.forward()
        async def poll():
            while True:
                await drive.get("speed")
        poller = asyncio.create_task(poll())
        print("running", flush=True)
        await asyncio.sleep(0.5)
        print("leaving", flush=True)
        raise RuntimeError("the bench failed")  # the stop queues behind a slow read

asyncio.run(main(sys.argv[1]))
"""


def test_ctrl_c_while_the_stop_waits_behind_a_read_still_sends_the_stop() -> None:
    device = DriveDevice()
    with Simulator(device) as sim:
        with running(CANCELLED_WHILE_THE_STOP_WAITS, sim.port) as proc:
            assert proc.stdout is not None
            sim.reply_delay = 0.8  # each read now holds the line for 0.8 s
            assert proc.stdout.readline() == "leaving\n"
            time.sleep(0.2)  # the stop is queued behind a read
            proc.send_signal(signal.SIGINT)
            proc.communicate(timeout=20)
        deadline = time.monotonic() + 3
        while device.commands != [1, 5] and time.monotonic() < deadline:
            time.sleep(0.05)
        assert device.commands == [1, 5]


def test_calls_reach_the_line_in_the_order_they_were_made_with_several_threads(
    sim: Simulator[RegisterDevice],
) -> None:
    """Eight threads: each call goes to the line only once the call made before it holds its
    place in the line's queue, so the line sees them in the order they were made, and the
    last of several writes to one register is the one that stays."""

    async def main() -> None:
        async with aio.AsyncBus(sim.port, timeout=0.3, workers=8) as bus:
            for _ in range(5):
                await asyncio.gather(*(bus.read_holding_registers(1, i, 1) for i in range(16)))
            for round_ in range(10):
                await asyncio.gather(*(bus.write_register(1, 40, round_ * 8 + v) for v in range(8)))
                assert device_of(sim).registers[40] == round_ * 8 + 7

    run(main)
    reads = [int.from_bytes(r[2:4], "big") for r in sim.requests if r[1] == 0x03]
    assert reads == list(range(16)) * 5


def test_a_token_says_when_its_call_took_its_place_in_line(
    sim: Simulator[RegisterDevice],
) -> None:
    with bb.Bus(sim.port, timeout=0.3) as bus:
        token = bb.CancelToken()
        assert not token.queued
        with token:
            with pytest.raises(ValueError):
                bus.read_holding_registers(1, 0, 0)  # refused before it asks for the line
            assert not token.queued
            bus.read_holding_registers(1, 0, 1)
        assert token.queued


def test_closing_begun_on_one_event_loop_is_awaited_from_another(
    sim: Simulator[RegisterDevice],
) -> None:
    """aclose() given up on a first loop (wait_for ran out while a call to a silent unit was
    on the line) goes on, and another loop's aclose() waits for the same closing."""
    sim.set_silent(2)
    bus = aio.AsyncBus(sim.port, timeout=0.5, retries=0)

    async def first() -> None:
        call = asyncio.create_task(bus.read_holding_registers(2, 0, 1))
        await asyncio.sleep(0.05)
        with pytest.raises(asyncio.TimeoutError):
            await asyncio.wait_for(bus.aclose(), 0.05)
        call.cancel()

    async def second() -> None:
        await asyncio.wait_for(bus.aclose(), 3)

    asyncio.run(first())
    asyncio.run(second())
    assert bus.closed
